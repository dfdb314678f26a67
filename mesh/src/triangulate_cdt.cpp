// Large polygons: CGAL's constrained Delaunay triangulation, O(n log n) (geometry.cpp's ear clipping is
// O(n^2) and kept for small polygons, where it is faster and its results are established).
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <deque>

#include "cdt_ties.hpp"
#include "triangulate_internal.hpp"

namespace lambert::mesh::detail {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<int, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K, Fbi>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
// Crossing constraints throw: a polygon whose edges cross is not simple (no triangulation is returned).
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::No_constraint_intersection_tag>;
}  // namespace

std::vector<std::array<int, 3>> triangulate_cdt(const std::vector<Eigen::Vector2d>& p) {
  const int m = static_cast<int>(p.size());
  if (m < 3) return {};
  // Counter-clockwise (the polygon's own winding seen from the normal) with non-zero area, as ear clipping.
  double twice_area = 0;
  for (int k = 0; k < m; ++k) {
    const auto& a = p[k];
    const auto& b = p[(k + 1) % m];
    twice_area += (a.x() - p[0].x()) * (b.y() - p[0].y()) - (b.x() - p[0].x()) * (a.y() - p[0].y());
  }
  if (!(twice_area > 0)) return {};
  try {
    CDT cdt;
    std::vector<CDT::Vertex_handle> vh(m);
    CDT::Face_handle hint;
    for (int k = 0; k < m; ++k) {
      vh[k] = cdt.insert(K::Point_2(p[k].x(), p[k].y()), hint);  // neighbours along the boundary: short walks
      if (cdt.number_of_vertices() != size_t(k) + 1) return {};  // a repeated point: not simple
      vh[k]->info() = k;
      hint = vh[k]->face();
    }
    for (int k = 0; k < m; ++k) cdt.insert_constraint(vh[k], vh[(k + 1) % m]);
    // Inside = odd nesting level across constrained edges, counted from the infinite face.
    settle_cocircular_ties(cdt);  // near-ties decided as exact ties (cdt_ties.hpp)
    mark_nesting_levels(cdt);
    std::vector<std::array<int, 3>> tris;
    tris.reserve(size_t(m - 2));
    for (auto f : cdt.finite_face_handles()) {
      if (f->info() != 1) {
        if (f->info() > 1) return {};  // nested loops: not a simple polygon
        continue;
      }
      tris.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
    }
    // A simple polygon with m corners and no inner points has exactly m - 2 triangles.
    if (static_cast<int>(tris.size()) != m - 2) return {};
    return canonical_triangles(std::move(tris));
  } catch (const CDT::Intersection_of_constraints_exception&) {
    return {};
  }
}

}  // namespace lambert::mesh::detail
