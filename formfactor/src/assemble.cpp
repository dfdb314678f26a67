// Dense assembly: option checks, set-up (patch data, occluders, the matrix) and the parallel loop over tiles.
#include "lambert/formfactor/assemble.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <string>

#include "assembler.hpp"
#include "enclosures.hpp"

namespace lambert::formfactor {
namespace detail {

void Assembler::check_options() {
  const int n = g_.size();
  if (!(o_.tolerance >= 0) || !std::isfinite(o_.tolerance))
    throw InputError("form factors: tolerance must be a positive number, or 0 for the automatic one (got " +
                     std::to_string(o_.tolerance) + ")");
  if (!(o_.max_reflectance < 1))
    throw InputError("form factors: max_reflectance must be < 1 (got " + std::to_string(o_.max_reflectance) + ")");
  tol_ = o_.tolerance > 0 ? o_.tolerance : default_tolerance(o_.max_reflectance);
  st_.tolerance = tol_;
  st_.rule = to_string(o_.rule, o_.order);
  st_.visibility = o_.visibility;
  st_.rays_per_pair = o_.rays_per_pair;
  st_.visibility_method = to_string(o_.visibility_method);
  if (!o_.fault_method.empty()) {
    for (int m = 0; m < kMethodCount; ++m)
      if (o_.fault_method == kMethodNames[m]) fault_method_ = m;
    if (fault_method_ < 0) throw InputError("form factors: unknown fault_method '" + o_.fault_method + "'");
  }
  if (o_.rule == Rule::Gauss && (o_.order < 1 || o_.order > 8))
    throw InputError("form factors: Gauss order must be in 1..8 (got " + std::to_string(o_.order) + ")");
  if (o_.reuse) {
    const Reuse& r = *o_.reuse;
    const int m = r.previous ? r.previous->size() : -1;
    LAMBERT_CHECK(m >= 0 && r.previous_index.size() == size_t(n),
                  "form factors: reuse needs the previous matrix and one index per patch (" + std::to_string(n) +
                      "), got " + std::to_string(r.previous_index.size()));
    std::vector<char> seen(size_t(std::max(m, 0)), 0);
    for (int p = 0; p < n; ++p) {
      const int q = r.previous_index[p];
      LAMBERT_CHECK(!(q < -1 || q >= m || (q >= 0 && seen[q]++)),
                    "form factors: reuse index of patch " + std::to_string(p) + " is " + std::to_string(q) +
                        " (out of range or repeated; previous matrix has " + std::to_string(m) + " patches)");
    }
    for (const auto* rows : {&r.previous_row_sigma, &r.previous_row_bound})
      LAMBERT_CHECK(rows->empty() || rows->size() == size_t(m),
                    "form factors: reuse's previous row sigma and bound need one value per previous patch (" +
                        std::to_string(m) + ") or none, got " + std::to_string(rows->size()));
    old_ = r.previous_index;
  }
  if (o_.rays_per_pair < 1)
    throw InputError("form factors: rays per pair must be >= 1 (got " + std::to_string(o_.rays_per_pair) + ")");
  st_.bytes = DenseMatrixOperator::bytes_for(std::size_t(n));
  check_matrix_size(n, o_.max_bytes);
}

DenseMatrixOperator Assembler::run() {
  const auto t_setup = Clock::now();
  const int n = g_.size();
  st_ = Stats{};
  st_.patches = n;
  st_.pairs_total = (long long)n * (n - 1) / 2;
  check_options();
  prep_ = std::make_unique<Prepared>(g_);
  if (o_.rule == Rule::Gauss) {
    rule_off_.assign(1, 0);
    std::vector<std::array<int, 3>> local;  // the patch's triangles, indexing its own corners
    for (int p = 0; p < n; ++p) {
      local.clear();
      for (int k = g_.triangle_offsets[p]; k < g_.triangle_offsets[p + 1]; ++k) {
        const auto& T = g_.triangles[size_t(k)];
        local.push_back({T[0] - g_.offsets[p], T[1] - g_.offsets[p], T[2] - g_.offsets[p]});
      }
      outer_rule(prep_->P.g->polygon(p), local, o_.order, rule_pts_);  // the kernel's (planar) polygon
      rule_off_.push_back(int(rule_pts_.size()));
    }
  }
  st_.seconds["setup"] = seconds_since(t_setup);

  const auto t_bvh = Clock::now();
  if (o_.visibility && n > 1) {
    const std::vector<int> occ = potential_occluders(g_);
    st_.occluders = int(occ.size());
    st_.scene_can_occlude = !occ.empty();
    if (st_.scene_can_occlude) {
      caster_ = o_.caster ? o_.caster : std::shared_ptr<const Visibility>(make_embree_visibility(g_, occ));
      tree_ = OccluderTree(g_, occ);
      occlusion_ = true;
      convex_.assign(size_t(n), 0);
      for (int p = 0; p < n; ++p) convex_[p] = prep_->P.kind[p] <= 2;  // triangle, parallelogram, convex quad
      Eigen::AlignedBox3d box;
      for (const Vec3& v : g_.points) box.extend(v);
      scale_ = box.diagonal().norm();
      plane_of_ = occluder_planes(g_, occ, scale_);
      for (int p = 0; p < n; ++p) {
        const int id = plane_of_[size_t(p)];
        if (id < 0) continue;
        if (id >= int(plane_members_.size())) plane_members_.resize(size_t(id) + 1);
        plane_members_[size_t(id)].push_back(p);
      }
      pbox_lo_.assign(size_t(n), Vec3::Constant(INFINITY));
      pbox_hi_.assign(size_t(n), Vec3::Constant(-INFINITY));
      for (int p = 0; p < n; ++p)
        for (const Vec3& v : g_.polygon(p)) {
          pbox_lo_[size_t(p)] = pbox_lo_[size_t(p)].cwiseMin(v);
          pbox_hi_[size_t(p)] = pbox_hi_[size_t(p)].cwiseMax(v);
        }
      if (o_.enclosures) {
        const Enclosures enc = find_enclosures(g_);
        st_.enclosures = enc.surfaces;
        st_.cells = enc.cells;
        st_.cell_unknown = enc.unknown;
        if (enc.surfaces > 0) cell_ = enc.cell;
        if (o_.portals) {
          rooms_ = find_rooms(g_, kEnclosureEps * scale_);
          st_.portals = (long long)rooms_.portals.size();
          st_.rooms = rooms_.rooms;
        }
      }
      if (o_.visibility_method != VisibilityMethod::Rays) {
        merged_ = merge_coplanar_occluders(g_, occ, scale_);
        tree_.set_groups(merged_.of_patch);
        for (int m : merged_.of_patch) st_.occluders_merged += m >= 0;
        st_.occluder_regions = int(merged_.polys.size());
        st_.convex_solids = int(merged_.solid_centre.size());
        for (int id : merged_.solid_of_patch) st_.convex_solid_faces += id >= 0;
      }
    }
  }
  rays_ = o_.rays_per_pair;
  st_.seconds["bvh"] = seconds_since(t_bvh);

  const auto t_ff = Clock::now();
  DenseMatrixOperator::Matrix F;
  allocate_matrix(F, n);
  F_ = &F;
  const int nb = (n + kBlock - 1) / kBlock;
  std::vector<std::pair<int, int>> tiles;
  tiles.reserve(size_t(nb) * (nb + 1) / 2);
  for (int bi = 0; bi < nb; ++bi)
    for (int bj = bi; bj < nb; ++bj) tiles.emplace_back(bi, bj);
  tbb::enumerable_thread_specific<Counters> counters([&] {
    Counters c;
    c.row_sum.assign(n, 0.0);
    c.row_err.assign(n, 0.0);
    c.row_vis_var.assign(n, 0.0);
    return c;
  });
  tbb::enumerable_thread_specific<TileBuffers> buffers;
  std::atomic<long long> done{0};
  std::mutex progress_mutex;
  auto last = Clock::now();
  const double total_tiles = double(tiles.size());
  auto body = [&](const tbb::blocked_range<size_t>& r) {
    Counters& c = counters.local();
    TileBuffers& b = buffers.local();
    const auto t0 = Clock::now();
    for (size_t t = r.begin(); t != r.end(); ++t) tile(tiles[t].first, tiles[t].second, b, c);
    c.tile_seconds += seconds_since(t0);
    const long long d = done.fetch_add((long long)r.size()) + (long long)r.size();
    if (o_.progress) {
      std::unique_lock lock(progress_mutex, std::try_to_lock);
      if (lock.owns_lock() && seconds_since(last) >= 0.1) {
        last = Clock::now();
        o_.progress(double(d) / total_tiles);
      }
    }
  };
  auto loop = [&] { tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles.size(), 1), body); };
  if (o_.threads > 0) {
    tbb::task_arena arena(o_.threads);
    arena.execute(loop);
  } else {
    loop();
  }
  if (n == 1) F(0, 0) = 0;
  if (o_.progress) o_.progress(1.0);
  st_.seconds["form_factors"] = seconds_since(t_ff);

