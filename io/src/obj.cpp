// Wavefront OBJ + MTL reader and writer.
#include <algorithm>
#include <filesystem>
#include <limits>
#include <set>
#include <unordered_map>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {
namespace {

namespace fs = std::filesystem;
using detail::fail;
using detail::quote;

struct UseMtl {
  std::string name;
  int line;
};

class ObjReader {
 public:
  explicit ObjReader(const std::string& path) : path_(path), soup_(mesh::make_empty_soup(path)) {}

  mesh::PolygonSoup run() {
    std::string text = detail::read_file(path_);
    detail::LineReader lines(text, /*continuation=*/true, /*comments=*/true);
    std::string_view l;
    int line = 0;
    while (lines.next(l, line)) statement(l, line);
    finish();
    return std::move(soup_);
  }

 private:
  void statement(std::string_view l, int line) {
    detail::split(l, tok_);
    if (tok_.empty()) return;
    std::string_view kw = tok_[0];
    if (kw == "v") {
      if (tok_.size() < 4)
        fail(path_, line, "vertex has " + std::to_string(tok_.size() - 1) + " numbers; expected 'v x y z [w]'");
      static const char* axis[] = {"x coordinate", "y coordinate", "z coordinate"};
      Vec3 p;
      for (int i = 0; i < 3; ++i) p[i] = detail::finite_number(tok_[i + 1], path_, line, axis[i]);
      soup_.positions.push_back(p);
      soup_.position_lines.push_back(line);
    } else if (kw == "f" || kw == "fo") {
      face(line);
    } else if (kw == "vt" || kw == "vn" || kw == "vp" || kw == "s") {
      // texture coordinates, normals, smoothing groups: not used by the radiosity solver
    } else if (kw == "l") {
      ++lines_;
    } else if (kw == "p") {
      ++points_;
    } else if (kw == "o" || kw == "g") {
      std::string name(rest(l, kw));
      if (name.empty()) {
        group_ = -1;  // "g" alone returns to the default (no) group
      } else {
        auto [it, added] = group_index_.emplace(name, static_cast<int>(soup_.groups.size()));
        if (added) soup_.groups.push_back(name);
        group_ = it->second;
      }
    } else if (kw == "mtllib") {
      mtllib(rest(l, kw), line);
    } else if (kw == "usemtl") {
      std::string name(rest(l, kw));
      if (name.empty()) fail(path_, line, "usemtl without a material name; expected 'usemtl NAME'");
      usemtl_.push_back({name, line});
    } else {
      if (unsupported_ == 0) first_unsupported_ = quote(kw) + " at line " + std::to_string(line);
      ++unsupported_;
    }
  }

  static std::string_view rest(std::string_view l, std::string_view kw) {
    std::string_view t = detail::trim(l);
    return detail::trim(t.substr(kw.size()));
  }

  void face(int line) {
    int n = static_cast<int>(tok_.size()) - 1;
    if (n < 3)
      fail(path_, line, "face has " + std::to_string(n) + " vertices; expected at least 3 ('f v1 v2 v3 ...')");
    mesh::SoupFace f;
    f.vertices.reserve(n);
    for (int i = 1; i <= n; ++i) f.vertices.push_back(vertex_ref(tok_[i], line));
    f.group = group_;
    f.line = line;
    soup_.faces.push_back(std::move(f));
    face_usemtl_.push_back(static_cast<int>(usemtl_.size()) - 1);
  }

  // "v", "v/vt", "v//vn", "v/vt/vn"; only v is used, vt/vn are checked for syntax.
  int vertex_ref(std::string_view t, int line) {
    std::string_view part[3];
    int parts = 0;
    std::size_t start = 0;
    for (;;) {
      std::size_t slash = t.find('/', start);
      if (parts == 3) break;  // a third slash
      part[parts++] = t.substr(start, slash == std::string_view::npos ? std::string_view::npos : slash - start);
      if (slash == std::string_view::npos) {
        start = std::string_view::npos;
        break;
      }
      start = slash + 1;
    }
    long long dummy;
    bool ok = start == std::string_view::npos && detail::parse_integer(part[0], dummy) == detail::NumStatus::ok;
    if (ok && parts == 2) ok = detail::parse_integer(part[1], dummy) == detail::NumStatus::ok;
    if (ok && parts == 3)
      ok = (part[1].empty() || detail::parse_integer(part[1], dummy) == detail::NumStatus::ok) &&
           detail::parse_integer(part[2], dummy) == detail::NumStatus::ok;
    if (!ok)
      fail(path_, line, "malformed face vertex " + quote(t) + "; expected v, v/vt, v//vn or v/vt/vn with integer indices");
    long long v = 0;
    detail::parse_integer(part[0], v);
    long long defined = static_cast<long long>(soup_.positions.size());
    if (v == 0) fail(path_, line, "vertex index 0 in face; OBJ indices start at 1 (negative = relative to the last vertex)");
    if (v < 0) {
      if (-v > defined)
        fail(path_, line, "relative vertex index " + std::to_string(v) + " is out of range: only " +
                              std::to_string(defined) + " vertices are defined before this line");
      return static_cast<int>(defined + v);
    }
    if (v > std::numeric_limits<int>::max())
      fail(path_, line, "vertex index " + std::to_string(v) + " is out of range");
    return static_cast<int>(v - 1);  // checked against the final vertex count in finish()
  }

