// Face splitting for adaptive refinement (see split.hpp).
#include "lambert/mesh/split.hpp"

#include <algorithm>
#include <utility>

namespace lambert::mesh {
namespace {

bool convex(std::span<const Vec3> poly, const Vec3& n) {
  const size_t m = poly.size();
  for (size_t i = 0; i < m; ++i) {
    const Vec3 e0 = poly[i] - poly[(i + m - 1) % m], e1 = poly[(i + 1) % m] - poly[i];
    if (e0.cross(e1).dot(n) < -1e-12 * e0.norm() * e1.norm()) return false;
  }
  return true;
}

// A convex quad much longer than wide (opposite edges both > 2x the other two): 1 = cut edges 0 and 2 at
// their midpoints, 2 = edges 1 and 3, 0 = no such quad.
int long_quad(std::span<const Vec3> q) {
  if (q.size() != 4) return 0;
  double l[4];
  for (int i = 0; i < 4; ++i) l[i] = (q[(i + 1) % 4] - q[i]).norm();
  if (std::min(l[0], l[2]) > 2 * std::max(l[1], l[3])) return 1;
  if (std::min(l[1], l[3]) > 2 * std::max(l[0], l[2])) return 2;
  return 0;
}

}  // namespace

int split_children(std::span<const Vec3> poly, const Vec3& n) {
  const int m = static_cast<int>(poly.size());
  if (m > 3 && !convex(poly, n)) return 0;
  return long_quad(poly) ? 2 : m == 3 ? 4 : m;
}

FaceSplitter::FaceSplitter(PolygonSoup& soup) : soup_(soup) {
  soup_.position_lines.resize(soup_.positions.size(), 0);
  for (size_t v = 0; v < soup_.positions.size(); ++v) {
    const Vec3& x = soup_.positions[v];
    index_.try_emplace({x.x(), x.y(), x.z()}, static_cast<int>(v));
  }
}

int FaceSplitter::vertex_at(const Vec3& x) {
  auto [it, added] = index_.try_emplace({x.x(), x.y(), x.z()}, static_cast<int>(soup_.positions.size()));
  if (added) {
    soup_.positions.push_back(x);
    soup_.position_lines.push_back(0);
  }
  return it->second;
}

std::vector<SoupFace> FaceSplitter::split(const SoupFace& f, const Vec3& n) {
  const std::vector<int>& v = f.vertices;
  const int m = static_cast<int>(v.size());
  std::vector<Vec3> poly;
  for (int i : v) poly.push_back(soup_.positions[i]);
  LAMBERT_CHECK(split_children(poly, n) > 0, "face with " + std::to_string(m) + " corners is not splittable");
  auto mid = [&](int a, int b) { return vertex_at(0.5 * (soup_.positions[a] + soup_.positions[b])); };
  std::vector<int> e(m, -1);  // e[i]: midpoint of edge (i, i+1), where used
  const int halve = long_quad(poly);
  for (int i = 0; i < m; ++i)
    if (halve == 0 || (halve == 1) == (i % 2 == 0)) e[i] = mid(v[i], v[(i + 1) % m]);
  std::vector<std::vector<int>> corners;
  if (halve == 1) {
    corners = {{v[0], e[0], e[2], v[3]}, {e[0], v[1], v[2], e[2]}};
  } else if (halve == 2) {
    corners = {{v[0], v[1], e[1], e[3]}, {e[3], e[1], v[2], v[3]}};
  } else if (m == 3) {
    corners = {{v[0], e[0], e[2]}, {e[0], v[1], e[1]}, {e[2], e[1], v[2]}, {e[0], e[1], e[2]}};
  } else {
    Vec3 c = Vec3::Zero();
    for (const Vec3& x : poly) c += x;
    const int ci = vertex_at(c / m);
    for (int i = 0; i < m; ++i) corners.push_back({v[i], e[i], ci, e[(i + m - 1) % m]});
  }
  std::vector<SoupFace> children;
  for (auto& cv : corners) {
    SoupFace child = f;
    child.vertices = std::move(cv);
    children.push_back(std::move(child));
  }
  return children;
}

PolygonSoup soup_from_scene(const PolygonSoup& in, const Scene& scene) {
  PolygonSoup s = in;
  s.positions.clear();
  s.position_lines.clear();
  s.faces.clear();
  std::map<std::array<double, 3>, int> index, back_index;  // backs of two-sided faces: their own vertices
  const auto& g = scene.geometry;
  for (int p = 0; p < scene.patches(); ++p) {
    SoupFace f;
    f.side = p < static_cast<int>(scene.side.size()) ? scene.side[p] : 0;
    for (const Vec3& v : g.polygon(p)) {
      auto [it, added] = (f.side == 1 ? back_index : index).try_emplace({v.x(), v.y(), v.z()}, static_cast<int>(s.positions.size()));
      if (added) {
        s.positions.push_back(v);
        s.position_lines.push_back(0);
      }
      f.vertices.push_back(it->second);
    }
    f.material = scene.material[p];
    f.group = scene.group[p];
    f.origin = scene.face_id[p];
    s.faces.push_back(std::move(f));
  }
  return s;
}

}  // namespace lambert::mesh
