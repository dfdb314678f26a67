#include "lambert/mesh/shapes.hpp"

#include <array>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

namespace lambert::mesh::shapes {

Polygons grid(const Vec3& origin, const Vec3& u, const Vec3& v, int nu, int nv) {
  if (nu < 1 || nv < 1) throw std::invalid_argument("grid: nu and nv must be >= 1");
  Polygons out;
  out.reserve(size_t(nu) * nv);
  auto at = [&](int i, int j) { return Vec3(origin + u * (double(i) / nu) + v * (double(j) / nv)); };
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) out.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
  return out;
}

Polygons box(const Vec3& lo, const Vec3& hi, int n, bool inward) {
  Polygons out;
  const Vec3 d = hi - lo;
  const Vec3 ex(d.x(), 0, 0), ey(0, d.y(), 0), ez(0, 0, d.z());
  // For each face: origin and two edges whose cross product points outward.
  const std::array<std::array<Vec3, 3>, 6> faces = {{
      {lo, ez, ey},           // -x: ez x ey = -x
      {lo + ex, ey, ez},      // +x
      {lo, ex, ez},           // -y: ex x ez = -y
      {lo + ey, ez, ex},      // +y
      {lo, ey, ex},           // -z: ey x ex = -z
      {lo + ez, ex, ey},      // +z
  }};
  for (const auto& f : faces) {
    // Swapping the edges flips the normal.
    Polygons g = inward ? grid(f[0], f[2], f[1], n, n) : grid(f[0], f[1], f[2], n, n);
    out.insert(out.end(), g.begin(), g.end());
  }
  return out;
}

Polygons icosphere(int subdivisions, double radius, bool inward) {
  if (subdivisions < 0 || subdivisions > 9) throw std::invalid_argument("icosphere: subdivisions must be in [0, 9]");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  // Outward-oriented icosahedron faces.
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = int(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> g;
    g.reserve(f.size() * 4);
    for (auto [a, b, c] : f) {
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      g.push_back({a, ab, ca});
      g.push_back({b, bc, ab});
      g.push_back({c, ca, bc});
      g.push_back({ab, bc, ca});
    }
    f = std::move(g);
  }
  Polygons out;
  out.reserve(f.size());
  for (auto [a, b, c] : f) {
    if (inward) std::swap(b, c);
    out.push_back({v[a] * radius, v[b] * radius, v[c] * radius});
  }
  return out;
}

Polygons room_with_block(int n, int m, const Vec3& lo, const Vec3& hi) {
  Polygons out = box(Vec3::Zero(), Vec3::Ones(), n, /*inward=*/true);
  Polygons b = box(lo, hi, m, /*inward=*/false);
  out.insert(out.end(), b.begin(), b.end());
  return out;
}

}  // namespace lambert::mesh::shapes
