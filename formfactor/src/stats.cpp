// The per-thread counters of the tiles, gathered into Stats.
#include <algorithm>

#include "assembler.hpp"

namespace lambert::formfactor::detail {

void Assembler::collect_stats(const std::vector<Counters*>& counters) {
  const int n = g_.size();
  std::vector<double> rows(n, 0.0);
  std::array<long long, kMethodCount> by{};
  long long fixed = 0;
  double tile_seconds = 0, visibility_seconds = 0;
  for (const Counters* cp : counters) {
    const Counters& c = *cp;
    tile_seconds += c.tile_seconds;
    visibility_seconds += c.visibility_seconds;
    for (int i = 0; i < n; ++i) rows[i] += c.row_sum[i];
    st_.pairs_orientation_culled += c.culled;
    st_.pairs_shaft_culled += c.shaft_culled;
    st_.pairs_ray_tested += c.ray_tested;
    st_.rays_cast += c.rays;
    st_.pairs_over_tolerance += c.over_tolerance;
    st_.pairs_reused += c.reused;
    fixed += c.fixed;
    st_.entries_outside_unit += c.outside;
    st_.reciprocity_residual = std::max(st_.reciprocity_residual, c.recip);
    for (int m = 0; m < kMethodCount; ++m) by[m] += c.by_method[m];
  }
  for (int m = 0; m < kMethodCount; ++m)
    if (by[m]) st_.pairs_by_method[kMethodNames[m]] = by[m];
  if (fixed) st_.pairs_by_method[to_string(o_.rule, o_.order)] = fixed;
  if (st_.pairs_reused) st_.pairs_by_method["reused"] = st_.pairs_reused;
  if (n > 0) {
    st_.row_sum_min = *std::min_element(rows.begin(), rows.end());
    st_.row_sum_max = *std::max_element(rows.begin(), rows.end());
    double sum = 0;
    for (double r : rows) sum += r;
    st_.row_sum_mean = sum / n;
  }
  // Wall-time share of visibility inside "form_factors" (integration and visibility interleave per tile).
  st_.seconds["visibility"] = tile_seconds > 0 ? st_.seconds["form_factors"] * visibility_seconds / tile_seconds : 0.0;
}

}  // namespace lambert::formfactor::detail
