// STL reader (binary and ASCII, told apart by content) and writer.
#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <vector>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "lambert/io/readers.hpp"
#include "lambert/mesh/geometry.hpp"
#include "read_util.hpp"

namespace lambert::io {
namespace {

using detail::fail;
using detail::quote;

constexpr std::size_t kHeader = 80 + 4, kFacet = 50;

float le_float(const char* p) {
  std::uint32_t u;
  std::memcpy(&u, p, 4);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

std::uint32_t le_u32(const char* p) {
  std::uint32_t u;
  std::memcpy(&u, p, 4);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
  return u;
}

bool binary_size_matches(const std::string& bytes) {
  return bytes.size() >= kHeader && bytes.size() == kHeader + kFacet * std::uint64_t(le_u32(bytes.data() + 80));
}

// ASCII when the first word is "solid" and the text has no NUL byte before its first "facet" or
// "endsolid" (binary headers may start with "solid" too: a matching binary size wins).
bool looks_ascii(const std::string& bytes) {
  std::size_t i = 0;
  while (i < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[i]))) ++i;
  if (bytes.compare(i, 5, "solid") != 0) return false;
  const std::size_t n = std::min<std::size_t>(bytes.size(), 4096);
  return std::memchr(bytes.data(), '\0', n) == nullptr;
}

void add_triangle(mesh::PolygonSoup& soup, const Vec3 (&v)[3], const int (&lines)[3], int line) {
  mesh::SoupFace f;
  for (int c = 0; c < 3; ++c) {
    f.vertices.push_back(static_cast<int>(soup.positions.size()));
    soup.positions.push_back(v[c]);
    soup.position_lines.push_back(lines[c]);
  }
  f.line = line;
  soup.faces.push_back(std::move(f));
}

mesh::PolygonSoup read_binary(const std::string& path, const std::string& bytes) {
  mesh::PolygonSoup soup = mesh::make_empty_soup(path);
  if (bytes.size() < kHeader)
    throw InputError(path + ": " + std::to_string(bytes.size()) +
                     " bytes: too short for a binary STL (an 80-byte header and a 4-byte facet count), and not "
                     "ASCII STL (which starts with 'solid')");
  const std::uint64_t n = le_u32(bytes.data() + 80);
  const std::uint64_t need = kHeader + kFacet * n;
  if (bytes.size() < need) {
    const std::uint64_t whole = (bytes.size() - kHeader) / kFacet;
    throw InputError(path + ": binary STL facet " + std::to_string(whole) + " is truncated: the header says " +
                     std::to_string(n) + " facets (" + std::to_string(need) + " bytes) but the file has " +
                     std::to_string(bytes.size()) + " bytes (" + std::to_string(whole) + " whole facets)");
  }
  if (bytes.size() > need)
    throw InputError(path + ": binary STL: the header says " + std::to_string(n) + " facets (" +
                     std::to_string(need) + " bytes) but the file has " + std::to_string(bytes.size()) +
                     " bytes: " + std::to_string(bytes.size() - need) + " bytes after facet " +
                     std::to_string(n == 0 ? 0 : n - 1) + " (a wrong facet count?)");
  soup.positions.reserve(3 * n);
  soup.faces.reserve(n);
  const int no_line[3] = {0, 0, 0};
  for (std::uint64_t k = 0; k < n; ++k) {
    const char* p = bytes.data() + kHeader + kFacet * k + 12;  // skip the normal: the winding decides
    Vec3 v[3];
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a) {
        const double x = le_float(p + 12 * c + 4 * a);
        if (!std::isfinite(x))
          throw InputError(path + ": binary STL facet " + std::to_string(k) + ", vertex " + std::to_string(c) +
                           ": non-finite coordinate");
        v[c][a] = x;
      }
    add_triangle(soup, v, no_line, 0);
  }
  return soup;
}

class AsciiReader {
 public:
  AsciiReader(const std::string& path, const std::string& text)
      : path_(path), lines_(text, false, false), soup_(mesh::make_empty_soup(path)) {}

  mesh::PolygonSoup run() {
    if (!next() || tok_[0] != "solid") fail(path_, line_, "expected 'solid NAME' at the start of an ASCII STL file");
    solid();
    while (next()) {
      if (tok_[0] != "solid")
        fail(path_, line_, "expected 'solid NAME' or the end of the file after 'endsolid', found " + quote(text_));
      solid();
    }
    return std::move(soup_);
  }

 private:
  void solid() {
    std::string name;
    for (std::size_t i = 1; i < tok_.size(); ++i) name += (i > 1 ? " " : "") + std::string(tok_[i]);
    int group = -1;
    if (!name.empty()) {
      soup_.groups.push_back(name);
      group = static_cast<int>(soup_.groups.size()) - 1;
    }
    while (true) {
      if (!next()) fail(path_, line_, "the file ends inside 'solid' (after facet " + last_facet() + "); expected 'endsolid'");
      if (tok_[0] == "endsolid") return;
      if (tok_[0] != "facet")
        fail(path_, line_, "facet " + std::to_string(soup_.faces.size()) + ": expected 'facet normal nx ny nz' or "
                           "'endsolid', found " + quote(text_));
      facet(group);
    }
  }

