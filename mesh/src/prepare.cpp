// mesh::prepare: weld, clean, orient (repair) and self-intersection / T-junction detection.
// Refinement is in prepare_refine.cpp.
#include "lambert/mesh/prepare.hpp"
#include "union_find.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include "prepare_internal.hpp"

namespace lambert::mesh {

namespace detail {

std::vector<Vec3> corners(const PolygonSoup& s, int k) {
  std::vector<Vec3> poly;
  poly.reserve(s.faces[k].vertices.size());
  for (int v : s.faces[k].vertices) poly.push_back(s.positions[v]);
  return poly;
}

bool zero_area(const std::vector<Vec3>& poly) {
  const int m = static_cast<int>(poly.size());
  const double area = 0.5 * newell_normal(poly).norm();
  double longest = 0;
  for (int c = 0; c < m; ++c) longest = std::max(longest, (poly[(c + 1) % m] - poly[c]).norm());
  return !(area > 0) || !std::isfinite(area) || area <= 1e-12 * longest * longest;
}

bool usable_face(const PolygonSoup& s, int k) {
  const auto& fv = s.faces[k].vertices;
  if (fv.size() < 3) return false;
  std::vector<int> sorted = fv;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return false;
  const auto poly = corners(s, k);
  if (zero_area(poly)) return false;
  if (poly.size() == 3) return true;
  // Same test as PatchGeometry::from_polygons: the triangles must tile the (projected) polygon.
  const Vec3 nn = newell_normal(poly);
  const Vec3 n = nn.normalized();
  const auto tris = triangulate_polygon(poly, n);
  if (tris.empty()) return false;
  double a = 0, extent2 = 0;
  for (const auto& t : tris) a += 0.5 * (poly[t[1]] - poly[t[0]]).cross(poly[t[2]] - poly[t[0]]).dot(n);
  for (const Vec3& q : poly) extent2 = std::max(extent2, (q - poly[0]).squaredNorm());
  return std::abs(a - 0.5 * nn.norm()) <= 1e-9 * 0.5 * nn.norm() + 1e-13 * double(poly.size()) * extent2;
}

std::string id_list(std::vector<int> ids, int shown) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  std::string s;
  const int n = static_cast<int>(ids.size());
  for (int i = 0; i < std::min(n, shown); ++i) s += (i ? ", " : "") + std::to_string(ids[i]);
  if (n > shown) s += " and " + std::to_string(n - shown) + " more";
  return s;
}

std::string num(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

}  // namespace detail

namespace {

using namespace detail;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using KE = CGAL::Exact_predicates_exact_constructions_kernel;  // intersection constructions: Epick's
                                                               // can produce non-finite points
using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;

std::string plural(long n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

std::string vertex_at(const PolygonSoup& s, int v) {
  const int line = v < static_cast<int>(s.position_lines.size()) ? s.position_lines[v] : 0;
  return "vertex " + std::to_string(v) + (line > 0 ? " (" + SourceLoc{s.file, line}.str() + ")" : "");
}

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
  return lo << 32 | hi;
}

// Used vertices and the length tolerance weld_tolerance * bounding-box diagonal.
double length_tolerance(const PolygonSoup& s, double relative) {
  Eigen::AlignedBox3d box;
  for (const auto& f : s.faces)
    for (int v : f.vertices) box.extend(s.positions[v]);
  return box.isEmpty() ? 0 : relative * box.diagonal().norm();
}

// ---- 1. weld --------------------------------------------------------------------------------------

using detail::UnionFind;

// Local scale of each used vertex for welding: the shortest edge at it that is longer than the global
// tolerance (edges shorter than that are what welding collapses), else its longest edge; infinite for a
// vertex whose edges all have zero length. A pair is welded only when it is closer than
// kLocalWeldShare of both vertices' scales, so one far outlier vertex (which inflates the bounding
// box, hence the global tolerance) cannot weld a scene's real corners together: welding stays a repair of
// round-off, never a change of shape.
constexpr double kLocalWeldShare = 0.01;

std::vector<double> weld_scales(const PolygonSoup& s, double tol) {
  const int nv = static_cast<int>(s.positions.size());
  std::vector<double> shortest_long(nv, INFINITY), longest(nv, 0);
  for (const auto& f : s.faces) {
    const size_t m = f.vertices.size();
    for (size_t c = 0; c < m; ++c) {
      const int a = f.vertices[c], b = f.vertices[(c + 1) % m];
      const double len = (s.positions[a] - s.positions[b]).norm();
      for (int v : {a, b}) {
        longest[v] = std::max(longest[v], len);
        if (len > tol) shortest_long[v] = std::min(shortest_long[v], len);
      }
    }
  }
  std::vector<double> scale(nv);
  for (int v = 0; v < nv; ++v)
    scale[v] = std::isfinite(shortest_long[v]) ? shortest_long[v] : longest[v] > 0 ? longest[v] : INFINITY;
  return scale;
}

void weld(PolygonSoup& s, double tol, Report& report) {
  const int nv = static_cast<int>(s.positions.size());
  std::vector<char> used(nv, 0);
  for (const auto& f : s.faces)
    for (int v : f.vertices) used[v] = 1;
  const std::vector<double> scale = weld_scales(s, tol);
  long kept_apart = 0;  // pairs within the global tolerance but not the local one
  auto close = [&](int v, int w) {
    const double d = (s.positions[w] - s.positions[v]).norm();
    if (d > tol) return false;
    if (d > kLocalWeldShare * std::min(scale[v], scale[w])) {
      ++kept_apart;
      return false;
    }
    return true;
  };
  UnionFind uf(nv);
  double extent = 0;
  for (int v = 0; v < nv; ++v)
    if (used[v]) extent = std::max(extent, s.positions[v].cwiseAbs().maxCoeff());
  if (tol > 1e-12 * extent) {  // else cell indices could overflow: exact duplicates only
    // Hash grid of cell tol: vertices within tol lie in the same or a neighbouring cell.
    struct Hash {
      size_t operator()(const std::array<std::int64_t, 3>& c) const {
        return std::hash<std::int64_t>()(c[0] * 73856093 ^ c[1] * 19349663 ^ c[2] * 83492791);
      }
    };
    std::unordered_map<std::array<std::int64_t, 3>, std::vector<int>, Hash> grid;
    auto cell = [&](const Vec3& p) {
      return std::array<std::int64_t, 3>{static_cast<std::int64_t>(std::floor(p.x() / tol)),
                                         static_cast<std::int64_t>(std::floor(p.y() / tol)),
                                         static_cast<std::int64_t>(std::floor(p.z() / tol))};
    };
    for (int v = 0; v < nv; ++v)
      if (used[v]) grid[cell(s.positions[v])].push_back(v);
    for (int v = 0; v < nv; ++v) {
      if (!used[v]) continue;
      const auto c = cell(s.positions[v]);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
            if (it == grid.end()) continue;
            for (int w : it->second)
              if (w < v && close(v, w)) uf.unite(v, w);
          }
    }
  } else {
    std::vector<int> order;
    for (int v = 0; v < nv; ++v)
      if (used[v]) order.push_back(v);
    auto less = [&](int a, int b) {
      const Vec3 &p = s.positions[a], &q = s.positions[b];
      return std::tie(p.x(), p.y(), p.z(), a) < std::tie(q.x(), q.y(), q.z(), b);
    };
    std::sort(order.begin(), order.end(), less);
    for (size_t i = 1; i < order.size(); ++i)
      if (s.positions[order[i]] == s.positions[order[i - 1]]) uf.unite(order[i], order[i - 1]);
  }
  long merged = 0;
  int ex = -1;
  for (int v = 0; v < nv; ++v)
    if (used[v] && uf.find(v) != v) {
      if (merged++ == 0) ex = v;
    }
  for (auto& f : s.faces)
    for (int& v : f.vertices) v = uf.find(v);
  report.counts["vertices_merged"] += 0;
  if (kept_apart > 0)
    report.warn("vertices_not_merged", kept_apart,
                plural(kept_apart, "pair of vertices", "pairs of vertices") + " within the weld tolerance " + num(tol) +
                    " m were kept apart: closer than that, but not much closer than their own edges (" +
                    num(100 * kLocalWeldShare) + " % of the shortest edge at them), so welding would change the shape");
  if (merged > 0)
    report.warn("vertices_merged", merged,
                plural(merged, "vertex was", "vertices were") + " merged into a vertex closer than " + num(tol) +
                    " m, e.g. " + vertex_at(s, ex) + " into " + vertex_at(s, uf.find(ex)));
}

// ---- 2. repeated corners, pinched and degenerate faces ---------------------------------------------

void clean_faces(PolygonSoup& s, Report& report) {
  std::vector<SoupFace> out;
  out.reserve(s.faces.size());
  std::vector<int> removed_ids, pinched_ids, repeated_ids;
  long corners_removed = 0;
  std::vector<int> stack;
  std::vector<Vec3> poly;
  for (int k = 0; k < static_cast<int>(s.faces.size()); ++k) {
    const SoupFace& f = s.faces[k];
    // Split the corner cycle into simple loops at repeated vertices: a b c a d e -> (a b c), (a d e);
    // consecutive repeats and spikes (a b c b) become loops of fewer than 3 corners and vanish.
    std::vector<std::vector<int>> loops;
    stack.clear();
    // Large faces find a repeat through a map from vertex to its place on the stack (linear, where the
    // scan would make a 10^6-corner face quadratic).
    const bool large = f.vertices.size() > 32;
    std::unordered_map<int, size_t> place;
    for (int v : f.vertices) {
      auto it = stack.end();
      if (large) {
        if (const auto p = place.find(v); p != place.end()) it = stack.begin() + static_cast<std::ptrdiff_t>(p->second);
      } else {
        it = std::find(stack.begin(), stack.end(), v);
      }
      if (it != stack.end()) {
        loops.emplace_back(it, stack.end());
        if (large)
          for (auto j = it + 1; j != stack.end(); ++j) place.erase(*j);
        stack.erase(it + 1, stack.end());
      } else {
        if (large) place.emplace(v, stack.size());
        stack.push_back(v);
      }
    }
    loops.push_back(stack);
    std::vector<std::vector<int>> kept;
    for (auto& loop : loops) {
      if (loop.size() < 3) continue;
      poly.clear();
      for (int v : loop) poly.push_back(s.positions[v]);
      if (zero_area(poly)) continue;
      kept.push_back(std::move(loop));
    }
    // Keep the loop order of the face: the loop containing the first corner last (as extracted).
    size_t kept_corners = 0;
    for (const auto& loop : kept) kept_corners += loop.size();
    if (kept.empty()) {
      removed_ids.push_back(origin_of(s, k));
      continue;
    }
    if (kept.size() > 1) pinched_ids.push_back(origin_of(s, k));
    if (kept_corners < f.vertices.size()) {
      corners_removed += static_cast<long>(f.vertices.size() - kept_corners);
      repeated_ids.push_back(origin_of(s, k));
    }
    if (kept.size() == 1 && kept[0].size() == f.vertices.size()) {
      out.push_back(f);  // unchanged (corner order as in the input)
      continue;
    }
    for (auto& loop : kept) {
      SoupFace piece = f;
      piece.vertices = std::move(loop);
      out.push_back(std::move(piece));
    }
  }
  s.faces = std::move(out);
  report.counts["degenerate_faces_removed"] += 0;
  report.counts["repeated_corners_removed"] += 0;
  report.counts["pinched_faces_split"] += 0;
  if (!removed_ids.empty())
    report.warn("degenerate_faces_removed", static_cast<long>(removed_ids.size()),
                plural(static_cast<long>(removed_ids.size()), "degenerate face was", "degenerate faces were") +
                    " removed (fewer than 3 distinct corners or zero area): input face" +
                    (removed_ids.size() == 1 ? " " : "s ") + id_list(removed_ids));
  if (corners_removed > 0)
    report.warn("repeated_corners_removed", corners_removed,
                plural(corners_removed, "repeated or folded-back corner was", "repeated or folded-back corners were") +
                    " removed from input face" + (repeated_ids.size() == 1 ? " " : "s ") + id_list(repeated_ids));
  if (!pinched_ids.empty())
    report.warn("pinched_faces_split", static_cast<long>(pinched_ids.size()),
                plural(static_cast<long>(pinched_ids.size()), "face touches", "faces touch") +
                    " itself at a corner and was split into its loops: input face" +
                    (pinched_ids.size() == 1 ? " " : "s ") + id_list(pinched_ids));
}

// ---- 3. orientation -------------------------------------------------------------------------------

// Signed solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee).
double solid_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double num_ = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2 * std::atan2(num_, den);
}