  const auto t_stats = Clock::now();
  std::vector<Counters*> all;
  for (Counters& c : counters) all.push_back(&c);
  collect_stats(all);
  if (o_.rule == Rule::Adaptive) check_reciprocity(all);
  st_.seconds["stats"] = seconds_since(t_stats);
  return DenseMatrixOperator(std::move(F));
}

}  // namespace detail


double default_tolerance(double max_reflectance) {
  // tolerance x rho / (1 - rho), the row-sum error's amplification, held at its value for rho = 0.9 (9e-8).
  const double rho = max_reflectance < 0 ? 0.9 : std::min(max_reflectance, 0.9999);
  return rho <= 0.9 ? 1e-8 : 1e-8 * 9 * (1 - rho) / rho;
}

std::string to_string(VisibilityMethod m) {
  switch (m) {
    case VisibilityMethod::Exact: return "exact";
    case VisibilityMethod::Rays: return "rays";
    default: return "auto";
  }
}

VisibilityMethod parse_visibility_method(std::string_view text) {
  if (text == "auto") return VisibilityMethod::Auto;
  if (text == "exact") return VisibilityMethod::Exact;
  if (text == "rays") return VisibilityMethod::Rays;
  throw InputError("unknown visibility method '" + std::string(text) + "' (choose exact, rays, auto)");
}

std::string to_string(Rule rule, int order) {
  switch (rule) {
    case Rule::Point: return "point";
    case Rule::Gauss: return "gauss" + std::to_string(order);
    default: return "adaptive";
  }
}

void parse_rule(std::string_view text, Rule& rule, int& order) {
  if (text == "adaptive") {
    rule = Rule::Adaptive;
    return;
  }
  if (text == "point") {
    rule = Rule::Point;
    return;
  }
  if (text.size() == 6 && text.substr(0, 5) == "gauss" && text[5] >= '1' && text[5] <= '8') {
    rule = Rule::Gauss;
    order = text[5] - '0';
    return;
  }
  throw InputError("unknown form-factor rule '" + std::string(text) + "' (choose adaptive, point, gauss1..gauss8)");
}

DenseMatrixOperator assemble(const mesh::PatchGeometry& geometry, const Options& options, Stats* stats) {
  Stats local;
  // A caller's caster is built on the geometry as given: keep its coordinates then.
  const std::unique_ptr<mesh::PatchGeometry> near = options.caster ? nullptr : detail::moved_to_origin(geometry);
  detail::Assembler a(near ? *near : geometry, options, stats ? *stats : local);
  return a.run();
}

}  // namespace lambert::formfactor