  void facet(int group) {
    const std::string who = "facet " + std::to_string(soup_.faces.size());
    const int facet_line = line_;
    if (tok_.size() != 5 || tok_[1] != "normal")
      fail(path_, line_, who + ": expected 'facet normal nx ny nz', found " + quote(text_));
    for (int a = 2; a < 5; ++a) detail::finite_number(tok_[a], path_, line_, who + " normal");
    expect("outer", who, "'outer loop'");
    if (tok_.size() != 2 || tok_[1] != "loop") fail(path_, line_, who + ": expected 'outer loop', found " + quote(text_));
    Vec3 v[3];
    int lines[3];
    for (int c = 0; c < 3; ++c) {
      expect("vertex", who, "'vertex x y z' (a facet has 3 vertices)");
      if (tok_.size() != 4)
        fail(path_, line_, who + ": vertex " + std::to_string(c) + " has " + std::to_string(tok_.size() - 1) +
                               " numbers; expected 'vertex x y z'");
      static const char* axis[] = {" x coordinate", " y coordinate", " z coordinate"};
      for (int a = 0; a < 3; ++a) v[c][a] = detail::finite_number(tok_[a + 1], path_, line_, who + axis[a]);
      lines[c] = line_;
    }
    if (!next()) fail(path_, line_, who + ": the file ends inside the facet; expected 'endloop'");
    if (tok_[0] == "vertex") fail(path_, line_, who + " has more than 3 vertices (STL facets are triangles)");
    if (tok_[0] != "endloop") fail(path_, line_, who + ": expected 'endloop', found " + quote(text_));
    expect("endfacet", who, "'endfacet'");
    add_triangle(soup_, v, lines, facet_line);
    soup_.faces.back().group = group;
  }

  void expect(std::string_view word, const std::string& who, const std::string& what) {
    if (!next()) fail(path_, line_, who + ": the file ends inside the facet; expected " + what);
    if (tok_[0] != word) fail(path_, line_, who + ": expected " + what + ", found " + quote(text_));
  }

  std::string last_facet() const {
    return soup_.faces.empty() ? std::string("none") : std::to_string(soup_.faces.size() - 1);
  }

  bool next() {
    std::string_view l;
    while (lines_.next(l, line_)) {
      text_ = detail::trim(l);
      if (text_.empty()) continue;
      detail::split(text_, tok_);
      return true;
    }
    line_ = lines_.last_line();
    return false;
  }

  std::string path_;
  detail::LineReader lines_;
  mesh::PolygonSoup soup_;
  std::vector<std::string_view> tok_;
  std::string_view text_;
  int line_ = 0;
};

}  // namespace

namespace detail {
bool is_stl(const std::string& bytes) { return binary_size_matches(bytes) || looks_ascii(bytes); }
}  // namespace detail

mesh::PolygonSoup read_stl(const std::string& path) {
  const std::string bytes = detail::read_file(path);
  if (binary_size_matches(bytes)) return read_binary(path, bytes);
  if (looks_ascii(bytes)) return AsciiReader(path, bytes).run();
  return read_binary(path, bytes);  // throws, naming the truncated facet or the size mismatch
}

void write_stl(const mesh::PolygonSoup& soup, const std::string& path, bool binary) {
  // Triangles: n-gons are split as build_scene would (ear clipping on their Newell plane).
  std::vector<std::array<Vec3, 3>> tris;
  for (const auto& f : soup.faces) {
    std::vector<Vec3> poly;
    for (int v : f.vertices) poly.push_back(soup.positions.at(v));
    if (poly.size() == 3) {
      tris.push_back({poly[0], poly[1], poly[2]});
      continue;
    }
    const Vec3 n = mesh::newell_normal(poly);
    if (!(n.norm() > 0)) throw InputError(path + ": cannot write a zero-area face to STL");
    for (const auto& t : mesh::triangulate_polygon(poly, n.normalized())) tris.push_back({poly[t[0]], poly[t[1]], poly[t[2]]});
  }
  std::string out;
  auto unit_normal = [](const std::array<Vec3, 3>& t) {
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
    return n.norm() > 0 ? Vec3(n.normalized()) : Vec3(Vec3::Zero());
  };
  if (binary) {
    out.assign(80, ' ');
    out.replace(0, 19, "binary STL, lambert");
    auto put32 = [&](std::uint32_t u) {
      if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
      out.append(reinterpret_cast<const char*>(&u), 4);
    };
    auto putf = [&](double x) {
      const float f = static_cast<float>(x);
      std::uint32_t u;
      std::memcpy(&u, &f, 4);
      put32(u);
    };
    put32(static_cast<std::uint32_t>(tris.size()));
    for (const auto& t : tris) {
      const Vec3 n = unit_normal(t);
      for (int a = 0; a < 3; ++a) putf(n[a]);
      for (const Vec3& p : t)
        for (int a = 0; a < 3; ++a) putf(p[a]);
      out.append(2, '\0');
    }
  } else {
    out = "solid lambert\n";
    for (const auto& t : tris) {
      const Vec3 n = unit_normal(t);
      out += "  facet normal " + detail::format_double(n[0]) + ' ' + detail::format_double(n[1]) + ' ' +
             detail::format_double(n[2]) + "\n    outer loop\n";
      for (const Vec3& p : t)
        out += "      vertex " + detail::format_double(p[0]) + ' ' + detail::format_double(p[1]) + ' ' +
               detail::format_double(p[2]) + '\n';
      out += "    endloop\n  endfacet\n";
    }
    out += "endsolid lambert\n";
  }
  detail::write_file_atomic(path, out);
}

}  // namespace lambert::io
