#pragma once
// Ray sampling for the visible fraction of a patch pair (internal).
#include <cstdint>
#include <span>
#include <vector>

#include "internal.hpp"
#include "lambert/formfactor/visibility.hpp"

namespace lambert::formfactor::detail {

std::uint64_t mix(std::uint64_t x);  // splitmix64

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
// The visible fraction of the pair (s, t) from R rays between R stratified points on each patch.
VisibleRatio visible_ratio(const mesh::PatchGeometry& g, const PatchData& P, const Visibility& caster, int s, int t,
                           int R, SampleBuffers& b);

}  // namespace lambert::formfactor::detail
