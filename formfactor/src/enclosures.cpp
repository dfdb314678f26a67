// Closed surfaces and the cells they split space into (enclosures.hpp).
#include "enclosures.hpp"

#include "lambert/formfactor/visibility.hpp"

#include <embree3/rtcore.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>

#include "embree_scene.hpp"

namespace lambert::formfactor::detail {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;
constexpr double kAngleTie = 1e-9;  // radians: faces about an edge closer than this are coincident

// Every hit along a ray: the context filter records each candidate and rejects it, so Embree goes on.
struct CollectContext {
  RTCIntersectContext ctx;
  std::vector<unsigned>* hits;
};

void collect_filter(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<CollectContext*>(args->context);
  for (unsigned k = 0; k < args->N; ++k) {
    if (args->valid[k] == 0) continue;
    c->hits->push_back(RTCHitN_primID(args->hit, args->N, k));
    args->valid[k] = 0;
  }
}

struct Device {
  RTCDevice d = rtcNewDevice(nullptr);
  Device() {
    if (!d) throw std::runtime_error("Embree: cannot create device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  }
  ~Device() { rtcReleaseDevice(d); }
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;
};

struct Scene {
  RTCScene s;
  explicit Scene(RTCDevice d) : s(rtcNewScene(d)) {
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
  }
  ~Scene() { rtcReleaseScene(s); }
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;
  // Primitive ids of the hits with t in [tnear, tfar] along o + t d (o relative to the centre, d unit), appended to
  // hits (a primitive may appear twice).
  void all_hits(const Vec3& o, const Vec3& d, double tnear, double tfar, std::vector<unsigned>& hits) const {
    CollectContext c;
    rtcInitIntersectContext(&c.ctx);
    c.ctx.filter = &collect_filter;
    c.hits = &hits;
    RTCRayHit rh;
    rh.ray.org_x = float(o.x());
    rh.ray.org_y = float(o.y());
    rh.ray.org_z = float(o.z());
    rh.ray.dir_x = float(d.x());
    rh.ray.dir_y = float(d.y());
    rh.ray.dir_z = float(d.z());
    rh.ray.tnear = float(tnear);
    rh.ray.tfar = float(tfar);
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(s, &c.ctx, &rh);
  }
};

// +1: y (in the polygon's plane) lies inside the polygon farther than margin from its boundary; -1: outside
// farther than margin; 0: within margin of the boundary.
int polygon_side(std::span<const Vec3> poly, const Vec3& n, const Vec3& y, double margin) {
  const int m = int(poly.size());
  double d2 = INFINITY;
  for (int k = 0; k < m; ++k) {
    const Vec3 &a = poly[k], &b = poly[(k + 1) % m];
    const Vec3 ab = b - a;
    const double l2 = ab.squaredNorm();
    const double t = l2 > 0 ? std::clamp((y - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
    d2 = std::min(d2, (a + t * ab - y).squaredNorm());
  }
  if (d2 <= margin * margin) return 0;
  int ax = 0;  // drop the normal's largest axis
  for (int k = 1; k < 3; ++k)
    if (std::abs(n[k]) > std::abs(n[ax])) ax = k;
  const int i = (ax + 1) % 3, j = (ax + 2) % 3;
  bool inside = false;
  for (int k = 0, l = m - 1; k < m; l = k++) {
    const Vec3 &a = poly[k], &b = poly[l];
    if ((a[j] > y[j]) != (b[j] > y[j]) && y[i] < (b[i] - a[i]) * (y[j] - a[j]) / (b[j] - a[j]) + a[i]) inside = !inside;
  }
  return inside ? 1 : -1;
}

struct UnionFind {
  std::vector<int> up;
  explicit UnionFind(int n) : up(static_cast<size_t>(n)) { std::iota(up.begin(), up.end(), 0); }
  int find(int x) {
    while (up[x] != x) x = up[x] = up[up[x]];
    return x;
  }
  void join(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) up[std::max(a, b)] = std::min(a, b);  // the root is the smallest member
  }
};

}  // namespace

Enclosures find_enclosures(const mesh::PatchGeometry& g, double eps) {
  const auto t0 = Clock::now();
  Enclosures out;
  const int n = g.size();
  out.cell.assign(size_t(n), 0);
  out.cells = n > 0 ? 1 : 0;
  if (n == 0 || !(eps > 0)) return out;
  const int nc = int(g.points.size());
  std::vector<int> patch_of(static_cast<size_t>(nc));
  for (int p = 0; p < n; ++p)
    for (int c = g.offsets[p]; c < g.offsets[p + 1]; ++c) patch_of[size_t(c)] = p;
  // Edge c runs from corner c to the next corner of its patch.
  auto next = [&](int c) { return c + 1 < g.offsets[patch_of[c] + 1] ? c + 1 : g.offsets[patch_of[c]]; };
  auto prev = [&](int c) { return c > g.offsets[patch_of[c]] ? c - 1 : g.offsets[patch_of[c] + 1] - 1; };
  Eigen::AlignedBox3d box;
  for (const Vec3& v : g.points) box.extend(v);
  const Vec3 centre = box.center();

  // 1. Distinct corner positions (exact equality) and the corners at each.
  std::vector<int> order(static_cast<size_t>(nc));
  std::iota(order.begin(), order.end(), 0);
  tbb::parallel_sort(order.begin(), order.end(), [&](int a, int b) {
    const Vec3 &x = g.points[a], &y = g.points[b];
    if (x.x() != y.x()) return x.x() < y.x();
    if (x.y() != y.y()) return x.y() < y.y();
    if (x.z() != y.z()) return x.z() < y.z();
    return a < b;
  });
  std::vector<int> start;  // distinct point u: corners order[start[u] .. start[u + 1])
  for (int k = 0; k < nc; ++k)
    if (k == 0 || g.points[order[k]] != g.points[order[k - 1]]) start.push_back(k);
  const int np = int(start.size());
  start.push_back(nc);

  // 2. Overlapping collinear edges of different patches, from a search for the points within eps of each edge
  // (spheres of radius 2 eps in Embree, float): two collinear edges overlap only where an end of one lies on the
  // other, so one of the two searches finds the pair.
  Device dev;  // one for the point search (step 2) and the triangles (steps 5 and 6)
  std::vector<std::pair<int, int>> pairs;
  {
    Scene spheres(dev.d);
    RTCGeometry geom = rtcNewGeometry(dev.d, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), size_t(np)));
    const float r = float(2 * eps);
    for (int u = 0; u < np; ++u) {
      const Vec3 v = g.points[order[start[u]]] - centre;
      vb[4 * u] = float(v.x());
      vb[4 * u + 1] = float(v.y());
      vb[4 * u + 2] = float(v.z());
      vb[4 * u + 3] = r;
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(spheres.s, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(spheres.s);
    struct Local {
      std::vector<unsigned> hits;
      std::vector<std::pair<int, int>> pairs;
    };
    tbb::enumerable_thread_specific<Local> locals;
    tbb::parallel_for(tbb::blocked_range<int>(0, nc, 1024), [&](const tbb::blocked_range<int>& range) {
      Local& loc = locals.local();
      for (int e = range.begin(); e < range.end(); ++e) {
        const Vec3 &A = g.points[e], &B = g.points[next(e)];
        const double L = (B - A).norm();
        if (!(L > eps)) continue;
        const Vec3 u = (B - A) / L;
        loc.hits.clear();
        spheres.all_hits(A - centre - 3 * double(r) * u, u, 0.0, L + 6 * double(r), loc.hits);
        std::sort(loc.hits.begin(), loc.hits.end());
        loc.hits.erase(std::unique(loc.hits.begin(), loc.hits.end()), loc.hits.end());
        for (unsigned h : loc.hits)
          for (int k = start[h]; k < start[h + 1]; ++k)
            for (int f : {order[k], prev(order[k])}) {
              if (patch_of[f] == patch_of[e]) continue;
              const Vec3 &C = g.points[f], &D = g.points[next(f)];
              const double Lf = (D - C).norm();
              if (!(Lf > eps)) continue;
              // The shorter edge's ends within eps of the longer one's line.
              const bool e_short = L <= Lf;
              const Vec3 &P0 = e_short ? A : C, &P1 = e_short ? B : D, &Q = e_short ? C : A;
              const Vec3 w = e_short ? Vec3((D - C) / Lf) : u;
              auto off = [&](const Vec3& x) { const Vec3 dx = x - Q; return (dx - dx.dot(w) * w).norm(); };
              if (off(P0) > eps || off(P1) > eps) continue;
              const double ta = (C - A).dot(u), tb = (D - A).dot(u);
              if (std::min(L, std::max(ta, tb)) - std::max(0.0, std::min(ta, tb)) > eps)
                loc.pairs.emplace_back(std::min(e, f), std::max(e, f));
            }
      }
    });
    for (Local& l : locals) pairs.insert(pairs.end(), l.pairs.begin(), l.pairs.end());
  }
  tbb::parallel_sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<int> poff(size_t(nc) + 1, 0), partner(2 * pairs.size());
  for (const auto& [a, b] : pairs) ++poff[a + 1], ++poff[b + 1];
  for (int k = 0; k < nc; ++k) poff[k + 1] += poff[k];
  {
    std::vector<int> fill(poff.begin(), poff.end() - 1);
    for (const auto& [a, b] : pairs) partner[fill[a]++] = b, partner[fill[b]++] = a;
  }

  // 3. Around each piece of each edge (between the ends of the edges that overlap it), the faces sorted by angle
  // about the edge: the two sides facing into the wedge between consecutive faces bound one region of space, so
  // they join one boundary surface. A piece of one face only: its front and back join (light goes round the edge).
  UnionFind sides(2 * n);  // side 2p: the front of patch p, 2p + 1: its back
  {
    struct Member {
      double angle;
      int s;      // +1: the face's front faces increasing angle
      int patch;
    };
    struct Local {
      std::vector<std::pair<int, int>> joins;
      std::vector<double> cut;
      std::vector<std::pair<double, double>> iv;
      std::vector<int> ivf;
      std::vector<Member> around;
    };
    tbb::enumerable_thread_specific<Local> locals;
    tbb::parallel_for(tbb::blocked_range<int>(0, nc, 1024), [&](const tbb::blocked_range<int>& range) {
      Local& loc = locals.local();
      for (int e = range.begin(); e < range.end(); ++e) {
        const Vec3 &A = g.points[e], &B = g.points[next(e)];
        const double L = (B - A).norm();
        if (!(L > eps)) continue;
        const Vec3 u = (B - A) / L;
        const int pe = patch_of[e];
        const Vec3 r1 = g.normal[pe].cross(u);  // into patch pe: angle 0
        const Vec3 r2 = u.cross(r1);
        loc.iv.clear();
        loc.ivf.clear();
        for (int k = poff[e]; k < poff[e + 1]; ++k) {
          const int f = partner[k];
          const double ta = (g.points[f] - A).dot(u), tb = (g.points[next(f)] - A).dot(u);
          const double lo = std::max(0.0, std::min(ta, tb)), hi = std::min(L, std::max(ta, tb));
          if (hi - lo > eps) loc.iv.emplace_back(lo, hi), loc.ivf.push_back(f);
        }
        loc.cut.assign({0.0, L});
        for (const auto& [lo, hi] : loc.iv) loc.cut.push_back(lo), loc.cut.push_back(hi);
        std::sort(loc.cut.begin(), loc.cut.end());
        for (size_t k = 0; k + 1 < loc.cut.size(); ++k) {
          if (!(loc.cut[k + 1] - loc.cut[k] > eps)) continue;
          const double m = 0.5 * (loc.cut[k] + loc.cut[k + 1]);
          loc.around.clear();
          loc.around.push_back({0.0, g.normal[pe].dot(u.cross(r1)) > 0 ? 1 : -1, pe});
          for (size_t i = 0; i < loc.iv.size(); ++i) {
            if (!(loc.iv[i].first < m && m < loc.iv[i].second)) continue;
            const int f = loc.ivf[i], pf = patch_of[f];
            const Vec3 w = g.normal[pf].cross((g.points[next(f)] - g.points[f]).normalized());  // into patch pf
            double ang = std::atan2(w.dot(r2), w.dot(r1));
            if (ang < 0) ang += 2 * kPi;
            if (ang > 2 * kPi - kAngleTie) ang = 0;
            loc.around.push_back({ang, g.normal[pf].dot(u.cross(w)) > 0 ? 1 : -1, pf});
          }
          // Coincident faces (a two-sided face's two patches): ordered by the side they face, then by index, so that
          // the order does not depend on rounding (either consistent order gives the same cells).
          std::sort(loc.around.begin(), loc.around.end(), [](const Member& x, const Member& y) {
            return x.angle < y.angle || (x.angle == y.angle && x.patch < y.patch);
          });
          for (size_t i = 0; i < loc.around.size();) {  // runs of angles within kAngleTie of the previous one
            size_t j = i + 1;
            while (j < loc.around.size() && loc.around[j].angle - loc.around[j - 1].angle <= kAngleTie) ++j;
            std::sort(loc.around.begin() + i, loc.around.begin() + j, [](const Member& x, const Member& y) {
              return x.s < y.s || (x.s == y.s && x.patch < y.patch);
            });
            i = j;
          }
          const size_t K = loc.around.size();
          for (size_t i = 0; i < K; ++i) {
            const Member &a = loc.around[i], &b = loc.around[(i + 1) % K];
            loc.joins.emplace_back(2 * a.patch + (a.s > 0 ? 0 : 1), 2 * b.patch + (b.s < 0 ? 0 : 1));
          }
        }
      }
    });
    for (const Local& l : locals)
      for (const auto& [x, y] : l.joins) sides.join(x, y);
  }
  std::vector<int>().swap(partner);
  std::vector<std::pair<int, int>>().swap(pairs);

  // 4. A boundary surface's faces with one side on it (not both: a panel with the same region on either side)
  // form a closed surface mod 2. Numbered by their first side; a face belongs to the surfaces of its two sides
  // when they differ.
  std::vector<std::array<int, 2>> surf(static_cast<size_t>(n), {-1, -1});
  int nsurf = 0;
  {
    std::vector<int> id(size_t(2) * n, -1);
    for (int p = 0; p < n; ++p) {
      const int f = sides.find(2 * p), b = sides.find(2 * p + 1);
      if (f == b) continue;
      for (int k = 0; k < 2; ++k) {
        const int root = k == 0 ? f : b;
        if (id[root] < 0) id[root] = nsurf++;
        surf[p][k] = id[root];
      }
    }
  }
  for (int p = 0; p < n; ++p) out.surface_patches += surf[p][0] >= 0;
  out.surfaces = nsurf;
  if (nsurf == 0) {
    out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return out;
  }
  auto on_surface = [&](int p) { return surf[p][0] >= 0; };
  auto share_surface = [&](int p, int q) {
    for (int a : surf[p])
      if (a >= 0 && (a == surf[q][0] || a == surf[q][1])) return true;
    return false;
  };

  // 5. Patches crossing a patch of a surface (an edge of one through the other, both ends more than eps off its
  // plane), or touched inside by a surface's edge: the front of either lies on both sides of some surface, so both
  // get cell -1.
  Scene tris(dev.d);
  std::vector<int> tri_patch;
  add_patch_triangles(dev.d, tris.s, g, {}, centre, tri_patch);
  rtcCommitScene(tris.s);
  std::vector<std::uint8_t> crossed(static_cast<size_t>(n), 0);
  {
    tbb::enumerable_thread_specific<std::vector<unsigned>> hits_local;
    tbb::enumerable_thread_specific<std::vector<int>> cross_local;
    tbb::parallel_for(tbb::blocked_range<int>(0, nc, 1024), [&](const tbb::blocked_range<int>& range) {
      std::vector<unsigned>& hits = hits_local.local();
      std::vector<int>& cr = cross_local.local();
      for (int e = range.begin(); e < range.end(); ++e) {
        const int pe = patch_of[e];
        const Vec3 &A = g.points[e], &B = g.points[next(e)];
        const double L = (B - A).norm();
        if (!(L > 2 * eps)) continue;
        const Vec3 u = (B - A) / L;
        hits.clear();
        tris.all_hits(A - centre, u, 0.0, L, hits);
        for (unsigned& h : hits) h = unsigned(tri_patch[h]);
        std::sort(hits.begin(), hits.end());
        hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
        for (unsigned h : hits) {
          const int q = int(h);
          if (q == pe || (!on_surface(pe) && !on_surface(q))) continue;
          const Vec3& nq = g.normal[q];
          const double ha = nq.dot(A - g.centroid[q]), hb = nq.dot(B - g.centroid[q]);
          if (!(ha * hb < 0) || std::min(std::abs(ha), std::abs(hb)) <= eps) continue;
          const Vec3 y = A + (ha / (ha - hb)) * (B - A);
          // Through the interior, or through the boundary (a seam between two of the surface's patches): crossed.
          // Not through the boundary of a patch of its own surface: there two patches of one surface meet (a floor's
          // edge along a wall's base passes the corner of a door jamb standing on it), nothing crosses.
          const int side = polygon_side(g.polygon(q), nq, y, eps);
          if (side > 0 || (side == 0 && !share_surface(pe, q))) cr.push_back(pe), cr.push_back(q);
        }
        // Contact inside a patch (a box standing on a floor that was not split where it stands): a surface's edge
        // lying in a patch's plane and inside it splits that patch's front. Probes at a quarter, half and three
        // quarters of each edge of each surface patch, with two short rays perpendicular to the edge (one of them
        // meets any plane through the edge at 45 degrees or more).
        if (!on_surface(pe)) continue;
        const Vec3 dirs[2] = {g.normal[pe], g.normal[pe].cross(u)};
        for (double f : {0.25, 0.5, 0.75}) {
          const Vec3 v = A + f * (B - A);
          for (const Vec3& d : dirs) {
            hits.clear();
            tris.all_hits(v - centre - 2 * eps * d, d, 0.0, 4 * eps, hits);
                for (unsigned h : hits) {
              const int q = tri_patch[h];
              if (q == pe) continue;
              const Vec3& nq = g.normal[q];
              const double hv = nq.dot(v - g.centroid[q]);
              if (std::abs(hv) > 2 * eps) continue;
              if (polygon_side(g.polygon(q), nq, v - hv * nq, eps) > 0) cr.push_back(q);
            }
          }
        }
      }
    });
    for (const auto& c : cross_local)
      for (int p : c) crossed[size_t(p)] = 1;
  }
  for (int p = 0; p < n; ++p) out.crossed += crossed[p];

  // 6. The side of each surface on which each patch's front lies: parity of the crossings of a ray from a point
  // just in front of the patch, for the surfaces whose box holds that point (outside the box: outside).
  const int nkept = nsurf;
  std::vector<Eigen::AlignedBox3d> cbox(static_cast<size_t>(nkept));
  for (int p = 0; p < n; ++p)
    for (int c : surf[p])
      if (c >= 0)
        for (const Vec3& v : g.polygon(p)) cbox[c].extend(v);
  for (auto& b : cbox) b = Eigen::AlignedBox3d(b.min().array() - eps, b.max().array() + eps);
  // A uniform grid over the scene's box lists the surfaces whose box meets each cell.
  const int G = std::clamp(int(std::lround(std::cbrt(double(nkept)))), 1, 64);
  const Vec3 glo = box.min().array() - eps, gsz = (box.max() - box.min()).array() + 2 * eps;
  auto cell_of = [&](double x, int a) { return std::clamp(int((x - glo[a]) / gsz[a] * G), 0, G - 1); };
  std::vector<std::vector<int>> grid(size_t(G) * G * G);
  for (int c = 0; c < nkept; ++c) {
    const Vec3 &lo = cbox[c].min(), &hi = cbox[c].max();
    for (int i = cell_of(lo.x(), 0); i <= cell_of(hi.x(), 0); ++i)
      for (int j = cell_of(lo.y(), 1); j <= cell_of(hi.y(), 1); ++j)
        for (int k = cell_of(lo.z(), 2); k <= cell_of(hi.z(), 2); ++k) grid[(size_t(i) * G + j) * G + k].push_back(c);
  }
  std::vector<std::vector<int>> sig(static_cast<size_t>(n));
  std::vector<std::uint8_t> unknown(size_t(n), 0);
  {
    struct Local {
      std::vector<unsigned> hits;
      std::vector<int> rel, parity;
    };
    tbb::enumerable_thread_specific<Local> locals;
    tbb::parallel_for(tbb::blocked_range<int>(0, n, 256), [&](const tbb::blocked_range<int>& range) {
      Local& loc = locals.local();
      for (int p = range.begin(); p < range.end(); ++p) {
        // A point inside the patch: the centroid of its largest triangle, then 4 eps in front.
        double best = -1;
        Vec3 ip = g.centroid[p];
        for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
          const auto& T = g.triangles[t];
          const Vec3 &a = g.points[T[0]], &b = g.points[T[1]], &c = g.points[T[2]];
          const double ar = (b - a).cross(c - a).norm();
          if (ar > best) best = ar, ip = (a + b + c) / 3;
        }
        const Vec3 x = ip + 4 * eps * g.normal[p];
        loc.rel.clear();
        for (int c : grid[(size_t(cell_of(x.x(), 0)) * G + cell_of(x.y(), 1)) * G + cell_of(x.z(), 2)])
          if (cbox[c].contains(x)) loc.rel.push_back(c);
        if (crossed[p]) {
          unknown[p] = 1;
          continue;
        }
        if (loc.rel.empty()) continue;
        bool decided = false;
        for (int attempt = 0; attempt < 8 && !decided; ++attempt) {
          const std::uint64_t s = splitmix64(std::uint64_t(p) * 8 + std::uint64_t(attempt));
          Vec3 v(double(s & 0xFFFFF), double((s >> 20) & 0xFFFFF), double((s >> 40) & 0xFFFFF));
          v = v / double(0xFFFFF) * 2 - Vec3::Ones();
          if (!(v.norm() > 0.1)) continue;
          const Vec3 d = (v.normalized() + 1.2 * g.normal[p]).normalized();  // into the front half space
          double tfar = 0;
          for (int c : loc.rel) {  // where the ray leaves the surfaces' boxes
            double exit = INFINITY;
            for (int a = 0; a < 3; ++a)
              if (d[a] != 0) exit = std::min(exit, ((d[a] > 0 ? cbox[c].max()[a] : cbox[c].min()[a]) - x[a]) / d[a]);
            tfar = std::max(tfar, exit);
          }
          loc.hits.clear();
          tris.all_hits(x - centre, d, 0.0, tfar + eps, loc.hits);
            for (unsigned& h : loc.hits) h = unsigned(tri_patch[h]);
          std::sort(loc.hits.begin(), loc.hits.end());
          loc.hits.erase(std::unique(loc.hits.begin(), loc.hits.end()), loc.hits.end());
          loc.parity.assign(loc.rel.size(), 0);
          bool ambiguous = false;
          for (unsigned h : loc.hits) {
            const int q = int(h);
            if (!on_surface(q)) continue;
            const auto i0 = std::find(loc.rel.begin(), loc.rel.end(), surf[q][0]);
            const auto i1 = std::find(loc.rel.begin(), loc.rel.end(), surf[q][1]);
            if (i0 == loc.rel.end() && i1 == loc.rel.end()) continue;
            const Vec3& nq = g.normal[q];
            const double hq = nq.dot(x - g.centroid[q]), dd = nq.dot(d);
            if (std::abs(dd) < 0.02) {  // grazing: the crossing point is not well defined
              ambiguous = true;
              break;
            }
            const double t = -hq / dd;
            if (t < eps) {
              if (t > -eps) ambiguous = true;
              if (ambiguous) break;
              continue;
            }
            const int side = polygon_side(g.polygon(q), nq, x + t * d, eps);
            if (side == 0) {
              ambiguous = true;
              break;
            }
            if (side > 0)
              for (auto it : {i0, i1})
                if (it != loc.rel.end()) loc.parity[size_t(it - loc.rel.begin())] ^= 1;
          }
          if (ambiguous) continue;
          decided = true;
          for (size_t k = 0; k < loc.rel.size(); ++k)
            if (loc.parity[k]) sig[p].push_back(loc.rel[k]);
          std::sort(sig[p].begin(), sig[p].end());
        }
        if (!decided) unknown[p] = 1;
      }
    });
  }
  // 7. Cells: distinct sets of surfaces a patch's front lies inside, numbered in patch order.
  std::map<std::vector<int>, int> ids;
  for (int p = 0; p < n; ++p) {
    if (unknown[p]) {
      out.cell[p] = -1;
      ++out.unknown;
      continue;
    }
    const auto [it, fresh] = ids.emplace(std::move(sig[p]), int(ids.size()));
    out.cell[p] = it->second;
  }
  out.cells = int(ids.size());
  out.cell_surfaces.resize(ids.size());
  for (const auto& [key, id] : ids) out.cell_surfaces[size_t(id)] = key;
  out.surfaces_of = std::move(surf);
  out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return out;
}

Enclosures find_enclosures(const mesh::PatchGeometry& g) {
  Eigen::AlignedBox3d box;
  for (const Vec3& v : g.points) box.extend(v);
  return find_enclosures(g, box.isEmpty() ? 0.0 : kEnclosureEps * box.diagonal().norm());
}

}  // namespace lambert::formfactor::detail

namespace lambert::formfactor {

std::vector<char> enclosed_patches(const mesh::PatchGeometry& geometry) {
  const detail::Enclosures e = detail::find_enclosures(geometry);
  std::vector<char> out(size_t(geometry.size()), 0);
  if (e.cell.size() != out.size()) return out;
  for (int p = 0; p < geometry.size(); ++p) {
    const int c = e.cell[size_t(p)];
    out[size_t(p)] = c >= 0 && size_t(c) < e.cell_surfaces.size() && !e.cell_surfaces[size_t(c)].empty();
  }
  return out;
}

}  // namespace lambert::formfactor
