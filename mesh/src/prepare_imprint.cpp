// mesh::prepare, step 3b: contact lines and crossings imprinted (Baum, Mann, Smith, Winget 1991:
// "Making radiosity usable: automatic preprocessing and meshing techniques for the generation of
// accurate radiosity solutions"). Where a face touches another face's interior along a line (a wall
// standing on a slab) or crosses it (a leg through a floor), both are split along that line; the
// fragments that end up hidden (under a wall, inside a solid, between coincident faces) are removed.
// Intersections with exact constructions (CGAL Epeck), splitting by a constrained Delaunay
// triangulation per face in its plane (robust predicates), pieces merged back into polygons.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <unordered_map>
#include <tuple>
#include <vector>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cdt_ties.hpp"
#include "prepare_internal.hpp"
#include "soup_rays.hpp"
#include "tri_tri.hpp"

namespace lambert::mesh::detail {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using KE = CGAL::Exact_predicates_exact_constructions_kernel;
using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
struct Info {
  int index = -1;  // soup position index; -1: a crossing of two constraints made by the triangulation
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<Info, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

KE::Point_3 ke(const Vec3& p) { return {p.x(), p.y(), p.z()}; }
Vec3 vec(const KE::Point_3& p) { return {CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())}; }

// Positions by location: a point within tol of an existing one is that one (hash grid of cell tol).
class PointIndex {
 public:
  PointIndex(PolygonSoup& s, double tol) : s_(s), tol_(tol), cell_(std::max(tol, 1e-300)) {
    for (const auto& f : s.faces)
      for (int v : f.vertices) add_existing(v);
  }
  int find_or_add(const Vec3& p) {
    const auto c = cell(p);
    int best = -1;
    double bd = tol_;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = grid_.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
          if (it == grid_.end()) continue;
          for (int w : it->second) {
            const double d = (s_.positions[w] - p).norm();
            if (d <= bd) bd = d, best = w;
          }
        }
    if (best >= 0) return best;
    const int v = static_cast<int>(s_.positions.size());
    s_.positions.push_back(p);
    s_.position_lines.push_back(0);
    grid_[key(c)].push_back(v);
    return v;
  }

 private:
  void add_existing(int v) {
    if (seen_.size() <= size_t(v)) seen_.resize(s_.positions.size(), 0);
    if (seen_[v]) return;
    seen_[v] = 1;
    grid_[key(cell(s_.positions[v]))].push_back(v);
  }
  std::array<std::int64_t, 3> cell(const Vec3& p) const {
    return {std::int64_t(std::floor(p.x() / cell_)), std::int64_t(std::floor(p.y() / cell_)),
            std::int64_t(std::floor(p.z() / cell_))};
  }
  static std::uint64_t key(const std::array<std::int64_t, 3>& c) {
    return std::uint64_t(c[0]) * 73856093u ^ std::uint64_t(c[1]) * 19349663u ^ std::uint64_t(c[2]) * 83492791u;
  }
  PolygonSoup& s_;
  double tol_, cell_;
  std::vector<char> seen_;
  std::unordered_map<std::uint64_t, std::vector<int>> grid_;
};

struct FaceData {
  std::vector<Vec3> poly;
  Vec3 n = Vec3::Zero();  // unit
  Vec3 u, v;              // plane basis, u x v = n
  double thickness = 0;    // largest corner distance from the plane through poly[0] with normal n, plus rounding (m)
  std::vector<KE::Triangle_3> tris;
  std::vector<std::array<Vec3, 3>> corners3;  // the same triangles' corners (double precision)
  std::vector<std::array<Vec3, 2>> cuts;  // segments to imprint (metres)
};

Eigen::Vector2d to2(const FaceData& f, const Vec3& p) { return {(p - f.poly[0]).dot(f.u), (p - f.poly[0]).dot(f.v)}; }

// Cuts found for one pair of faces (f's and g's), applied to the faces in pair order afterwards.
using Cuts = std::vector<std::array<Vec3, 2>>;

void add_cut(const FaceData& f, Cuts& cuts, const Vec3& a, const Vec3& b, double tol) {
  if ((a - b).norm() <= tol) return;
  // On the face's boundary already: nothing to split.
  const Vec3 m = 0.5 * (a + b);
  if (distance_to_boundary(m, f.poly) <= tol && distance_to_boundary(a, f.poly) <= tol &&
      distance_to_boundary(b, f.poly) <= tol)
    return;
  cuts.push_back({a, b});
}

// Pieces of one line (direction d) found triangle by triangle, joined where they touch (within tol):
// triangulation diagonals must not leave extra vertices on a cut.
std::vector<std::array<Vec3, 2>> join_collinear(std::vector<std::array<Vec3, 2>> pieces, const Vec3& d, double tol) {
  for (auto& p : pieces)
    if (p[0].dot(d) > p[1].dot(d)) std::swap(p[0], p[1]);
  std::sort(pieces.begin(), pieces.end(), [&](const auto& a, const auto& b) { return a[0].dot(d) < b[0].dot(d); });
  std::vector<std::array<Vec3, 2>> out;
  for (const auto& p : pieces) {
    if (!out.empty() && p[0].dot(d) <= out.back()[1].dot(d) + tol) {
      if (p[1].dot(d) > out.back()[1].dot(d)) out.back()[1] = p[1];
    } else {
      out.push_back(p);
    }
  }
  return out;
}

// All of g's corners farther than f's own thickness (its corners' largest distance from its plane, plus
// rounding) from f's plane, on one side: the faces cannot meet. A filter only (double precision, with margin):
// the exact intersection below decides every pair it lets through. Candidate pairs from boxes include faces
// near each other that do not touch (furniture by a wall), whose exact test costs ~60 us.
bool separated_by_plane(const FaceData& f, const FaceData& g, double tol) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& q : g.poly) {
    const double d = f.n.dot(q - f.poly[0]);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  // Not nearer than tol either: an edge within tol of the plane is a contact (near_contacts), the way a wall
  // stands on a slab in a model whose corners were rounded to single precision (an STL export: 1e-6 m off).
  const double margin = std::max(f.thickness, tol);
  return lo > margin || hi < -margin;
}

