#pragma once
// Basic value types shared by every lambert module.
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products
#include <stdexcept>
#include <string>

namespace lambert {

using Vec3 = Eigen::Vector3d;  // positions in metres, or unit directions
using RGB = Eigen::Array3d;    // one value per colour channel (R, G, B)

// Per-patch colour field, one row per patch, columns R, G, B.
using ColorField = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Bad user input (malformed file, invalid value, ...). The message names the file and line, or the
// face index, and says what is wrong; the CLI prints it and exits non-zero.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A file location for error messages: "scene.obj:12".
struct SourceLoc {
  std::string file;
  int line = 0;  // 1-based; 0 = unknown
  std::string str() const { return line > 0 ? file + ":" + std::to_string(line) : file; }
};

}  // namespace lambert
