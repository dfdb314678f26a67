#pragma once
// Ray sampling for the visible fraction of a patch pair (internal).
#include <cstdint>
#include <span>
#include <vector>

#include "internal.hpp"
#include "lambert/formfactor/visibility.hpp"

namespace lambert::formfactor::detail {

inline std::uint64_t mix(std::uint64_t x) { return splitmix64(x); }

// n = k1 k2 stratified points on patch p, uniform in area: a k1 x k2 grid of equal-area strata, jittered inside
// each stratum, so no point lies on the patch boundary. Parallelograms through their bilinear map; triangles,
// other convex quads and polygons through their triangles by cumulative area (both coordinates stratified).
void sample_patch(const mesh::PatchGeometry& g, const PatchData& P, int p, int k1, int k2, std::uint64_t seed,
                  std::vector<Vec3>& out);
// n stratified points on a planar polygon with unit normal `normal` (the part of a patch in front of another
// patch's plane): triangles by cumulative area, the square-to-triangle map inside each (both coordinates
// stratified).
void sample_polygon(std::span<const Vec3> poly, const Vec3& normal, int n, std::uint64_t seed, std::vector<Vec3>& out);

struct SampleBuffers {
  std::vector<Vec3> xs, ys, from, to;
  std::vector<std::uint8_t> hidden;
  std::vector<double> fx;
};
struct VisibleRatio {
  double ratio = 0;    // estimated visible fraction of the unoccluded F_st, in [0, 1]
  double sigma = 0;    // its standard error (plain-sampling formula, see Stats::row_visibility_sigma)
  long long rays = 0;  // rays cast
  bool no_sample = false;  // no sample pair faced each other: ratio 0
};
// Rays for a pair that may be partly hidden and carries `share` of a row (max(F_st, F_ts), the larger of its two
// entries), for R rays asked per pair (--rays). Its ray error adds to its rows' in quadrature, weighted by the entry:
// pairs carrying >= 2 % / >= 10 % of a row get 16x / 81x R (2 and 3 times the points per side), and pairs carrying
// less than 1 / (64 R) of it get max(1, R / 4): on the 10k generated building those held 56 % of the leaf pairs' rays
// and 1.4 % of their variance (4.3 % with a quarter of the rays). Together they add at most 1 / (8 R) to a row's
// visibility sigma (the sum of F^2 / (4 n) over entries below 1 / (64 R) whose sum is at most 1), 7.8e-3 at R = 16.
int rays_for_share(int R, double share);
// The visible fraction of the pair (s, t) from R rays between R stratified points on each patch.
VisibleRatio visible_ratio(const mesh::PatchGeometry& g, const PatchData& P, const Visibility& caster, int s, int t,
                           int R, SampleBuffers& b);

}  // namespace lambert::formfactor::detail