  void mtllib(std::string_view names, int line) {
    if (names.empty()) fail(path_, line, "mtllib without a file name; expected 'mtllib FILE.mtl ...'");
    fs::path dir = fs::path(path_).parent_path();
    std::vector<std::string> files;
    std::error_code ec;
    // A single name with blanks in it, else blank-separated names.
    if (names.find_first_of(" \t") != std::string_view::npos && fs::is_regular_file(dir / fs::path(names), ec)) {
      files.emplace_back(names);
    } else {
      std::vector<std::string_view> t;
      detail::split(names, t);
      for (auto n : t) files.emplace_back(n);
    }
    for (const std::string& name : files) {
      fs::path p = dir / fs::path(name);
      std::string key = fs::weakly_canonical(p, ec).string();
      if (ec) key = p.lexically_normal().string();
      if (!loaded_mtl_.insert(key).second) continue;  // same library listed twice
      std::string text, error;
      if (!detail::try_read_file(p.string(), text, error))
        fail(path_, line, "cannot read material library " + quote(name) + " (" + p.string() + "): " + error);
      parse_mtl(text, p.string());
    }
  }

  void parse_mtl(const std::string& text, const std::string& file) {
    detail::LineReader lines(text, true, true);
    std::string_view l;
    int line = 0;
    std::vector<std::string_view> t;
    mesh::Material* cur = nullptr;
    while (lines.next(l, line)) {
      detail::split(l, t);
      if (t.empty()) continue;
      std::string kw = detail::lower(t[0]);
      if (kw == "newmtl") {
        std::string name(rest(l, t[0]));
        if (name.empty()) fail(file, line, "newmtl without a material name; expected 'newmtl NAME'");
        SourceLoc at{file, line};
        if (name == "default" && !default_defined_) {
          default_defined_ = true;  // a "default" in the MTL replaces the built-in default material
          soup_.materials[0].defined_at = at;
          cur = &soup_.materials[0];
          material_index_.emplace(name, 0);
          continue;
        }
        auto [it, added] = material_index_.emplace(name, static_cast<int>(soup_.materials.size()));
        if (!added || name == "default")
          fail(file, line, "material " + quote(name) + " is defined twice (first at " +
                               soup_.materials[it->second].defined_at.str() + "); expected unique names");
        mesh::Material m;
        m.name = name;
        m.defined_at = at;
        soup_.materials.push_back(m);
        cur = &soup_.materials.back();
      } else if (kw == "kd" || kw == "ke") {
        std::string what = kw == "kd" ? "Kd (diffuse reflectance)" : "Ke (emitted radiance)";
        if (!cur) fail(file, line, what + " before any newmtl; expected 'newmtl NAME' first");
        if (t.size() != 2 && t.size() != 4)
          fail(file, line, what + " has " + std::to_string(t.size() - 1) + " values; expected 1 (grey) or 3 (r g b)");
        RGB c;
        for (int i = 0; i < 3; ++i)
          c[i] = detail::finite_number(t[t.size() == 2 ? 1 : i + 1], file, line, what);
        (kw == "kd" ? cur->reflectance : cur->emission) = c;
      } else if (kw == "transmittance") {
        // lambert extension: diffuse visible transmittance of glazing, 1 (grey) or 3 values in [0, 1]
        // (used by daylight solves, --sky). MTL's own Tf is not read: exporters write "Tf 1 1 1" for opaque
        // materials.
        const std::string what = "transmittance (diffuse visible transmittance)";
        if (!cur) fail(file, line, what + " before any newmtl; expected 'newmtl NAME' first");
        if (t.size() != 2 && t.size() != 4)
          fail(file, line, what + " has " + std::to_string(t.size() - 1) + " values; expected 1 (grey) or 3 (r g b)");
        for (int i = 0; i < 3; ++i) {
          const double v = detail::finite_number(t[t.size() == 2 ? 1 : i + 1], file, line, what);
          if (!(v >= 0 && v <= 1)) fail(file, line, what + " " + detail::format_double(v) + " is outside [0, 1]");
          cur->transmittance[i] = v;
        }
      } else if (kw == "two_sided") {
        // lambert extension: "two_sided" or "two_sided 1" = both sides reflect (two patches per face);
        // "two_sided 0" = one-sided (the default).
        if (!cur) fail(file, line, "two_sided before any newmtl; expected 'newmtl NAME' first");
        if (t.size() > 2 || (t.size() == 2 && t[1] != "0" && t[1] != "1"))
          fail(file, line, "two_sided takes no value, 0 or 1; found " + quote(rest(l, t[0])));
        cur->two_sided = t.size() == 1 || t[1] == "1";
      }
      // Ka, Ks, Ns, Ni, d, Tr, illum, map_* ...: not part of a Lambertian model, ignored.
    }
  }

