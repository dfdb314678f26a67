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
  std::vector<double> seg, tris;  // the direct test's segments (SoA) and triangles
};
struct VisibleRatio {
  double ratio = 0;    // estimated visible fraction of the unoccluded F_st, in [0, 1]
  double sigma = 0;    // its standard error (plain-sampling formula, see Stats::row_visibility_sigma)
  long long rays = 0;  // rays cast
  bool no_sample = false;  // no sample pair faced each other: ratio 0
};
// The visible fraction of the pair (s, t) from R rays between R stratified points on each patch. occluders, if
// given: every patch that can meet a segment between s and t (OccluderTree::collect on the pair's shaft); the
// segments are then tested against their triangles directly, in double precision (segments_hidden in batch.hpp),
// instead of by the caster (a single-precision BVH over the whole scene).
// Up to this many occluders in a pair's shaft, its rays are tested against them directly (visible_ratio); past it
// the caster's BVH is faster.
constexpr size_t kDirectOccluders = 64;
VisibleRatio visible_ratio(const mesh::PatchGeometry& g, const PatchData& P, const Visibility& caster, int s, int t,
                           int R, SampleBuffers& b, const std::vector<int>* occluders = nullptr);
// hidden[k] = 1 if the open segment from[k] -> to[k] meets a triangle of the patches `occluders`, else 0 (double
// precision; the caller has excluded the patches the segments start and end on and those in their planes).
void segments_hidden(const mesh::PatchGeometry& g, std::span<const int> occluders, std::span<const Vec3> from,
                     std::span<const Vec3> to, SampleBuffers& b, std::span<std::uint8_t> hidden);

}  // namespace lambert::formfactor::detail