// Coplanar f and g whose overlap is a band narrower than `margin` along some line (an edge's normal in f's plane):
// all of f's corners within `margin` on one side of the line, all of g's on the other. Every point common to
// both is then within `margin` of either face's boundary, so clipping one's edges to the other finds only
// segments on the boundary, which add_cut drops. A filter only (double precision; the caller passes half the
// tolerance add_cut uses): most coplanar candidates are neighbours in one wall or floor that meet along an edge
// without sharing its corners (T-junctions), and the exact clipping cost ~200 us per pair.
bool separated_in_plane(const FaceData& f, const FaceData& g, double margin) {
  auto in_plane = [&](const Vec3& p) { return Eigen::Vector2d((p - f.poly[0]).dot(f.u), (p - f.poly[0]).dot(f.v)); };
  std::vector<Eigen::Vector2d> pf, pg;
  for (const Vec3& p : f.poly) pf.push_back(in_plane(p));
  for (const Vec3& p : g.poly) pg.push_back(in_plane(p));
  auto separates = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d e = b - a;
    const double len = e.norm();
    if (!(len > 0)) return false;
    const Eigen::Vector2d nrm(e.y() / len, -e.x() / len);
    double f_lo = std::numeric_limits<double>::infinity(), f_hi = -f_lo, g_lo = f_lo, g_hi = -f_lo;
    for (const auto& p : pf) f_lo = std::min(f_lo, nrm.dot(p - a)), f_hi = std::max(f_hi, nrm.dot(p - a));
    for (const auto& p : pg) g_lo = std::min(g_lo, nrm.dot(p - a)), g_hi = std::max(g_hi, nrm.dot(p - a));
    return f_hi - g_lo <= margin || g_hi - f_lo <= margin;
  };
  for (size_t c = 0; c < pf.size(); ++c)
    if (separates(pf[c], pf[(c + 1) % pf.size()])) return true;
  for (size_t c = 0; c < pg.size(); ++c)
    if (separates(pg[c], pg[(c + 1) % pg.size()])) return true;
  return false;
}

// The parts of segment [a, b] (points of f's plane) inside f's polygon, in f's plane coordinates: the segment cut
// at every crossing with f's edges, the pieces whose midpoints lie strictly inside (CGAL's bounded_side_2) kept.
std::vector<std::array<Vec3, 2>> clip_to_face(const FaceData& f, const Vec3& a, const Vec3& b) {
  const Eigen::Vector2d A = to2(f, a), B = to2(f, b), d = B - A;
  std::vector<double> ts{0.0, 1.0};
  const size_t m = f.poly.size();
  std::vector<Eigen::Vector2d> P(m);
  std::vector<K::Point_2> outline;
  for (size_t k = 0; k < m; ++k) {
    P[k] = to2(f, f.poly[k]);
    outline.emplace_back(P[k].x(), P[k].y());
  }
  for (size_t k = 0; k < m; ++k) {
    const Eigen::Vector2d &p = P[k], e = P[(k + 1) % m] - P[k];
    const double den = d.x() * e.y() - d.y() * e.x();
    if (den == 0) continue;
    const Eigen::Vector2d w = p - A;
    const double t = (w.x() * e.y() - w.y() * e.x()) / den, s = (w.x() * d.y() - w.y() * d.x()) / den;
    if (t > 0 && t < 1 && s >= 0 && s <= 1) ts.push_back(t);
  }
  std::sort(ts.begin(), ts.end());
  std::vector<std::array<Vec3, 2>> out;
  for (size_t k = 0; k + 1 < ts.size(); ++k) {
    if (!(ts[k + 1] > ts[k])) continue;
    const Eigen::Vector2d c = A + 0.5 * (ts[k] + ts[k + 1]) * d;
    if (CGAL::bounded_side_2(outline.begin(), outline.end(), K::Point_2(c.x(), c.y()), K()) == CGAL::ON_BOUNDED_SIDE)
      out.push_back({a + ts[k] * (b - a), a + ts[k + 1] * (b - a)});
  }
  return out;
}

// Edges of `from` lying within tol of `on`'s plane without lying in it exactly (a face standing on another in a
// model turned by a rotation that is not a quarter turn: its corners rounded 1e-16 off the other's plane): the exact
// intersection finds no contact where such an edge stays above the plane, or a piece of it where it dips below. Each
// such edge, projected onto the plane and clipped to `on`, is where the two meet (CornellBox-Original.obj turned
// about (1, 2, 3) by 0.7 rad kept its floor whole under both blocks: 17 patches instead of 30). Appended to `found`,
// to be joined with the exact pieces along the same line.
void near_contacts(const FaceData& on, const FaceData& from, double tol, std::vector<std::array<Vec3, 2>>& found) {
  const size_t m = from.poly.size();
  for (size_t c = 0; c < m; ++c) {
    const Vec3 &p = from.poly[c], &q = from.poly[(c + 1) % m];
    const double dp = on.n.dot(p - on.poly[0]), dq = on.n.dot(q - on.poly[0]);
    if (std::abs(dp) > tol || std::abs(dq) > tol) continue;
    // In the plane exactly (exact predicates; both corners against every triangle of `on`): the exact intersection
    // has it. A distance that rounds to 0 is not enough: in examples/floorplan.obj turned about the vertical by 30
    // degrees a worktop's edge was 0.0 from a wall's plane in double precision but in front of it exactly, so neither
    // found the contact, and the cavity under the counter, leaning on that wall, was kept (248 hidden fragments
    // instead of 336: 11 m^2 of floor and wall inside the counter left as patches; test
    // PrepareInvariance.FloorPlanTurnedAboutTheVerticalIsPreparedAsUpright).
    auto exactly_in = [&](const Vec3& x) {
      const K::Point_3 px(x.x(), x.y(), x.z());
      for (const auto& t : on.corners3)
        if (CGAL::orientation(K::Point_3(t[0].x(), t[0].y(), t[0].z()), K::Point_3(t[1].x(), t[1].y(), t[1].z()),
                              K::Point_3(t[2].x(), t[2].y(), t[2].z()), px) != CGAL::COPLANAR)
          return false;
      return true;
    };
    if (exactly_in(p) && exactly_in(q)) continue;
    for (const auto& seg : clip_to_face(on, p - dp * on.n, q - dq * on.n)) found.push_back(seg);
  }
}

// f and g in one plane: parallel to 1e-9 and within tol of each other's plane, or every corner of each within tol of
// the other's plane. The second takes faces that rounding tilted apart: a model exported in single precision (an STL)
// and turned in GIS coordinates has a wall's normal and a furniture panel's against it 1e-6 apart, so they were
// taken as crossing, not lying against each other, and the wall behind the panel was not even tested for hiding.
bool coplanar_faces(const FaceData& f, const FaceData& g, double tol) {
  if (f.n.cross(g.n).norm() <= 1e-9) return std::abs(f.n.dot(g.poly[0] - f.poly[0])) <= tol;
  auto within = [&](const FaceData& a, const FaceData& b) {
    for (const Vec3& q : b.poly)
      if (!(std::abs(a.n.dot(q - a.poly[0])) <= tol)) return false;
    return true;
  };
  return within(f, g) && within(g, f);
}

