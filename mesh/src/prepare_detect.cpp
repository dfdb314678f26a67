// mesh::prepare, detection: faces whose interiors cross or coincide facing the same way, and
// T-junctions (cracks). Read-only: reported, never changed (see prepare.hpp, steps 4 and 5).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prepare_internal.hpp"
#include "tri_tri.hpp"

namespace lambert::mesh::detail {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using KE = CGAL::Exact_predicates_exact_constructions_kernel;  // intersection constructions: Epick's
                                                               // can produce non-finite points
using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;

Vec3 to_vec(const KE::Point_3& p) { return {CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())}; }

KE::Triangle_3 exact(const K::Triangle_3& t) {
  auto pt = [](const K::Point_3& p) { return KE::Point_3(p.x(), p.y(), p.z()); };
  return {pt(t.vertex(0)), pt(t.vertex(1)), pt(t.vertex(2))};
}

// Do triangles (vertex indices a, b) touch beyond the vertices they share? Exact predicates only, as
// in CGAL's self_intersections: sharing an edge, only a coplanar fold overlaps; sharing a corner,
// only if a far edge of one meets the other triangle. False means contact at shared vertices only.
bool may_touch_beyond_shared(const std::array<int, 3>& a, const std::array<int, 3>& b, const K::Triangle_3& ta,
                             const K::Triangle_3& tb) {
  int shared = 0, ia = -1, ib = -1;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (a[i] == b[j]) ++shared, ia = i, ib = j;
  if (shared == 3) return true;  // the same triangle twice
  if (shared == 2) {
    // The corners not shared: a's is the one whose index is in no pair; same for b.
    int ca = 0, cb = 0;
    while (std::find(b.begin(), b.end(), a[ca]) != b.end()) ++ca;
    while (std::find(a.begin(), a.end(), b[cb]) != a.end()) ++cb;
    const auto& p = ta.vertex((ca + 1) % 3);
    const auto& q = ta.vertex((ca + 2) % 3);
    return CGAL::coplanar(p, q, ta.vertex(ca), tb.vertex(cb)) &&
           CGAL::coplanar_orientation(p, q, ta.vertex(ca), tb.vertex(cb)) == CGAL::POSITIVE;
  }
  if (shared == 1) {
    const K::Segment_3 far_a(ta.vertex((ia + 1) % 3), ta.vertex((ia + 2) % 3));
    const K::Segment_3 far_b(tb.vertex((ib + 1) % 3), tb.vertex((ib + 2) % 3));
    return CGAL::do_intersect(ta, far_b) || CGAL::do_intersect(tb, far_a);
  }
  return CGAL::do_intersect(ta, tb);
}

}  // namespace

