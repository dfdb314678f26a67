// Ray sampling for the visible fraction of a patch pair: stratified points on both patches, paired.
#include "sampling.hpp"

#include <algorithm>
#include <cmath>

namespace lambert::formfactor::detail {
namespace {

double jitter(std::uint64_t seed, int k) {  // in [0.05, 0.95]: samples stay inside their stratum
  return 0.05 + 0.9 * double(mix(seed + std::uint64_t(k)) >> 11) * 0x1.0p-53;
}

// True if some corner of patch a lies behind the plane of patch b by more than eps. eps is the scene's
// (P.scene_eps, 1e-10 of its size, as the form-factor pairs decide straddling), not 1e-12 of the patches' size:
// corners of a block standing on a floor lie on the floor's plane only to the rounding of the file's coordinates
// (~1e-10 m at 1e6 m), so with the tighter margin such pairs were sampled as straddling or not depending on where
// the model sat (CornellBox-Original.obj moved by (1e6, 2e6, 0) m: 6 pairs sampled otherwise, an entry 1 % off).
bool behind_plane(const mesh::PatchGeometry& g, int a, int b, double eps) {
  const Vec3& n = g.normal[b];
  const double offset = n.dot(g.centroid[b]);
  for (const Vec3& p : g.polygon(a))
    if (n.dot(p) - offset < -eps) return true;
  return false;
}

}  // namespace

void sample_patch(const mesh::PatchGeometry& g, const PatchData& P, int p, int k1, int k2, std::uint64_t seed,
                  std::vector<Vec3>& out) {
  out.clear();
  const auto poly = g.polygon(p);
  const int n = k1 * k2;
  // Parallelograms: the bilinear map, whose Jacobian is constant (uniform in area). Not for other convex quads:
  // there it is not, and a trapezoid 8 times wider at one end than the other (a leg face cut by the floor)
  // had its narrow end sampled 8 times too densely; they take the area-weighted triangles below.
  if (P.kind[p] == 1) {
    for (int a = 0; a < k1; ++a)
      for (int b = 0; b < k2; ++b) {
        const int k = a * k2 + b;
        const double s = (a + jitter(seed, 2 * k)) / k1, t = (b + jitter(seed, 2 * k + 1)) / k2;
        out.push_back((1 - s) * (1 - t) * poly[0] + s * (1 - t) * poly[1] + s * t * poly[2] + (1 - s) * t * poly[3]);
      }
    return;
  }
  // Triangles of the patch by cumulative area; within a triangle, the square-to-triangle map. Both of its
  // coordinates are stratified: u (cumulative area) in n strata, v (across the triangle, from T[1]'s side to
  // T[2]'s) in k2 strata, each run of k2 consecutive u strata taking every v stratum once (a k1 x k2 grid of
  // equal-area strata). An unstratified v jittered in [0.05, 0.95] never sampled the wedges along the edges
  // T[0]T[1] and T[0]T[2] (5 % of the area each): on a sliver whose short edge touches an occluder, the shadow
  // there was missed and the visible fraction biased high, at any number of rays.
  const int t0 = g.triangle_offsets[p], t1 = g.triangle_offsets[p + 1];
  if (t1 - t0 == 1) {  // one triangle (most patches of imported meshes): u / area directly, no areas to add up
    const auto& T = g.triangles[t0];
    const Vec3 &A = g.points[T[0]], &B = g.points[T[1]], &C = g.points[T[2]];
    const double inv_n = 1.0 / n, inv_k2 = 1.0 / k2;
    for (int a = 0; a < k1; ++a)
      for (int b = 0; b < k2; ++b) {
        const int k = a * k2 + b;
        const double su = std::sqrt(std::min((k + jitter(seed, 2 * k)) * inv_n, 1.0));
        const double v = (b + jitter(seed, 2 * k + 1)) * inv_k2;
        out.push_back((1 - su) * A + su * (1 - v) * B + su * v * C);
      }
    return;
  }
  thread_local std::vector<double> areas;  // the triangles' areas, once per call (not per sample)
  areas.clear();
  for (int t = t0; t < t1; ++t) {
    const auto& T = g.triangles[t];
    areas.push_back(0.5 * (g.points[T[1]] - g.points[T[0]]).cross(g.points[T[2]] - g.points[T[0]]).norm());
  }
  for (int a = 0; a < k1; ++a)
    for (int b = 0; b < k2; ++b) {
      const int k = a * k2 + b;
      double u = (k + jitter(seed, 2 * k)) / n * P.area[p];
      int t = t0;
      double at = 0;
      for (; t < t1; ++t) {
        at = areas[size_t(t - t0)];
        if (u <= at || t == t1 - 1) break;
        u -= at;
      }
      const double su = std::sqrt(std::clamp(u / at, 0.0, 1.0)), v = (b + jitter(seed, 2 * k + 1)) / k2;
      const auto& T = g.triangles[t];
      out.push_back((1 - su) * g.points[T[0]] + su * (1 - v) * g.points[T[1]] + su * v * g.points[T[2]]);
    }
}

void sample_polygon(std::span<const Vec3> poly, const Vec3& normal, int n, std::uint64_t seed, std::vector<Vec3>& out) {
  out.clear();
  std::vector<std::array<int, 3>> tris = mesh::triangulate_polygon(poly, normal);
  if (tris.empty())  // a clipped non-convex patch with bridge edges: fan, weighted by unsigned area
    for (int k = 1; k + 1 < int(poly.size()); ++k) tris.push_back({0, k, k + 1});
  std::vector<double> area(tris.size());
  double total = 0;
  for (size_t t = 0; t < tris.size(); ++t) {
    const auto& T = tris[t];
    area[t] = 0.5 * (poly[T[1]] - poly[T[0]]).cross(poly[T[2]] - poly[T[0]]).norm();
    total += area[t];
  }
  if (!(total > 0)) return;
  // u (cumulative area) in n strata, v in k2 strata swept by each run of k2 consecutive u strata (as in
  // sample_patch: an unstratified v misses the wedges along two edges of every triangle).
  const int k2 = std::max(1, int(std::floor(std::sqrt(double(n)))));
  for (int k = 0; k < n; ++k) {
    double u = (k + jitter(seed, 2 * k)) / n * total;
    size_t t = 0;
    for (; t + 1 < tris.size() && u > area[t]; ++t) u -= area[t];
    const double su = std::sqrt(std::clamp(area[t] > 0 ? u / area[t] : 0.0, 0.0, 1.0)),
                 v = (k % k2 + jitter(seed, 2 * k + 1)) / k2;
    const auto& T = tris[t];
    out.push_back((1 - su) * poly[T[0]] + su * (1 - v) * poly[T[1]] + su * v * poly[T[2]]);
  }
}

int rays_for_share(int R, double share) {
  if (share >= 0.1) return 81 * R;
  if (share >= 0.02) return 16 * R;
  if (share < 1.0 / (64.0 * R)) return std::max(1, R / 4);
  return R;
}

VisibleRatio visible_ratio(const mesh::PatchGeometry& g, const PatchData& P, const Visibility& caster, int s, int t,
                           int R, SampleBuffers& b) {
  // R rays between R stratified points on each patch, paired by a random permutation ("padding"): every
  // ray has its own source and target stratum, so both patches are sampled R-fold, not sqrt(R)-fold as
  // with all pairs of sqrt(R) points per side (same rays, several times smaller error on shadow edges).
  VisibleRatio res;
  int k1 = std::max(1, int(std::floor(std::sqrt(double(R))))), k2 = std::max(1, R / k1);
  const std::uint64_t seed = mix(std::uint64_t(s) * 0x100000001ull + std::uint64_t(t));
  const Vec3 &ns = g.normal[s], &nt = g.normal[t];
  // Patches crossing each other's planes exchange light only between the parts in front of each other:
  // sample those parts, or a thin visible strip may get no sample at all (and a pair seen through a wall
  // would be taken as unoccluded).
  const double eps = P.scene_eps;
  const bool straddle = behind_plane(g, s, t, eps) || behind_plane(g, t, s, eps);
  if (straddle) {
    std::vector<Vec3> ps, pt;
    clip_front(g.polygon(s), nt, nt.dot(g.centroid[t]), eps, ps);
    clip_front(g.polygon(t), ns, ns.dot(g.centroid[s]), eps, pt);
    sample_polygon(ps, ns, k1 * k2, seed, b.xs);
    sample_polygon(pt, nt, k1 * k2, mix(seed), b.ys);
  } else {
    sample_patch(g, P, s, k1, k2, seed, b.xs);
    sample_patch(g, P, t, k1, k2, mix(seed), b.ys);
  }
  // Pairing: a seeded Fisher-Yates permutation of the target points.
  const size_t count = std::min(b.xs.size(), b.ys.size());
  for (size_t k = count; k > 1; --k) std::swap(b.ys[k - 1], b.ys[mix(seed + 7 * k) % k]);
  // Rays between stratified points of the two patches; each sample pair is weighted by the kernel
  // cos cos / r^2, so the ratio estimates int int K V / int int K. Pairs of points that do not see each
  // other's front (straddling patches) carry no weight and cast no ray.
  b.from.clear();
  b.to.clear();
  b.fx.clear();
  for (size_t k = 0; k < count; ++k) {
    const Vec3 &x = b.xs[k], &y = b.ys[k], d = y - x;
    const double cx = ns.dot(d), cy = -nt.dot(d);
    if (!(cx > 0 && cy > 0)) continue;
    const double r2 = d.squaredNorm();
    b.from.push_back(x);
    b.to.push_back(y);
    b.fx.push_back(cx * cy / (r2 * r2));
  }
  b.hidden.assign(b.from.size(), 0);
  if (!b.from.empty()) caster.occluded(b.from, b.to, s, t, b.hidden);
  res.rays = (long long)b.from.size();
  double num = 0, den = 0;
  for (size_t k = 0; k < b.from.size(); ++k) {
    den += b.fx[k];
    if (!b.hidden[k]) num += b.fx[k];
  }
  // No sample pair sees the other even after clipping: the parts in front of each other have (numerically)
  // no area, so nothing is exchanged. Never 1 here: that let light through walls (a leak).
  if (!(den > 0)) {
    res.no_sample = true;
    return res;
  }
  res.ratio = num / den;  // <= 1: num sums a subset of den's non-negative terms in the same order
  // Standard error of the weighted ratio estimate (plain sampling; stratification only makes it smaller).
  if (res.ratio > 0 && res.ratio < 1) {
    double var = 0;
    for (size_t k = 0; k < b.from.size(); ++k) {
      const double dv = (b.hidden[k] ? 0.0 : 1.0) - res.ratio;
      var += b.fx[k] * b.fx[k] * dv * dv;
    }
    res.sigma = std::sqrt(var) / den;
  }
  return res;
}

}  // namespace lambert::formfactor::detail
