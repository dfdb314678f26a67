#include "lambert/mesh/geometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <string>

#include "triangulate_internal.hpp"

namespace lambert::mesh {

Vec3 newell_normal(std::span<const Vec3> polygon) {
  Vec3 n = Vec3::Zero();
  const size_t m = polygon.size();
  // Relative to the first corner: cancels the large offsets of scenes far from the origin.
  const Vec3 o = m ? polygon[0] : Vec3::Zero();
  for (size_t k = 0; k < m; ++k) n += (polygon[k] - o).cross(polygon[(k + 1) % m] - o);
  return n;
}

std::vector<int> plane_ids(const PatchGeometry& g, std::span<const int> patches, double scale) {
  std::vector<int> id(size_t(g.size()), -1);
  if (!(scale > 0)) return id;
  std::map<std::array<long long, 4>, int> planes;
  for (int p : patches) {
    Vec3 n = g.normal[size_t(p)];
    int big = 0;
    for (int c = 1; c < 3; ++c)
      if (std::abs(n[c]) > std::abs(n[big])) big = c;
    if (n[big] < 0) n = -n;
    const double d = n.dot(g.centroid[size_t(p)]);
    const std::array<long long, 4> key{std::llround(n.x() * 1e9), std::llround(n.y() * 1e9), std::llround(n.z() * 1e9),
                                       std::llround(d / (1e-9 * scale))};
    id[size_t(p)] = planes.try_emplace(key, int(planes.size())).first->second;
  }
  return id;
}

double planarity_deviation(std::span<const Vec3> polygon) {
  Vec3 n = newell_normal(polygon);
  const double len = n.norm();
  if (!(len > 0)) return 0;
  n /= len;
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : polygon) c += p;
  c /= double(polygon.size());
  double worst = 0;
  for (const Vec3& p : polygon) worst = std::max(worst, std::abs((p - c).dot(n)));
  return worst;
}

namespace {
// Twice the signed area of 2D triangle (a, b, c).
double orient2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}
}  // namespace

namespace {
// The polygon's corners on its plane, in an orthonormal basis (u, v) with (u, v, n) right-handed: counter-clockwise
// in 2D then means the polygon's own winding.
std::vector<Eigen::Vector2d> in_plane(std::span<const Vec3> polygon, const Vec3& normal) {
  const Vec3 n = normal.normalized();
  const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 v = n.cross(u);
  std::vector<Eigen::Vector2d> p(polygon.size());
  for (size_t k = 0; k < polygon.size(); ++k) {
    const Vec3 d = polygon[k] - polygon[0];
    p[k] = {d.dot(u), d.dot(v)};
  }
  return p;
}
}  // namespace

std::vector<std::array<int, 3>> detail::triangulate_polygon_delaunay(std::span<const Vec3> polygon, const Vec3& normal) {
  if (polygon.size() < 3) return {};
  if (polygon.size() == 3) return {{0, 1, 2}};
  return triangulate_cdt(in_plane(polygon, normal));
}

std::vector<std::array<int, 3>> triangulate_polygon(std::span<const Vec3> polygon, const Vec3& normal) {
  const int m = static_cast<int>(polygon.size());
  std::vector<std::array<int, 3>> tris;
  if (m < 3) return tris;
  if (m == 3) return {{0, 1, 2}};
  const std::vector<Eigen::Vector2d> p = in_plane(polygon, normal);
  // Ear clipping is O(m^2) (11.8 s at 16,000 corners): large polygons go to CGAL's constrained Delaunay
  // triangulation, O(m log m) (0.x s at 10^6 corners), with the same contract.
  if (m > detail::kEarClippingMaxCorners) return detail::triangulate_cdt(p);
  std::vector<int> idx(m);
  for (int k = 0; k < m; ++k) idx[k] = k;
  double scale = 0;
  for (auto& q : p) scale = std::max(scale, q.cwiseAbs().maxCoeff());
  const double eps = 1e-14 * scale * scale;
  int guard = 0;
  while (idx.size() > 3 && guard < 4 * m * m) {
    ++guard;
    const int r = static_cast<int>(idx.size());
    bool clipped = false;
    for (int k = 0; k < r; ++k) {
      const int a = idx[(k + r - 1) % r], b = idx[k], c = idx[(k + 1) % r];
      if (orient2(p[a], p[b], p[c]) <= eps) continue;  // reflex or flat corner: not an ear
      bool inside = false;
      for (int t : idx) {
        if (t == a || t == b || t == c) continue;
        if (orient2(p[a], p[b], p[t]) >= -eps && orient2(p[b], p[c], p[t]) >= -eps &&
            orient2(p[c], p[a], p[t]) >= -eps) {
          inside = true;
          break;
        }
      }
      if (inside) continue;
      tris.push_back({a, b, c});
      idx.erase(idx.begin() + k);
      clipped = true;
      break;
    }
    if (!clipped) {
      // Only flat corners left (collinear runs): drop a collinear corner if any, else give up.
      bool dropped = false;
      for (int k = 0; k < r && !dropped; ++k) {
        const int a = idx[(k + r - 1) % r], b = idx[k], c = idx[(k + 1) % r];
        if (std::abs(orient2(p[a], p[b], p[c])) <= eps) {
          idx.erase(idx.begin() + k);
          dropped = true;
        }
      }
      if (!dropped) return {};
    }
  }
  if (idx.size() == 3) {
    if (orient2(p[idx[0]], p[idx[1]], p[idx[2]]) > eps) tris.push_back({idx[0], idx[1], idx[2]});
  }
  return tris;
}

