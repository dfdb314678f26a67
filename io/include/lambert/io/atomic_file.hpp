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
