// OFF / COFF reader and writer.
#include <algorithm>
#include <limits>
#include <unordered_map>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {
namespace {

using detail::fail;
using detail::quote;

class OffReader {
 public:
  explicit OffReader(const std::string& path) : path_(path), soup_(mesh::make_empty_soup(path)) {}

  mesh::PolygonSoup run() {
    std::string text = detail::read_file(path_);
    detail::LineReader lines(text, false, /*comments=*/true);
    lines_ = &lines;

    if (!next_line())
      fail(path_, 1, "empty file; expected the header 'OFF' followed by the counts 'vertices faces edges'");
    header();
    std::size_t first = 1;  // counts may follow the header on the same line
    if (tok_.size() == 1) {
      if (!next_line()) fail(path_, line_, "the file ends after the header; expected the counts 'vertices faces edges'");
      first = 0;
    }
    counts(first);
    // A count cannot promise more than the file holds: a vertex line takes at least 6 bytes ("0 0 0\n"), a
    // face line 8 ("3 0 1 2\n"); reservations are capped by that, and a count beyond it ends in "the file
    // ends after K of N" (with the line) after reading only what is there.
    const long long vertex_fit = static_cast<long long>(text.size() / 6), face_fit = static_cast<long long>(text.size() / 8);
    soup_.positions.reserve(static_cast<std::size_t>(std::min(nv_, vertex_fit)));
    for (long long i = 0; i < nv_; ++i) {
      if (!next_line()) ends("vertices", i, nv_);
      if (tok_.size() < 3)
        fail(path_, line_, "vertex " + std::to_string(i) + " has " + std::to_string(tok_.size()) +
                               " numbers; expected 'x y z'");
      static const char* axis[] = {"x coordinate", "y coordinate", "z coordinate"};
      Vec3 p;
      for (int c = 0; c < 3; ++c) p[c] = detail::finite_number(tok_[c], path_, line_, axis[c]);
      // Further numbers (COFF colour, NOFF normal) are not used but must be numbers.
      for (std::size_t c = 3; c < tok_.size(); ++c) detail::finite_number(tok_[c], path_, line_, "a vertex attribute");
      soup_.positions.push_back(p);
      soup_.position_lines.push_back(line_);
    }

    soup_.faces.reserve(static_cast<std::size_t>(std::min(nf_, face_fit)));
    for (long long i = 0; i < nf_; ++i) {
      if (!next_line()) ends("faces", i, nf_);
      face(i);
    }
    long extra = 0;
    while (next_line()) ++extra;
    if (extra) soup_.warnings.push_back(path_ + ": " + std::to_string(extra) + " lines after the last face ignored");
    return std::move(soup_);
  }

 private:
  // Next non-empty line (comments removed) into tok_.
  bool next_line() {
    std::string_view l;
    while (lines_->next(l, line_)) {
      detail::split(l, tok_);
      if (!tok_.empty()) return true;
    }
    line_ = lines_->last_line();
    return false;
  }

  [[noreturn]] void ends(const char* what, long long have, long long want) {
    fail(path_, line_, "the file ends after " + std::to_string(have) + " of " + std::to_string(want) + " " + what +
                           "; expected " + std::to_string(want) + " (counts at line " + std::to_string(counts_line_) + ")");
  }

  void header() {
    std::string_view h = tok_[0];
    if (h == "OFF" || h == "COFF" || h == "NOFF" || h == "CNOFF" || h == "NCOFF") {
      if (tok_.size() > 1 && tok_[1] == "BINARY") fail(path_, line_, "binary OFF is not supported; expected an ascii OFF file");
      return;
    }
    if (h.size() > 3 && h.substr(h.size() - 3) == "OFF")
      fail(path_, line_, "unsupported OFF variant " + quote(h) + "; expected OFF, COFF, NOFF or CNOFF");
    fail(path_, line_, "bad OFF header " + quote(h) + "; expected the keyword 'OFF' (or COFF) on the first line");
  }

  void counts(std::size_t first) {
    std::size_t n = tok_.size() - first;
    if (n < 2 || n > 3)
      fail(path_, line_, "malformed counts line; expected 'vertices faces edges' (3 integers), found " + std::to_string(n) + " values");
    counts_line_ = line_;
    long long c[3] = {0, 0, 0};
    static const char* what[] = {"vertex", "face", "edge"};
    for (std::size_t i = 0; i < n; ++i)
      if (detail::parse_integer(tok_[first + i], c[i]) != detail::NumStatus::ok || c[i] < 0 ||
          c[i] > std::numeric_limits<int>::max())
        fail(path_, line_, std::string("malformed ") + what[i] + " count " + quote(tok_[first + i]) + "; expected an integer >= 0");
    nv_ = c[0];
    nf_ = c[1];
  }

