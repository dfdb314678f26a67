#include <filesystem>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {

mesh::PolygonSoup read_soup(const std::string& path) {
  std::string ext = detail::lower(std::filesystem::path(path).extension().string());
  if (ext == ".obj") return read_obj(path);
  if (ext == ".ply") return read_ply(path);
  if (ext == ".off") return read_off(path);
  throw InputError(path + ": unknown scene file extension " + (ext.empty() ? std::string("(none)") : detail::quote(ext)) +
                   "; supported: .obj (with .mtl), .ply, .off");
}

}  // namespace lambert::io
