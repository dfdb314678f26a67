// The adaptive refinement driver (see adaptive.hpp): solve, estimate, mark, split, re-solve.
#include "lambert/refine/adaptive.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "lambert/mesh/split.hpp"
#include "lambert/refine/indicators.hpp"

namespace lambert::refine {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void check_options(const AdaptiveOptions& o) {
  if (o.max_patches < 1)
    throw InputError("adaptive refinement: max_patches must be >= 1, got " + std::to_string(o.max_patches));
  if (!(o.mark_fraction > 0 && o.mark_fraction <= 1))
    throw InputError("adaptive refinement: mark_fraction must be in (0, 1], got " + std::to_string(o.mark_fraction));
  if (!(o.tolerance > 0) || !std::isfinite(o.tolerance))
    throw InputError("adaptive refinement: tolerance must be finite and > 0, got " + std::to_string(o.tolerance));
  if (o.max_rounds < 0)
    throw InputError("adaptive refinement: max_rounds must be >= 0, got " + std::to_string(o.max_rounds));
}

// Per-patch indicator eta_p: the largest of the enabled indicators; the round's maxima go into info.
std::vector<double> indicators(const mesh::Scene& scene, const formfactor::DenseMatrixOperator& F,
                               const ColorField& radiance, const AdaptiveOptions& o, AdaptiveRound& info) {
  const int n = scene.patches();
  std::vector<double> ind = jump_indicator(scene, radiance);
  if (!ind.empty()) info.max_jump = *std::max_element(ind.begin(), ind.end());
  auto merge = [&](const std::vector<double>& d, double& max) {
    for (int p = 0; p < n; ++p) {
      max = std::max(max, d[p]);
      ind[p] = std::max(ind[p], d[p]);
    }
  };
  if (o.gather_indicator) merge(gather_indicator(scene, F, radiance), info.max_gather);
  if (o.direct_indicator) merge(direct_indicator(scene, radiance), info.max_direct);
  return ind;
}

}  // namespace