// Segments where face g meets face f: into cf (f's) and cg (g's).
void intersect_pair(const FaceData& f, const FaceData& g, double tol, Cuts& cf, Cuts& cg) {
  const bool parallel = f.n.cross(g.n).norm() <= 1e-9;
  const bool coplanar = coplanar_faces(f, g, tol);
  if (coplanar && separated_in_plane(f, g, 0.5 * tol)) return;
  if (coplanar) {
    // Overlapping coplanar faces: each gets the other's edges, clipped to itself.
    auto clip_edges = [&](const FaceData& to, const FaceData& from, Cuts& cuts) {
      for (size_t c = 0; c < from.poly.size(); ++c) {
        const KE::Segment_3 e(ke(from.poly[c]), ke(from.poly[(c + 1) % from.poly.size()]));
        // Project onto to's plane first (coplanar within tol, not exactly).
        const KE::Plane_3 plane(to.tris[0].vertex(0), to.tris[0].vertex(1), to.tris[0].vertex(2));
        const KE::Segment_3 ep(plane.projection(e.source()), plane.projection(e.target()));
        // An edge perpendicular to the plane projects to a point: CGAL's triangle-segment intersection
        // asserts on a degenerate segment (found by tests/fuzz on a non-planar quad given twice).
        if (ep.is_degenerate()) continue;
        std::vector<std::array<Vec3, 2>> found;
        for (const auto& t : to.tris) {
          const auto x = CGAL::intersection(t, ep);
          if (!x) continue;
          if (const auto* s = boost::get<KE::Segment_3>(&*x)) found.push_back({vec(s->source()), vec(s->target())});
        }
        const Vec3 d = (from.poly[(c + 1) % from.poly.size()] - from.poly[c]).normalized();
        for (const auto& seg : join_collinear(found, d, tol)) add_cut(to, cuts, seg[0], seg[1], tol);
      }
    };
    clip_edges(f, g, cf);
    clip_edges(g, f, cg);
    return;
  }
  if (parallel || separated_by_plane(f, g, tol) || separated_by_plane(g, f, tol)) return;
  std::vector<std::array<Vec3, 2>> found;
  for (size_t i = 0; i < f.tris.size(); ++i)
    for (size_t j = 0; j < g.tris.size(); ++j) {
      const KE::Triangle_3 &tf = f.tris[i], &tg = g.tris[j];
      if (!CGAL::do_overlap(tf.bbox(), tg.bbox())) continue;
      // Exact sides, double-precision points; planes or edges within 1e-4 rad of the other's plane take the exact
      // constructions (tri_tri.hpp).
      const TriangleContact c = intersect_triangles(f.corners3[i], g.corners3[j]);
      if (c.kind == TriangleContact::kSegment) found.push_back({c.a, c.b});
      if (c.kind != TriangleContact::kNeedsExact || !CGAL::do_intersect(tf, tg)) continue;
      const auto x = CGAL::intersection(tf, tg);
      if (!x) continue;
      if (const auto* s = boost::get<KE::Segment_3>(&*x)) found.push_back({vec(s->source()), vec(s->target())});
    }
  near_contacts(f, g, tol, found);
  near_contacts(g, f, tol, found);
  for (const auto& seg : join_collinear(found, f.n.cross(g.n).normalized(), tol)) {
    add_cut(f, cf, seg[0], seg[1], tol);
    add_cut(g, cg, seg[0], seg[1], tol);
  }
}