PatchGeometry PatchGeometry::from_polygons(const std::vector<std::vector<Vec3>>& polygons) {
  PatchGeometry g;
  const int n = static_cast<int>(polygons.size());
  g.offsets.reserve(n + 1);
  g.offsets.push_back(0);
  g.triangle_offsets.push_back(0);
  for (int p = 0; p < n; ++p) {
    const auto& poly = polygons[p];
    if (poly.size() < 3)
      throw InputError("polygon " + std::to_string(p) + " has " + std::to_string(poly.size()) +
                       " corners (need at least 3)");
    const Vec3 nn = newell_normal(poly);
    const double twice_area = nn.norm();
    if (!(twice_area > 0) || !std::isfinite(twice_area))
      throw InputError("polygon " + std::to_string(p) + " has zero area");
    const Vec3 unit = nn / twice_area;
    auto tris = triangulate_polygon(poly, unit);
    if (tris.empty())
      throw InputError("polygon " + std::to_string(p) + " could not be triangulated (self-intersecting?)");
    const int base = static_cast<int>(g.points.size());
    Vec3 c = Vec3::Zero();
    double a = 0;
    for (auto& t : tris) {
      const Vec3 &A = poly[t[0]], &B = poly[t[1]], &C = poly[t[2]];
      const double at = 0.5 * (B - A).cross(C - A).dot(unit);
      a += at;
      c += at * (A + B + C) / 3.0;
      g.triangles.push_back({base + t[0], base + t[1], base + t[2]});
    }
    // Ear clipping can "succeed" on a self-intersecting polygon; its triangles then do not tile
    // the polygon, and their projected area differs from the Newell area (equal for simple ones,
    // up to the flat corners dropped, each below 1e-14 L^2).
    double extent2 = 0;
    for (const Vec3& q : poly) extent2 = std::max(extent2, (q - poly[0]).squaredNorm());
    if (std::abs(a - 0.5 * twice_area) > 1e-9 * 0.5 * twice_area + 1e-13 * double(poly.size()) * extent2)
      throw InputError("polygon " + std::to_string(p) + " is not simple (self-intersecting): triangulated area " +
                       std::to_string(a) + " != polygon area " + std::to_string(0.5 * twice_area));
    for (const Vec3& q : poly) g.points.push_back(q);
    g.offsets.push_back(static_cast<int>(g.points.size()));
    g.triangle_offsets.push_back(static_cast<int>(g.triangles.size()));
    g.normal.push_back(unit);
    g.area.push_back(a);
    g.centroid.push_back(c / a);
  }
  return g;
}

Eigen::Matrix3d alignment(const PatchGeometry& g) {
  const int n = g.size();
  if (n == 0) return Eigen::Matrix3d::Identity();
  // Candidate directions: the normals of the 64 largest patches and of 192 spread over the patch order (sign-free),
  // scored by the area of (at most 65,536 evenly spread) patches whose normal lies within 1 degree of them (and, for
  // the second axis, of the direction at right angles in the first axis' plane).
  std::vector<int> order(static_cast<size_t>(n));
  for (int p = 0; p < n; ++p) order[size_t(p)] = p;
  const size_t m = std::min<size_t>(64, order.size());
  std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(m), order.end(), [&](int a, int b) {
    return g.area[size_t(a)] > g.area[size_t(b)] || (g.area[size_t(a)] == g.area[size_t(b)] && a < b);
  });
  std::vector<int> candidates(order.begin(), order.begin() + std::ptrdiff_t(m));
  for (int k = 0; k < 192 && k < n; ++k) candidates.push_back(int((long long)k * n / std::min(192, n)));
  const int stride = std::max(1, n / 65536);
  const double near = std::cos(std::numbers::pi / 180);
  auto score = [&](const Vec3& c) {
    double s = 0;
    for (int p = 0; p < n; p += stride)
      if (std::abs(g.normal[size_t(p)].dot(c)) > near) s += g.area[size_t(p)];
    return s;
  };
  Vec3 u1 = Vec3::Zero();
  double best = -1;
  for (int p : candidates) {
    const Vec3& c = g.normal[size_t(p)];
    const double sc = score(c);
    if (sc > best) best = sc, u1 = c;
  }
  Vec3 u2 = Vec3::Zero();
  best = -1;
  for (int p : candidates) {
    Vec3 c = g.normal[size_t(p)];
    c -= c.dot(u1) * u1;
    if (!(c.norm() > 0.5)) continue;  // not across the first axis
    c.normalize();
    const double sc = score(c) + score(u1.cross(c));
    if (sc > best) best = sc, u2 = c;
  }
  if (!(u2.norm() > 0)) u2 = u1.unitOrthogonal();
  // Already along the axes (within 1 degree each): left as it is, to the bit.
  auto on_axis = [&](const Vec3& v) { return v.cwiseAbs().maxCoeff() > near; };
  if (on_axis(u1) && on_axis(u2)) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R;
  R.row(0) = u2.transpose();
  R.row(1) = u1.cross(u2).transpose();
  R.row(2) = u1.transpose();
  return R;
}

PatchGeometry moved_and_turned(const PatchGeometry& g, const Vec3& centre, const Eigen::Matrix3d* R) {
  PatchGeometry t = g;
  for (Vec3& p : t.points) p -= centre;
  for (Vec3& c : t.centroid) c -= centre;
  if (R) {
    for (Vec3& p : t.points) p = *R * p;
    for (Vec3& c : t.centroid) c = *R * c;
    for (Vec3& n : t.normal) n = *R * n;
  }
  return t;
}

}  // namespace lambert::mesh
