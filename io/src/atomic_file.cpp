#include "lambert/io/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <random>
#include <sstream>
#include <system_error>

#include "lambert/mesh/types.hpp"

namespace lambert::io {

namespace fs = std::filesystem;

// ---- temporaries removed on SIGINT / SIGTERM ---------------------------------------------------------
// A fixed table of paths, written before a temporary is created and cleared after it was renamed or
// removed; the handler only reads it (lock-free atomics, unlink and write: async-signal-safe).
namespace {

constexpr int kSlots = 64;
constexpr std::size_t kPathMax = 4096;
char g_paths[kSlots][kPathMax];
std::atomic<int> g_state[kSlots];  // 0 free, 1 being filled, 2 registered

static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs lock-free atomics");

void append(char* buf, std::size_t& n, std::size_t cap, const char* s) {
  while (*s && n + 1 < cap) buf[n++] = *s++;
}

extern "C" void remove_temporaries_and_die(int sig) {
  int removed = 0;
  for (int i = 0; i < kSlots; ++i)
    if (g_state[i].load() == 2 && ::unlink(g_paths[i]) == 0) ++removed;
  char msg[200];
  std::size_t n = 0;
  append(msg, n, sizeof msg, sig == SIGINT ? "lambert: interrupted (SIGINT)" : "lambert: terminated (SIGTERM)");
  append(msg, n, sizeof msg, ": removed ");
  char digits[12];
  int d = 0, r = removed;
  do digits[d++] = char('0' + r % 10), r /= 10;
  while (r && d < 11);
  while (d) msg[n++] = digits[--d];
  append(msg, n, sizeof msg, removed == 1 ? " temporary output file" : " temporary output files");
  append(msg, n, sizeof msg, "; outputs not yet renamed are unchanged\n");
  ssize_t ignored = ::write(STDERR_FILENO, msg, n);
  (void)ignored;
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

int register_temporary(const std::string& path) {
  remove_temporaries_on_signal();
  if (path.size() >= kPathMax) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (g_state[i].compare_exchange_strong(expected, 1)) {
      std::memcpy(g_paths[i], path.c_str(), path.size() + 1);
      g_state[i].store(2);
      return i;
    }
  }
  return -1;  // table full: the temporary is still removed on every failure, just not on a signal
}

void unregister_temporary(int slot) {
  if (slot >= 0) g_state[slot].store(0);
}

// Registers a temporary for its lifetime.
struct Registered {
  explicit Registered(const std::string& p) : slot(register_temporary(p)) {}
  ~Registered() { unregister_temporary(slot); }
  Registered(const Registered&) = delete;
  Registered& operator=(const Registered&) = delete;
  int slot;
};

}  // namespace

void remove_temporaries_on_signal() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (int sig : {SIGINT, SIGTERM}) {
      struct sigaction old{};
      if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;  // e.g. nohup: keep ignoring
      struct sigaction sa{};
      sa.sa_handler = remove_temporaries_and_die;
      sigemptyset(&sa.sa_mask);
      ::sigaction(sig, &sa, nullptr);
    }
  });
}

std::string temporary_sibling(const std::string& path) {
  // Random bits plus a process-wide counter: distinct names for concurrent writers in one process and,
  // with overwhelming probability, across processes.
  static std::atomic<unsigned long> counter{0};
  thread_local std::mt19937_64 rng{std::random_device{}()};
  const unsigned long long tag = rng() ^ (counter.fetch_add(1) * 0x9E3779B97F4A7C15ull);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", tag);
  const fs::path p(path);
  std::string name = p.filename().string();
  name.insert(name.begin(), '.');  // hidden: file browsers and globs skip it
  name.append(".tmp-").append(hex);
  return (p.parent_path() / name).string();
}

void commit_temporary(const std::string& temporary, const std::string& path) {
  std::error_code ec;
  fs::rename(temporary, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw InputError("cannot write '" + path + "': rename of the temporary file failed: " + ec.message());
  }
}

