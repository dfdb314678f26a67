#include "lambert/io/atomic_file.hpp"

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <system_error>

#include "lambert/mesh/types.hpp"

namespace lambert::io {

namespace fs = std::filesystem;

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

void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& fill) {
  const std::string tmp = temporary_sibling(path);
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
  commit_temporary(tmp, path);
}

}  // namespace lambert::io
