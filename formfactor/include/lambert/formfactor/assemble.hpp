#pragma once
// Dense assembly of all patch-to-patch form factors F_ij (dimensionless), with visibility.
//
// Accuracy. `tolerance` bounds the absolute error of every unoccluded F_ij, and of F_ji, which reciprocity
// gives from it (each pair is integrated once, from its smaller patch, so F_ji's error is at most F_ij's).
// A pair is integrated by the cheapest method whose error estimate is <= tolerance:
//   far_field         centroid-to-centroid kernel + second-order (Hessian) terms on both patches
//   centroid_hessian  analytic point-to-polygon from the source centroid + Hessian term
//   gauss4/9/16/36/64 m x m Gauss outer rule over the source, analytic (contour) inner integral
// chosen a priori from size/distance (estimate C S r^p: S = A_t/(pi d^2), r = R_s/d with R_s the source's
// circumradius; C = 4x the worst ratio seen on 40,000 random pairs; src/tiers.hpp, one implementation for the
// scalar and SIMD paths),
//   contour           the rest: touching pairs, pairs closer than 2 source radii (source centroid to the
//                     target's bounding sphere), pairs cutting each other's
//                     plane, pairs no rule fits: mutual clipping, then the double line integral with adaptive
//                     Gauss-Kronrod, stopped when its (conservative) error estimate is <= tolerance.
// Triangles and convex quads run in SIMD batches; other polygons take the same rules in scalar code.
// The far-field tiers' errors have one sign along a row, so a row sum's error grows with the number of such
// entries; the solve amplifies a row-sum error delta to a radiance error of about rho delta / (1 - rho)
// (docs/physics.md). Hence the automatic tolerance (Options::tolerance = 0) follows the scene's largest
// reflectance: default_tolerance() below. Measured errors and costs: docs/benchmarks.md, docs/accuracy.md.
// Visibility (only for pairs whose segments may actually be blocked, after shaft culling) is computed per pair
// by one of two paths (Options::visibility_method):
//   exact  occluders between the pair (from the occluder tree) are culled against the convex hull of the two
//          patches; a pair none reaches is unoccluded, a pair one convex occluder separates completely is
//          hidden; otherwise, at each point x of an adaptive outer rule on the source, the occluders are
//          clipped to the cone from x through the target, projected on the target's plane, united (Clipper,
//          integer coordinates) and the union's contour integral is the hidden part of F(x -> target). The
//          outer rule (an embedded degree-7/5 rule per element, bisected where the two differ most) refines until
//          the hidden part's estimated error is <= tolerance: occluded pairs meet the unoccluded entries' tolerance.
//   rays   the visible fraction is a ray estimate (rays_per_pair), Stats::row_visibility_sigma its error.
// auto takes the exact path, except for pairs whose unoccluded F (either direction) is at most the tolerance,
// where any visible fraction is within the tolerance: those take the rays.
// What each assembly admits (per-row error bounds, an independent reciprocity check, entries outside [0, 1])
// is reported in Stats; check.hpp checks row sums independently with rays.
// Storage: double (8 N^2 bytes), see dense.hpp.
#include <cstdint>
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

// How partially occluded pairs get their visible part (see above). "auto", "exact", "rays" (to_string/parse).
enum class VisibilityMethod { Auto, Exact, Rays };
std::string to_string(VisibilityMethod m);
VisibilityMethod parse_visibility_method(std::string_view text);  // throws InputError naming the choices

// Reuse of a previous assembly on a geometry sharing identical patches (adaptive refinement).
struct Reuse {
  const DenseMatrixOperator* previous = nullptr;
  // Per patch of the new geometry: index of the identical patch (same polygon, same corner order) in the
  // previous geometry, or -1 if new. Pairs of two reused patches are copied from `previous`, visibility
  // included: the caller guarantees that the rest of the scene (the occluders) is unchanged.
  std::vector<int> previous_index;
  // Per patch of the previous geometry: its row's visibility standard error and integration bound as that assembly
  // reported them (Stats::row_visibility_sigma, row_error_bound), or empty. A reused patch's row adds them as a
  // bound on what its copied pairs carry (they are part of that row): without them a refined scene's rows had no
  // sigma for their copied ray estimates, and the row-sum check failed right rows.
  std::vector<double> previous_row_sigma, previous_row_bound;
};