void orient(PolygonSoup& s, double tol, Report& report) {
  const int nf = static_cast<int>(s.faces.size());
  // Edge uses: (key, face, +1 if the face runs from the lower to the higher vertex).
  struct Use {
    std::uint64_t key;
    int face;
    int dir;
  };
  std::vector<Use> uses;
  for (int k = 0; k < nf; ++k) {
    const auto& fv = s.faces[k].vertices;
    for (size_t c = 0; c < fv.size(); ++c) {
      const int a = fv[c], b = fv[(c + 1) % fv.size()];
      uses.push_back({edge_key(a, b), k, a < b ? 1 : -1});
    }
  }
  std::sort(uses.begin(), uses.end(),
            [](const Use& x, const Use& y) { return x.key != y.key ? x.key < y.key : x.face < y.face; });
  // Adjacency across manifold edges: (neighbour, same direction?) ; boundary / non-manifold edges
  // make their faces' component open.
  std::vector<std::vector<std::pair<int, int>>> adj(nf);
  std::vector<char> open_edge(nf, 0);
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2) {
      const int rel = uses[i].dir == uses[i + 1].dir ? 1 : 0;
      adj[uses[i].face].push_back({uses[i + 1].face, rel});
      adj[uses[i + 1].face].push_back({uses[i].face, rel});
    } else {
      for (size_t t = i; t < j; ++t) open_edge[uses[t].face] = 1;
    }
    i = j;
  }
  // Components by BFS from the lowest face; parity = flip relative to the component's first face.
  std::vector<int> comp(nf, -1), parity(nf, 0);
  std::vector<std::vector<int>> members;
  std::vector<char> closed;
  long non_orientable = 0;
  for (int k = 0; k < nf; ++k) {
    if (comp[k] >= 0) continue;
    const int c = static_cast<int>(members.size());
    members.emplace_back();
    bool is_closed = true, conflict = false;
    std::vector<int> queue{k};
    comp[k] = c;
    for (size_t q = 0; q < queue.size(); ++q) {
      const int f = queue[q];
      members[c].push_back(f);
      if (open_edge[f]) is_closed = false;
      for (auto [g, rel] : adj[f]) {
        if (comp[g] < 0) {
          comp[g] = c;
          parity[g] = parity[f] ^ rel;
          queue.push_back(g);
        } else if (parity[g] != (parity[f] ^ rel)) {
          conflict = true;
        }
      }
    }
    std::sort(members[c].begin(), members[c].end());
    if (conflict) ++non_orientable;
    closed.push_back(is_closed && !conflict);
  }
  const int nc = static_cast<int>(members.size());

  // Oriented triangles of a component (fan per face, with the parity applied).
  auto for_each_triangle = [&](int c, auto&& fn) {
    for (int f : members[c]) {
      const auto& fv = s.faces[f].vertices;
      const int m = static_cast<int>(fv.size());
      for (int t = 1; t + 1 < m; ++t) {
        const Vec3 &a = s.positions[fv[0]], &b = s.positions[fv[t]], &cc = s.positions[fv[t + 1]];
        if (parity[f])
          fn(a, cc, b);
        else
          fn(a, b, cc);
      }
    }
  };

  // Closed shells: signed volume (> 0: normals outward) and nesting depth by winding numbers.
  std::vector<double> volume(nc, 0);
  std::vector<Eigen::AlignedBox3d> box(nc);
  std::vector<std::vector<Vec3>> samples(nc);
  for (int c = 0; c < nc; ++c) {
    if (!closed[c]) continue;
    for (int f : members[c])
      for (int v : s.faces[f].vertices) box[c].extend(s.positions[v]);
    const Vec3 o = box[c].center();
    double area = 0;
    for_each_triangle(c, [&](const Vec3& a, const Vec3& b, const Vec3& cc) {
      volume[c] += (a - o).dot((b - o).cross(cc - o)) / 6;
      area += 0.5 * (b - a).cross(cc - a).norm();
    });
    // A flat shell (e.g. two faces back to back) encloses nothing: decide it like an open one.
    if (!(std::abs(volume[c]) > 1e-9 * std::pow(area, 1.5))) {
      closed[c] = 0;
      continue;
    }
    // Sample points on the shell: inside the first ear of its largest faces.
    std::vector<int> by_area = members[c];
    std::vector<double> fa(nf, 0);
    for (int f : by_area) fa[f] = newell_normal(corners(s, f)).norm();
    std::stable_sort(by_area.begin(), by_area.end(), [&](int a, int b) { return fa[a] > fa[b]; });
    for (int f : by_area) {
      if (samples[c].size() == 5) break;
      const auto poly = corners(s, f);
      const auto tris = triangulate_polygon(poly, newell_normal(poly).normalized());
      if (!tris.empty())
        samples[c].push_back((poly[tris[0][0]] + poly[tris[0][1]] + poly[tris[0][2]]) / 3);
    }
  }
  std::vector<int> depth(nc, 0);
  for (int a = 0; a < nc; ++a) {
    if (!closed[a] || samples[a].empty()) continue;
    for (int b = 0; b < nc; ++b) {
      if (b == a || !closed[b]) continue;
      Eigen::AlignedBox3d outer = box[b];
      outer.extend(outer.min() - Vec3::Constant(tol)).extend(outer.max() + Vec3::Constant(tol));
      if (!outer.contains(box[a])) continue;
      // |winding number| is 1 inside, 0 outside, 1/2 on the surface: use the sample farthest from 1/2
      // (a block standing on the room's floor has samples on the floor).
      double best = 0.5;
      for (const Vec3& p : samples[a]) {
        double w = 0;
        for_each_triangle(b, [&](const Vec3& x, const Vec3& y, const Vec3& z) { w += solid_angle(x - p, y - p, z - p); });
        w = std::abs(w) / (4 * std::numbers::pi);
        if (std::abs(w - 0.5) > std::abs(best - 0.5)) best = w;
      }
      if (best > 0.5) ++depth[a];
    }
  }
  // Final flip per component, then per face.
  long flipped = 0;
  std::vector<int> flipped_ids;
  for (int c = 0; c < nc; ++c) {
    int flip_all = 0;
    if (closed[c]) {
      const bool want_outward = depth[c] % 2 == 1;
      flip_all = (volume[c] > 0) != want_outward;
    } else {
      long ones = 0;
      for (int f : members[c]) ones += parity[f];
      flip_all = 2 * ones > static_cast<long>(members[c].size());  // ties keep the first face
    }
    for (int f : members[c])
      if (parity[f] ^ flip_all) {
        auto& fv = s.faces[f].vertices;
        std::reverse(fv.begin() + 1, fv.end());  // keeps the first corner
        ++flipped;
        flipped_ids.push_back(origin_of(s, f));
      }
  }
  report.counts["faces_reoriented"] += 0;
  report.counts["non_orientable_components"] += 0;
  if (flipped > 0)
    report.warn("faces_reoriented", flipped,
                plural(flipped, "face was", "faces were") +
                    " reoriented to agree with their neighbours (closed shells: outermost facing inward, nested "
                    "ones alternating; open surfaces: their majority): input face" +
                    (flipped_ids.size() == 1 ? " " : "s ") + id_list(flipped_ids));
  if (non_orientable > 0)
    report.warn("non_orientable_components", non_orientable,
                plural(non_orientable, "connected surface is", "connected surfaces are") +
                    " not orientable (like a Moebius strip); some neighbours keep opposite orientations");
}

