// Near-ties of a constrained Delaunay triangulation decided as exact ties are, not by rounding.
//
// Four corners on one circle admit either diagonal as Delaunay. CGAL decides exact ties by a symbolic perturbation
// (Devillers and Teillaud: the corners ordered lexicographically, x then y), so that one triangulation is chosen
// whatever the insertion order. But corners that are cocircular in the model (an isosceles trapezoid between a
// floor's corners and a centred footprint's, any rectangle, two footprints of CornellBox-Original.obj to 4e-17) are
// cocircular only to rounding once read from a file and projected into a face's plane: which diagonal such a
// quadrilateral got depended on the decimals, so a model moved by 1e6 m was triangulated otherwise than the same
// model at the origin (CornellBox-Original.obj: other floor patches, other ray samples, entries 2.8e-3 apart). This
// pass takes every unconstrained edge whose quadrilateral is convex and cocircular within `relative` (of its longest
// side or diagonal, to the fourth power; the file's decimals of a model in GIS coordinates are ~1e-6 m, the doubles'
// 2e-9 m at 1e7 m) and gives it the diagonal CGAL's perturbation gives an exact tie, with coordinates that differ by
// less than 1e-7 of that length taken as equal in the lexicographic order. Exact ties at the origin keep CGAL's
// choice; near-ties anywhere take the one the exact tie would. Returns the number of flips.
#pragma once

#include <CGAL/number_utils.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace lambert::mesh::detail {

template <class CDT>
int settle_cocircular_ties(CDT& cdt, double relative = 1e-6) {
  using Face_handle = typename CDT::Face_handle;
  using Vertex_handle = typename CDT::Vertex_handle;
  using Point = typename CDT::Point;
  if (cdt.dimension() < 2) return 0;
  int flips = 0;
  // A flip changes the quadrilaterals around it: passes until none flips (a guard: the perturbed decisions are those
  // of one Delaunay triangulation of perturbed points, which flips reach without cycles).
  for (int pass = 0; pass < 8; ++pass) {
    std::vector<std::array<Vertex_handle, 2>> edges;
    for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
      const Face_handle f = e->first;
      const int i = e->second;
      if (cdt.is_constrained(*e) || cdt.is_infinite(f) || cdt.is_infinite(f->neighbor(i))) continue;
      edges.push_back({f->vertex(CDT::ccw(i)), f->vertex(CDT::cw(i))});
    }
    int flipped = 0;
    for (const auto& [vb, vc] : edges) {
      Face_handle f;
      int i;
      if (!cdt.is_edge(vb, vc, f, i)) continue;  // flipped away by an earlier flip of this pass
      const Face_handle g = f->neighbor(i);
      if (cdt.is_infinite(f) || cdt.is_infinite(g) || cdt.is_constrained({f, i})) continue;
      const Vertex_handle va = f->vertex(i), vd = cdt.mirror_vertex(f, i);
      // Coordinates relative to a (differences of nearby corners: exact or nearly so).
      const double ax = CGAL::to_double(va->point().x()), ay = CGAL::to_double(va->point().y());
      auto rel = [&](const Vertex_handle& v) {
        return std::array<double, 2>{CGAL::to_double(v->point().x()) - ax, CGAL::to_double(v->point().y()) - ay};
      };
      const auto b = rel(vb), c = rel(vc), d = rel(vd);
      auto cross = [](const std::array<double, 2>& p, const std::array<double, 2>& q) { return p[0] * q[1] - p[1] * q[0]; };
      auto sq = [](const std::array<double, 2>& p) { return p[0] * p[0] + p[1] * p[1]; };
      const std::array<double, 2> cb{c[0] - b[0], c[1] - b[1]}, db{d[0] - b[0], d[1] - b[1]}, dc{d[0] - c[0], d[1] - c[1]};
      const double l2 = std::max({sq(b), sq(c), sq(d), sq(cb), sq(db), sq(dc)});
      // Convex, not nearly degenerate: b and c clearly on either side of a-d (a and d are on either side of b-c, as
      // the two triangles are).
      const double sb = cross(d, b), sc = cross(d, c);
      if (!(sb < -1e-6 * l2 && sc > 1e-6 * l2) && !(sb > 1e-6 * l2 && sc < -1e-6 * l2)) continue;
      // In-circle determinant of (a, b, c; d) relative to a.
      const double det = b[0] * (c[1] * sq(d) - sq(c) * d[1]) - b[1] * (c[0] * sq(d) - sq(c) * d[0]) +
                         sq(b) * (c[0] * d[1] - c[1] * d[0]);
      if (!(std::abs(det) <= relative * l2 * l2)) continue;
      // CGAL's perturbation (Triangulation_2::side_of_oriented_circle) for f = (p0, p1, p2) against p = d, with the
      // lexicographic order tolerant: is d inside f's perturbed circle (then the edge flips)?
      const double tol = 1e-7 * std::sqrt(l2);
      auto before = [&](const Vertex_handle& u, const Vertex_handle& v) {
        const auto pu = rel(u), pv = rel(v);
        if (std::abs(pu[0] - pv[0]) > tol) return pu[0] < pv[0];
        return std::abs(pu[1] - pv[1]) > tol && pu[1] < pv[1];
      };
      const Vertex_handle v0 = f->vertex(0), v1 = f->vertex(1), v2 = f->vertex(2);
      std::array<Vertex_handle, 4> order{v0, v1, v2, vd};
      std::stable_sort(order.begin(), order.end(), before);
      const Point &p0 = v0->point(), &p1 = v1->point(), &p2 = v2->point(), &p = vd->point();
      bool inside = false;  // ON_NEGATIVE_SIDE unless a leading term says otherwise
      for (int k = 3; k > 0; --k) {
        if (order[size_t(k)] == vd) break;
        CGAL::Orientation o = CGAL::COLLINEAR;
        if (order[size_t(k)] == v2) o = cdt.orientation(p0, p1, p);
        else if (order[size_t(k)] == v1) o = cdt.orientation(p0, p, p2);
        else o = cdt.orientation(p, p1, p2);
        if (o != CGAL::COLLINEAR) {
          inside = o == CGAL::POSITIVE;
          break;
        }
      }
      if (!inside) continue;
      Face_handle fh = f;
      cdt.flip(fh, i);
      ++flipped;
    }
    flips += flipped;
    if (flipped == 0) break;
  }
  return flips;
}

// Triangles (corner indices, winding kept) each from its smallest corner, sorted: an order that does not depend on
// how the triangulation reached them.
inline std::vector<std::array<int, 3>> canonical_triangles(std::vector<std::array<int, 3>> tris) {
  for (auto& t : tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(tris.begin(), tris.end());
  return tris;
}

}  // namespace lambert::mesh::detail
