#pragma once
// Output files appear complete or not at all: write a temporary sibling, then rename it over the target.
#include <functional>
#include <ostream>
#include <string>

namespace lambert::io {

// A fresh, unused-looking name "<dir>/.<name>.tmp-<random hex>" in the directory of `path`
// (same file system, so the final rename is atomic). Does not create anything.
std::string temporary_sibling(const std::string& path);

// Renames `temporary` to `path` (replacing it). On failure removes `temporary` and throws
// lambert::InputError naming `path` and the reason.
void commit_temporary(const std::string& temporary, const std::string& path);

// Writes `path` by calling fill(stream) on a binary stream to a temporary sibling, checking the stream
// after fill and after close, then renaming. Throws lambert::InputError naming `path` if the file cannot
// be created, written or renamed; an exception thrown by `fill` propagates unchanged. In every failure
// the temporary is removed and an existing `path` is left untouched.
void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& fill);

}  // namespace lambert::io

#include <memory>
#include <vector>

namespace lambert::io {

// All outputs of one run as a transaction: each is written to a temporary sibling of its target, and
// only when every output was written completely are the temporaries renamed over their targets. If any
// write fails, or the run ends early (exception, SIGINT/SIGTERM), no existing file changes and no
// temporary is left behind.
//
//   OutputSet out;
//   out.add_input(scene);                     // files the run reads: never an output
//   out.add_output(vtu, "-o");                // checked now, before any work
//   ... work ...
//   out.write(vtu, [&](std::ostream& os) { ... });
//   out.commit();                             // all renamed, or none (InputError)
//
// Paths are checked when added (InputError, exit 1 in the CLI): an output may not be an input of the run
// or another output (same file, also through links), nor a directory, FIFO, socket or device node,
// except the plainly meant streams "-" (standard output), /dev/stdout, /dev/stderr and /dev/null, which
// are written directly at commit (not transactional). A symbolic link is written through: its final
// target is replaced, the link stays. The target's directory must exist.
class OutputSet {
 public:
  OutputSet();
  ~OutputSet();  // uncommitted: removes every temporary
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  // A file the run reads (scene, MTL, --materials). Throws InputError if it is already an output.
  void add_input(const std::string& path);
  // An output; `what` names it in messages (e.g. "-o", "--stats"). Throws InputError as described above.
  void add_output(const std::string& path, const std::string& what);
  // Writes the complete content of a declared output to its temporary (an exception from fill, a write
  // error or a full disk throws, removing that temporary; the targets stay untouched).
  void write(const std::string& path, const std::function<void(std::ostream&)>& fill);
  // Renames all temporaries over their targets, then writes the streams. If a rename fails, the targets
  // renamed before are restored from hard-link backups (where the file system allows them) and
  // InputError names the path. Call once.
  void commit();

 private:
  struct Entry;
  std::vector<std::unique_ptr<Entry>> outputs_;
  std::vector<std::string> inputs_;  // as given, for messages
  std::vector<std::string> input_keys_;
  Entry& find(const std::string& path);
  bool committed_ = false;
};

// Installs (once) SIGINT/SIGTERM handlers that remove every registered temporary and say so on stderr,
// then end the process by the same signal. write_file_atomically and OutputSet register their
// temporaries themselves; the CLI calls this at start so that an interrupted run leaves nothing behind.
void remove_temporaries_on_signal();

}  // namespace lambert::io
