// Openings as portal polygons (portals.hpp).
#include "portals.hpp"

#include "enclosures.hpp"

#include <polyclipping/clipper.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <numeric>
#include <unordered_map>
#include <array>
#include <map>

namespace lambert::formfactor::detail {

std::vector<std::vector<Vec3>> find_openings(const mesh::PatchGeometry& g, double eps) {
  std::vector<std::vector<Vec3>> out;
  const int n = g.size();
  if (n < 2 || !(eps > 0)) return out;
  Eigen::AlignedBox3d box;
  for (const Vec3& v : g.points) box.extend(v);
  const double scale = box.diagonal().norm();
  if (!(scale > 0)) return out;
  // Planes: canonical normals (largest component positive) in buckets of 1e-6, then offsets from the scene's centre
  // (a model in GIS coordinates: offsets from the origin would carry its normals' rounding times 1e6 m) chained
  // where consecutive ones lie within eps / 4. Planes numbered in order of their first patch: deterministic.
  const Vec3 centre = box.center();
  std::vector<Vec3> canon(static_cast<size_t>(n));
  std::vector<std::array<long long, 3>> bucket(static_cast<size_t>(n));
  std::vector<double> offset(static_cast<size_t>(n));
  for (int p = 0; p < n; ++p) {
    Vec3 nrm = g.normal[p];
    int big = 0;
    for (int c = 1; c < 3; ++c)
      if (std::abs(nrm[c]) > std::abs(nrm[big])) big = c;
    if (nrm[big] < 0) nrm = -nrm;
    canon[size_t(p)] = nrm;
    bucket[size_t(p)] = {std::llround(nrm.x() * 1e6), std::llround(nrm.y() * 1e6), std::llround(nrm.z() * 1e6)};
    offset[size_t(p)] = nrm.dot(g.centroid[p] - centre);
  }
  std::vector<int> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    if (bucket[size_t(a)] != bucket[size_t(b)]) return bucket[size_t(a)] < bucket[size_t(b)];
    if (offset[size_t(a)] != offset[size_t(b)]) return offset[size_t(a)] < offset[size_t(b)];
    return a < b;
  });
  std::vector<int> chain(static_cast<size_t>(n));
  for (size_t k = 0; k < order.size(); ++k) {
    const int p = order[k], q = k > 0 ? order[k - 1] : -1;
    const bool same = q >= 0 && bucket[size_t(p)] == bucket[size_t(q)] && offset[size_t(p)] - offset[size_t(q)] <= eps / 4;
    chain[size_t(p)] = same ? chain[size_t(q)] : p;  // the chain's first patch in sorted order
  }
  std::vector<int> plane(static_cast<size_t>(n), -1), id_of(static_cast<size_t>(n), -1);
  int planes = 0;
  for (int p = 0; p < n; ++p) {
    int& id = id_of[size_t(chain[size_t(p)])];
    if (id < 0) id = planes++;
    plane[size_t(p)] = id;
  }
  // Patches per plane, in patch order.
  std::vector<int> count(size_t(planes) + 1, 0);
  for (int p = 0; p < n; ++p) ++count[size_t(plane[p]) + 1];
  for (int k = 0; k < planes; ++k) count[size_t(k) + 1] += count[size_t(k)];
  std::vector<int> members(static_cast<size_t>(n));
  {
    std::vector<int> at(count.begin(), count.end() - 1);
    for (int p = 0; p < n; ++p) members[size_t(at[size_t(plane[p])]++)] = p;
  }
  const double lim = double(ClipperLib::loRange);
  // Clipper units: eps / 16, so that snapped corners stay within eps / 32 of the patches' (enclosures.hpp joins
  // edges within eps).
  const double unit = eps / 16, inv = 1.0 / unit;
  // The planes' normals: their first patch's.
  std::vector<Vec3> plane_normal(static_cast<size_t>(planes));
  for (int k = 0; k < planes; ++k) plane_normal[size_t(k)] = canon[size_t(members[size_t(count[size_t(k)])])];
  // Edges lying in a plane, by the plane's normal direction and offset (bins of eps): the traces of faces that meet
  // a plane along an edge (a threshold under a door, a floor's edge along a wall's base) close the openings that
  // reach the plane's border, as a door reaches the floor. The kMaxDirections directions with the most patches (an
  // architectural model has a handful; a rotated one the same handful).
  constexpr int kMaxDirections = 32;
  std::vector<int> direction_of(static_cast<size_t>(planes), -1);
  std::vector<Vec3> directions;
  {
    std::map<std::array<long long, 3>, std::pair<int, int>> key;  // quantised normal -> (patches, first plane)
    for (int k = 0; k < planes; ++k) {
      const Vec3& nk = plane_normal[size_t(k)];
      auto& e = key.try_emplace({std::llround(nk.x() * 1e6), std::llround(nk.y() * 1e6), std::llround(nk.z() * 1e6)},
                                0, k).first->second;
      e.first += count[size_t(k) + 1] - count[size_t(k)];
    }
    std::vector<std::pair<int, int>> by_count;  // (-patches, first plane): deterministic order
    for (const auto& [q, e] : key) by_count.push_back({-e.first, e.second});
    std::sort(by_count.begin(), by_count.end());
    if (by_count.size() > size_t(kMaxDirections)) by_count.resize(size_t(kMaxDirections));
    for (const auto& [c, k] : by_count) directions.push_back(plane_normal[size_t(k)]);
    for (int k = 0; k < planes; ++k)
      for (size_t d = 0; d < directions.size(); ++d)
        if ((plane_normal[size_t(k)] - directions[d]).cwiseAbs().maxCoeff() < 2e-6) direction_of[size_t(k)] = int(d);
  }
  struct Edge {
    int patch, corner;  // from corner to the next corner of the patch
  };
  std::vector<std::unordered_map<long long, std::vector<Edge>>> in_plane(directions.size());
  for (int p = 0; p < n; ++p) {
    const auto poly = g.polygon(p);
    for (size_t i = 0; i < poly.size(); ++i) {
      const Vec3 &a = poly[i], &b = poly[(i + 1) % poly.size()];
      for (size_t d = 0; d < directions.size(); ++d)
        if (std::abs(directions[d].dot(b - a)) <= eps)
          in_plane[d][std::llround(directions[d].dot(a - centre) / eps)].push_back({p, int(i)});
    }
  }
  // The planes in parallel, each with its own Clipper and buffers, their openings gathered in plane order: the same
  // list for any thread count.
  auto openings_of = [&](int k, std::vector<std::vector<Vec3>>& found) {
    ClipperLib::Clipper clipper;
    ClipperLib::Paths own, all, merged, ring, cover, near;
    std::vector<ClipperLib::IntRect> own_box;
    const int b = count[size_t(k)], e = count[size_t(k) + 1];
    // The plane's frame: its normal, origin at its first patch's centroid.
    const int p0 = members[size_t(b)];
    const Vec3& nrm = plane_normal[size_t(k)];
    const Vec3 u = (std::abs(nrm.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(nrm).normalized();
    const Vec3 v = nrm.cross(u);
    const Vec3 o = g.centroid[p0];
    bool fits = true;
    auto snap = [&](const Vec3& c) {
      const double x = u.dot(c - o) * inv, y = v.dot(c - o) * inv;
      if (!(std::abs(x) < lim && std::abs(y) < lim)) fits = false;
      return ClipperLib::IntPoint(ClipperLib::cInt(std::llround(fits ? x : 0)), ClipperLib::cInt(std::llround(fits ? y : 0)));
    };
    own.clear();
    for (int m = b; m < e && fits; ++m) {
      ClipperLib::Path path;
      for (const Vec3& c : g.polygon(members[size_t(m)])) path.push_back(snap(c));
      if (path.size() < 3) continue;
      if (!ClipperLib::Orientation(path)) ClipperLib::ReversePath(path);  // faces facing either way: all positive
      own.push_back(std::move(path));
    }
    if (!fits || own.empty()) return;
    own_box.clear();
    for (const ClipperLib::Path& q : own) {
      ClipperLib::IntRect r{q[0].X, q[0].Y, q[0].X, q[0].Y};
      for (const auto& pt : q) r = {std::min(r.left, pt.X), std::min(r.top, pt.Y), std::max(r.right, pt.X), std::max(r.bottom, pt.Y)};
      own_box.push_back(r);
    }
    all = own;
    if (const int d = direction_of[size_t(k)]; d >= 0) {  // the other faces' edges in this plane, strips eps / 4 wide
      const Vec3& nd = directions[size_t(d)];
      const double c0 = nd.dot(o - centre);
      const long long bin = std::llround(c0 / eps);
      for (long long bb = bin - 1; bb <= bin + 1; ++bb) {
        const auto it = in_plane[size_t(d)].find(bb);
        if (it == in_plane[size_t(d)].end()) continue;
        for (const Edge& ed : it->second) {
          const auto poly = g.polygon(ed.patch);
          const Vec3 &ea = poly[size_t(ed.corner)], &eb = poly[(size_t(ed.corner) + 1) % poly.size()];
          if (plane[size_t(ed.patch)] == k || std::abs(nrm.dot(ea - o)) > eps || std::abs(nrm.dot(eb - o)) > eps) continue;
          const ClipperLib::IntPoint pa = snap(ea), pb = snap(eb);
          const double dx = double(pb.X - pa.X), dy = double(pb.Y - pa.Y), len = std::hypot(dx, dy);
          if (!fits || !(len > 0)) continue;
          const double tx = 2 * dx / len, ty = 2 * dy / len;  // 2 units (eps / 8) along and across
          auto at = [&](const ClipperLib::IntPoint& q, double sx, double sy) {
            return ClipperLib::IntPoint(q.X + ClipperLib::cInt(std::llround(sx)), q.Y + ClipperLib::cInt(std::llround(sy)));
          };
          ClipperLib::Path strip{at(pa, -tx + ty, -ty - tx), at(pb, tx + ty, ty - tx), at(pb, tx - ty, ty + tx),
                                 at(pa, -tx - ty, -ty + tx)};
          if (!ClipperLib::Orientation(strip)) ClipperLib::ReversePath(strip);
          all.push_back(std::move(strip));
        }
      }
    }
    if (!fits || all.size() < 2) return;  // one simple polygon has no hole
    // Paths, not a PolyTree, and not strictly simple: both make Clipper 6 quadratic in the polygons that share
    // edges (a ground of 6,000 triangles took minutes). A hole is a path of negative orientation (inputs positive,
    // non-zero fill); one that touches itself is left out below (the ear clipping refuses it).
    clipper.Clear();
    clipper.AddPaths(all, ClipperLib::ptSubject, true);
    if (!clipper.Execute(ClipperLib::ctUnion, merged, ClipperLib::pftNonZero, ClipperLib::pftNonZero)) return;
    for (const ClipperLib::Path& contour : merged) {
      if (ClipperLib::Orientation(contour)) continue;
      ClipperLib::Path hole = contour;
      ClipperLib::CleanPolygon(hole, 1.415);
      if (hole.size() < 3) continue;
      double perimeter = 0;
      for (size_t i = 0; i < hole.size(); ++i) {
        const auto &a = hole[i], &c = hole[(i + 1) % hole.size()];
        perimeter += std::hypot(double(c.X - a.X), double(c.Y - a.Y));
      }
      const double area = std::abs(ClipperLib::Area(hole));  // in units^2
      if (!(area > 64 * perimeter)) continue;                 // a sliver: narrower than ~8 eps
      // An opening is mostly bounded by the plane's own faces (a door: jambs' wall on three sides, the threshold
      // on one); a region fenced by other faces' edges only (walls' edges around a table top's plane) is not.
      if (!ClipperLib::Orientation(hole)) ClipperLib::ReversePath(hole);
      ClipperLib::ClipperOffset grow;
      grow.AddPath(hole, ClipperLib::jtMiter, ClipperLib::etClosedPolygon);
      ring.clear();
      grow.Execute(ring, 8.0);  // half an eps
      clipper.Clear();
      clipper.AddPaths(ring, ClipperLib::ptSubject, true);
      clipper.AddPath(hole, ClipperLib::ptClip, true);
      clipper.Execute(ClipperLib::ctDifference, ring, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
      // Only the plane's patches near the hole (a ground of thousands of triangles around a building's footprint).
      ClipperLib::IntRect rb{hole[0].X, hole[0].Y, hole[0].X, hole[0].Y};
      for (const auto& pt : hole) rb = {std::min(rb.left, pt.X), std::min(rb.top, pt.Y), std::max(rb.right, pt.X), std::max(rb.bottom, pt.Y)};
      rb = {rb.left - 16, rb.top - 16, rb.right + 16, rb.bottom + 16};  // the ring is 8 units wide
      near.clear();
      for (size_t m = 0; m < own.size(); ++m)
        if (own_box[m].left <= rb.right && rb.left <= own_box[m].right && own_box[m].top <= rb.bottom &&
            rb.top <= own_box[m].bottom)
          near.push_back(own[m]);
      clipper.Clear();
      clipper.AddPaths(ring, ClipperLib::ptSubject, true);
      clipper.AddPaths(near, ClipperLib::ptClip, true);
      clipper.Execute(ClipperLib::ctIntersection, cover, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
      double ring_area = 0, cover_area = 0;
      for (const auto& r : ring) ring_area += ClipperLib::Area(r);
      for (const auto& r : cover) cover_area += ClipperLib::Area(r);
      if (!(cover_area >= 0.5 * ring_area)) continue;
      std::vector<Vec3> poly;
      poly.reserve(hole.size());
      for (const auto& pt : hole) {
        Vec3 c = o + (double(pt.X) * unit) * u + (double(pt.Y) * unit) * v;
        c += nrm.dot(o - c) * nrm;  // in the plane
        poly.push_back(c);
      }
      // A hole the ear clipping cannot take (left open: its rooms stay one cell, which only refuses less).
      if (mesh::triangulate_polygon(poly, nrm).empty()) continue;
      found.push_back(std::move(poly));
    }
  };
  std::vector<std::vector<std::vector<Vec3>>> per_plane(static_cast<size_t>(planes));
  tbb::parallel_for(tbb::blocked_range<int>(0, planes, 1), [&](const tbb::blocked_range<int>& range) {
    for (int k = range.begin(); k < range.end(); ++k) openings_of(k, per_plane[size_t(k)]);
  });
  for (auto& found : per_plane)
    for (auto& poly : found) out.push_back(std::move(poly));
  return out;
}

Rooms find_rooms(const mesh::PatchGeometry& g, double eps) {
  const auto t0 = std::chrono::steady_clock::now();
  Rooms r;
  r.portals = find_openings(g, eps);
  if (!r.portals.empty()) {
    const int n = g.size();
    std::vector<std::vector<Vec3>> polys(size_t(n) + r.portals.size());
    for (int p = 0; p < n; ++p) polys[size_t(p)].assign(g.polygon(p).begin(), g.polygon(p).end());
    for (size_t q = 0; q < r.portals.size(); ++q) polys[size_t(n) + q] = r.portals[q];
    // The patches were built from these same polygons and the portals were triangulated: from_polygons cannot
    // refuse them; if it ever did, the scene keeps its apartments (no rooms), which only refuses less.
    Enclosures e;
    try {
      e = find_enclosures(mesh::PatchGeometry::from_polygons(polys), eps);
    } catch (const InputError&) {
      e = Enclosures{};
    }
    if (e.surfaces > 0) {
      r.cell.assign(e.cell.begin(), e.cell.begin() + n);
      r.rooms = e.cells;
      r.room_surfaces = std::move(e.cell_surfaces);
      r.surface_portals.assign(size_t(e.surfaces), {});
      r.portal_box.resize(r.portals.size());
      for (size_t q = 0; q < r.portals.size(); ++q) {
        for (const Vec3& v : r.portals[q]) r.portal_box[q].add(v);
        const auto& sides = e.surfaces_of[size_t(n) + q];
        for (int side = 0; side < 2; ++side)
          if (sides[side] >= 0 && (side == 0 || sides[1] != sides[0]))
            r.surface_portals[size_t(sides[side])].push_back(int(q));
      }
    }
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

bool Rooms::path(const Shaft& shaft, int ra, int rb) const {
  const std::vector<int>& sa = room_surfaces[size_t(ra)];
  const std::vector<int>& sb = room_surfaces[size_t(rb)];
  auto through = [&](int S) {
    for (int q : surface_portals[size_t(S)])
      if (polygon_may_meet(shaft, portal_box[size_t(q)], portals[size_t(q)])) return true;
    return false;
  };
  // The symmetric difference of the two sorted surface lists.
  size_t i = 0, j = 0;
  while (i < sa.size() || j < sb.size()) {
    int S;
    if (j == sb.size() || (i < sa.size() && sa[i] < sb[j])) S = sa[i++];
    else if (i == sa.size() || sb[j] < sa[i]) S = sb[j++];
    else {
      ++i, ++j;
      continue;
    }
    if (!through(S)) return false;
  }
  return true;
}

}  // namespace lambert::formfactor::detail