// ---- 4. self-intersections ------------------------------------------------------------------------

double distance_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 d = b - a;
  const double l2 = d.squaredNorm();
  const double t = l2 > 0 ? std::clamp((p - a).dot(d) / l2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

double distance_to_boundary(const Vec3& p, const std::vector<Vec3>& poly) {
  double d = std::numeric_limits<double>::infinity();
  for (size_t c = 0; c < poly.size(); ++c) d = std::min(d, distance_to_segment(p, poly[c], poly[(c + 1) % poly.size()]));
  return d;
}

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
  for (auto [f, g] : candidates) {
    const int of = origin_of(s, f), og = origin_of(s, g);
    if (of == og) continue;
    bool hit = false;
    for (size_t i = 0; i < tris[f].size() && !hit; ++i) {
      const auto& tf = tris[f][i];
      for (size_t j = 0; j < tris[g].size() && !hit; ++j) {
        const auto& tg = tris[g][j];
        if (!CGAL::do_overlap(tf.bbox(), tg.bbox()) ||
            !may_touch_beyond_shared(tri_vertices[f][i], tri_vertices[g][j], tf, tg))
          continue;
        // Where exactly (exact constructions, then rounded): is any of it inside both faces?
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
    if (hit) found.emplace_back(std::min(of, og), std::max(of, og));
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

}  // namespace

PolygonSoup prepare(const PolygonSoup& soup, const PrepareOptions& options, Report& report) {
  if (!(options.max_edge >= 0) || !std::isfinite(options.max_edge))
    throw InputError("max edge length " + num(options.max_edge) + " m must be finite and >= 0 (0: no refinement)");
  if (!(options.weld_tolerance >= 0) || !std::isfinite(options.weld_tolerance))
    throw InputError("weld tolerance " + num(options.weld_tolerance) + " must be finite and >= 0");
  const int nv = static_cast<int>(soup.positions.size());
  for (int k = 0; k < static_cast<int>(soup.faces.size()); ++k) {
    const auto& f = soup.faces[k];
    const std::string where = SourceLoc{soup.file, f.line}.str() + ": face " + std::to_string(origin_of(soup, k));
    for (size_t c = 0; c < f.vertices.size(); ++c) {
      const int v = f.vertices[c];
      if (v < 0 || v >= nv)
        throw InputError(where + ": corner " + std::to_string(c) + " refers to vertex " + std::to_string(v) +
                         ", out of range (the file has " + std::to_string(nv) + " vertices, 0-based)");
      if (!soup.positions[v].allFinite())
        throw InputError(where + " uses " + vertex_at(soup, v) + ", which has a non-finite coordinate");
    }
  }

  check_geometric_scale(soup);  // before any work that depends on it

  PolygonSoup out = soup;
  if (!options.repair && options.max_edge == 0) {
    // Nothing changes; only the read-only detection runs.
  } else {
    if (out.input_faces < 0) out.input_faces = static_cast<int>(out.faces.size());
    for (int k = 0; k < static_cast<int>(out.faces.size()); ++k) out.faces[k].origin = origin_of(out, k);
  }
  const double tol = length_tolerance(out, options.weld_tolerance);
  if (options.repair) {
    weld(out, tol, report);
    clean_faces(out, report);
    orient(out, tol, report);
  }
  std::vector<char> usable(out.faces.size());
  for (size_t k = 0; k < out.faces.size(); ++k) usable[k] = usable_face(out, static_cast<int>(k));
  detect_self_intersections(out, usable, tol, report);
  detect_t_junctions(out, usable, tol, report);
  if (options.max_edge > 0) refine(out, options.max_edge, report, options.max_patches);
  return out;
}

Scene prepare_and_build(const PolygonSoup& soup, const PrepareOptions& options, const BuildOptions& build) {
  Report prep;
  const PolygonSoup ready = prepare(soup, options, prep);
  Scene scene = build_scene(ready, build);
  // Preparation first: it ran first, and build_scene's warnings are about the prepared faces.
  for (const auto& [key, count] : scene.report.counts) prep.counts[key] += count;
  prep.warnings.insert(prep.warnings.end(), scene.report.warnings.begin(), scene.report.warnings.end());
  prep.worst_nonplanarity = scene.report.worst_nonplanarity;
  prep.worst_nonplanar_face = scene.report.worst_nonplanar_face;
  scene.report = std::move(prep);
  return scene;
}

}  // namespace lambert::mesh