  void face(long long index) {
    long long n = 0;
    if (detail::parse_integer(tok_[0], n) != detail::NumStatus::ok)
      fail(path_, line_, "malformed vertex count " + quote(tok_[0]) + " of face " + std::to_string(index) +
                             "; expected 'n i1 .. in [r g b [a]]'");
    if (n < 3) fail(path_, line_, "face " + std::to_string(index) + " has " + std::to_string(n) + " vertices; expected at least 3");
    if (static_cast<long long>(tok_.size()) - 1 < n)
      fail(path_, line_, "face " + std::to_string(index) + " lists " + std::to_string(tok_.size() - 1) + " of its " +
                             std::to_string(n) + " vertex indices");
    mesh::SoupFace f;
    f.line = line_;
    f.vertices.reserve(n);
    for (long long i = 1; i <= n; ++i) {
      long long v = 0;
      if (detail::parse_integer(tok_[i], v) != detail::NumStatus::ok)
        fail(path_, line_, "malformed vertex index " + quote(tok_[i]) + " in face " + std::to_string(index) + "; expected an integer");
      if (v < 0 || v >= nv_)
        fail(path_, line_, "vertex index " + std::to_string(v) + " in face " + std::to_string(index) +
                               " is out of range; expected 0 .. " + std::to_string(nv_ - 1) + " (" + std::to_string(nv_) + " vertices)");
      f.vertices.push_back(static_cast<int>(v));
    }
    std::size_t nc = tok_.size() - 1 - n;
    if (nc == 0) {
      ++soup_.faces_without_material;
    } else if (nc == 3 || nc == 4) {
      bool ints = true;
      for (std::size_t c = 0; c < nc; ++c) ints = ints && detail::integer_syntax(tok_[n + 1 + c]);
      RGB colour;
      for (std::size_t c = 0; c < nc; ++c) {
        double v = detail::finite_number(tok_[n + 1 + c], path_, line_, "a face colour value");
        if (c < 3) colour[c] = ints ? v / 255.0 : v;  // integers are 0..255, decimals 0..1; alpha unused
      }
      f.material = detail::colour_material(soup_, colour_index_, colour, SourceLoc{path_, line_});
    } else {
      fail(path_, line_, "face " + std::to_string(index) + " has " + std::to_string(nc) +
                             " values after its indices; expected 0 or a colour 'r g b' or 'r g b a'");
    }
    soup_.faces.push_back(std::move(f));
  }

  std::string path_;
  mesh::PolygonSoup soup_;
  detail::LineReader* lines_ = nullptr;
  std::vector<std::string_view> tok_;
  int line_ = 0, counts_line_ = 0;
  long long nv_ = 0, nf_ = 0;
  std::unordered_map<std::string, int> colour_index_;
};

std::string colour_text(const RGB& c) {
  int k[3];
  bool bytes = detail::byte_value(c[0], k[0]) && detail::byte_value(c[1], k[1]) && detail::byte_value(c[2], k[2]);
  std::string s;
  for (int i = 0; i < 3; ++i) {
    s += ' ';
    if (bytes) {
      s += std::to_string(k[i]);
    } else {
      std::string d = detail::format_double(c[i]);
      if (detail::integer_syntax(d)) d += ".0";  // a decimal, so the reader does not take it as 0..255
      s += d;
    }
  }
  return s;
}

}  // namespace

mesh::PolygonSoup read_off(const std::string& path) { return OffReader(path).run(); }

void write_off(const mesh::PolygonSoup& soup, const std::string& path) {
  std::string out = "OFF\n# written by lambert\n";
  out += std::to_string(soup.positions.size()) + ' ' + std::to_string(soup.faces.size()) + " 0\n";
  for (const Vec3& p : soup.positions)
    out += detail::format_double(p[0]) + ' ' + detail::format_double(p[1]) + ' ' + detail::format_double(p[2]) + '\n';
  for (const mesh::SoupFace& f : soup.faces) {
    out += std::to_string(f.vertices.size());
    for (int v : f.vertices) out += ' ' + std::to_string(v);
    if (f.material != 0) out += colour_text(soup.materials.at(f.material).reflectance);
    out += '\n';
  }
  detail::write_file_atomic(path, out);
}

}  // namespace lambert::io
