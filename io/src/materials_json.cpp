// --materials FILE.json: material overrides and per-face-range assignment.
#include <algorithm>
#include <cmath>
#include <queue>
#include <set>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "lambert/io/readers.hpp"
#include "read_util.hpp"

namespace lambert::io {
namespace {

using json = nlohmann::json;
using detail::quote;

class JsonMaterials {
 public:
  JsonMaterials(mesh::PolygonSoup& soup, const std::string& path) : soup_(soup), path_(path) {}

  void run() {
    std::string text = detail::read_file(path_);
    json doc;
    // SAX parse into the DOM, keeping the position of the first error: a number out of the range of a
    // double (1e400) is reported with its line and column like a syntax error.
    Located sax(doc);
    try {
      json::sax_parse(text, &sax, nlohmann::detail::input_format_t::json, /*strict=*/true, /*ignore_comments=*/true);
    } catch (const json::exception& e) {
      error("", std::string("cannot parse: ") + e.what());
    }
    if (sax.failed) located_error(text, sax.byte, sax.token, sax.what);
    for (std::size_t i = 0; i < soup_.materials.size(); ++i) by_name_.emplace(soup_.materials[i].name, static_cast<int>(i));
    if (!doc.is_object()) error("", "the top level is " + kind(doc) + "; expected an object {\"materials\": ..., \"faces\": ...}");
    for (auto& [key, value] : doc.items())
      if (key != "materials" && key != "faces")
        error("", "unknown top-level key " + quote(key) + "; expected \"materials\" and/or \"faces\"");

    if (doc.contains("materials")) materials(doc["materials"]);
    if (doc.contains("faces")) faces(doc["faces"]);

    std::vector<bool> used(soup_.materials.size(), false);
    for (const mesh::SoupFace& f : soup_.faces) used[f.material] = true;
    for (int m : touched_)
      if (!used[m])
        soup_.warnings.push_back(path_ + ": material " + quote(soup_.materials[m].name) +
                                 " from this file is not used by any face");
  }

 private:
  // The DOM builder, stopping at the first error and keeping where it was (byte: 1-based index of the
  // last character read).
  struct Located : nlohmann::detail::json_sax_dom_parser<json> {
    explicit Located(json& j) : nlohmann::detail::json_sax_dom_parser<json>(j, false) {}
    bool parse_error(std::size_t position, const std::string& last_token, const nlohmann::detail::exception& ex) {
      failed = true;
      byte = position;
      token = last_token;
      what = ex.what();
      return false;
    }
    bool failed = false;
    std::size_t byte = 0;
    std::string token, what;
  };

  [[noreturn]] void located_error(const std::string& text, std::size_t byte, const std::string& token, std::string what) {
    std::size_t end = std::min<std::size_t>(byte > 0 ? byte - 1 : 0, text.size());
    int line = 1;
    std::size_t line_start = 0;
    for (std::size_t i = 0; i < end; ++i)
      if (text[i] == '\n') {
        ++line;
        line_start = i + 1;
      }
    std::size_t column = end - line_start + 1;
    if (what.find("number overflow") != std::string::npos)
      detail::fail(path_, line, "column " + std::to_string(column) + ": number " + quote(token) +
                                    " is out of the range of a double; expected a finite number");
    std::size_t col = what.find("column ");
    std::size_t colon = col == std::string::npos ? std::string::npos : what.find(": ", col);
    if (colon != std::string::npos) what = what.substr(colon + 2);
    else if (const auto bracket = what.find("] "); bracket != std::string::npos) what = what.substr(bracket + 2);
    detail::fail(path_, line, "column " + std::to_string(column) + ": JSON syntax error: " + what);
  }

  [[noreturn]] void error(const std::string& where, const std::string& what) const {
    throw InputError(path_ + ": " + (where.empty() ? "" : where + ": ") + what);
  }

  static std::string kind(const json& j) {
    switch (j.type()) {
      case json::value_t::null: return "null";
      case json::value_t::object: return "an object";
      case json::value_t::array: return "an array";
      case json::value_t::string: return "a string";
      case json::value_t::boolean: return "a boolean";
      case json::value_t::number_float:
      case json::value_t::number_integer:
      case json::value_t::number_unsigned: return "a number";
      default: return "an unsupported value";
    }
  }