void detect_self_intersections(const PolygonSoup& s, const std::vector<char>& usable, double tol, Report& report) {
  const int nf = static_cast<int>(s.faces.size());
  std::vector<std::vector<Vec3>> polys(nf);
  std::vector<std::vector<K::Triangle_3>> tris(nf);
  std::vector<std::vector<std::array<int, 3>>> tri_vertices(nf);
  std::vector<Box> boxes;
  // Vertices with identical coordinates count as shared (an unwelded soup, without repair): the
  // exact-predicate shortcuts then apply to them too.
  std::vector<int> same(s.positions.size());
  {
    std::vector<int> order;
    for (int k = 0; k < nf; ++k)
      if (usable[k]) order.insert(order.end(), s.faces[k].vertices.begin(), s.faces[k].vertices.end());
    auto less = [&](int a, int b) {
      const Vec3 &p = s.positions[a], &q = s.positions[b];
      return std::tie(p.x(), p.y(), p.z(), a) < std::tie(q.x(), q.y(), q.z(), b);
    };
    std::sort(order.begin(), order.end(), less);
    for (size_t i = 0; i < order.size(); ++i)
      same[order[i]] = i > 0 && s.positions[order[i]] == s.positions[order[i - 1]] ? same[order[i - 1]] : order[i];
  }
  std::vector<Vec3> normal(nf, Vec3::Zero());
  for (int k = 0; k < nf; ++k) {
    if (!usable[k]) continue;
    polys[k] = corners(s, k);
    const auto& poly = polys[k];
    normal[k] = newell_normal(poly);
    std::vector<int> fv;
    for (int v : s.faces[k].vertices) fv.push_back(same[v]);
    for (const auto& t : triangulate_polygon(poly, newell_normal(poly).normalized())) {
      K::Triangle_3 tri({poly[t[0]].x(), poly[t[0]].y(), poly[t[0]].z()},
                        {poly[t[1]].x(), poly[t[1]].y(), poly[t[1]].z()},
                        {poly[t[2]].x(), poly[t[2]].y(), poly[t[2]].z()});
      if (tri.is_degenerate()) continue;
      tris[k].push_back(tri);
      tri_vertices[k].push_back({fv[t[0]], fv[t[1]], fv[t[2]]});
    }
    CGAL::Bbox_3 bb;
    for (const auto& t : tris[k]) bb += t.bbox();
    boxes.emplace_back(bb, k);
  }
  std::vector<std::pair<int, int>> candidates;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
    candidates.emplace_back(std::min(a.info(), b.info()), std::max(a.info(), b.info()));
  });
  std::sort(candidates.begin(), candidates.end());
  // A contact counts when some intersection point lies farther than tol from both faces' boundaries:
  // crossing walls, coplanar overlap. Contact along edges or at corners (shared or not) does not.
  auto interior_to_both = [&](const Vec3& p, int f, int g) {
    return distance_to_boundary(p, polys[f]) > tol && distance_to_boundary(p, polys[g]) > tol;
  };
  std::vector<std::pair<int, int>> found;  // input face ids
  // Candidates in parallel, each deciding only its own flag; read in order (the same list for any thread count).
  std::vector<char> crosses(candidates.size(), 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, candidates.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t c = range.begin(); c < range.end(); ++c) {
      const auto [f, g] = candidates[c];
      if (origin_of(s, f) == origin_of(s, g)) continue;
      bool hit = false;
      for (size_t i = 0; i < tris[f].size() && !hit; ++i) {
        const auto& tf = tris[f][i];
        for (size_t j = 0; j < tris[g].size() && !hit; ++j) {
          const auto& tg = tris[g][j];
          if (!CGAL::do_overlap(tf.bbox(), tg.bbox()) ||
              !may_touch_beyond_shared(tri_vertices[f][i], tri_vertices[g][j], tf, tg))
            continue;
          // Where (exact sides, double-precision points): is any of it inside both faces? Coplanar triangles, and
          // planes or edges within 1e-4 rad of the other's plane, take the exact constructions, then rounded.
          auto corners3 = [](const K::Triangle_3& t) {
            std::array<Vec3, 3> q;
            for (int m = 0; m < 3; ++m) q[size_t(m)] = {t.vertex(m).x(), t.vertex(m).y(), t.vertex(m).z()};
            return q;
          };
          const TriangleContact contact = intersect_triangles(corners3(tf), corners3(tg));
          if (contact.kind == TriangleContact::kNone || contact.kind == TriangleContact::kPoint) continue;
          if (contact.kind == TriangleContact::kSegment) {
            hit = interior_to_both(0.5 * (contact.a + contact.b), f, g);
            continue;
          }
          const auto x = CGAL::intersection(exact(tf), exact(tg));
          if (!x) continue;
          Vec3 p;
          if (const auto* seg = boost::get<KE::Segment_3>(&*x)) {
            p = 0.5 * (to_vec(seg->source()) + to_vec(seg->target()));
          } else if (normal[f].dot(normal[g]) < 0) {
            continue;  // coincident back to back: one-sided surfaces that do not see each other
          } else if (const auto* tri = boost::get<KE::Triangle_3>(&*x)) {
            p = (to_vec(tri->vertex(0)) + to_vec(tri->vertex(1)) + to_vec(tri->vertex(2))) / 3;
          } else if (const auto* pts = boost::get<std::vector<KE::Point_3>>(&*x)) {
            p = Vec3::Zero();
            for (const auto& q : *pts) p += to_vec(q);
            p /= double(pts->size());
          } else {
            continue;  // a single point: always on an edge of one of them
          }
          hit = interior_to_both(p, f, g);
        }
      }
      crosses[c] = hit;
    }
  });
  for (size_t c = 0; c < candidates.size(); ++c) {
    if (!crosses[c]) continue;
    const int of = origin_of(s, candidates[c].first), og = origin_of(s, candidates[c].second);
    found.emplace_back(std::min(of, og), std::max(of, og));
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  const long n = static_cast<long>(found.size());
  report.counts["self_intersections"] += 0;
  if (n > 0) {
    std::string pairs;
    for (long i = 0; i < std::min<long>(n, 5); ++i)
      pairs += (i ? ", " : "") + std::string("(") + std::to_string(found[i].first) + ", " +
               std::to_string(found[i].second) + ")";
    if (n > 5) pairs += " and " + std::to_string(n - 5) + " more";
    report.warn("self_intersections", n,
                plural(n, "pair of faces crosses or overlaps", "pairs of faces cross or overlap") +
                    " (light leaks through crossings; coincident faces facing the same way count twice): input "
                    "faces " +
                    pairs);
  }
}

// ---- 5. T-junctions -------------------------------------------------------------------------------