  void finish() {
    const long long nv = static_cast<long long>(soup_.positions.size());
    for (const mesh::SoupFace& f : soup_.faces)
      for (int v : f.vertices)
        if (v >= nv)
          fail(path_, f.line, "vertex index " + std::to_string(v + 1) + " is out of range: the file defines " +
                                  std::to_string(nv) + " vertices");
    std::vector<int> resolved(usemtl_.size());
    for (std::size_t i = 0; i < usemtl_.size(); ++i) {
      auto it = material_index_.find(usemtl_[i].name);
      if (it == material_index_.end()) {
        std::string known;
        for (std::size_t m = 1; m < soup_.materials.size() && m <= 10; ++m)
          known += (m > 1 ? ", " : "") + soup_.materials[m].name;
        if (soup_.materials.size() > 11) known += ", ...";
        fail(path_, usemtl_[i].line,
             "unknown material " + quote(usemtl_[i].name) + " in usemtl: not defined in any loaded MTL file" +
                 (loaded_mtl_.empty() ? " (the file has no mtllib statement)"
                                      : known.empty() ? "" : " (defined: " + known + ")"));
      }
      resolved[i] = it->second;
    }
    for (std::size_t k = 0; k < soup_.faces.size(); ++k) {
      if (face_usemtl_[k] < 0) {
        soup_.faces[k].material = 0;
        ++soup_.faces_without_material;
      } else {
        soup_.faces[k].material = resolved[face_usemtl_[k]];
      }
    }
    if (lines_ || points_)
      soup_.warnings.push_back(path_ + ": ignored " + std::to_string(lines_) + " line (l) and " +
                               std::to_string(points_) + " point (p) statements; only faces (f) are patches");
    if (unsupported_)
      soup_.warnings.push_back(path_ + ": ignored " + std::to_string(unsupported_) +
                               " unsupported statements (first: " + first_unsupported_ + ")");
  }

  std::string path_;
  mesh::PolygonSoup soup_;
  std::vector<std::string_view> tok_;
  int group_ = -1;
  std::unordered_map<std::string, int> group_index_;
  std::unordered_map<std::string, int> material_index_;
  bool default_defined_ = false;
  std::set<std::string> loaded_mtl_;
  std::vector<UseMtl> usemtl_;
  std::vector<int> face_usemtl_;  // per face: index into usemtl_, -1 = before any usemtl
  long lines_ = 0, points_ = 0, unsupported_ = 0;
  std::string first_unsupported_;
};

bool writable_name(const std::string& s) {
  return !s.empty() && s.find_first_of("\n\r#") == std::string::npos && detail::trim(s) == s;
}

void rgb(std::string& out, const char* kw, const RGB& c) {
  out += kw;
  for (int i = 0; i < 3; ++i) out += ' ' + detail::format_double(c[i]);
  out += '\n';
}

}  // namespace

mesh::PolygonSoup read_obj(const std::string& path) { return ObjReader(path).run(); }

void write_obj(const mesh::PolygonSoup& soup, const std::string& obj_path) {
  fs::path mtl_path = fs::path(obj_path).replace_extension(".mtl");
  for (const mesh::Material& m : soup.materials)
    if (!writable_name(m.name)) throw InputError(obj_path + ": material name " + quote(m.name) + " cannot be written to MTL");
  for (const std::string& g : soup.groups)
    if (!writable_name(g)) throw InputError(obj_path + ": group name " + quote(g) + " cannot be written to OBJ");

  std::string mtl = "# written by lambert\n";
  for (const mesh::Material& m : soup.materials) {
    mtl += "newmtl " + m.name + '\n';
    rgb(mtl, "Kd", m.reflectance);
    rgb(mtl, "Ke", m.emission);
    if (m.two_sided) mtl += "two_sided 1\n";
    if ((m.transmittance != 0).any()) rgb(mtl, "transmittance", m.transmittance);
  }

  std::string obj = "# written by lambert\nmtllib " + mtl_path.filename().string() + '\n';
  for (const Vec3& p : soup.positions) rgb(obj, "v", p.array());
  int group = -1, material = 0;
  for (const mesh::SoupFace& f : soup.faces) {
    if (f.group != group) {
      obj += f.group < 0 ? std::string("g\n") : "g " + soup.groups.at(f.group) + '\n';
      group = f.group;
    }
    // Faces with material 0 before any usemtl stay "without material" when read back.
    if (f.material != material) {
      obj += "usemtl " + soup.materials.at(f.material).name + '\n';
      material = f.material;
    }
    obj += 'f';
    for (int v : f.vertices) obj += ' ' + std::to_string(v + 1);
    obj += '\n';
  }
  detail::write_file_atomic(mtl_path.string(), mtl);
  detail::write_file_atomic(obj_path, obj);
}

}  // namespace lambert::io
