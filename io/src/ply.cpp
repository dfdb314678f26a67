// PLY reader (ascii, binary little/big endian) and writer.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <unordered_map>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {
namespace {

using detail::fail;
using detail::quote;

enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };

std::optional<Type> type_from_name(std::string_view s) {
  static const std::pair<const char*, Type> names[] = {
      {"char", Type::i8},     {"int8", Type::i8},     {"uchar", Type::u8},  {"uint8", Type::u8},
      {"short", Type::i16},   {"int16", Type::i16},   {"ushort", Type::u16}, {"uint16", Type::u16},
      {"int", Type::i32},     {"int32", Type::i32},   {"uint", Type::u32},  {"uint32", Type::u32},
      {"float", Type::f32},   {"float32", Type::f32}, {"double", Type::f64}, {"float64", Type::f64}};
  for (auto& [n, t] : names)
    if (s == n) return t;
  return std::nullopt;
}

const char* type_name(Type t) {
  static const char* n[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double"};
  return n[static_cast<int>(t)];
}

int type_size(Type t) {
  static const int s[] = {1, 1, 2, 2, 4, 4, 4, 8};
  return s[static_cast<int>(t)];
}

bool is_integer(Type t) { return t != Type::f32 && t != Type::f64; }

struct Property {
  std::string name;
  bool list = false;
  Type count_type = Type::u8;
  Type type = Type::f32;  // item type for lists
  int line = 0;           // header line
};

struct Element {
  std::string name;
  long long count = 0;
  int line = 0;
  std::vector<Property> props;
};

enum class Format { ascii, binary_le, binary_be };

// Where a value is read: the role a property plays for lambert.
enum class Role { skip, x, y, z, indices, red, green, blue };

// Reads the values of one element instance, from an ascii line or from binary bytes.
class Source {
 public:
  Source(const std::string& file, std::string_view data, Format format, int first_line)
      : file_(file), data_(data), format_(format), lines_(data, false, false), line_offset_(first_line - 1) {}

  // Starts element instance `index` of `elem`.
  void begin(const Element& elem, long long index) {
    elem_ = &elem;
    index_ = index;
    if (format_ != Format::ascii) return;
    std::string_view l;
    do {
      if (!lines_.next(l, line_)) {
        line_ = lines_.last_line() + line_offset_;
        error("the file ends; expected " + std::to_string(elem.count) + " '" + elem.name + "' lines (header line " +
              std::to_string(elem.line) + ")");
      }
      line_ += line_offset_;
      detail::split(l, tok_);
    } while (tok_.empty());
    next_tok_ = 0;
  }

  void end() {
    if (format_ == Format::ascii && next_tok_ < tok_.size())
      error(std::to_string(tok_.size() - next_tok_) + " extra values at the end of the line; expected " +
            std::to_string(next_tok_) + " values for this '" + elem_->name + "'");
  }

  // One value of type t as double (integers are exact: at most 32 bits).
  double value(Type t, const Property& prop, bool need_finite) {
    if (format_ == Format::ascii) return ascii_value(t, prop, need_finite);
    return binary_value(t, prop, need_finite);
  }

  [[noreturn]] void error(const std::string& what) const {
    std::string where = "element '" + elem_->name + "' " + std::to_string(index_) + " (of " + std::to_string(elem_->count) + ")";
    if (format_ == Format::ascii) fail(file_, line_, where + ": " + what);
    throw InputError(file_ + ": " + where + ": " + what);
  }

  // Trailing content after the last element (reported, not an error).
  std::string trailing() {
    if (format_ != Format::ascii) {
      std::size_t rest = data_.size() - pos_;
      return rest ? std::to_string(rest) + " bytes of data after the last element ignored" : "";
    }
    std::string_view l;
    int line, n = 0;
    while (lines_.next(l, line))
      if (!detail::trim(l).empty()) ++n;
    return n ? std::to_string(n) + " non-empty lines after the last element ignored" : "";
  }

  int line() const { return format_ == Format::ascii ? line_ : 0; }

  // How many more values of type t the data can still hold (ascii: on this line; binary: in the bytes
  // left). Caps a list's reservation: a count cannot promise more than the file holds.
  double capacity(Type t) const {
    if (format_ == Format::ascii) return static_cast<double>(tok_.size() - next_tok_);
    return static_cast<double>((data_.size() - pos_) / static_cast<std::size_t>(type_size(t)));
  }

 private:
  double ascii_value(Type t, const Property& prop, bool need_finite) {
    if (next_tok_ >= tok_.size())
      error("the line ends at property '" + prop.name + "'; expected more values (" + std::to_string(next_tok_) +
            " found)");
    std::string_view tok = tok_[next_tok_++];
    if (is_integer(t)) {
      long long v = 0;
      static const long long lo[] = {-128, 0, -32768, 0, std::numeric_limits<std::int32_t>::min(), 0};
      static const long long hi[] = {127, 255, 32767, 65535, std::numeric_limits<std::int32_t>::max(),
                                     std::numeric_limits<std::uint32_t>::max()};
      int ti = static_cast<int>(t);
      if (detail::parse_integer(tok, v) != detail::NumStatus::ok || v < lo[ti] || v > hi[ti])
        error("value " + quote(tok) + " of property '" + prop.name + "' is not a " + type_name(t) + "; expected an integer in [" +
              std::to_string(lo[ti]) + ", " + std::to_string(hi[ti]) + "]");
      return static_cast<double>(v);
    }
    double v = 0;
    switch (detail::parse_double(tok, v)) {
      case detail::NumStatus::ok:
        return v;
      case detail::NumStatus::malformed:
        error("malformed number " + quote(tok) + " for property '" + prop.name + "'; expected a decimal number");
      case detail::NumStatus::out_of_range:
      case detail::NumStatus::not_finite:
        if (need_finite)
          error("property '" + prop.name + "' is " + quote(tok) + " (not a finite double); expected a finite number");
        return v;  // a skipped property may hold anything
    }
    return v;
  }

  double binary_value(Type t, const Property& prop, bool need_finite) {
    int n = type_size(t);
    if (data_.size() - pos_ < static_cast<std::size_t>(n))
      error("truncated binary data: the file ends inside property '" + prop.name + "' (" + type_name(t) + ", " +
            std::to_string(n) + " bytes needed, " + std::to_string(data_.size() - pos_) + " left)");
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, n);
    pos_ += n;
    bool little = format_ == Format::binary_le;
    if (little != (std::endian::native == std::endian::little)) std::reverse(b, b + n);
    double v = 0;
    switch (t) {
      case Type::i8: v = static_cast<std::int8_t>(b[0]); break;
      case Type::u8: v = b[0]; break;
      case Type::i16: { std::int16_t x; std::memcpy(&x, b, 2); v = x; break; }
      case Type::u16: { std::uint16_t x; std::memcpy(&x, b, 2); v = x; break; }
      case Type::i32: { std::int32_t x; std::memcpy(&x, b, 4); v = x; break; }
      case Type::u32: { std::uint32_t x; std::memcpy(&x, b, 4); v = x; break; }
      case Type::f32: { float x; std::memcpy(&x, b, 4); v = x; break; }
      case Type::f64: { std::memcpy(&v, b, 8); break; }
    }
    if (need_finite && !std::isfinite(v))
      error("property '" + prop.name + "' is " + detail::format_double(v) + "; expected a finite number");
    return v;
  }

  const std::string& file_;
  std::string_view data_;
  Format format_;
  std::size_t pos_ = 0;  // binary read position
  detail::LineReader lines_;
  int line_offset_;  // header lines before data_
  int line_ = 0;
  std::vector<std::string_view> tok_;
  std::size_t next_tok_ = 0;
  const Element* elem_ = nullptr;
  long long index_ = 0;
};