// Splits face k along its cuts: the pieces (corner index lists, same winding), or empty if none.
// Cut ends within tol of the face's boundary are made vertices of the boundary (on a corner, or inserted into
// the edge), so that a cut from an edge into the face and back closes its region whichever side of the edge
// rounding put the end: left in the interior by 1e-16, the region stayed open and the face was not split, and
// which of the two happened depended on where the model sits (uDALES moved by (5e5, 4e6) m split other faces).
std::vector<std::vector<int>> split_face(const PolygonSoup& s, int k, const FaceData& f, PointIndex& index,
                                         double tol) {
  CDT cdt;
  const auto& fv = s.faces[k].vertices;
  const size_t nc = fv.size();
  // A cut ending within tol of another cut's interior (a partition wall's end against a wall's footprint) ends on it:
  // the end is moved onto that cut and the cut is split there. Turned by 30 degrees, the storey's partition ended
  // 1e-16 short of the wall's footprint in the ceiling, which then was not split (one piece half lit instead of a lit
  // and a dark one), and 1e-16 past it in the floor (a zero-area sliver): 0.4 % of the light went elsewhere.
  std::vector<std::array<Vec3, 2>> cuts(f.cuts.begin(), f.cuts.end());
  for (int round = 0, changed = 1; changed && round < 4; ++round) {
    changed = 0;
    for (size_t i = 0; i < cuts.size(); ++i)
      for (int e = 0; e < 2; ++e)
        for (size_t j = 0; j < cuts.size(); ++j) {
          if (j == i) continue;
          const Vec3 p = cuts[i][size_t(e)], a = cuts[j][0], b = cuts[j][1];
          const double len2 = (b - a).squaredNorm();
          if (!(len2 > 0)) continue;
          const double t = (p - a).dot(b - a) / len2;
          if (!(t > 0 && t < 1)) continue;
          const Vec3 q = a + t * (b - a);
          if ((q - p).norm() > tol || (p - a).norm() <= tol || (p - b).norm() <= tol) continue;
          cuts[i][size_t(e)] = q;
          cuts[j][1] = q;
          cuts.push_back({q, b});
          changed = 1;
        }
  }
  // Cut ends on the boundary: per end, the corner it is (c) or the edge it lies in (nc + c, with its parameter).
  struct OnBoundary {
    size_t at = SIZE_MAX;  // corner c, or nc + c for edge c (from corner c to c + 1)
    double t = 0;          // parameter along the edge
  };
  std::vector<std::array<OnBoundary, 2>> ends(cuts.size());
  std::vector<std::vector<std::pair<double, Vec3>>> on_edge(nc);
  for (size_t k2 = 0; k2 < cuts.size(); ++k2)
    for (int e = 0; e < 2; ++e) {
      const Vec3& p = cuts[k2][size_t(e)];
      double best = tol;
      for (size_t c = 0; c < nc; ++c) {
        const double d = (p - f.poly[c]).norm();
        if (d <= best) best = d, ends[k2][size_t(e)] = {c, 0.0};
      }
      if (ends[k2][size_t(e)].at != SIZE_MAX) continue;
      for (size_t c = 0; c < nc; ++c) {
        const Vec3 &a = f.poly[c], &b = f.poly[(c + 1) % nc];
        const double len2 = (b - a).squaredNorm();
        if (!(len2 > 0)) continue;
        const double t = std::clamp((p - a).dot(b - a) / len2, 0.0, 1.0);
        const double d = (a + t * (b - a) - p).norm();
        if (d <= best) best = d, ends[k2][size_t(e)] = {nc + c, t};
      }
      if (ends[k2][size_t(e)].at != SIZE_MAX && ends[k2][size_t(e)].at >= nc)
        on_edge[ends[k2][size_t(e)].at - nc].push_back({ends[k2][size_t(e)].t, p});
    }
  // The outline: corners, and in each edge the cut ends lying in it (in order along it, one per position).
  std::vector<CDT::Vertex_handle> corner(nc);
  std::vector<std::vector<std::pair<double, CDT::Vertex_handle>>> edge_vertices(nc);
  std::vector<K::Point_2> outline;
  std::vector<CDT::Vertex_handle> ring;
  for (size_t c = 0; c < nc; ++c) {
    const Eigen::Vector2d q = to2(f, f.poly[c]);
    outline.emplace_back(q.x(), q.y());
    corner[c] = cdt.insert(outline.back());
    corner[c]->info().index = fv[c];
    ring.push_back(corner[c]);
    auto& pts = on_edge[c];
    std::sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    Vec3 last(INFINITY, INFINITY, INFINITY);
    for (const auto& [t, p] : pts) {
      if ((p - last).norm() <= tol) {  // the same point again (two cuts meeting on the edge)
        edge_vertices[c].push_back({t, edge_vertices[c].back().second});
        continue;
      }
      last = p;
      // The end's position on the edge (within tol of the cut's end; a point of the face's plane).
      const Vec3 a = f.poly[c], b = f.poly[(c + 1) % nc];
      const Eigen::Vector2d q2 = to2(f, a + t * (b - a));
      outline.emplace_back(q2.x(), q2.y());
      const CDT::Vertex_handle h = cdt.insert(outline.back());
      if (h->info().index < 0) h->info().index = index.find_or_add(p);
      edge_vertices[c].push_back({t, h});
      ring.push_back(h);
    }
  }
  for (size_t r = 0; r < ring.size(); ++r)
    if (ring[r] != ring[(r + 1) % ring.size()]) cdt.insert_constraint(ring[r], ring[(r + 1) % ring.size()]);
  // Cut ends inside the face, each inserted once: an end within tol of one inserted before is that vertex (two cuts
  // meeting at a corner of a block standing on the face meet there only to rounding when the model is turned: left
  // apart by 1e-16, the cuts did not close the footprint and the face was not split).
  std::vector<std::pair<Vec3, CDT::Vertex_handle>> inner_ends;
  for (size_t k2 = 0; k2 < cuts.size(); ++k2) {
    const auto& cut = cuts[k2];
    CDT::Vertex_handle h[2];
    for (int e = 0; e < 2; ++e) {
      const OnBoundary& ob = ends[k2][size_t(e)];
      if (ob.at < nc) {
        h[e] = corner[ob.at];
        continue;
      }
      if (ob.at != SIZE_MAX) {
        for (const auto& [t, hv] : edge_vertices[ob.at - nc])
          if (t == ob.t) h[e] = hv;
        continue;
      }
      const Vec3& p = cut[size_t(e)];
      double best = tol;
      for (const auto& [q, hv] : inner_ends)
        if (const double d = (p - q).norm(); d <= best) best = d, h[e] = hv;
      if (h[e] != CDT::Vertex_handle()) continue;
      const Eigen::Vector2d q = to2(f, p);
      h[e] = cdt.insert({q.x(), q.y()});
      if (h[e]->info().index < 0) h[e]->info().index = index.find_or_add(p);
      inner_ends.push_back({p, h[e]});
    }
    if (h[0] != h[1]) cdt.insert_constraint(h[0], h[1]);
  }
  // Vertices the triangulation made where constraints cross: back to 3D in the face's plane.
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    if (v->info().index < 0) {
      const auto& p = v->point();
      v->info().index = index.find_or_add(f.poly[0] + p.x() * f.u + p.y() * f.v);
    }
  // Regions with holes are emitted as their triangles: near-cocircular quadrilaterals decided as exact ties (cdt_ties.hpp).
  settle_cocircular_ties(cdt);
  // Triangles inside the face, grouped into regions bounded by constraints. Regions are numbered in the
  // triangulation's order (`inside`), not in the map's: its keys are handles, ordered by address, and the pieces (their
  // order, their first corner) then depended on where the allocator had put the faces: the first mesh::prepare of a
  // process gave other soups than the next ones (examples/floorplan.obj: a face reversed, vertices renumbered).
  std::map<CDT::Face_handle, int> region;  // lookups only
  std::vector<CDT::Face_handle> inside;
  std::vector<std::vector<CDT::Face_handle>> regions;
  // A triangle with an edge of the outline is inside if it lies on the edge's left (the outline runs counter-clockwise
  // in the face's frame, and a triangle's corners too): decided by the handles, not by a rounded point. The centroid
  // of a sliver along the outline (a cut's end placed on an edge lands within rounding of it, on either side) fell
  // on either side of the outline by rounding, and the sliver became a piece of its own.
  std::map<std::pair<CDT::Vertex_handle, CDT::Vertex_handle>, char> outline_edges;  // lookups only
  for (size_t r = 0; r < ring.size(); ++r) outline_edges[{ring[r], ring[(r + 1) % ring.size()]}] = 1;
  auto side_of_outline = [&](const CDT::Face_handle& fh) {  // 1 inside, 0 outside, -1 no edge on the outline
    for (int i = 0; i < 3; ++i) {
      const CDT::Vertex_handle a = fh->vertex(CDT::ccw(i)), b = fh->vertex(CDT::cw(i));  // fh lies left of a -> b
      if (outline_edges.count({a, b})) return 1;
      if (outline_edges.count({b, a})) return 0;
    }
    return -1;
  };
  for (auto fh = cdt.finite_faces_begin(); fh != cdt.finite_faces_end(); ++fh) {
    const int side = side_of_outline(fh);
    if (side == 0) continue;
    if (side < 0) {
      const auto c = CGAL::centroid(fh->vertex(0)->point(), fh->vertex(1)->point(), fh->vertex(2)->point());
      if (CGAL::bounded_side_2(outline.begin(), outline.end(), c, K()) != CGAL::ON_BOUNDED_SIDE) continue;
    }
    region[fh] = -1;
    inside.push_back(fh);
  }
  for (const CDT::Face_handle& start : inside) {
    if (region[start] >= 0) continue;
    const int r = static_cast<int>(regions.size());
    regions.emplace_back();
    std::vector<CDT::Face_handle> stack{start};
    region[start] = r;
    while (!stack.empty()) {
      const auto fh = stack.back();
      stack.pop_back();
      regions[r].push_back(fh);
      for (int i = 0; i < 3; ++i) {
        if (cdt.is_constrained({fh, i})) continue;
        const auto nh = fh->neighbor(i);
        const auto it = region.find(nh);
        if (it == region.end() || it->second >= 0) continue;
        it->second = r;
        stack.push_back(nh);
      }
    }
  }
  if (regions.size() <= 1) return {};
  std::vector<std::vector<int>> pieces;
  for (int r = 0; r < static_cast<int>(regions.size()); ++r) {
    // Boundary of the region: directed edges (counter-clockwise) whose other side is another region.
    std::map<int, int> next;
    bool simple = true;
    size_t edges = 0;
    for (const auto& fh : regions[r])
      for (int i = 0; i < 3; ++i) {
        const auto it = region.find(fh->neighbor(i));
        if (it != region.end() && it->second == r) continue;
        const int a = fh->vertex(CDT::ccw(i))->info().index, b = fh->vertex(CDT::cw(i))->info().index;
        if (!next.emplace(a, b).second) simple = false;
        ++edges;
      }
    std::vector<int> loop;
    if (simple && !next.empty()) {
      int v = next.begin()->first;
      for (size_t guard = 0; guard <= edges; ++guard) {
        loop.push_back(v);
        const auto it = next.find(v);
        if (it == next.end()) {
          simple = false;
          break;
        }
        v = it->second;
        if (v == loop.front()) break;
      }
      simple = simple && loop.size() == edges;
    }
    if (simple) {
      // Corners snapped onto one position (closer than the weld tolerance) collapse.
      std::vector<int> clean;
      for (int v : loop)
        if (clean.empty() || clean.back() != v) clean.push_back(v);
      while (clean.size() > 1 && clean.back() == clean.front()) clean.pop_back();
      std::vector<int> sorted = clean;
      std::sort(sorted.begin(), sorted.end());
      if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) simple = false;  // pinched
      else if (clean.size() >= 3) pieces.push_back(clean);
    }
    if (!simple) {  // a region with holes (or pinched): its triangles
      std::vector<std::array<int, 3>> tris;
      for (const auto& fh : regions[r]) {
        const int a = fh->vertex(0)->info().index, b = fh->vertex(1)->info().index, c = fh->vertex(2)->info().index;
        if (a != b && b != c && a != c) tris.push_back({a, b, c});
      }
      // In an order of their own (the triangulation's faces and their first corners depend on its history).
      for (const std::array<int, 3>& t : canonical_triangles(std::move(tris))) pieces.push_back({t[0], t[1], t[2]});
    }
  }
  // Pieces in an order of their own: regions are found in the triangulation's face order, which depends on the
  // corners' rounding (the same floor moved by 1e6 m listed its regions otherwise). Each piece starts at its smallest
  // corner (loops from the smallest key of `next`, triangles rotated), so sorting them fixes the order.
  std::sort(pieces.begin(), pieces.end());
  return pieces;
}