struct Options {
  // Absolute error bound on each unoccluded F_ij (see above); > 0, or 0 = automatic: default_tolerance(
  // max_reflectance) (Stats::tolerance reports the value used).
  double tolerance = 0;
  // Largest reflectance of the scene over patches and colour channels, in [0, 1); < 0 = unknown (then the
  // automatic tolerance is that of max_reflectance <= 0.9). Only the automatic tolerance uses it.
  double max_reflectance = -1;
  Rule rule = Rule::Adaptive;
  int order = 1;            // Rule::Gauss: points per side of the source rule, 1..8
  const Reuse* reuse = nullptr;  // null: compute every pair
  bool visibility = true;   // false: every pair is treated as unoccluded
  // exact, rays or auto (see above). Default rays: the exact path is ~100x the cost of a 16-ray estimate per pair
  // (docs/benchmarks.md, "Exact visibility"), too slow to be the default yet.
  VisibilityMethod visibility_method = VisibilityMethod::Rays;
  int rays_per_pair = 16;   // rays R for a pair that may be occluded: R stratified points on each patch, paired by a
                            // seeded random permutation (x16 / x81 for pairs carrying >= 2% / 10% of a row)
  int threads = 0;          // 0 = all cores (or the caller's tbb::global_control); otherwise a task_arena of this size
  std::function<void(double fraction_done)> progress;  // <= ~10 calls/s, serialised, from any thread
  std::size_t max_bytes = 0;  // limit on the dense matrix; 0 = 80% of physical RAM
  // Occlusion caster; null = Embree over the potential occluders. Tests inject the brute-force one.
  std::shared_ptr<const Visibility> caster;
  bool cull_occlusion = true;  // false: ray-test every visible pair, even those shaft culling proves clear (tests)
  // Closed surfaces (rooms, apartments, shut boxes) split space into cells; pairs whose patches face different cells
  // are zero without rays (as HierarchyOptions::enclosures).
  bool enclosures = true;
  // With enclosures: openings closed by portals split the closed surfaces into rooms (as HierarchyOptions::portals);
  // pairs in different rooms whose shaft meets no portal between them are zero without rays.
  bool portals = true;
  // Independent reciprocity check (Stats::reciprocity_*): about this many sampled pairs per method; 0 = off.
  int reciprocity_samples = 40;
  // Fault injection, for the tests of the checks only: every unoccluded F computed by the method named here
  // ("far_field", "gauss9", "contour", ...; see Stats::pairs_by_method) is multiplied by (1 + fault_relative),
  // in both directions. Empty = none.
  std::string fault_method;
  double fault_relative = 0;
};

// The automatic form-factor tolerance for a scene whose largest reflectance is max_reflectance (< 0 =
// unknown, taken as 0.9). A per-entry error that has one sign along a row (the far-field tiers' do) adds up to
// a row-sum error delta, which the solve amplifies to a radiance error of about rho delta / (1 - rho)
// (docs/physics.md); the tolerance therefore shrinks with 1 - rho above 0.9 and stays at 1e-8 below.
// The formula and its measured effect are in docs/benchmarks.md ("Default form-factor tolerance").
double default_tolerance(double max_reflectance);

// Rows that sum above 1 by more than their admitted error, error[i] + k sigma[i] + 1e-11 (summation round-off;
// k = 3 + sqrt(2 ln N), N rows: the largest of N rows' ray noise is about sqrt(2 ln N) sigma). No patch sees more
// than its whole hemisphere (first-hit visibility; glazing is opaque here), so such a row proves an error beyond the
// stated bounds, in any scene, open or closed.
struct RowsAboveOne {
  long long rows = 0;        // rows beyond their admitted error
  double max_ratio = 0;      // largest (row sum - 1) / admitted error over the rows above 1 (0 if none; <= 1: all fine)
  int worst_patch = -1;      // its row (-1 if no row is above 1)
  double worst_row_sum = 0, worst_allowed = 0;  // its sum and admitted error
};

struct Stats {
  // What the assembly used (Options, resolved): the rule's name (to_string), the per-entry tolerance
  // (Options::tolerance or the automatic one), visibility, rays per pair.
  std::string rule = "adaptive";
  double tolerance = 0;
  bool visibility = true;
  int rays_per_pair = 0;
  int patches = 0;
  long long pairs_total = 0;               // unordered pairs i < j
  long long pairs_orientation_culled = 0;  // one is behind the other's plane (or coplanar): F = 0, no work
  long long pairs_shaft_culled = 0;        // potentially visible but proven unoccluded by shaft culling: no rays
  long long pairs_ray_tested = 0;          // visible fraction estimated with rays
  std::string visibility_method = "rays";  // Options::visibility_method
  // Exact path (pairs not shaft-culled that took it): proven clear by the convex-hull test, proven hidden by one
  // occluder, integrated by the adaptive outer rule (its point evaluations, pairs stopped above tolerance).
  long long pairs_exact_clear = 0, pairs_exact_hidden = 0, pairs_exact_integrated = 0;
  long long exact_points = 0, pairs_exact_over_tolerance = 0;
  // Pairs proven hidden by a separating plane (a wall or slab of occluders covering every segment between them,
  // both paths: whole 8 x 8 sub-tiles, and single pairs on the exact path), and the proofs tried.
  long long pairs_plane_hidden = 0, plane_tests = 0;
  // Closed surfaces found (Options::enclosures), the cells they split space into, patches of no known cell, and the
  // pairs set to zero because their patches face different cells.
  int enclosures = 0, cells = 0;
  long long cell_unknown = 0, pairs_cell_hidden = 0;
  // Openings closed by portals (Options::portals), the rooms, and the pairs set to zero by them.
  long long portals = 0, rooms = 0, pairs_portal_hidden = 0;
  // Exact path: occluder patches merged with coplanar touching neighbours (a meshed wall or block face) into
  // this many polygons, one per connected region of their union.
  int occluders_merged = 0, occluder_regions = 0;
  int convex_solids = 0, convex_solid_faces = 0;  // exact path: convex solids (closed or open) among the occluders, their faces
  std::map<std::string, long long> pairs_by_method;  // unoccluded-integral method per computed pair
  long long rays_cast = 0;
  bool scene_can_occlude = false;  // false: no patch can block another (convex enclosure), no rays at all
  int occluders = 0;               // patches that can block something (the ray-tracing scene)
  double row_sum_min = 0, row_sum_max = 0, row_sum_mean = 0;
  // Rows above 1 beyond their admitted error (RowsAboveOne). Counted under the adaptive rule with visibility and no
  // reused pairs only (the fixed rules state no bound; without visibility a row counts hidden surfaces too; reused
  // pairs' bounds are not carried over).
  RowsAboveOne rows_above_one;