double colour_scale(Type t) {
  switch (t) {
    case Type::i16:
    case Type::u16: return 65535.0;
    case Type::f32:
    case Type::f64: return 1.0;
    default: return 255.0;
  }
}

class PlyReader {
 public:
  explicit PlyReader(const std::string& path) : path_(path), soup_(mesh::make_empty_soup(path)) {}

  mesh::PolygonSoup run() {
    text_ = detail::read_file(path_);
    std::size_t data_start = header();
    Source src(path_, std::string_view(text_).substr(data_start), format_, header_lines_ + 1);
    for (const Element& e : elements_) {
      if (e.name == "vertex") vertices(src, e);
      else if (e.name == "face") faces(src, e);
      else skip(src, e);
    }
    std::string rest = src.trailing();
    if (!rest.empty()) soup_.warnings.push_back(path_ + ": " + rest);
    return std::move(soup_);
  }

 private:
  std::size_t header() {
    detail::LineReader lines(text_, false, false);
    std::string_view l;
    int line = 0;
    std::vector<std::string_view> t;
    if (!lines.next(l, line) || detail::trim(l) != "ply")
      fail(path_, 1, "not a PLY file: the first line is " + quote(detail::trim(l)) + "; expected 'ply'");
    bool have_format = false;
    while (true) {
      if (!lines.next(l, line)) fail(path_, line, "the header has no 'end_header' line");
      detail::split(l, t);
      if (t.empty()) continue;
      if (t[0] == "end_header") break;
      if (t[0] == "comment" || t[0] == "obj_info") continue;
      if (t[0] == "format") {
        if (t.size() != 3) fail(path_, line, "malformed format line; expected 'format ascii|binary_little_endian|binary_big_endian 1.0'");
        if (t[1] == "ascii") format_ = Format::ascii;
        else if (t[1] == "binary_little_endian") format_ = Format::binary_le;
        else if (t[1] == "binary_big_endian") format_ = Format::binary_be;
        else fail(path_, line, "unknown PLY format " + quote(t[1]) + "; expected ascii, binary_little_endian or binary_big_endian");
        if (t[2] != "1.0" && t[2] != "1") fail(path_, line, "unsupported PLY version " + quote(t[2]) + "; expected 1.0");
        have_format = true;
      } else if (t[0] == "element") {
        if (t.size() != 3) fail(path_, line, "malformed element line; expected 'element NAME COUNT'");
        Element e;
        e.name = t[1];
        e.line = line;
        if (detail::parse_integer(t[2], e.count) != detail::NumStatus::ok || e.count < 0 ||
            e.count > std::numeric_limits<int>::max())
          fail(path_, line, "element count " + quote(t[2]) + " is not a valid count; expected an integer >= 0");
        for (const Element& o : elements_)
          if (o.name == e.name) fail(path_, line, "element '" + e.name + "' is declared twice (line " + std::to_string(o.line) + ")");
        elements_.push_back(e);
      } else if (t[0] == "property") {
        if (elements_.empty()) fail(path_, line, "property before any element line; expected 'element NAME COUNT' first");
        Property p;
        auto type = [&](std::string_view s) {
          auto ty = type_from_name(s);
          if (!ty)
            fail(path_, line, "unknown property type " + quote(s) +
                                  "; expected char, uchar, short, ushort, int, uint, float, double (or int8 ... float64)");
          return *ty;
        };
        if (t.size() == 5 && t[1] == "list") {
          p.list = true;
          p.count_type = type(t[2]);
          if (!is_integer(p.count_type)) fail(path_, line, "list count type " + quote(t[2]) + " is not an integer type");
          p.type = type(t[3]);
          p.name = t[4];
        } else if (t.size() == 3 && t[1] != "list") {
          p.type = type(t[1]);
          p.name = t[2];
        } else {
          fail(path_, line, "malformed property line; expected 'property TYPE NAME' or 'property list COUNT_TYPE ITEM_TYPE NAME'");
        }
        p.line = line;
        elements_.back().props.push_back(p);
      } else {
        fail(path_, line, "unknown header line " + quote(t[0]) + "; expected format, element, property, comment, obj_info or end_header");
      }
    }
    if (!have_format) fail(path_, line, "the header has no 'format' line");
    header_lines_ = line;
    check_roles();
    return lines.offset();
  }