void detect_t_junctions(const PolygonSoup& s, const std::vector<char>& usable, double tol, Report& report) {
  const int nf = static_cast<int>(s.faces.size());
  // Unique undirected edges with their faces, and the faces of each vertex.
  struct EdgeUse {
    std::uint64_t key;
    int face;
  };
  std::vector<EdgeUse> uses;
  std::unordered_map<int, std::vector<int>> vertex_faces;
  std::vector<int> verts;
  for (int k = 0; k < nf; ++k) {
    if (!usable[k]) continue;
    const auto& fv = s.faces[k].vertices;
    for (size_t c = 0; c < fv.size(); ++c) {
      uses.push_back({edge_key(fv[c], fv[(c + 1) % fv.size()]), origin_of(s, k)});
      auto& vf = vertex_faces[fv[c]];
      if (vf.empty()) verts.push_back(fv[c]);
      vf.push_back(origin_of(s, k));
    }
  }
  std::sort(uses.begin(), uses.end(),
            [](const EdgeUse& a, const EdgeUse& b) { return a.key != b.key ? a.key < b.key : a.face < b.face; });
  std::vector<std::uint64_t> edges;
  std::vector<std::vector<int>> edge_faces;
  for (const auto& u : uses) {
    if (edges.empty() || edges.back() != u.key) {
      edges.push_back(u.key);
      edge_faces.emplace_back();
    }
    edge_faces.back().push_back(u.face);
  }
  // Only open (boundary) edges can leave a crack: a vertex on an edge that two faces share (a floor
  // continuing under a table leg) is contact, not a T-junction. The vertex must also end an open
  // edge of its own along the same line (the wall's bottom edge along the floor's edge).
  std::unordered_map<int, std::vector<int>> open_neighbours;
  std::vector<Box> eboxes, vboxes;
  for (size_t e = 0; e < edges.size(); ++e) {
    if (edge_faces[e].size() != 1) continue;
    const int ia = static_cast<int>(edges[e] >> 32), ib = static_cast<int>(edges[e] & 0xffffffffu);
    open_neighbours[ia].push_back(ib);
    open_neighbours[ib].push_back(ia);
    const Vec3 &a = s.positions[ia], &b = s.positions[ib];
    const Vec3 lo = a.cwiseMin(b).array() - tol, hi = a.cwiseMax(b).array() + tol;
    double l[3] = {lo.x(), lo.y(), lo.z()}, h[3] = {hi.x(), hi.y(), hi.z()};
    eboxes.emplace_back(l, h, static_cast<int>(e));
  }
  std::sort(verts.begin(), verts.end());
  for (int v : verts) {
    if (!open_neighbours.count(v)) continue;
    const Vec3& p = s.positions[v];
    double l[3] = {p.x() - tol, p.y() - tol, p.z() - tol}, h[3] = {p.x() + tol, p.y() + tol, p.z() + tol};
    vboxes.emplace_back(l, h, v);
  }
  auto distance_to_line = [](const Vec3& p, const Vec3& a, const Vec3& b) {
    return (p - a).cross(b - a).norm() / (b - a).norm();
  };
  std::vector<std::pair<int, int>> found;  // (vertex, edge index)
  CGAL::box_intersection_d(vboxes.begin(), vboxes.end(), eboxes.begin(), eboxes.end(),
                           [&](const Box& vb, const Box& eb) {
                             const int v = vb.info();
                             const int a = static_cast<int>(edges[eb.info()] >> 32);
                             const int b = static_cast<int>(edges[eb.info()] & 0xffffffffu);
                             if (v == a || v == b) return;
                             const Vec3 &p = s.positions[v], &pa = s.positions[a], &pb = s.positions[b];
                             if ((p - pa).norm() <= tol || (p - pb).norm() <= tol) return;
                             if (distance_to_segment(p, pa, pb) > tol) return;
                             for (int w : open_neighbours.at(v))
                               if (distance_to_line(s.positions[w], pa, pb) <= tol) {
                                 found.emplace_back(v, eb.info());
                                 return;
                               }
                           });
  std::sort(found.begin(), found.end(), [&](auto x, auto y) {
    return edges[x.second] != edges[y.second] ? edges[x.second] < edges[y.second] : x.first < y.first;
  });
  found.erase(std::unique(found.begin(), found.end()), found.end());
  const long n = static_cast<long>(found.size());
  report.counts["t_junctions"] += 0;
  if (n > 0) {
    std::string ex;
    std::vector<int> ids;
    for (const auto& [v, e] : found) {
      for (int f : edge_faces[e]) ids.push_back(f);
      for (int f : vertex_faces[v]) ids.push_back(f);
    }
    for (long i = 0; i < std::min<long>(n, 3); ++i) {
      const auto [v, e] = found[i];
      ex += (i ? "; " : "") + vertex_at(s, v) + " of input face" + (vertex_faces[v].size() == 1 ? " " : "s ") +
            id_list(vertex_faces[v], 3) + " lies on the edge " + std::to_string(edges[e] >> 32) + "-" +
            std::to_string(edges[e] & 0xffffffffu) + " of input face" + (edge_faces[e].size() == 1 ? " " : "s ") +
            id_list(edge_faces[e], 3);
    }
    if (n > 3) ex += "; and " + std::to_string(n - 3) + " more";
    report.warn("t_junctions", n,
                plural(n, "T-junction", "T-junctions") +
                    " (a vertex inside another face's edge: the faces are not connected there, light can leak "
                    "and vertex colours seam), input faces " +
                    id_list(ids) + ": " + ex);
  }
}

}  // namespace lambert::mesh::detail