  // A number (grey) or an array of 1 or 3 finite numbers.
  RGB colour(const json& j, const std::string& where) const {
    auto number = [&](const json& v, const std::string& w) {
      if (!v.is_number()) error(w, "found " + kind(v) + "; expected a number");
      double d = v.get<double>();
      if (!std::isfinite(d)) error(w, "value is not finite; expected a finite number");
      return d;
    };
    if (j.is_number()) return RGB::Constant(number(j, where));
    if (j.is_array() && (j.size() == 1 || j.size() == 3)) {
      RGB c;
      for (int i = 0; i < 3; ++i) {
        std::size_t k = j.size() == 1 ? 0 : i;
        c[i] = number(j[k], where + "[" + std::to_string(k) + "]");
      }
      return c;
    }
    if (j.is_array())
      error(where, "array of length " + std::to_string(j.size()) + "; expected a number or an array of 1 or 3 numbers");
    error(where, "found " + kind(j) + "; expected a number or an array of 1 or 3 numbers");
  }

  bool flag(const json& j, const std::string& where) const {
    if (!j.is_boolean()) error(where, "found " + kind(j) + "; expected true or false");
    return j.get<bool>();
  }

  // First material with this name (hash map: O(1) instead of a scan of all materials).
  int find(const std::string& name) const {
    const auto it = by_name_.find(name);
    return it == by_name_.end() ? -1 : it->second;
  }

  int add(const std::string& name) {
    by_name_.emplace(name, static_cast<int>(soup_.materials.size()));
    mesh::Material m;
    m.name = name;
    m.defined_at = SourceLoc{path_, 0};
    soup_.materials.push_back(m);
    return static_cast<int>(soup_.materials.size()) - 1;
  }

  void materials(const json& j) {
    if (!j.is_object()) error("\"materials\"", "found " + kind(j) + "; expected an object {\"NAME\": {...}, ...}");
    for (auto& [name, value] : j.items()) {
      std::string where = "\"materials\".\"" + name + "\"";
      if (name.empty()) error(where, "empty material name");
      if (!value.is_object())
        error(where, "found " + kind(value) + "; expected an object {\"reflectance\": ..., \"emission\": ...}");
      for (auto& [key, v] : value.items())
        if (key != "reflectance" && key != "emission" && key != "two_sided" && key != "transmittance")
          error(where, "unknown key " + quote(key) +
                           "; expected \"reflectance\", \"emission\", \"transmittance\" and/or \"two_sided\"");
      int m = find(name);
      if (m < 0) m = add(name);
      mesh::Material& mat = soup_.materials[m];
      if (value.contains("reflectance")) mat.reflectance = colour(value["reflectance"], where + ".reflectance");
      if (value.contains("emission")) mat.emission = colour(value["emission"], where + ".emission");
      if (value.contains("two_sided")) mat.two_sided = flag(value["two_sided"], where + ".two_sided");
      if (value.contains("transmittance")) mat.transmittance = colour(value["transmittance"], where + ".transmittance");
      mat.defined_at = SourceLoc{path_, 0};
      touched_.insert(m);
    }
  }