  // A header count cannot promise more than the file holds: each element instance takes at least a fixed
  // number of bytes (binary: its scalars and list counts; ascii: a character and a separator per value), so
  // reservations are capped by what the data can hold; a count beyond that ends in the reader's own
  // "the file ends" error (with line and element index) after reading only what is there.
  long long capacity(const Element& e) const {
    double per = 0;
    for (const Property& p : e.props)
      per += format_ == Format::ascii ? 2.0 : static_cast<double>(type_size(p.list ? p.count_type : p.type));
    const double fit = static_cast<double>(text_.size()) / std::max(per, 1.0);
    return static_cast<long long>(std::min(static_cast<double>(e.count), fit));
  }

  void check_roles() {
    for (const Element& el : elements_) {
      auto find = [&](std::string_view name) -> int {
        for (std::size_t i = 0; i < el.props.size(); ++i)
          if (el.props[i].name == name) return static_cast<int>(i);
        return -1;
      };
      if (el.name == "vertex") {
        for (const char* c : {"x", "y", "z"}) {
          int i = find(c);
          if (i < 0) fail(path_, el.line, std::string("element 'vertex' has no property '") + c + "'; expected x, y, z");
          if (el.props[i].list) fail(path_, el.props[i].line, std::string("vertex property '") + c + "' is a list; expected a scalar");
        }
      } else if (el.name == "face") {
        int i = find("vertex_indices");
        if (i < 0) i = find("vertex_index");
        if (i < 0) fail(path_, el.line, "element 'face' has no property 'vertex_indices' (or 'vertex_index')");
        indices_prop_ = i;
        if (!el.props[i].list) fail(path_, el.props[i].line, "face property '" + el.props[i].name + "' is not a list; expected 'property list uchar int " + el.props[i].name + "'");
        if (!is_integer(el.props[i].type)) fail(path_, el.props[i].line, "face property '" + el.props[i].name + "' has item type " + type_name(el.props[i].type) + "; expected an integer type");
        int colours = 0;
        for (const char* c : {"red", "green", "blue"}) {
          int k = find(c);
          if (k >= 0 && el.props[k].list) fail(path_, el.props[k].line, std::string("face property '") + c + "' is a list; expected a scalar");
          colours += k >= 0;
        }
        if (colours != 0 && colours != 3) fail(path_, el.line, "element 'face' has only some of red, green, blue; expected all three or none");
      }
    }
    bool has_vertex = std::any_of(elements_.begin(), elements_.end(), [](auto& e) { return e.name == "vertex"; });
    for (const Element& el : elements_)
      if (el.name == "face" && el.count > 0 && !has_vertex) fail(path_, el.line, "element 'face' without an element 'vertex'");
  }

