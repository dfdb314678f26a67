#pragma once
// Independent check of assembled row sums by ray casting (Embree over every patch of the scene).
//
// sum_j F_ij (with visibility) is the fraction of the energy leaving patch i (uniformly over its area,
// cosine-distributed over directions) that reaches the front side of some patch. check_row_sums estimates it
// for a sample of patches by casting cosine-weighted rays from stratified points of each and counting the rays
// whose first hit is a patch's front side (a front side within 1e-5 of the scene of a back side counts: the two
// sides of a two-sided face, split alike or not), and compares it with the assembled row sum:
//   allowed_i = k_sigma * sqrt(sigma_ray_i^2 + sigma_vis_i^2) + bound_i + 1e-4 (ray set-up: origins offset by
//   1e-6 of the scene size, single-precision rays),
// sigma_ray_i = sqrt(max(p(1 - p), 1/n) / n) the binomial standard error of the fraction p over n rays (plain
// sampling; the stratified rays' error is smaller), sigma_vis_i and bound_i = Stats::row_visibility_sigma[i]
// and Stats::row_error_bound[i] of the assembly when given. Closed and open scenes alike.
#include <cstdint>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/operator.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor {

struct RowSumCheckOptions {
  int patches = 64;           // patches sampled, evenly spaced in patch order (all if the scene has fewer)
  int rays_per_patch = 4096;  // rays per sampled patch (>= 1)
  double k_sigma = 5;         // statistical margin, in standard errors
  int threads = 0;            // 0 = all cores
};

struct RowSumCheck {
  int patches_checked = 0;
  int rows_skipped = 0;       // rows the assembly left unresolved (Stats::row_unresolved), not sampled
  long long rays = 0;
  double max_difference = 0;  // max over sampled patches of |assembled row sum - ray estimate|
  double max_ratio = 0;       // max of |difference| / allowed: <= 1 passes
  int worst_patch = -1;       // patch of max_ratio
  double worst_row_sum = 0, worst_estimate = 0, worst_allowed = 0;
  bool passed = true;         // max_ratio <= 1
};

// F: the assembled matrix (row i = patch i of geometry); stats: its assembly's Stats for the bounds, or null
// (then sigma_vis and bound are 0). Throws lambert::InputError if the sizes differ or options are invalid.
RowSumCheck check_row_sums(const mesh::PatchGeometry& geometry, const TransportOperator& F, const Stats* stats = nullptr,
                           const RowSumCheckOptions& options = {});

}  // namespace lambert::formfactor
