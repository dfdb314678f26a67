#pragma once
// Basic value types shared by every lambert module.
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products
#include <cstdint>
#include <stdexcept>
#include <string>

namespace lambert {

using Vec3 = Eigen::Vector3d;  // positions in metres, or unit directions
using RGB = Eigen::Array3d;    // one value per colour channel (R, G, B)

// splitmix64 (Steele, Lea, Flood 2014): a 64-bit hash of an index, for sample jitter and seeds derived from indices
// alone (the same samples at any position and thread count).
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Per-patch colour field, one row per patch, columns R, G, B.
using ColorField = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Bad user input (malformed file, invalid value, ...). The message names the file and line, or the
// face index, and says what is wrong; the CLI prints it and exits non-zero.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A broken internal invariant (a bug, never the user's input): the CLI exits 2 ("internal error").
// Raise it with LAMBERT_CHECK, not by hand.
struct InternalError : std::logic_error {
  using std::logic_error::logic_error;
};

[[noreturn]] void check_failed(const char* condition, const char* file, int line, const std::string& what);

// LAMBERT_CHECK(cond, message): throws InternalError naming the condition, file:line and the message (any
// expression convertible to std::string) when cond is false. Always on (also in Release builds): the checks
// guard invariants whose breach would otherwise give a wrong answer silently.
#define LAMBERT_CHECK(cond, message)                                                 \
  do {                                                                               \
    if (!(cond)) ::lambert::check_failed(#cond, __FILE__, __LINE__, (message));      \
  } while (false)

// A file location for error messages: "scene.obj:12".
struct SourceLoc {
  std::string file;
  int line = 0;  // 1-based; 0 = unknown
  std::string str() const { return line > 0 ? file + ":" + std::to_string(line) : file; }
};

}  // namespace lambert