  long long vertex_count() const {
    for (const Element& e : elements_)
      if (e.name == "vertex") return e.count;
    return 0;
  }

  static Role role(const Element& e, const Property& p) {
    if (e.name == "vertex") {
      if (p.name == "x") return Role::x;
      if (p.name == "y") return Role::y;
      if (p.name == "z") return Role::z;
    } else if (e.name == "face") {
      if (p.name == "vertex_indices" || p.name == "vertex_index") return Role::indices;
      if (p.name == "red") return Role::red;
      if (p.name == "green") return Role::green;
      if (p.name == "blue") return Role::blue;
    }
    return Role::skip;
  }

  void skip_list(Source& src, const Property& p) {
    double n = src.value(p.count_type, p, false);
    if (n < 0) src.error("list property '" + p.name + "' has negative length " + detail::format_double(n));

    for (long long i = 0; i < static_cast<long long>(n); ++i) src.value(p.type, p, false);
  }

  void vertices(Source& src, const Element& e) {
    soup_.positions.reserve(static_cast<std::size_t>(capacity(e)));
    for (long long k = 0; k < e.count; ++k) {
      src.begin(e, k);
      Vec3 p = Vec3::Zero();
      for (const Property& prop : e.props) {
        Role r = role(e, prop);
        if (r == Role::skip) {
          if (prop.list) skip_list(src, prop);
          else src.value(prop.type, prop, false);
        } else {
          p[static_cast<int>(r) - static_cast<int>(Role::x)] = src.value(prop.type, prop, true);
        }
      }
      src.end();
      soup_.positions.push_back(p);
      soup_.position_lines.push_back(src.line());
    }
  }

  void faces(Source& src, const Element& e) {
    const long long nv = vertex_count();
    soup_.faces.reserve(static_cast<std::size_t>(capacity(e)));
    for (long long k = 0; k < e.count; ++k) {
      src.begin(e, k);
      mesh::SoupFace f;
      RGB colour = RGB::Zero();
      bool coloured = false;
      for (std::size_t pi = 0; pi < e.props.size(); ++pi) {
        const Property& prop = e.props[pi];
        Role r = role(e, prop);
        if (static_cast<int>(pi) == indices_prop_) {
          double n = src.value(prop.count_type, prop, true);
          if (n < 3) src.error("face has " + detail::format_double(n) + " vertices; expected at least 3");
          f.vertices.clear();
          // Capped by what the data can still hold (a list count of 4e9 in a small file).
          f.vertices.reserve(static_cast<std::size_t>(std::min(n, src.capacity(prop.type))));
          for (long long i = 0; i < static_cast<long long>(n); ++i) {
            double v = src.value(prop.type, prop, true);
            if (v < 0 || v >= static_cast<double>(nv))
              src.error("vertex index " + detail::format_double(v) + " is out of range; expected 0 .. " +
                        std::to_string(nv - 1) + " (" + std::to_string(nv) + " vertices)");
            f.vertices.push_back(static_cast<int>(v));
          }
        } else if (r == Role::red || r == Role::green || r == Role::blue) {
          colour[static_cast<int>(r) - static_cast<int>(Role::red)] = src.value(prop.type, prop, true) / colour_scale(prop.type);
          coloured = true;
        } else if (prop.list) {
          skip_list(src, prop);
        } else {
          src.value(prop.type, prop, false);
        }
      }
      src.end();
      f.line = src.line();
      if (coloured) {
        f.material = detail::colour_material(soup_, colour_index_, colour, SourceLoc{path_, f.line});
      } else {
        ++soup_.faces_without_material;
      }
      soup_.faces.push_back(std::move(f));
    }
  }