namespace {

// Writes fill's output to `tmp` (created new), checking the stream after fill and after close. On any
// failure removes tmp and throws (InputError naming `path`, or fill's own exception).
void write_temporary(const std::string& tmp, const std::string& path, const std::function<void(std::ostream&)>& fill) {
  auto discard = [&] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
  };
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  if (!out.is_open()) {
    const int err = errno;
    discard();  // nothing should exist, but never leave a stray temporary
    throw InputError("cannot write '" + path + "': cannot create a file in its directory" +
                     (err ? std::string(": ") + std::strerror(err) : std::string()));
  }
  try {
    fill(out);
  } catch (...) {
    out.close();
    discard();
    throw;
  }
  if (!out) {
    out.close();
    discard();
    throw InputError("cannot write '" + path + "': write error (disk full or I/O error?)");
  }
  out.close();  // flushes: a full disk often shows up only here
  if (!out) {
    discard();
    throw InputError("cannot write '" + path + "': error when closing the file (disk full or I/O error?)");
  }
}

}  // namespace

void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& fill) {
  const std::string tmp = temporary_sibling(path);
  Registered reg(tmp);
  write_temporary(tmp, path, fill);
  commit_temporary(tmp, path);
}

// ---- OutputSet ------------------------------------------------------------------------------------------

namespace {

bool is_stream_name(const std::string& p) {
  return p == "-" || p == "/dev/stdout" || p == "/dev/stderr" || p == "/dev/null";
}

// The final target of a chain of symbolic links (the path itself if it is not a link).
fs::path follow_links(const std::string& path) {
  fs::path p(path);
  for (int depth = 0; depth < 40; ++depth) {
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(p, ec);
    if (ec || !fs::is_symlink(st)) return p;
    const fs::path t = fs::read_symlink(p, ec);
    if (ec) return p;
    p = t.is_absolute() ? t : p.parent_path() / t;
  }
  throw InputError("cannot write '" + path + "': too many levels of symbolic links");
}

// Identity of a file: device and inode when it exists (hard links and symlinks compare equal), else
// its normalised absolute path.
std::string file_key(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) return "inode:" + std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(fs::path(path), ec), ec);
  if (ec) p = fs::absolute(fs::path(path)).lexically_normal();
  return "path:" + p.string();
}

const char* kind_of(const fs::file_status& st) {
  switch (st.type()) {
    case fs::file_type::directory: return "a directory";
    case fs::file_type::fifo: return "a FIFO (named pipe)";
    case fs::file_type::socket: return "a socket";
    case fs::file_type::block: return "a block device";
    case fs::file_type::character: return "a character device";
    default: return "not a regular file";
  }
}

}  // namespace

struct OutputSet::Entry {
  std::string path;    // as given
  std::string what;    // option name for messages
  std::string target;  // after following symbolic links (what the rename replaces)
  std::string key;
  bool stream = false;
  bool written = false;
  std::string tmp;
  std::unique_ptr<Registered> reg;
  std::string buffer;  // stream outputs: content until commit
};

OutputSet::OutputSet() { remove_temporaries_on_signal(); }

OutputSet::~OutputSet() {
  if (committed_) return;
  for (auto& e : outputs_)
    if (!e->tmp.empty()) {
      std::error_code ignored;
      fs::remove(e->tmp, ignored);
    }
}

void OutputSet::add_input(const std::string& path) {
  const std::string key = file_key(path);
  for (const auto& e : outputs_)
    if (!e->stream && e->key == key)
      throw InputError("refusing to write " + e->what + " '" + e->path + "': it is an input of this run ('" + path +
                       "'); choose another output path");
  inputs_.push_back(path);
  input_keys_.push_back(key);
}

void OutputSet::add_output(const std::string& path, const std::string& what) {
  if (path.empty()) throw InputError(what + ": empty output path");
  auto e = std::make_unique<Entry>();
  e->path = path;
  e->what = what;
  if (is_stream_name(path)) {
    e->stream = true;
    e->key = "stream:" + path;
    outputs_.push_back(std::move(e));
    return;
  }
  e->target = follow_links(path).string();
  std::error_code ec;
  const fs::file_status st = fs::status(e->target, ec);
  if (!ec && fs::exists(st) && !fs::is_regular_file(st))
    throw InputError("refusing to write " + what + " '" + path + "': " +
                     (e->target == path ? std::string() : "it links to '" + e->target + "', which is ") + kind_of(st) +
                     "; outputs must be regular files (or -, /dev/stdout, /dev/stderr, /dev/null)");
  fs::path dir = fs::path(e->target).parent_path();
  if (dir.empty()) dir = ".";
  if (!fs::is_directory(dir, ec))
    throw InputError("cannot write " + what + " '" + path + "': the directory '" + dir.string() + "' does not exist");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw InputError("cannot write " + what + " '" + path + "': the directory '" + dir.string() +
                     "' is not writable: " + std::strerror(errno));
  e->key = file_key(e->target);
  for (size_t i = 0; i < input_keys_.size(); ++i)
    if (input_keys_[i] == e->key)
      throw InputError("refusing to write " + what + " '" + path + "': it is an input of this run ('" + inputs_[i] +
                       "'); choose another output path");
  for (const auto& o : outputs_)
    if (o->key == e->key)
      throw InputError("refusing to write " + what + " '" + path + "': it is also the " + o->what + " output ('" +
                       o->path + "'); choose distinct output paths");
  outputs_.push_back(std::move(e));
}

