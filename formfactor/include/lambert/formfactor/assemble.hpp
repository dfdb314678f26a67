#pragma once
// Dense assembly of all patch-to-patch form factors F_ij (dimensionless), with visibility.
//
// Accuracy. `tolerance` bounds the absolute error of every unoccluded F_ij, and of F_ji, which reciprocity
// gives from it (each pair is integrated once, from its smaller patch, so F_ji's error is at most F_ij's).
// A pair is integrated by the cheapest method whose error estimate is <= tolerance:
//   far_field         centroid-to-centroid kernel + second-order (Hessian) terms on both patches
//   centroid_hessian  analytic point-to-polygon from the source centroid + Hessian term
//   gauss4/9/16       m x m Gauss outer rule over the source, analytic (contour) inner integral
// chosen a priori from size/distance (estimate C S r^p: S = A_t/(pi d^2), r = rho_s/d; C = 4x the worst
// ratio seen on 40,000 random pairs; on 6,000 further random pairs the largest error was 0.15 x tolerance),
//   contour           the rest: touching pairs, pairs within 2.5 source radii, pairs cutting each other's
//                     plane, pairs no rule fits: mutual clipping, then the double line integral with adaptive
//                     Gauss-Kronrod, stopped when its (conservative) error estimate is <= tolerance.
// Triangles and convex quads run in SIMD batches; other polygons take the same rules in scalar code.
// Default 1e-8: catalogue values come out within ~1e-10, every entry of a closed cube within 1e-9.
// Visibility is NOT covered by `tolerance`: the visible fraction is a ray estimate (rays_per_pair), and only
// pairs whose segments may actually be blocked are ray-tested.
// Storage: double (8 N^2 bytes), see dense.hpp.
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "lambert/formfactor/dense.hpp"
#include "lambert/formfactor/visibility.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor {

// Fixed-cost rules for accuracy/cost studies and textbook comparisons (`tolerance` is then ignored):
//   point  one point per patch: F_ij = cos_i cos_j A_j / (pi r^2) between the centroids (0 if either faces
//          away); the classic baseline, badly wrong for near and touching pairs.
//   gauss  order x order outer Gauss points on the source (the smaller patch), analytic (contour) inner
//          integral over the target, no error control; order 1 = centroid-to-polygon (what a perfect hemicube
//          converges to).
enum class Rule { Adaptive, Point, Gauss };

// Reuse of a previous assembly on a geometry sharing identical patches (adaptive refinement).
struct Reuse {
  const DenseMatrixOperator* previous = nullptr;
  // Per patch of the new geometry: index of the identical patch (same polygon, same corner order) in the
  // previous geometry, or -1 if new. Pairs of two reused patches are copied from `previous`, visibility
  // included: the caller guarantees that the rest of the scene (the occluders) is unchanged.
  std::vector<int> previous_index;
};

struct Options {
  double tolerance = 1e-8;  // absolute error bound on each unoccluded F_ij (see above); > 0
  Rule rule = Rule::Adaptive;
  int order = 1;            // Rule::Gauss: points per side of the source rule, 1..8
  const Reuse* reuse = nullptr;  // null: compute every pair
  bool visibility = true;   // false: every pair is treated as unoccluded
  int rays_per_pair = 16;   // rays R for a pair that may be occluded: R stratified points on each patch, paired by a
                            // seeded random permutation (x16 / x81 for pairs carrying >= 2% / 10% of a row)
  int threads = 0;          // 0 = all cores (or the caller's tbb::global_control); otherwise a task_arena of this size
  std::function<void(double fraction_done)> progress;  // <= ~10 calls/s, serialised, from any thread
  std::size_t max_bytes = 0;  // limit on the dense matrix; 0 = 80% of physical RAM
  // Occlusion caster; null = Embree over the potential occluders. Tests inject the brute-force one.
  std::shared_ptr<const Visibility> caster;
  bool cull_occlusion = true;  // false: ray-test every visible pair, even those shaft culling proves clear (tests)
};

struct Stats {
  // What the assembly used (Options, resolved): the rule's name (to_string), tolerance, visibility, rays.
  std::string rule = "adaptive";
  double tolerance = 0;
  bool visibility = true;
  int rays_per_pair = 0;
  int patches = 0;
  long long pairs_total = 0;               // unordered pairs i < j
  long long pairs_orientation_culled = 0;  // one is behind the other's plane (or coplanar): F = 0, no work
  long long pairs_shaft_culled = 0;        // potentially visible but proven unoccluded by shaft culling: no rays
  long long pairs_ray_tested = 0;          // visible fraction estimated with rays
  std::map<std::string, long long> pairs_by_method;  // unoccluded-integral method per computed pair
  long long rays_cast = 0;
  bool scene_can_occlude = false;  // false: no patch can block another (convex enclosure), no rays at all
  int occluders = 0;               // patches that can block something (the ray-tracing scene)
  double row_sum_min = 0, row_sum_max = 0, row_sum_mean = 0;
  double reciprocity_residual = 0;  // max |A_i F_ij - A_j F_ji| / max(A_i F_ij, A_j F_ji) over stored entries
  long long entries_outside_unit = 0;  // F_ij < 0 or > 1 (never clamped); must be 0
  long long pairs_over_tolerance = 0;  // adaptive integration stopped (interval limit) above the tolerance
  long long pairs_reused = 0;          // copied from Options::reuse (not computed, no rays)
  // "setup", "bvh", "form_factors" (integration + visibility), "visibility" (its share of form_factors,
  // from thread times), "stats"
  std::map<std::string, double> seconds;
  std::size_t bytes = 0;                  // dense matrix size
};

// N x N matrix, F(i, j) from patch i to patch j, F(i, i) = 0. Throws lambert::InputError (with the needed
// and allowed bytes) before allocating if N^2 * 8 bytes exceeds max_bytes, if tolerance <= 0, if the Gauss
// order is outside 1..8, or if reuse does not match (index sizes, indices out of range or repeated).
// "adaptive", "point", "gauss1".."gauss8" <-> (rule, order); parse throws InputError naming the choices.
std::string to_string(Rule rule, int order);
void parse_rule(std::string_view text, Rule& rule, int& order);

DenseMatrixOperator assemble(const mesh::PatchGeometry& geometry, const Options& options = {}, Stats* stats = nullptr);

// Aggregation to input faces when a face was split into several patches: F_IJ = sum_{i in I} A_i sum_{j in J}
// F_ij / sum_{i in I} A_i. face_id[p] in [0, input_faces) for each patch p. Nonzero entries, sorted by (i, j).
struct FaceEntry {
  int i, j;
  double F;
};
std::vector<FaceEntry> aggregate_to_faces(const DenseMatrixOperator& F, const mesh::PatchGeometry& g,
                                          const std::vector<int>& face_id, int input_faces);

}  // namespace lambert::formfactor