  void faces(const json& j) {
    if (!j.is_array()) error("\"faces\"", "found " + kind(j) + "; expected an array of {\"range\": [first, last], ...}");
    const long long nf = static_cast<long long>(soup_.faces.size());
    struct Assign {
      long long first, last;
      int material;
    };
    std::vector<Assign> assign;  // entry order: later entries win
    assign.reserve(j.size());
    for (std::size_t e = 0; e < j.size(); ++e) {
      const json& entry = j[e];
      std::string where = "\"faces\"[" + std::to_string(e) + "]";
      if (!entry.is_object()) error(where, "found " + kind(entry) + "; expected an object {\"range\": [first, last], ...}");
      for (auto& [key, v] : entry.items())
        if (key != "range" && key != "material" && key != "reflectance" && key != "emission" && key != "two_sided")
          error(where, "unknown key " + quote(key) +
                           "; expected \"range\" with \"material\" or \"reflectance\"/\"emission\"/\"two_sided\"");
      if (!entry.contains("range")) error(where, "no \"range\"; expected \"range\": [first, last] (inclusive face indices)");
      const json& r = entry["range"];
      if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
        error(where + ".range", "found " + r.dump() + "; expected [first, last] with two integer face indices");
      long long a = r[0].get<long long>(), b = r[1].get<long long>();
      if (a > b) error(where + ".range", "range [" + std::to_string(a) + ", " + std::to_string(b) + "] is reversed; expected first <= last");
      if (a < 0 || b >= nf)
        error(where + ".range", "range [" + std::to_string(a) + ", " + std::to_string(b) +
                                    "] is out of bounds: the scene has " + std::to_string(nf) + " faces" +
                                    (nf > 0 ? " (indices 0 .. " + std::to_string(nf - 1) + ")" : ""));
      bool inline_values = entry.contains("reflectance") || entry.contains("emission") || entry.contains("two_sided");
      int m;
      if (entry.contains("material")) {
        if (inline_values)
          error(where, "has both \"material\" and inline \"reflectance\"/\"emission\"/\"two_sided\"; expected one of them");
        const json& name = entry["material"];
        if (!name.is_string()) error(where + ".material", "found " + kind(name) + "; expected a material name (string)");
        m = find(name.get<std::string>());
        if (m < 0)
          error(where + ".material", "unknown material " + quote(name.get<std::string>()) +
                                         "; expected a material from the scene file or from \"materials\"");
      } else if (inline_values) {
        std::string base = "faces_" + std::to_string(a) + "-" + std::to_string(b), name = base;
        if (find(name) >= 0) {  // faces_A-B_2, _3, ...: the next free suffix, remembered per base name
          int& k = next_suffix_.try_emplace(base, 2).first->second;
          do name = base + "_" + std::to_string(k++);
          while (find(name) >= 0);
        }
        RGB refl = RGB::Constant(0.5), emit = RGB::Zero();
        if (entry.contains("reflectance")) refl = colour(entry["reflectance"], where + ".reflectance");
        if (entry.contains("emission")) emit = colour(entry["emission"], where + ".emission");
        const bool two = entry.contains("two_sided") && flag(entry["two_sided"], where + ".two_sided");
        m = add(name);
        soup_.materials[m].reflectance = refl;
        soup_.materials[m].emission = emit;
        soup_.materials[m].two_sided = two;
        touched_.insert(m);
      } else {
        error(where, "no \"material\" and no \"reflectance\"/\"emission\"; expected one of them");
      }
      assign.push_back({a, b, m});
    }
    // Each face gets the material of the last entry whose range holds it: one sweep over the faces with
    // a heap of the open ranges (latest entry on top), O((faces + entries) log entries) instead of
    // touching every face of every range.
    std::vector<int> by_start(assign.size());
    for (std::size_t e = 0; e < assign.size(); ++e) by_start[e] = static_cast<int>(e);
    std::sort(by_start.begin(), by_start.end(), [&](int x, int y) { return assign[x].first < assign[y].first; });
    std::priority_queue<int> open;  // entry indices
    std::size_t next = 0;
    for (long long k = 0; k < nf && (next < by_start.size() || !open.empty()); ++k) {
      while (next < by_start.size() && assign[by_start[next]].first == k) open.push(by_start[next++]);
      while (!open.empty() && assign[open.top()].last < k) open.pop();
      if (open.empty()) {
        if (next < by_start.size()) k = assign[by_start[next]].first - 1;  // skip to the next range
        continue;
      }
      mesh::SoupFace& f = soup_.faces[k];
      const int m = assign[open.top()].material;
      if (f.material == 0 && m != 0 && soup_.faces_without_material > 0) --soup_.faces_without_material;
      f.material = m;
    }
  }

  mesh::PolygonSoup& soup_;
  std::string path_;
  std::set<int> touched_;  // materials defined or changed by this file
  std::unordered_map<std::string, int> by_name_;      // material name -> first index
  std::unordered_map<std::string, int> next_suffix_;  // "faces_A-B" -> next k to try for "faces_A-B_k"
};

}  // namespace

void apply_materials_json(mesh::PolygonSoup& soup, const std::string& json_path) {
  JsonMaterials(soup, json_path).run();
}

}  // namespace lambert::io