// p (in the polygon's plane) strictly inside the polygon with unit normal n.
bool inside_polygon(const std::vector<Vec3>& poly, const Vec3& n, const Vec3& p) {
  const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized(), v = n.cross(u);
  std::vector<K::Point_2> q;
  for (const Vec3& c : poly) q.emplace_back((c - poly[0]).dot(u), (c - poly[0]).dot(v));
  const K::Point_2 x((p - poly[0]).dot(u), (p - poly[0]).dot(v));
  return CGAL::bounded_side_2(q.begin(), q.end(), x, K()) == CGAL::ON_BOUNDED_SIDE;
}

// Inserts into every face edge the vertices with used[v] != 0 that lie inside it (within tol). The edges' boxes are
// built in parallel and intersected with CGAL's sequential box intersection (its Parallel_tag took 9.5 s instead of
// 3.1 s on the million-face building); what it finds is sorted, not kept in a map (conform 7.2 -> 4.1 s there).
void conform(PolygonSoup& s, double tol, std::vector<char> used) {
  used.resize(s.positions.size(), 0);
  std::vector<Box> vboxes;
  for (int v = 0; v < static_cast<int>(used.size()); ++v)
    if (used[v]) {
      const Vec3& p = s.positions[v];
      double lo[3] = {p.x() - tol, p.y() - tol, p.z() - tol}, hi[3] = {p.x() + tol, p.y() + tol, p.z() + tol};
      vboxes.emplace_back(lo, hi, v);
    }
  if (vboxes.empty()) return;
  const int nf = static_cast<int>(s.faces.size());
  std::vector<int> first_edge(nf + 1, 0);  // face k's edges are first_edge[k] .. first_edge[k + 1] - 1
  for (int k = 0; k < nf; ++k) first_edge[k + 1] = first_edge[k] + static_cast<int>(s.faces[k].vertices.size());
  std::vector<int> edge_face(first_edge[nf]);
  std::vector<Box> eboxes(first_edge[nf]);
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int k = range.begin(); k < range.end(); ++k) {
      const auto& fv = s.faces[k].vertices;
      for (size_t c = 0; c < fv.size(); ++c) {
        const Vec3 &a = s.positions[fv[c]], &b = s.positions[fv[(c + 1) % fv.size()]];
        double lo[3], hi[3];
        for (int i = 0; i < 3; ++i) lo[i] = std::min(a[i], b[i]) - tol, hi[i] = std::max(a[i], b[i]) + tol;
        const int e = first_edge[k] + static_cast<int>(c);
        eboxes[e] = Box(lo, hi, e);
        edge_face[e] = k;
      }
    }
  });
  struct Insert {
    int edge;  // first_edge[face] + corner: the edge from that corner to the next
    double t;
    int v;
    bool operator<(const Insert& o) const { return std::tie(edge, t, v) < std::tie(o.edge, o.t, o.v); }
  };
  std::vector<Insert> inserts;
  CGAL::box_intersection_d(vboxes.begin(), vboxes.end(), eboxes.begin(), eboxes.end(), [&](const Box& vb, const Box& eb) {
    const int e = eb.info(), k = edge_face[e], c = e - first_edge[k];
    const auto& fv = s.faces[k].vertices;
    const int ia = fv[c], ib = fv[(c + 1) % fv.size()], v = vb.info();
    if (v == ia || v == ib) return;
    const Vec3 &a = s.positions[ia], &b = s.positions[ib], &p = s.positions[v];
    const double l2 = (b - a).squaredNorm();
    if (!(l2 > 0)) return;
    const double t = (p - a).dot(b - a) / l2;
    if (t * std::sqrt(l2) <= tol || (1 - t) * std::sqrt(l2) <= tol) return;
    if ((a + t * (b - a) - p).norm() > tol) return;
    inserts.push_back({e, t, v});
  });
  std::sort(inserts.begin(), inserts.end());
  for (size_t i = 0; i < inserts.size();) {
    const int k = edge_face[inserts[i].edge];
    auto& fv = s.faces[k].vertices;
    std::vector<int> out;
    for (size_t c = 0; c < fv.size(); ++c) {
      out.push_back(fv[c]);
      for (; i < inserts.size() && inserts[i].edge == first_edge[k] + static_cast<int>(c); ++i) {
        const int v = inserts[i].v;
        if (std::find(out.begin(), out.end(), v) == out.end() && std::find(fv.begin(), fv.end(), v) == fv.end())
          out.push_back(v);
      }
    }
    fv = std::move(out);
  }
}

}  // namespace

