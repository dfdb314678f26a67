// Which patches can block anything: those with some scene corner strictly behind their plane.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "lambert/formfactor/visibility.hpp"

namespace lambert::formfactor {

std::vector<int> potential_occluders(const mesh::PatchGeometry& g) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = K::Point_3;
  std::vector<int> out;
  if (g.size() == 0) return out;
  double scale = 0;
  Eigen::AlignedBox3d box;
  // Corners shared by neighbouring patches appear once per patch: deduplicate (exactly) before the hull,
  // duplicates only cost CGAL exact-arithmetic fallbacks.
  std::vector<std::array<double, 3>> uniq;
  uniq.reserve(g.points.size());
  for (const Vec3& p : g.points) {
    uniq.push_back({p.x(), p.y(), p.z()});
    box.extend(p);
  }
  scale = box.diagonal().norm();  // the scene's size, not |coordinates|: translation invariant
  std::sort(uniq.begin(), uniq.end());
  uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
  std::vector<Point> pts;
  pts.reserve(uniq.size());
  for (const auto& p : uniq) pts.emplace_back(p[0], p[1], p[2]);
  const double eps = 1e-10 * std::max(scale, 1e-300);
  // The minimum of a linear function over the corners is attained on the convex hull. If the corners span
  // less than 3 dimensions every patch is coplanar with every corner: nothing is strictly behind anything.
  CGAL::Surface_mesh<Point> hull;
  CGAL::convex_hull_3(pts.begin(), pts.end(), hull);
  if (hull.number_of_faces() == 0 || hull.number_of_vertices() < 4) return out;
  std::vector<Vec3> hv;
  std::vector<std::vector<int>> adj;
  hv.reserve(hull.number_of_vertices());
  for (auto v : hull.vertices()) {
    const Point& p = hull.point(v);
    hv.emplace_back(p.x(), p.y(), p.z());
  }
  adj.resize(hv.size());
  for (auto e : hull.edges()) {
    const int a = int(hull.vertex(e, 0)), b = int(hull.vertex(e, 1));
    adj[a].push_back(b);
    adj[b].push_back(a);
  }
  // Hill-climb to the vertex minimising n.w: on a convex polytope a vertex with no better neighbour is
  // optimal (the simplex method's criterion). Consecutive patches are usually neighbours: start from the
  // previous answer.
  int cur = 0;
  for (int p = 0; p < g.size(); ++p) {
    const Vec3& n = g.normal[p];
    double best = n.dot(hv[cur]);
    for (bool moved = true; moved;) {
      moved = false;
      for (int nb : adj[cur]) {
        const double v = n.dot(hv[nb]);
        if (v < best) {
          best = v;
          cur = nb;
          moved = true;
          break;
        }
      }
    }
    if (n.dot(hv[cur] - g.centroid[p]) < -eps) out.push_back(p);  // a difference first: translation invariant
  }
  return out;
}

}  // namespace lambert::formfactor
