// mesh::prepare: the driver, weld and face cleaning. Orientation is in prepare_orient.cpp,
// imprinting of contact lines and crossings in prepare_imprint.cpp (repair); self-intersection and
// T-junction detection in prepare_detect.cpp; refinement in prepare_refine.cpp.
#include "lambert/mesh/prepare.hpp"
#include "union_find.hpp"

#include <algorithm>
#include <chrono>
#include <map>
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

}  // namespace detail

namespace {

using namespace detail;

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
        // Unsigned: cell indices of a model 4e6 m from the origin at a 1e-5 m weld tolerance reach 4e11, and their
        // signed products overflowed (undefined; UBSan, PrepareInvariance.MovedModelIsTriangulatedAsTheOneAtTheOrigin).
        return std::hash<std::uint64_t>()(std::uint64_t(c[0]) * 73856093u ^ std::uint64_t(c[1]) * 19349663u ^
                                          std::uint64_t(c[2]) * 83492791u);
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
  // Vertices at exactly the position they join (a file that stores a copy of each corner per face, as many
  // exporters do) change no geometry: counted, but not warned about. Only moved vertices are a repair.
  long merged = 0, shared = 0;  // moved, and at exactly the same position
  int ex = -1;
  for (int v = 0; v < nv; ++v)
    if (used[v] && uf.find(v) != v) {
      if (ex < 0) ex = v;
      ++(s.positions[v] == s.positions[uf.find(v)] ? shared : merged);
    }
  for (auto& f : s.faces)
    for (int& v : f.vertices) v = uf.find(v);
  // vertices_merged counts both kinds (as before); vertices_shared_exact says how many of them did not move.
  report.counts["vertices_merged"] += shared;
  report.counts["vertices_shared_exact"] += shared;
  if (kept_apart > 0)
    report.warn("vertices_not_merged", kept_apart,
                plural(kept_apart, "pair of vertices", "pairs of vertices") + " within the weld tolerance " + num(tol) +
                    " m were kept apart: closer than that, but not much closer than their own edges (" +
                    num(100 * kLocalWeldShare) + " % of the shortest edge at them), so welding would change the shape");
  if (merged > 0)
    report.warn("vertices_merged", merged,
                plural(merged + shared, "vertex was", "vertices were") + " merged into a vertex closer than " +
                    num(tol) + " m (" + std::to_string(merged) + " moved, " + std::to_string(shared) +
                    " at exactly the same position), e.g. " + vertex_at(s, ex) + " into " + vertex_at(s, uf.find(ex)));
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

// ---- 3. duplicate faces ---------------------------------------------------------------------------------
// Two faces with the same corners in the same cyclic order (after welding) are one surface modelled twice
// (e.g. the public Cornell box repeats a side of each block as its "bottom"): both would receive and emit,
// so whatever faces them would count the surface twice (row sums above 1). The later copy is removed,
// counted and named. Coincident faces wound the opposite way (a zero-thickness sheet, seen from both sides)
// are two surfaces and stay.
void remove_duplicate_faces(PolygonSoup& s, Report& report) {
  std::map<std::vector<int>, int> first;  // canonical corner cycle -> input face that has it
  std::vector<SoupFace> out;
  out.reserve(s.faces.size());
  std::vector<std::string> pairs;
  long removed = 0;
  for (int k = 0; k < static_cast<int>(s.faces.size()); ++k) {
    const std::vector<int>& v = s.faces[k].vertices;
    std::vector<int> key(v.size());
    const size_t start = static_cast<size_t>(std::min_element(v.begin(), v.end()) - v.begin());
    for (size_t c = 0; c < v.size(); ++c) key[c] = v[(start + c) % v.size()];
    const auto [it, added] = first.try_emplace(std::move(key), origin_of(s, k));
    if (added) {
      out.push_back(s.faces[k]);
      continue;
    }
    ++removed;
    if (pairs.size() < 5)
      pairs.push_back("input face " + std::to_string(origin_of(s, k)) + " repeats input face " +
                      std::to_string(it->second));
  }
  report.counts["duplicate_faces_removed"] += 0;
  if (removed == 0) return;
  s.faces = std::move(out);
  std::string list;
  for (const auto& p : pairs) list += (list.empty() ? "" : "; ") + p;
  if (removed > static_cast<long>(pairs.size())) list += "; and " + std::to_string(removed - long(pairs.size())) + " more";
  report.warn("duplicate_faces_removed", removed,
              plural(removed, "face repeats", "faces repeat") +
                  " another face corner for corner (the same surface twice, which would count twice) and " +
                  (removed == 1 ? "was" : "were") + " removed: " + list);
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
  report.counts["faces_reversed_as_asked"] += 0;
  if (options.reverse_winding) {
    // The first corner kept, as the orientation repair flips: corner 0 and the face ids unchanged.
    for (SoupFace& f : out.faces) std::reverse(f.vertices.begin() + 1, f.vertices.end());
    const long n = static_cast<long>(out.faces.size());
    report.warn("faces_reversed_as_asked", n,
                "the winding of all " + plural(n, "face", "faces") + " was reversed as asked (--reverse-winding)");
  }
  if (!options.repair && options.max_edge == 0) {
    // Nothing changes; only the read-only detection runs.
  } else {
    if (out.input_faces < 0) out.input_faces = static_cast<int>(out.faces.size());
    for (int k = 0; k < static_cast<int>(out.faces.size()); ++k) out.faces[k].origin = origin_of(out, k);
  }
  // Each stage timed (Report::seconds: --stats and the summary line "prepare").
  auto t0 = std::chrono::steady_clock::now();
  auto stage = [&](const char* name) {
    const auto t1 = std::chrono::steady_clock::now();
    report.seconds.emplace_back(name, std::chrono::duration<double>(t1 - t0).count());
    t0 = t1;
  };
  const double tol = length_tolerance(out, options.weld_tolerance);
  if (options.repair) {
    weld(out, tol, report);
    clean_faces(out, report);
    remove_duplicate_faces(out, report);
    stage("weld");
    orient(out, options.orient, tol, report);
    stage("orient");
    if (options.imprint) {
      imprint(out, tol, report);
      stage("imprint");
    }
  }
  std::vector<char> usable(out.faces.size());
  for (size_t k = 0; k < out.faces.size(); ++k) usable[k] = usable_face(out, static_cast<int>(k));
  detect_self_intersections(out, usable, tol, report);
  stage("self_intersections");
  detect_t_junctions(out, usable, tol, report);
  stage("t_junctions");
  if (options.max_edge > 0) {
    refine(out, options.max_edge, report, options.max_patches);
    stage("refine");
  }
  duplicate_two_sided(out, report);
  return out;
}

Scene prepare_and_build(const PolygonSoup& soup, const PrepareOptions& options, const BuildOptions& build) {
  Report prep;
  const PolygonSoup ready = prepare(soup, options, prep);
  const auto t0 = std::chrono::steady_clock::now();
  Scene scene = build_scene(ready, build);
  prep.seconds.emplace_back("build", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  // Preparation first: it ran first, and build_scene's warnings are about the prepared faces.
  for (const auto& [key, count] : scene.report.counts) prep.counts[key] += count;
  prep.warnings.insert(prep.warnings.end(), scene.report.warnings.begin(), scene.report.warnings.end());
  prep.worst_nonplanarity = scene.report.worst_nonplanarity;
  prep.worst_nonplanar_face = scene.report.worst_nonplanar_face;
  scene.report = std::move(prep);
  return scene;
}

}  // namespace lambert::mesh