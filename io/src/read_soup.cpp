#include <filesystem>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {

namespace detail {
bool is_stl(const std::string& bytes);  // stl.cpp
}

mesh::PolygonSoup read_soup(const std::string& path) {
  std::string ext = detail::lower(std::filesystem::path(path).extension().string());
  if (ext == ".obj") return read_obj(path);
  if (ext == ".ply") return read_ply(path);
  if (ext == ".off") return read_off(path);
  if (ext == ".stl") return read_stl(path);
  // Unknown extension: by content.
  std::string bytes, error;
  if (detail::try_read_file(path, bytes, error)) {
    auto starts = [&](std::string_view word) {
      return bytes.size() >= word.size() && std::string_view(bytes).substr(0, word.size()) == word;
    };
    if (starts("ply\n") || starts("ply\r\n")) return read_ply(path);
    if (starts("OFF") || starts("COFF") || starts("NOFF") || starts("CNOFF")) return read_off(path);
    if (detail::is_stl(bytes)) return read_stl(path);
  }
  throw InputError(path + ": unknown scene file extension " + (ext.empty() ? std::string("(none)") : detail::quote(ext)) +
                   " and not recognised by content; supported: .obj (with .mtl), .ply, .off, .stl (binary or ASCII)");
}

}  // namespace lambert::io