OutputSet::Entry& OutputSet::find(const std::string& path) {
  for (auto& e : outputs_)
    if (e->path == path) return *e;
  check_failed("declared output", __FILE__, __LINE__, "output '" + path + "' was not declared with add_output");
}

void OutputSet::write(const std::string& path, const std::function<void(std::ostream&)>& fill) {
  Entry& e = find(path);
  LAMBERT_CHECK(!committed_ && !e.written, "output '" + path + "' written twice or after commit");
  if (e.stream) {
    std::ostringstream os;
    fill(os);
    e.buffer = std::move(os).str();
    e.written = true;
    return;
  }
  e.tmp = temporary_sibling(e.target);
  e.reg = std::make_unique<Registered>(e.tmp);
  try {
    write_temporary(e.tmp, path, fill);
  } catch (...) {
    e.reg.reset();
    e.tmp.clear();
    throw;
  }
  // Keep the permissions of the file it replaces.
  std::error_code ec;
  const fs::file_status old = fs::status(e.target, ec);
  if (!ec && fs::is_regular_file(old)) fs::permissions(e.tmp, old.permissions(), ec);
  e.written = true;
}

void OutputSet::commit() {
  LAMBERT_CHECK(!committed_, "OutputSet::commit called twice");
  for (const auto& e : outputs_) LAMBERT_CHECK(e->written, "output '" + e->path + "' was declared but not written");
  // Hard-link backups of the files about to be replaced, so that a failed rename can undo the earlier ones.
  std::vector<std::string> backups(outputs_.size());
  std::vector<std::unique_ptr<Registered>> backup_regs;
  auto drop_backups = [&] {
    for (auto& b : backups)
      if (!b.empty()) ::unlink(b.c_str());
    backup_regs.clear();
  };
  for (size_t i = 0; i < outputs_.size(); ++i) {
    const Entry& e = *outputs_[i];
    if (e.stream || !fs::exists(e.target)) continue;
    std::string b = temporary_sibling(e.target);
    if (::link(e.target.c_str(), b.c_str()) == 0) backups[i] = b;
  }
  for (size_t i = 0; i < outputs_.size(); ++i) {
    Entry& e = *outputs_[i];
    if (e.stream) continue;
    std::error_code ec;
    fs::rename(e.tmp, e.target, ec);
    if (ec) {
      std::string undone;
      for (size_t j = 0; j < i; ++j) {
        Entry& d = *outputs_[j];
        if (d.stream) continue;
        std::error_code ignored;
        if (!backups[j].empty()) {
          fs::rename(backups[j], d.target, ignored);
          backups[j].clear();
        } else {
          undone += " '" + d.path + "' (could not be restored)";
        }
      }
      drop_backups();
      for (size_t j = i; j < outputs_.size(); ++j)
        if (!outputs_[j]->tmp.empty()) {
          std::error_code ignored;
          fs::remove(outputs_[j]->tmp, ignored);
        }
      committed_ = true;
      throw InputError("cannot write " + e.what + " '" + e.path + "': rename of the temporary file failed: " +
                       ec.message() + (undone.empty() ? "; no output was changed" : "; changed:" + undone));
    }
    e.reg.reset();
    e.tmp.clear();
  }
  drop_backups();
  committed_ = true;
  for (auto& e : outputs_) {
    if (!e->stream) continue;
    if (e->path == "-" || e->path == "/dev/stdout") {
      std::cout.write(e->buffer.data(), std::streamsize(e->buffer.size()));
      std::cout.flush();
      if (!std::cout) throw InputError("cannot write " + e->what + " to standard output: write error");
    } else {
      std::ofstream os(e->path, std::ios::binary);
      os.write(e->buffer.data(), std::streamsize(e->buffer.size()));
      os.close();
      if (!os) throw InputError("cannot write " + e->what + " '" + e->path + "': write error");
    }
  }
}

}  // namespace lambert::io