  void skip(Source& src, const Element& e) {
    for (long long k = 0; k < e.count; ++k) {
      src.begin(e, k);
      for (const Property& prop : e.props) {
        if (prop.list) skip_list(src, prop);
        else src.value(prop.type, prop, false);
      }
      src.end();
    }
  }

  std::string path_;
  mesh::PolygonSoup soup_;
  std::string text_;
  Format format_ = Format::ascii;
  std::vector<Element> elements_;
  int indices_prop_ = -1;  // position of the face index list among the face properties
  int header_lines_ = 0;
  std::unordered_map<std::string, int> colour_index_;
};

template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if constexpr (std::endian::native != std::endian::little) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

}  // namespace

mesh::PolygonSoup read_ply(const std::string& path) { return PlyReader(path).run(); }

void write_ply(const mesh::PolygonSoup& soup, const std::string& path, bool binary) {
  bool coloured = false, bytes = true, small = true;
  for (const mesh::SoupFace& f : soup.faces) {
    small = small && f.vertices.size() <= 255;
    if (f.material != 0) coloured = true;
  }
  if (coloured)
    for (const mesh::SoupFace& f : soup.faces)
      for (int c = 0; c < 3; ++c) {
        int k;
        bytes = bytes && detail::byte_value(soup.materials.at(f.material).reflectance[c], k);
      }
  std::string out = "ply\nformat ";
  out += binary ? "binary_little_endian 1.0\n" : "ascii 1.0\n";
  out += "comment written by lambert\n";
  out += "element vertex " + std::to_string(soup.positions.size()) + "\n";
  out += "property double x\nproperty double y\nproperty double z\n";
  out += "element face " + std::to_string(soup.faces.size()) + "\n";
  out += small ? "property list uchar int vertex_indices\n" : "property list uint int vertex_indices\n";
  if (coloured)
    for (const char* c : {"red", "green", "blue"}) out += std::string("property ") + (bytes ? "uchar " : "double ") + c + "\n";
  out += "end_header\n";
  for (const Vec3& p : soup.positions) {
    if (binary) {
      for (int i = 0; i < 3; ++i) put<double>(out, p[i]);
    } else {
      out += detail::format_double(p[0]) + ' ' + detail::format_double(p[1]) + ' ' + detail::format_double(p[2]) + '\n';
    }
  }
  for (const mesh::SoupFace& f : soup.faces) {
    const RGB& c = soup.materials.at(f.material).reflectance;
    if (binary) {
      if (small) put<std::uint8_t>(out, static_cast<std::uint8_t>(f.vertices.size()));
      else put<std::uint32_t>(out, static_cast<std::uint32_t>(f.vertices.size()));
      for (int v : f.vertices) put<std::int32_t>(out, v);
      if (coloured)
        for (int i = 0; i < 3; ++i) {
          int k = 0;
          if (bytes && detail::byte_value(c[i], k)) put<std::uint8_t>(out, static_cast<std::uint8_t>(k));
          else put<double>(out, c[i]);
        }
    } else {
      out += std::to_string(f.vertices.size());
      for (int v : f.vertices) out += ' ' + std::to_string(v);
      if (coloured)
        for (int i = 0; i < 3; ++i) {
          int k = 0;
          out += ' ';
          out += bytes && detail::byte_value(c[i], k) ? std::to_string(k) : detail::format_double(c[i]);
        }
      out += '\n';
    }
  }
  detail::write_file_atomic(path, out);
}

}  // namespace lambert::io