  // Error admitted by the assembly, per row i (dimensionless, like F). Reused pairs contribute 0.
  //   row_error_bound[i]: sum_j of the integration error bound of F_ij (the a-priori model's estimate, or the
  //     adaptive contour's error estimate; for F_ij obtained by reciprocity, the bound scaled by A_j / A_i).
  //     The unoccluded integrals' errors; a bound, not a statistical estimate. Empty for the fixed rules
  //     (point, gaussN), which carry no error estimate (then row_error_bound_max = -1).
  //   row_visibility_sigma[i]: sqrt(sum_j sigma_ij^2), sigma_ij the standard error of the ray estimate of F_ij's
  //     visible fraction times the unoccluded F_ij, sigma^2 = sum_k w_k^2 (V_k - v)^2 / (sum_k w_k)^2 over the
  //     kernel-weighted rays w_k (the plain-sampling formula: stratification makes the true error smaller;
  //     pairs whose rays all agree get 0, although a shadow missed by every ray is then not seen). Rows
  //     combined as independent errors. Zero when nothing is ray-tested.
  // A caller can state the row-sum error as delta_i <= row_error_bound[i] + k row_visibility_sigma[i] (k ~ 3),
  // and a radiance error as about rho delta / (1 - rho (1 + delta)).
  std::vector<double> row_error_bound, row_visibility_sigma;
  double row_error_bound_max = 0, row_visibility_sigma_max = 0;  // maxima over rows
  // Per row, or empty: 1 where the row was left unresolved because its patch receives nothing that matters (the
  // hierarchical operator's dark patches, HierarchyOptions::radiance_only); check_row_sums skips those rows.
  std::vector<std::uint8_t> row_unresolved;

  // Independent reciprocity check (adaptive rule only; 0 pairs for the fixed rules): on a deterministic sample
  // of computed pairs (every method represented, up to Options::reciprocity_samples each, independent of the
  // thread count), A_s F_st as assembled (s the smaller patch, the integrated direction; the unoccluded value,
  // taken before visibility: the check is on the integral, not on the ray estimate) is compared with A_t F_ts
  // integrated independently from the other patch by the adaptive double contour integral, t's edges outer
  // (to 1e-2 x the tolerance).
  long long reciprocity_check_pairs = 0;
  double reciprocity_residual = 0;      // max |A_s F_st - A_t F_ts| / max(A_s F_st, A_t F_ts) over the sample
  // max |F_st - F_ts A_t / A_s| / (error bound of F_st + the reference's error + 1e-14): <= 1 when every
  // sampled entry is within its stated bound; > 1 means some method does not meet its tolerance.
  double reciprocity_bound_ratio = 0;
  std::string reciprocity_worst_method;  // the method of the pair with the largest bound ratio
  std::map<std::string, long long> reciprocity_pairs_by_method;

  // Entries F_ij outside [0, 1] (never clamped silently):
  long long entries_roundoff = 0;      // outside by at most the entry's error bound + 1e-14: set to 0 or 1, counted
  long long entries_outside_unit = 0;  // outside by more (left as computed): untrustworthy, must be 0
  long long pairs_over_tolerance = 0;  // adaptive integration stopped (interval limit) above the tolerance;
                                       // includes pairs_exact_over_tolerance (the exact path's point limit)
  long long pairs_no_visible_sample = 0;  // ray-tested pairs where no sample pair faced each other: F set to 0
  long long pairs_reused = 0;          // copied from Options::reuse (not computed, no rays)
  // "setup", "bvh", "form_factors" (integration + visibility), "visibility" (its share of form_factors,
  // from thread times), "visibility_exact" and "visibility_rays" (the shares of the two paths in it, same
  // basis), "stats" (row sums, the reciprocity check)
  std::map<std::string, double> seconds;
  std::size_t bytes = 0;                  // dense matrix size
};

// N x N matrix, F(i, j) from patch i to patch j, F(i, i) = 0. Throws lambert::InputError (with the needed
// and allowed bytes) before allocating if N^2 * 8 bytes exceeds max_bytes, if tolerance < 0, if
// max_reflectance >= 1, if fault_method names no method, if the Gauss
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