AdaptiveResult solve_adaptive(const mesh::PolygonSoup& input, const AdaptiveOptions& options) {
  check_options(options);
  const auto start = std::chrono::steady_clock::now();

  AdaptiveResult result;
  mesh::PolygonSoup soup = input;
  // Children take their face's place, so indices shift: pin each face's input index in origin.
  if (soup.input_faces < 0) soup.input_faces = static_cast<int>(soup.faces.size());
  for (size_t k = 0; k < soup.faces.size(); ++k)
    if (soup.faces[k].origin < 0) soup.faces[k].origin = static_cast<int>(k);

  ColorField guess;                       // previous radiance mapped to the current patches
  formfactor::DenseMatrixOperator F_old;  // previous round's matrix
  mesh::PatchGeometry g_old;
  std::vector<int> kept_from;             // per face of `soup`: its face in the previous round, -1 if new
  std::vector<double> sigma_old, bound_old;  // the previous round's row visibility sigma and integration bound
  for (int round = 0;; ++round) {
    mesh::Scene scene = mesh::build_scene(soup);
    if (scene.patches() != static_cast<int>(soup.faces.size())) {
      // build_scene triangulated non-planar faces: continue on its patches (only in round 0, since
      // splits of planar faces are planar).
      soup = mesh::soup_from_scene(soup, scene);
      scene = mesh::build_scene(soup);
      kept_from.clear();
    }
    const int n = scene.patches();
    if (round == 0 && n > options.max_patches)
      throw InputError(input.file + ": " + std::to_string(n) + " patches before refinement, above max_patches = " +
                       std::to_string(options.max_patches));
    result.patches_per_round.push_back(n);
    AdaptiveRound info;
    info.patches = n;
    info.pairs_total = static_cast<long long>(n) * (n - 1) / 2;

    // Reuse: a kept face's patch must have exactly its old polygon (checked, not assumed).
    formfactor::Options ffo = options.ff;
    formfactor::Reuse reuse;
    ffo.reuse = nullptr;
    if (options.reuse && static_cast<int>(kept_from.size()) == n && F_old.size() == g_old.size()) {
      reuse.previous = &F_old;
      reuse.previous_index.assign(n, -1);
      for (int p = 0; p < n; ++p) {
        const int q = kept_from[p];
        if (q < 0) continue;
        const auto a = scene.geometry.polygon(p), b = g_old.polygon(q);
        if (a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin())) reuse.previous_index[p] = q;
      }
      reuse.previous_row_sigma = sigma_old;
      reuse.previous_row_bound = bound_old;
      ffo.reuse = &reuse;
    }
    auto t0 = std::chrono::steady_clock::now();
    formfactor::DenseMatrixOperator F = formfactor::assemble(scene.geometry, ffo, &info.ff);
    info.assemble_seconds = seconds_since(t0);
    info.pairs_reused = info.ff.pairs_reused;
    F_old = formfactor::DenseMatrixOperator();  // free it before the solve

    t0 = std::chrono::steady_clock::now();
    solver::Options so = options.solve;
    so.initial_guess = guess.rows() == n ? guess : ColorField();
    if (so.initial_guess.rows() == n) {
      // A patch that sees nothing (e.g. floor under a block) has L = Le exactly; a parent's value as its
      // start would leave round-off (tiny negative radiances) there.
      const ColorField Le = scene.emission_field();
      for (int p = 0; p < n; ++p)
        if (F.row_sum(p) == 0) so.initial_guess.row(p) = Le.row(p);
    }
    solver::Solution sol =
        solver::solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field(), so);
    info.solve_seconds = seconds_since(t0);
    info.solve_converged = sol.converged;
    for (const auto& c : sol.channels) info.solve_residual = std::max(info.solve_residual, c.residual);
    if (!sol.converged) {  // indicators from an unconverged solve mean nothing: stop here, unconverged
      result.rounds.push_back(std::move(info));
      result.max_indicator.push_back(0);
      result.error_estimate.push_back(0);
      result.stop = "solve_not_converged";
      result.final_matrix = std::make_shared<const formfactor::DenseMatrixOperator>(std::move(F));
      result.soup = std::move(soup);
      result.scene = std::move(scene);
      result.solution = std::move(sol);
      break;
    }

    t0 = std::chrono::steady_clock::now();
    const std::vector<double> ind = indicators(scene, F, sol.radiance, options, info);
    info.indicator_seconds = seconds_since(t0);
    result.max_indicator.push_back(std::max({info.max_jump, info.max_direct, info.max_gather}));

    // Global estimate: the area-weighted L2 size of the local indicators against that of the reflected
    // radiance (both relative to its maximum, so the scale cancels).
    const ColorField R = sol.radiance - scene.emission_field();
    const double rscale = R.maxCoeff();
    std::vector<double> weight(n, 0.0);  // A_p eta_p^2: patch p's share of the estimated squared error
    double total = 0, norm = 0;
    for (int p = 0; p < n; ++p) {
      const double a = scene.geometry.area[p];
      weight[p] = a * ind[p] * ind[p];
      total += weight[p];
      if (rscale > 0) norm += a * std::pow(std::max(0.0, R.row(p).maxCoeff()) / rscale, 2);
    }
    info.error_estimate = norm > 0 ? std::sqrt(total / norm) : 0.0;
    result.error_estimate.push_back(info.error_estimate);
    const bool converged = !(info.error_estimate > options.tolerance);

    // Doerfler marking: the patches with the largest shares until they carry `mark_fraction` of the total.
    std::vector<int> order;
    for (int p = 0; p < n; ++p)
      if (weight[p] > 0) order.push_back(p);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return weight[a] > weight[b]; });
    std::vector<char> split(n, 0);
    int count = n, chosen = 0, marked = 0;
    long not_splittable = 0;
    double covered = 0;
    for (int p : order) {
      if (converged || covered >= options.mark_fraction * total) break;
      ++marked;
      const int children = mesh::split_children(scene.geometry.polygon(p), scene.geometry.normal[p]);
      if (children == 0) {
        ++not_splittable;
        continue;
      }
      if (count + children - 1 > options.max_patches) continue;
      count += children - 1;
      split[p] = 1;
      covered += weight[p];
      ++chosen;
    }
    result.not_splittable = not_splittable;
    info.marked = marked;
    info.split = chosen;
    result.rounds.push_back(std::move(info));

    const bool last = converged || chosen == 0 || round == options.max_rounds;
    if (last) {
      result.stop = converged ? "converged" : chosen == 0 ? "budget" : "max_rounds";
      result.final_matrix = std::make_shared<const formfactor::DenseMatrixOperator>(std::move(F));
      result.soup = std::move(soup);
      result.scene = std::move(scene);
      result.solution = std::move(sol);
      break;
    }

    // Split the marked faces; children take their parent's place and its radiance as a start.
    mesh::PolygonSoup next = soup;
    next.faces.clear();
    mesh::FaceSplitter splitter(next);
    std::vector<int> parent;
    kept_from.clear();
    for (int p = 0; p < n; ++p) {
      const mesh::SoupFace& f = soup.faces[p];
      if (!split[p]) {
        next.faces.push_back(f);
        parent.push_back(p);
        kept_from.push_back(p);
        continue;
      }
      for (mesh::SoupFace& child : splitter.split(f, scene.geometry.normal[p])) {
        next.faces.push_back(std::move(child));
        parent.push_back(p);
        kept_from.push_back(-1);
      }
    }
    guess.resize(static_cast<Eigen::Index>(parent.size()), 3);
    for (size_t k = 0; k < parent.size(); ++k) guess.row(static_cast<Eigen::Index>(k)) = sol.radiance.row(parent[k]);
    if (options.reuse) {
      F_old = std::move(F);
      g_old = scene.geometry;
      sigma_old = result.rounds.back().ff.row_visibility_sigma;
      bound_old = result.rounds.back().ff.row_error_bound;
    }
    soup = std::move(next);
  }
  result.seconds = seconds_since(start);
  return result;
}

}  // namespace lambert::refine
