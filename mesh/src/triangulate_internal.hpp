#pragma once
// Internal: the O(n log n) triangulation behind mesh::triangulate_polygon for large polygons.
#include <Eigen/Core>
#include <array>
#include <vector>

namespace lambert::mesh::detail {

// Polygons with more corners go to triangulate_cdt (ear clipping and the pairwise edge test are O(n^2)).
constexpr int kEarClippingMaxCorners = 64;

// Constrained Delaunay triangulation (CGAL) of a simple polygon given by its 2D corners, counter-clockwise.
// Corner-index triples, counter-clockwise; empty if the polygon is not simple (crossing or touching
// edges, repeated corners), clockwise or of zero area.
std::vector<std::array<int, 3>> triangulate_cdt(const std::vector<Eigen::Vector2d>& p);

}  // namespace lambert::mesh::detail
