// The per-thread counters of the tiles, gathered into Stats.
#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "assembler.hpp"

namespace lambert::formfactor::detail {

// Slack for a row sum's round-off: rows of up to ~1e5 entries of at most 1, each rounded to 1.1e-16.
constexpr double kRowSumRoundoff = 1e-11;

RowsAboveOne find_rows_above_one(std::span<const double> row_sums, std::span<const double> error,
                                 std::span<const double> sigma, std::span<const std::uint8_t> skip) {
  RowsAboveOne r;
  const size_t n = row_sums.size();
  // The rays' sigmas are estimates, and the largest of n rows' noise is about sqrt(2 ln n) sigma: k = 3 + that.
  const double k_sigma = 3 + std::sqrt(2 * std::log(std::max(2.0, double(n))));
  for (size_t i = 0; i < n; ++i) {
    if (!skip.empty() && skip[i]) continue;
    const double allowed = error[i] + k_sigma * sigma[i] + kRowSumRoundoff;
    const double ratio = (row_sums[i] - 1) / allowed;
    if (ratio > 1) ++r.rows;
    if (ratio > r.max_ratio) {
      r.max_ratio = ratio;
      r.worst_patch = int(i);
      r.worst_row_sum = row_sums[i];
      r.worst_allowed = allowed;
    }
  }
  return r;
}

void Assembler::collect_stats(const std::vector<Counters*>& counters) {
  const int n = g_.size();
  std::vector<double> rows(n, 0.0);
  st_.row_error_bound.assign(n, 0.0);
  st_.row_visibility_sigma.assign(n, 0.0);
  std::array<long long, kMethodCount> by{};
  long long fixed = 0;
  double tile_seconds = 0, visibility_seconds = 0, exact_seconds = 0, rays_seconds = 0, plane_seconds = 0;
  for (const Counters* cp : counters) {
    const Counters& c = *cp;
    tile_seconds += c.tile_seconds;
    visibility_seconds += c.visibility_seconds;
    exact_seconds += c.exact_seconds;
    rays_seconds += c.rays_seconds;
    st_.pairs_exact_clear += c.exact_clear;
    st_.pairs_exact_hidden += c.exact_hidden;
    st_.pairs_plane_hidden += c.plane_hidden;
    st_.pairs_cell_hidden += c.cell_hidden;
    st_.pairs_portal_hidden += c.portal_hidden;
    st_.plane_tests += c.plane_tests;
    plane_seconds += c.plane_seconds;
    st_.pairs_exact_integrated += c.exact_integrated;
    st_.exact_points += c.exact_points;
    st_.pairs_exact_over_tolerance += c.exact_over;
    for (int i = 0; i < n; ++i) {
      rows[i] += c.row_sum[i];
      st_.row_error_bound[i] += c.row_err[i];
      st_.row_visibility_sigma[i] += c.row_vis_var[i];
    }
    st_.pairs_orientation_culled += c.culled;
    st_.pairs_shaft_culled += c.shaft_culled;
    st_.pairs_ray_tested += c.ray_tested;
    st_.rays_cast += c.rays;
    st_.pairs_over_tolerance += c.over_tolerance;
    st_.pairs_no_visible_sample += c.no_visible_sample;
    st_.pairs_reused += c.reused;
    fixed += c.fixed;
    st_.entries_outside_unit += c.outside;
    st_.entries_roundoff += c.roundoff;
    for (int m = 0; m < kMethodCount; ++m) by[m] += c.by_method[m];
  }
  // Rows of reused patches: their copied pairs' sigma and bound, bounded by the previous row's (Reuse).
  bool carried = false;
  if (const Reuse* r = o_.reuse; r && st_.pairs_reused > 0 && !old_.empty()) {
    const bool sig = !r->previous_row_sigma.empty(), bnd = !r->previous_row_bound.empty();
    carried = sig && bnd;
    for (int i = 0; i < n; ++i) {
      const int q = old_[size_t(i)];
      if (q < 0) continue;
      if (sig) st_.row_visibility_sigma[i] += r->previous_row_sigma[size_t(q)] * r->previous_row_sigma[size_t(q)];
      if (bnd) st_.row_error_bound[i] += r->previous_row_bound[size_t(q)];  // sizes checked in the constructor
    }
  }
  for (int m = 0; m < kMethodCount; ++m)
    if (by[m]) st_.pairs_by_method[kMethodNames[m]] = by[m];
  if (fixed) st_.pairs_by_method[to_string(o_.rule, o_.order)] = fixed;
  if (st_.pairs_reused) st_.pairs_by_method["reused"] = st_.pairs_reused;
  for (double& v : st_.row_visibility_sigma) v = std::sqrt(v);
  if (o_.rule != Rule::Adaptive) {
    st_.row_error_bound.clear();  // fixed rules carry no error estimate
    st_.row_error_bound_max = -1;
  } else {
    for (double v : st_.row_error_bound) st_.row_error_bound_max = std::max(st_.row_error_bound_max, v);
  }
  for (double v : st_.row_visibility_sigma) st_.row_visibility_sigma_max = std::max(st_.row_visibility_sigma_max, v);
  if (n > 0) {
    st_.row_sum_min = *std::min_element(rows.begin(), rows.end());
    st_.row_sum_max = *std::max_element(rows.begin(), rows.end());
    double sum = 0;
    for (double r : rows) sum += r;
    st_.row_sum_mean = sum / n;
  }
  // (With reused pairs only if their rows' bounds were carried over.)
  if (o_.rule == Rule::Adaptive && o_.visibility && (st_.pairs_reused == 0 || carried))
    st_.rows_above_one = find_rows_above_one(rows, st_.row_error_bound, st_.row_visibility_sigma);
  // Wall-time share of visibility inside "form_factors" (integration and visibility interleave per tile).
  const double per_thread_second = tile_seconds > 0 ? st_.seconds["form_factors"] / tile_seconds : 0.0;
  st_.seconds["visibility"] = per_thread_second * visibility_seconds;
  st_.seconds["visibility_exact"] = per_thread_second * exact_seconds;
  st_.seconds["visibility_rays"] = per_thread_second * rays_seconds;
  st_.seconds["visibility_plane"] = per_thread_second * plane_seconds;
}

void Assembler::check_reciprocity(const std::vector<Counters*>& counters) {
  // The sample: per method, the reciprocity_samples candidates with the smallest keys over all threads
  // (keys depend on the tile only, so the sample does not depend on the thread count).
  std::vector<RecipCandidate> sample;
  for (int m = 0; m < kMethodCount; ++m) {
    std::vector<RecipCandidate> all;
    for (const Counters* c : counters) all.insert(all.end(), c->recip_candidates[m].begin(), c->recip_candidates[m].end());
    std::sort(all.begin(), all.end());
    if (int(all.size()) > o_.reciprocity_samples) all.resize(size_t(o_.reciprocity_samples));
    sample.insert(sample.end(), all.begin(), all.end());
  }
  const PatchData& P = prep_->P;
  std::vector<double> residual(sample.size(), 0.0), ratio(sample.size(), 0.0);
  tbb::parallel_for(size_t(0), sample.size(), [&](size_t k) {
    const RecipCandidate& rc = sample[k];
    const double ref_tol = 1e-2 * tol_;
    const ReverseIntegral r = reverse_integral(P, rc.s, rc.t, ref_tol, tol_);
    const double af = P.area[rc.s] * rc.F, diff = std::abs(af - r.AF), mx = std::max(std::abs(af), std::abs(r.AF));
    residual[k] = mx > 0 ? diff / mx : 0.0;
    ratio[k] = diff / P.area[rc.s] / (rc.err + r.error / P.area[rc.s] + 1e-14);
  });
  st_.reciprocity_check_pairs = (long long)sample.size();
  for (size_t k = 0; k < sample.size(); ++k) {
    ++st_.reciprocity_pairs_by_method[kMethodNames[sample[k].method]];
    st_.reciprocity_residual = std::max(st_.reciprocity_residual, residual[k]);
    if (ratio[k] >= st_.reciprocity_bound_ratio) {
      st_.reciprocity_bound_ratio = ratio[k];
      st_.reciprocity_worst_method = kMethodNames[sample[k].method];
    }
  }
}

}  // namespace lambert::formfactor::detail