void imprint(PolygonSoup& s, double tol, Report& report) {
  const int nf = static_cast<int>(s.faces.size());
  report.counts["faces_imprinted"] += 0;
  report.counts["hidden_fragments_removed"] += 0;
  if (nf == 0) return;
  std::vector<FaceData> fd(nf);
  std::vector<Box> boxes;
  for (int k = 0; k < nf; ++k) {
    if (!usable_face(s, k)) continue;
    FaceData& f = fd[k];
    f.poly = corners(s, k);
    f.n = newell_normal(f.poly).normalized();
    f.u = (std::abs(f.n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(f.n).normalized();
    f.v = f.n.cross(f.u);
    double extent = 0;
    for (const Vec3& q : f.poly) {
      f.thickness = std::max(f.thickness, std::abs(f.n.dot(q - f.poly[0])));
      extent = std::max(extent, (q - f.poly[0]).lpNorm<Eigen::Infinity>());
    }
    // Rounding of the distances (of coordinates up to |poly[0]| + extent): generous, 1e-12 relative.
    f.thickness += 1e-12 * (f.poly[0].lpNorm<Eigen::Infinity>() + extent) + 1e-300;
    for (const auto& t : triangulate_polygon(f.poly, f.n)) {
      KE::Triangle_3 tri(ke(f.poly[t[0]]), ke(f.poly[t[1]]), ke(f.poly[t[2]]));
      if (tri.is_degenerate()) continue;
      f.tris.push_back(tri);
      f.corners3.push_back({f.poly[t[0]], f.poly[t[1]], f.poly[t[2]]});
    }
    if (f.tris.empty()) continue;
    Eigen::AlignedBox3d b;
    for (const Vec3& p : f.poly) b.extend(p);
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = b.min()[a] - tol, hi[a] = b.max()[a] + tol;
    boxes.emplace_back(lo, hi, k);
  }
  std::vector<std::pair<int, int>> pairs;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
    pairs.emplace_back(std::min(a.info(), b.info()), std::max(a.info(), b.info()));
  });
  std::sort(pairs.begin(), pairs.end());
  std::vector<char> in_contact(nf, 0);
  auto shared_corners = [&](int a, int b) {
    int n = 0;
    for (int v : s.faces[a].vertices)
      n += std::find(s.faces[b].vertices.begin(), s.faces[b].vertices.end(), v) != s.faces[b].vertices.end();
    return n;
  };
  // Per pair: skipped, or its cuts. Pairs in parallel, in blocks (the cuts of a block are kept until applied);
  // applied in pair order, so the result does not depend on the thread count.
  auto skip_pair = [&](int a, int b) {
    if (origin_of(s, a) == origin_of(s, b)) return true;
    // Neighbours across an edge that are not coplanar meet only along it (a fold would be coplanar).
    // Coplanar neighbours across an edge, on either side of it, do not overlap either.
    if (shared_corners(a, b) >= 2) {
      if (fd[a].n.cross(fd[b].n).norm() > 1e-9) return true;
      const auto& fa = s.faces[a].vertices;
      int e0 = -1, e1 = -1;
      for (size_t c = 0; c < fa.size() && e1 < 0; ++c) {
        const int v = fa[c], w = fa[(c + 1) % fa.size()];
        const auto& fb = s.faces[b].vertices;
        if (std::find(fb.begin(), fb.end(), v) != fb.end() && std::find(fb.begin(), fb.end(), w) != fb.end())
          e0 = v, e1 = w;
      }
      if (e1 >= 0) {
        const Vec3 &p0 = s.positions[e0], &p1 = s.positions[e1];
        const Vec3 side = (p1 - p0).cross(fd[a].n);
        Vec3 ca = Vec3::Zero(), cb = Vec3::Zero();
        for (const Vec3& q : fd[a].poly) ca += q / double(fd[a].poly.size());
        for (const Vec3& q : fd[b].poly) cb += q / double(fd[b].poly.size());
        if (side.dot(ca - p0) * side.dot(cb - p0) < 0) return true;
      }
    }
    return false;
  };
  struct PairCuts {
    bool skipped = true;
    Cuts a, b;
  };
  constexpr size_t kBlock = 1 << 14;
  std::vector<PairCuts> block;
  for (size_t first = 0; first < pairs.size(); first += kBlock) {
    const size_t last = std::min(pairs.size(), first + kBlock);
    block.assign(last - first, PairCuts{});
    tbb::parallel_for(tbb::blocked_range<size_t>(first, last, 64), [&](const tbb::blocked_range<size_t>& range) {
      for (size_t i = range.begin(); i < range.end(); ++i) {
        const auto [a, b] = pairs[i];
        PairCuts& r = block[i - first];
        r.skipped = skip_pair(a, b);
        if (!r.skipped) intersect_pair(fd[a], fd[b], tol, r.a, r.b);
      }
    });
    for (size_t i = first; i < last; ++i) {
      const auto [a, b] = pairs[i];
      PairCuts& r = block[i - first];
      if (r.skipped) continue;
      fd[a].cuts.insert(fd[a].cuts.end(), r.a.begin(), r.a.end());
      fd[b].cuts.insert(fd[b].cuts.end(), r.b.begin(), r.b.end());
      // Coincident or touching faces are candidates for hiding even when nothing splits them.
      if (!r.a.empty() || !r.b.empty() || coplanar_faces(fd[a], fd[b], tol)) in_contact[a] = in_contact[b] = 1;
    }
  }

  PointIndex index(s, tol);
  std::vector<SoupFace> out;
  std::vector<char> check;  // per output face: test for hiding
  std::vector<char> is_piece;  // per output face: a piece of a split face
  std::vector<int> split_ids;
  long pieces_added = 0, slivers = 0;
  for (int k = 0; k < nf; ++k) {
    std::vector<std::vector<int>> pieces;
    if (!fd[k].cuts.empty()) pieces = split_face(s, k, fd[k], index, tol);
    if (pieces.empty()) {
      out.push_back(s.faces[k]);
      check.push_back(in_contact[k]);
      is_piece.push_back(0);
      continue;
    }
    split_ids.push_back(origin_of(s, k));
    pieces_added += static_cast<long>(pieces.size()) - 1;
    for (auto& p : pieces) {
      std::vector<Vec3> poly;
      for (int v : p) poly.push_back(s.positions[v]);
      if (zero_area(poly)) {  // a sliver left by corners snapped together (within the weld tolerance)
        ++slivers;
        continue;
      }
      SoupFace piece = s.faces[k];
      piece.origin = origin_of(s, k);
      piece.vertices = std::move(p);
      out.push_back(std::move(piece));
      check.push_back(1);
      is_piece.push_back(1);
    }
  }
  s.faces = std::move(out);
  report.counts["imprint_slivers_dropped"] += 0;
  if (slivers > 0)
    report.warn("imprint_slivers_dropped", slivers,
                plural(slivers, "zero-area sliver", "zero-area slivers") +
                    " left by splitting (corners closer than the weld tolerance) were dropped");
  if (!split_ids.empty())
    report.warn("faces_imprinted", static_cast<long>(split_ids.size()),
                plural(static_cast<long>(split_ids.size()), "face was", "faces were") +
                    " split along the lines where other faces touch or cross it (" +
                    plural(pieces_added, "piece", "pieces") + " added; no patch straddles a wall): input face" +
                    (split_ids.size() == 1 ? " " : "s ") + id_list(split_ids));

  // Corners of the pieces inserted into every edge they lie on (within tol), so that faces next to a
  // split face stay conforming (no new T-junctions).
  {
    std::vector<char> corner_of_piece(s.positions.size(), 0);
    for (size_t k = 0; k < s.faces.size(); ++k)
      if (is_piece[k])
        for (int v : s.faces[k].vertices) corner_of_piece[v] = 1;
    conform(s, tol, corner_of_piece);
  }

  // Hidden fragments: rays from points of the piece into its front hemisphere; a face in the piece's own plane is
  // met only at the ray's start and does not count. A ray is covered when the first face met (or any face met at
  // the same distance: a wall's top under the ceiling) is met from its back: under a wall, inside a solid. A ray
  // that first meets the front of another tested face leans on it: a cavity (an open-backed bookshelf against a
  // wall) is bounded by the backs of the solid and by the fronts of the wall and floor pieces inside it, which see
  // each other. A piece is hidden when every ray is covered or leans on hidden pieces (the largest such set, found
  // by dropping pieces until none leans on a kept one) and at least a quarter of its rays are covered (a room whose
  // faces are all split, hence all tested, leans on itself but meets no back side; the floor plan's cavities have
  // 31-95 % covered). No ray may be seen: a face partly seen (a ceiling tile a light panel hangs under, 2 cm below)
  // is kept, whatever the rest of it sees; removing it would open the room.
  // The ray origins and directions come from one low-discrepancy sequence for every face (Roberts' R5: fractional
  // parts of i / phi^j, phi^6 = phi + 1), not from a generator seeded by the face's index, so the answer depends
  // on the face's shape and surroundings only, not on where it sits in the file or in space: a part seen from a
  // third of the face gets about a third of the origins. Interior origins (uniform by area) come first, then
  // origins just inside the boundary (kBoundaryRays, by length), where a gap along an edge is seen widest.
  // Then a face coincident with a hidden one and facing the other way (a wall's bottom on the removed floor strip)
  // is hidden too: between coincident faces.
  const int n = static_cast<int>(s.faces.size());
  std::vector<char> usable(n);
  for (int k = 0; k < n; ++k) usable[k] = usable_face(s, k);
  const SoupRays rays(s, usable);
  std::vector<char> hidden(n, 0);
  std::vector<int> hidden_ids;
  double hidden_area = 0;
  constexpr int kInteriorRays = 48, kBoundaryRays = 16;
  static const std::array<double, 5> kAlpha = [] {
    double phi = 1.2;  // the real root of x^6 = x + 1 (Newton)
    for (int i = 0; i < 50; ++i) phi -= (std::pow(phi, 6) - phi - 1) / (6 * std::pow(phi, 5) - 1);
    std::array<double, 5> alpha{};
    for (int j = 0; j < 5; ++j) alpha[j] = std::pow(phi, -(j + 1));
    return alpha;
  }();
  auto sequence = [](int i, int j) {
    const double x = 0.5 + kAlpha[j] * (i + 1);
    return x - std::floor(x);
  };
  auto coplanar = [&](int f, int g) {
    const Vec3 &n_f = rays.normal(f), &n_g = rays.normal(g);
    return std::abs(n_f.dot(n_g)) > 1 - 1e-9 &&
           std::abs(n_f.dot(s.positions[s.faces[g].vertices[0]] - s.positions[s.faces[f].vertices[0]])) <= tol;
  };
  auto tested = [&](int f) { return check[f] && rays.has(f); };
  std::vector<Vec3> probe(n, Vec3::Zero());
  std::vector<char> seen(n, 0);                 // a ray met no back: it escaped, or met the front of a kept face
  std::vector<std::vector<int>> leans_on(n);    // tested faces whose fronts its rays met first (sorted, unique)
  std::vector<int> cast(n, 0), covered(n, 0);  // rays cast, and covered (met a back first)
  // Rays [from, to) of face k, until one is seen (meets the front of a face that is not tested, or of one in
  // `kept`, or escapes).
  auto cast_rays = [&](int k, int from, int to, const std::vector<char>& kept, std::vector<int>& skip) {
    const Vec3& nk = rays.normal(k);
    const std::vector<Vec3> poly = corners(s, k);
    std::vector<double> perimeter(poly.size() + 1, 0);  // cumulative edge lengths
    for (size_t e = 0; e < poly.size(); ++e)
      perimeter[e + 1] = perimeter[e] + (poly[(e + 1) % poly.size()] - poly[e]).norm();
    std::vector<int>& leans = leans_on[k];
    for (int r = from; r < to && !seen[k]; ++r) {
      Vec3 o;
      if (r < kInteriorRays) {
        o = rays.sample(k, sequence(r, 0), sequence(r, 1), sequence(r, 2));
      } else {  // 4 tol inside an edge (left of it, seen from the front), if that is inside the face
        const double at = sequence(r, 0) * perimeter.back();
        const size_t e = std::min(poly.size() - 1,
                                  size_t(std::upper_bound(perimeter.begin(), perimeter.end(), at) - perimeter.begin()) - 1);
        const Vec3 edge = poly[(e + 1) % poly.size()] - poly[e];
        const double len = edge.norm();
        if (!(len > 8 * tol)) continue;
        o = poly[e] + edge * ((at - perimeter[e]) / len) + nk.cross(edge / len) * (4 * tol);
        if (!inside_polygon(poly, nk, o)) continue;
      }
      const Vec3 d = cosine_direction(nk, sequence(r, 3), sequence(r, 4));
      skip.assign(1, k);
      auto skipped = [&](int f) { return std::find(skip.begin(), skip.end(), f) != skip.end(); };
      bool back = false;
      int lean = -1;
      double first_t = -1;
      for (int tries = 0; tries < 8; ++tries) {
        // Past the first face met, only faces at its distance (within tol) matter.
        const auto h = rays.first(o, d, skipped, first_t < 0 ? std::numeric_limits<double>::infinity() : first_t + tol);
        if (h.face < 0) break;
        skip.push_back(h.face);
        if (h.t <= tol && coplanar(k, h.face)) continue;  // touches the start only
        if (first_t < 0) first_t = h.t;
        if (h.t > first_t + tol) break;
        back = back || !h.front;
        if (h.front && tested(h.face) && (lean < 0 || h.face < lean)) lean = h.face;
      }
      ++cast[k];
      if (back) {
        ++covered[k];
      } else if (lean < 0 || kept[lean]) {
        seen[k] = 1;
      } else if (std::find(leans.begin(), leans.end(), lean) == leans.end()) {
        leans.push_back(lean);
      }
    }
    std::sort(leans.begin(), leans.end());
  };
  // flag[k] = 1 for every face that leans, directly or through others, on a flagged face (breadth first over the
  // reversed lean edges).
  auto spread = [&](std::vector<char>& flag) {
    std::vector<int> start(n + 1, 0), from;
    for (int k = 0; k < n; ++k)
      for (int f : leans_on[k]) ++start[f + 1];
    for (int k = 0; k < n; ++k) start[k + 1] += start[k];
    from.resize(start[n]);
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int k = 0; k < n; ++k)
      for (int f : leans_on[k]) from[fill[f]++] = k;
    std::vector<int> queue;
    for (int k = 0; k < n; ++k)
      if (flag[k]) queue.push_back(k);
    while (!queue.empty()) {
      const int f = queue.back();
      queue.pop_back();
      for (int i = start[f]; i < start[f + 1]; ++i)
        if (!flag[from[i]]) flag[from[i]] = 1, queue.push_back(from[i]);
    }
  };
  // Rounds of rays, faces in parallel, each writing only its own entries (the same result for any thread count):
  // rays [0, 4) of every tested face, then [4, 16) and [16, 64) of the faces that lean on no kept one, with a ray
  // that meets the front of a kept face ending the face's test (a face that sees a kept face is kept), and after
  // each round every face that leans on a kept one kept. The answer is the one all rays of every face would give
  // (a face kept early leans on a kept one whatever its other rays meet); most faces of a room are decided by
  // their first rays, through the few that see a light or a window.
  std::vector<char> kept(n, 0);
  int done = 0;
  for (const int next : {4, 16, kInteriorRays + kBoundaryRays}) {
    tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& range) {
      std::vector<int> skip;
      for (int k = range.begin(); k < range.end(); ++k)
        if (tested(k) && !kept[k]) {
          if (done == 0) probe[k] = rays.sample(k, 0.5, 1.0 / 3, 1.0 / 3);
          cast_rays(k, done, next, kept, skip);
        }
    });
    for (int k = 0; k < n; ++k) kept[k] = kept[k] || seen[k];
    spread(kept);
    done = next;
  }
  for (int k = 0; k < n; ++k) kept[k] = !tested(k) || kept[k] || seen[k] || 4 * covered[k] < cast[k];
  spread(kept);  // the largest set of faces that lean only on each other
  for (int k = 0; k < n; ++k) hidden[k] = !kept[k];
  // Between coincident faces: opposite-facing, coplanar, its probe point inside a hidden face of the first pass.
  // Candidates from boxes (the probe point within tol of the hidden face's box), not every face against every
  // hidden one: that was quadratic (a 1M-face building has ~4e4 hidden fragments).
  std::vector<Box> probe_boxes, hidden_boxes;
  for (int k = 0; k < n; ++k) {
    if (!rays.has(k)) continue;
    if (hidden[k]) {
      Eigen::AlignedBox3d b;
      for (int v : s.faces[k].vertices) b.extend(s.positions[v]);
      double lo[3], hi[3];
      for (int a = 0; a < 3; ++a) lo[a] = b.min()[a] - tol, hi[a] = b.max()[a] + tol;
      hidden_boxes.emplace_back(lo, hi, k);
    } else if (check[k]) {
      double lo[3], hi[3];
      for (int a = 0; a < 3; ++a) lo[a] = hi[a] = probe[k][a];
      probe_boxes.emplace_back(lo, hi, k);
    }
  }
  std::vector<std::pair<int, int>> near;  // (face, hidden face)
  CGAL::box_intersection_d(probe_boxes.begin(), probe_boxes.end(), hidden_boxes.begin(), hidden_boxes.end(),
                           [&](const Box& pb, const Box& hb) { near.emplace_back(pb.info(), hb.info()); });
  std::sort(near.begin(), near.end());
  std::vector<char> between(n, 0);
  for (const auto& [k, h] : near) {
    if (between[k] || rays.normal(k).dot(rays.normal(h)) > -1 + 1e-9 || !coplanar(k, h)) continue;
    if (inside_polygon(corners(s, h), rays.normal(h), probe[k])) between[k] = 1;
  }
  for (int k = 0; k < n; ++k) hidden[k] = hidden[k] || between[k];
  for (int k = 0; k < n; ++k)
    if (hidden[k]) {
      hidden_ids.push_back(origin_of(s, k));
      hidden_area += 0.5 * newell_normal(corners(s, k)).norm();
    }
  if (!hidden_ids.empty()) {
    std::vector<SoupFace> remaining;
    for (int k = 0; k < n; ++k)
      if (!hidden[k]) remaining.push_back(std::move(s.faces[k]));
    s.faces = std::move(remaining);
    report.warn("hidden_fragments_removed", static_cast<long>(hidden_ids.size()),
                plural(static_cast<long>(hidden_ids.size()), "hidden fragment was", "hidden fragments were") +
                    " removed (" + num(hidden_area) +
                    " m^2 under walls, inside solids or between coincident faces: they would neither receive "
                    "nor emit correctly): from input face" + (hidden_ids.size() == 1 ? " " : "s ") + id_list(hidden_ids));
  }
}

}  // namespace lambert::mesh::detail
