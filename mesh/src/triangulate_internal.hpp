#pragma once
// Internal: the O(n log n) triangulation behind mesh::triangulate_polygon for large polygons.
#include <Eigen/Core>
#include <span>

#include "lambert/mesh/geometry.hpp"
#include <array>
#include <deque>
#include <utility>
#include <vector>

namespace lambert::mesh::detail {

// Polygons with more corners go to triangulate_cdt (ear clipping and the pairwise edge test are O(n^2)).
constexpr int kEarClippingMaxCorners = 64;

// Constrained Delaunay triangulation (CGAL) of a simple polygon given by its 2D corners, counter-clockwise.
// Corner-index triples, counter-clockwise; empty if the polygon is not simple (crossing or touching
// edges, repeated corners), clockwise or of zero area.
std::vector<std::array<int, 3>> triangulate_cdt(const std::vector<Eigen::Vector2d>& p);

// triangulate_polygon's contract by the constrained Delaunay triangulation whatever the corner count: it avoids slivers
// where the polygon allows (ear clipping takes the first ear, a sliver between corners nearly in a line included).
std::vector<std::array<int, 3>> triangulate_polygon_delaunay(std::span<const Vec3> polygon, const Vec3& normal);

// Sets f->info() of every face of a CGAL constrained triangulation (faces with an int info) to its nesting
// level: the number of constrained edges crossed on the way from the infinite face (odd = inside).
template <class CDT>
void mark_nesting_levels(CDT& cdt) {
  for (auto f : cdt.all_face_handles()) f->info() = -1;
  std::deque<std::pair<typename CDT::Face_handle, int>> border{{cdt.infinite_face(), 0}};
  while (!border.empty()) {
    auto [start, level] = border.front();
    border.pop_front();
    if (start->info() >= 0) continue;
    std::deque<typename CDT::Face_handle> queue{start};
    start->info() = level;
    while (!queue.empty()) {
      const auto f = queue.front();
      queue.pop_front();
      for (int i = 0; i < 3; ++i) {
        const auto g = f->neighbor(i);
        if (g->info() >= 0) continue;
        if (cdt.is_constrained({f, i})) {
          border.push_back({g, level + 1});
        } else {
          g->info() = level;
          queue.push_back(g);
        }
      }
    }
  }
}

}  // namespace lambert::mesh::detail
