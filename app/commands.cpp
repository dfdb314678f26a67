#include "commands.hpp"

#include <fmt/format.h>

#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/check.hpp"
#include "lambert/formfactor/json.hpp"
#include "lambert/mesh/json.hpp"
#include "lambert/refine/json.hpp"
#include "lambert/solver/json.hpp"
#include "lambert/io/atomic_file.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/io/vtk.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/refine/adaptive.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/verify/verify.hpp"
#include "daylight.hpp"
#include "outputs.hpp"
#include "progress.hpp"

#ifndef LAMBERT_VERSION
#define LAMBERT_VERSION "dev"
#endif

namespace lambert::app {
namespace {

using nlohmann::json;

void say(const CommonOptions& o, const std::string& line) {
  if (!o.quiet) std::fprintf(stderr, "%s\n", line.c_str());
}

std::string rgb_str(const RGB& c, const char* f = "{:.4g}") {
  if (c[0] == c[1] && c[1] == c[2]) return fmt::format(fmt::runtime(f), c[0]);
  return fmt::format("({}, {}, {})", fmt::format(fmt::runtime(f), c[0]), fmt::format(fmt::runtime(f), c[1]),
                     fmt::format(fmt::runtime(f), c[2]));
}

// Reads the scene file and applies --materials.
mesh::PolygonSoup read_input(const CommonOptions& o, PhaseTimer& timer) {
  timer.start("load");
  mesh::PolygonSoup soup = io::read_soup(o.scene);
  if (!o.materials.empty()) io::apply_materials_json(soup, o.materials);
  declare_soup_inputs(soup);  // an MTL library is an input too: never an output
  return soup;
}

// Reads, applies --materials, prepares, validates. Prints validation warnings unless quiet.
// `solving`: the run solves for radiance (a scene without emitters is then worth a warning).
mesh::Scene load(const CommonOptions& o, PhaseTimer& timer, bool solving = true) {
  const mesh::PolygonSoup soup = read_input(o, timer);
  timer.start("prepare");
  mesh::BuildOptions build;
  build.warn_no_emitter = solving;
  mesh::Scene scene = mesh::prepare_and_build(soup, o.prepare, build);
  timer.stop();
  malloc_trim(0);  // the preparation's freed heap back to the system before the operator is built
  for (const auto& w : scene.report.warnings) say(o, "lambert: warning: " + w);
  return scene;
}

json phases_json(const PhaseTimer& t) {
  json j = json::object();
  for (const auto& [name, s] : t.phases()) j[name] = j.value(name, 0.0) + s;
  return j;
}

std::string phases_line(const PhaseTimer& t) {
  std::string s;
  for (const auto& [name, sec] : t.phases()) s += fmt::format("{} {:.3g} s, ", name, sec);
  return s + fmt::format("total {:.3g} s", t.total());
}

void write_json(const std::string& path, const json& j) {
  write_output(path, [&](std::ostream& os) { os << j.dump(2) << '\n'; });
}

// The largest reflectance over patches (or soup faces) and channels: the automatic form-factor tolerance
// follows it (formfactor::default_tolerance).
double max_reflectance(const std::vector<mesh::Material>& materials) {
  double m = 0;
  for (const auto& mat : materials) m = std::max(m, mat.reflectance.maxCoeff());
  return m;
}

formfactor::Options ff_options(const CommonOptions& o, double rho_max, Progress* progress) {
  formfactor::Options f = o.ff;
  f.enclosures = o.enclosures == "on";
  f.portals = o.portals == "on";
  f.max_reflectance = rho_max;
  f.visibility = !o.no_visibility;
  formfactor::parse_rule(o.ff_rule, f.rule, f.order);
  f.visibility_method = formfactor::parse_visibility_method(o.visibility);
  f.threads = o.threads;
  if (progress) f.progress = [progress](double x) { progress->update(x); };
  return f;
}

std::string scene_line(const mesh::Scene& scene) {
  std::string extra;
  if (scene.patches() != scene.input_faces)
    extra = fmt::format(", from {} input faces", scene.input_faces);
  return fmt::format("  patches      {}{}; {} vertices, {} materials\n", scene.patches(), extra, scene.mesh.n_vertices(),
                     scene.materials.size());
}

// The independent row-sum check (formfactor/check.hpp) on the assembled matrix: rays cast from a sample of
// patches count what each patch sees, compared with its row sum within the assembly's own bounds. Skipped
// without visibility (then the rays would see occluders the matrix ignores).
formfactor::RowSumCheck check_rows(const CommonOptions& o, const mesh::Scene& scene,
                                   const formfactor::TransportOperator& F, const formfactor::Stats& st) {
  if (o.no_visibility || scene.patches() == 0) return {};
  formfactor::RowSumCheckOptions c;
  c.threads = o.threads;
  return formfactor::check_row_sums(scene.geometry, F, &st, c);
}

// --operator: which transport operator, and why (printed and in --stats). Throws InputError, with the estimate
// and what to change, when the requested operator cannot fit in the memory available.
struct OperatorChoice {
  bool hierarchical = false;
  std::string reason;
};
constexpr int kAutoDenseMaxPatches = 10000;  // dense is faster below (docs/benchmarks.md, "Hierarchical operator")

std::string megabytes(std::size_t b) { return fmt::format("{:.0f} MB", double(b) / 1048576.0); }

OperatorChoice choose_operator(const CommonOptions& o, int n, double rho_max) {
  const formfactor::MemoryLimit mem = o.ff.max_bytes ? formfactor::MemoryLimit{o.ff.max_bytes, "max_bytes"}
                                                     : formfactor::system_memory_limit();
  const std::size_t dense = formfactor::DenseMatrixOperator::bytes_for(std::size_t(n));
  const std::size_t hier = formfactor::estimate_hierarchy_bytes(std::size_t(n), o.hierarchy.tolerance);
  const std::string avail = fmt::format("{} available ({})", megabytes(mem.bytes), mem.source);
  const bool fixed_rule = o.ff_rule != "adaptive";
  if (o.op == "hierarchical") {
    if (o.adaptive_budget > 0)
      throw InputError("--operator hierarchical: adaptive refinement (--adaptive-budget) reuses dense matrices between "
                       "rounds; use --operator dense or auto");
    if (fixed_rule)
      throw InputError("--operator hierarchical: the fixed rule '" + o.ff_rule +
                       "' is a dense-assembly study option; use --rule/--ff-rule adaptive or --operator dense");
    if (hier > mem.bytes)
      throw InputError(fmt::format("--operator hierarchical: {} patches are estimated to need {}, more than the {}; "
                                   "raise --hierarchy-tolerance, use fewer patches (a larger --max-edge) or more memory",
                                   n, megabytes(hier), avail));
    return {true, fmt::format("requested; estimated {} of {}", megabytes(hier), avail)};
  }
  if (o.op == "dense") {
    if (dense > mem.bytes)
      throw InputError(fmt::format("--operator dense: the matrix for {} patches needs {} ({}^2 doubles), more than the "
                                   "{}; use --operator hierarchical (estimated {}) or fewer patches (a larger --max-edge)",
                                   n, megabytes(dense), n, avail, megabytes(hier)));
    return {false, fmt::format("requested; {} of {}", megabytes(dense), avail)};
  }
  if (o.adaptive_budget > 0 || fixed_rule) {
    const std::string why =
        fixed_rule ? "the fixed rule '" + o.ff_rule + "'" : std::string("adaptive refinement (--adaptive-budget)");
    if (dense > mem.bytes)
      throw InputError(fmt::format("the dense matrix for {} patches needs {}, more than the {}, and {} needs the dense "
                                   "operator; use fewer patches (a larger --max-edge)",
                                   n, megabytes(dense), avail, why));
    return {false, fmt::format("auto: {} needs the dense operator; {} of {}", why, megabytes(dense), avail)};
  }
  // Bright interiors: the hierarchy refines to tolerance (1 - rho)/rho and loses its advantage; dense if it fits.
  if (rho_max > 0.95 && dense <= mem.bytes / 2)
    return {false, fmt::format("auto: reflectance up to {:.4g} amplifies the hierarchy's row error {:.0f}-fold; the dense "
                               "matrix fits ({} of {})",
                               rho_max, rho_max / (1 - rho_max), megabytes(dense), avail)};
  if (n <= kAutoDenseMaxPatches && dense <= mem.bytes / 2)
    return {false, fmt::format("auto: {} patches <= {}, where the dense matrix is faster and exact to the form-factor "
                               "tolerance; {} of {}",
                               n, kAutoDenseMaxPatches, megabytes(dense), avail)};
  if (hier > mem.bytes)
    throw InputError(fmt::format("{} patches: the dense matrix needs {} and the hierarchical operator an estimated {}, "
                                 "more than the {}; raise --hierarchy-tolerance or use fewer patches (a larger --max-edge)",
                                 n, megabytes(dense), megabytes(hier), avail));
  if (n <= kAutoDenseMaxPatches)
    return {true, fmt::format("auto: the dense matrix would need {}, more than half of the {}; hierarchical estimated {}",
                              megabytes(dense), avail, megabytes(hier))};
  return {true, fmt::format("auto: {} patches > {}, where the hierarchical operator is faster (dense would need {}); "
                            "estimated {} of {}",
                            n, kAutoDenseMaxPatches, megabytes(dense), megabytes(hier), avail)};
}

// Options of the hierarchical operator from the CLI's; brightness: the a-priori bound L_i <= Le_i + rho_i
// max(Le) / (1 - rho_max) (largest channel), so links from black, non-emitting surfaces are accepted coarse.
// `emission`: the solve's emission term when it is more than the materials' (a sky's rho E_sky / pi and glazing's
// tau E_out / pi); the links' error is weighed by it, so a daylit scene without lamps is not treated as dark.
formfactor::HierarchyOptions hierarchy_options(const CommonOptions& o, const mesh::Scene& scene, Progress* progress,
                                               const ColorField* emission = nullptr) {
  formfactor::HierarchyOptions h = o.hierarchy;
  h.enclosures = o.enclosures == "on";
  h.portals = o.portals == "on";
  const double rho_max = max_reflectance(scene.materials);
  h.entry_tolerance = o.ff.tolerance;
  h.max_reflectance = rho_max;
  h.visibility = !o.no_visibility;
  h.visibility_method = formfactor::parse_visibility_method(o.visibility);
  h.rays_per_pair = o.ff.rays_per_pair;
  h.threads = o.threads;
  h.max_bytes = o.ff.max_bytes;
  if (progress) h.progress = [progress](double x) { progress->update(x); };
  const ColorField Le = emission ? *emission : scene.emission_field(), rho = scene.reflectance_field();
  const double le_max = Le.size() ? Le.maxCoeff() : 0.0;
  h.brightness.resize(size_t(scene.patches()));
  for (int p = 0; p < scene.patches(); ++p)
    h.brightness[size_t(p)] = Le.row(p).maxCoeff() + rho.row(p).maxCoeff() * le_max / (1 - std::min(rho_max, 0.999999));
  if (emission) {  // a solve: closed cells without an emitter are dark, and pairs of dark patches carry nothing
    h.emission.resize(size_t(scene.patches()));
    for (int p = 0; p < scene.patches(); ++p) h.emission[size_t(p)] = Le.row(p).maxCoeff();
    h.radiance_only = true;
  }
  return h;
}

// The assembly statistics the summary, the checks and --stats read, from a hierarchical build.
formfactor::Stats stats_of(const formfactor::HierarchyStats& h, const formfactor::HierarchyOptions& o) {
  formfactor::Stats st;
  st.rule = "hierarchical";
  st.tolerance = h.entry_tolerance;
  st.visibility = o.visibility;
  st.rays_per_pair = o.rays_per_pair;
  st.patches = h.patches;
  st.pairs_total = h.dense_pairs_equivalent;
  st.pairs_ray_tested = h.pairs_ray_tested;
  st.pairs_shaft_culled = h.pairs_shaft_clear;
  st.pairs_orientation_culled = h.pairs_culled;
  st.rays_cast = h.rays_cast;
  st.visibility_method = formfactor::to_string(o.visibility_method);
  st.pairs_exact_clear = h.pairs_exact_clear;
  st.pairs_exact_hidden = h.pairs_exact_hidden;
  st.pairs_exact_integrated = h.pairs_exact_integrated;
  st.exact_points = h.exact_points;
  st.pairs_exact_over_tolerance = h.pairs_exact_over_tolerance;
  st.pairs_over_tolerance = h.pairs_exact_over_tolerance;  // the finding "pairs above tolerance"
  st.row_sum_min = h.row_sum_min;
  st.row_sum_max = h.row_sum_max;
  st.row_sum_mean = h.row_sum_mean;
  st.row_error_bound = h.row_error;         // far links' admitted error plus the leaf entries' bounds
  st.row_unresolved = h.row_dark;
  st.row_error_bound_max = h.row_error_max;
  st.row_visibility_sigma = h.row_visibility_sigma;
  st.row_visibility_sigma_max = h.row_visibility_sigma_max;
  st.rows_above_one = h.rows_above_one;
  st.seconds["form_factors"] = h.seconds_total;
  st.bytes = h.bytes;
  return st;
}

// One run of `solve` or `formfactors`: what the summary and --stats describe (one schema for both).
struct Run {
  std::string command;                             // "solve" | "formfactors"
  const CommonOptions* options = nullptr;
  const mesh::Scene* scene = nullptr;
  const formfactor::Stats* ff = nullptr;           // the (final) assembly
  const solver::Solution* solution = nullptr;      // solve only
  const refine::AdaptiveResult* adaptive = nullptr;  // solve --adaptive-budget only
  const formfactor::RowSumCheck* row_check = nullptr;  // independent ray estimate of row sums (final assembly)
  long long entries_written = -1;                  // formfactors only
  const DaylightRun* daylight = nullptr;           // solve with --sky / sensors / --units photometric
  std::string op_kind, op_reason;                  // "dense" | "hierarchical", and why (choose_operator)
  const formfactor::HierarchyStats* hierarchy = nullptr;  // the hierarchical operator's build
};

// A finding that the summary and --stats report; `fatal` findings make the result untrustworthy (exit 3,
// no output written).
struct Finding {
  std::string key;
  double value = 0;
  std::string message;
  bool fatal = false;
};

// Everything a run found wrong with its own result, one entry per kind, only when nonzero.
std::vector<Finding> assess(const Run& r) {
  std::vector<Finding> out;
  auto add = [&](std::string key, double value, std::string message, bool fatal) {
    if (value != 0) out.push_back({std::move(key), value, std::move(message), fatal});
  };
  // Form-factor failures, over every adaptive round (each computed pair is counted in the round that
  // computed it).
  long long over = 0, outside = 0, roundoff = 0, blind = 0;
  double recip_ratio = 0;
  std::string recip_method;
  auto count = [&](const formfactor::Stats& st) {
    over += st.pairs_over_tolerance;
    outside += st.entries_outside_unit;
    roundoff += st.entries_roundoff;
    blind += st.pairs_no_visible_sample;
    if (st.reciprocity_bound_ratio > recip_ratio) {
      recip_ratio = st.reciprocity_bound_ratio;
      recip_method = st.reciprocity_worst_method;
    }
  };
  if (r.adaptive) {
    for (const auto& rd : r.adaptive->rounds) count(rd.ff);
  } else if (r.ff) {
    count(*r.ff);
  }
  add("pairs_over_tolerance", double(over),
      fmt::format("{} pairs stopped their adaptive integration above the form-factor tolerance", over), false);
  add("pairs_no_visible_sample", double(blind),
      fmt::format("{} ray-tested pairs had no sample pair facing each other (taken as exchanging nothing)", blind),
      false);
  add("entries_roundoff", double(roundoff),
      fmt::format("{} form factors were outside [0, 1] by no more than their error bound (round-off; set to 0 or 1)",
                  roundoff),
      false);
  add("entries_outside_unit", double(outside),
      fmt::format("{} form factors outside [0, 1] beyond their error bound (never clamped): the form factors are wrong",
                  outside),
      true);
  // The sky lights a model from behind when, of its near-horizontal patches with nothing in front of them, more
  // than twice as much faces the earth as faces the sky: a model inside out (a mirrored export) that no other
  // surface could turn round (one connected surface, as a city of buildings joined to their ground), or --up
  // pointing down. (A building without ground has about as much floor underside as roof.)
  if (r.daylight && r.daylight->sky_active()) {
    const daylight::PatchSkyStats& st = r.daylight->patch_stats();
    if (st.area_facing_down > 2 * st.area_facing_up)
      add("sky_from_behind", st.area_facing_down,
          fmt::format("the sky lights the model from behind: {:.4g} m^2 of near-horizontal patches face the earth with "
                      "nothing in front of them, {:.4g} m^2 face the sky so (faces are one-sided: ground and roofs "
                      "facing the earth get no sky). Is the model inside out (a mirrored export: --reverse-winding) "
                      "or --up wrong?",
                      st.area_facing_down, st.area_facing_up),
          false);
  }
  // A row above 1 beyond its admitted error (formfactor::Stats::rows_above_one): the bounds do not hold. Fatal
  // where visibility is exact (the bound is a bound); a warning where rays estimate it (sigmas are estimates) and
  // under the hierarchy (its links' errors are estimates).
  if (r.ff && !r.adaptive && r.ff->rows_above_one.rows > 0) {
    const formfactor::Stats& st = *r.ff;
    const formfactor::RowsAboveOne& ra = st.rows_above_one;
    const bool rays = st.pairs_ray_tested > 0 || r.hierarchy;
    add("rows_above_one", double(ra.rows),
        fmt::format("{} rows sum above 1 by more than their admitted error (no patch sees more than its hemisphere): "
                    "patch {} sums to 1 + {:.3g}, {:.3g}x its bound {:.2e}{}",
                    ra.rows, ra.worst_patch, ra.worst_row_sum - 1, ra.max_ratio, ra.worst_allowed,
                    r.hierarchy ? " (the hierarchy's admitted row error, an estimate, + 3 + sqrt(2 ln N) sigma of its "
                                  "ray-estimated patch pairs)"
                    : rays ? " (integration bound + 3 + sqrt(2 ln N) sigma of the ray-estimated visibility)"
                         : ": form factors or exact visibility are wrong"),
        !rays);
  }
  if (recip_ratio > 1)
    add("reciprocity_check", recip_ratio,
        fmt::format("reciprocity check: {} pairs integrated independently in the reverse direction differ by {:.3g}x "
                    "their error bound (worst method {}); the error bound does not hold",
                    r.ff ? r.ff->reciprocity_check_pairs : 0, recip_ratio, recip_method),
        true);
  if (r.row_check && !r.row_check->passed) {
    // Fatal under the adaptive rule, whose error is controlled; the fixed rules (point, gaussN) exist to show
    // what uncontrolled rules do, so there it is reported and the result still written.
    const formfactor::RowSumCheck& c = *r.row_check;
    const bool controlled = !r.ff || r.ff->rule == "adaptive" || r.ff->rule == "hierarchical";
    add("row_sum_check", c.max_ratio,
        fmt::format("row-sum check: patch {} sums to {:.6f} but rays cast from it find {:.6f} (allowed difference "
                    "{:.2e}, exceeded {:.3g}x): form factors or visibility are wrong (a leak, or missing light){}",
                    c.worst_patch, c.worst_row_sum, c.worst_estimate, c.worst_allowed, c.max_ratio,
                    controlled ? "" : "; expected of a fixed rule without error control"),
        controlled);
  }
  if (r.adaptive) {
    long unconverged = 0;
    for (const auto& rd : r.adaptive->rounds) unconverged += rd.solve_converged ? 0 : 1;
    add("unconverged_solves", double(unconverged),
        fmt::format("{} adaptive round(s) ended with a solve that did not reach the tolerance", unconverged), true);
  } else if (r.solution && !r.solution->converged) {
    std::string why;
    for (size_t c = 0; c < r.solution->channels.size(); ++c)
      why += fmt::format(" channel {}: {} after {} iterations, residual {:.3e};", c, r.solution->channels[c].stop,
                         r.solution->channels[c].iterations, r.solution->channels[c].residual);
    add("unconverged_solves", 1,
        fmt::format("the solve did not reach the tolerance {:g}:{} (try --method bicgstab or a larger "
                    "--max-iterations)", r.options->solve.tolerance, why),
        true);
  }
  return out;
}

// Error bound on the radiance in the max norm, relative to the largest radiance (docs/physics.md §5):
// (rho_max delta + r) / (1 - rho_max s_max), delta the form factors' row error bound, r the solve's residual.
// Visibility (a ray estimate) is not part of the bound; `visibility_estimated` says whether it played a role.
struct ErrorBound {
  double total = INFINITY, form_factors = 0, solve = 0;
  double visibility = 0;  // 3 x the largest row's visibility standard error (an estimate, not a bound)
  bool visibility_estimated = false;
  bool exists = false;  // false for fixed rules (no error estimate) and when rho_max s_max >= 1
};

ErrorBound error_bound(const Run& r) {
  ErrorBound b;
  if (!r.ff || !r.solution || !r.scene) return b;
  double rho_max = 0;
  for (int p = 0; p < r.scene->patches(); ++p) rho_max = std::max(rho_max, r.scene->reflectance(p).maxCoeff());
  const formfactor::Stats& s = *r.ff;
  // Integration: the largest row's sum of per-entry error bounds (fixed rules carry none). Adaptive rounds
  // copy entries from earlier rounds: take the largest over every round.
  b.form_factors = s.row_error_bound_max >= 0 ? s.row_error_bound_max : INFINITY;
  if (r.adaptive)
    for (const auto& rd : r.adaptive->rounds)
      b.form_factors = rd.ff.row_error_bound_max >= 0 ? std::max(b.form_factors, rd.ff.row_error_bound_max) : INFINITY;
  b.visibility = 3 * s.row_visibility_sigma_max;
  for (const auto& c : r.solution->channels) b.solve = std::max(b.solve, c.residual_max);
  b.visibility_estimated = s.rays_cast > 0;
  const double denom = 1 - rho_max * std::max(1.0, s.row_sum_max);
  b.exists = denom > 0 && std::isfinite(b.form_factors);
  if (b.exists) b.total = (rho_max * (b.form_factors + b.visibility) + b.solve) / denom;
  return b;
}

json stats_json(const Run& r, const PhaseTimer& timer, const std::vector<Finding>& findings) {
  const mesh::Scene& scene = *r.scene;
  json j;
  j["version"] = LAMBERT_VERSION;
  j["command"] = r.command;
  j["scene"] = scene.source;
  j["patches"] = scene.patches();
  j["input_faces"] = scene.input_faces;
  j["vertices"] = scene.mesh.n_vertices();
  j["materials"] = scene.materials.size();
  j["warnings"] = scene.report;
  j["output"] = r.options->output;
  j["phases"] = phases_json(timer);
  j["iterations"] = 0;
  j["residual"] = 0.0;
  if (r.ff) j["form_factors"] = *r.ff;
  if (r.solution) {
    j.update(json(*r.solution));
    j["tolerance"] = r.options->solve.tolerance;
  }
  if (r.adaptive) {
    json a = *r.adaptive;
    a["budget"] = r.options->adaptive.max_patches;
    a["tolerance"] = r.options->adaptive.tolerance;
    j["adaptive"] = a;
  }
  if (r.entries_written >= 0) j["entries_written"] = r.entries_written;
  if (r.daylight && r.daylight->active()) j["daylight"] = r.daylight->stats();
  if (!r.op_kind.empty()) j["operator"] = {{"kind", r.op_kind}, {"reason", r.op_reason}};
  if (r.hierarchy) {
    const formfactor::HierarchyStats& h = *r.hierarchy;
    j["hierarchy"] = {{"tolerance", h.tolerance}, {"link_tolerance", h.link_tolerance},
                      {"entry_tolerance", h.entry_tolerance}, {"nodes", h.nodes},
                      {"levels", h.levels}, {"far_links", h.far_links}, {"leaf_links", h.leaf_links},
                      {"far_links_per_level", h.far_links_per_level}, {"pairs_culled", h.pairs_culled},
                      {"links_shaft_clear", h.links_shaft_clear}, {"links_ray_tested", h.links_ray_tested},
                      {"links_blocked", h.links_blocked}, {"pairs_ray_tested", h.pairs_ray_tested},
                      {"pairs_exact_clear", h.pairs_exact_clear}, {"pairs_exact_hidden", h.pairs_exact_hidden},
                      {"pairs_exact_integrated", h.pairs_exact_integrated}, {"exact_points", h.exact_points},
                      {"pairs_exact_over_tolerance", h.pairs_exact_over_tolerance},
                      {"pairs_shaft_clear", h.pairs_shaft_clear},
                      {"enclosures", {{"surfaces", h.enclosures}, {"patches_crossing", h.cell_crossed},
                                      {"surface_patches", h.enclosure_patches}, {"cells", h.cells},
                                      {"patches_of_unknown_cell", h.cell_unknown}, {"pairs_refused", h.pairs_cell_culled},
                                      {"dark_cells", h.dark_cells}, {"seconds", h.seconds_enclosures}}},
                      {"dark_patches", h.dark_patches}, {"pairs_dark_refused", h.pairs_dark_culled},
                      {"portals", {{"openings", h.portals}, {"room_cells", h.room_cells},
                                   {"pairs_refused", h.pairs_portal_culled}, {"seconds", h.seconds_portals}}},
                      {"rays_cast", h.rays_cast}, {"row_error_max", h.row_error_max},
                      {"rows_above_one", h.rows_above_one},
                      {"radiance_error_max", h.radiance_error_max},
                      {"row_visibility_sigma_max", h.row_visibility_sigma_max}, {"bytes", h.bytes},
                      {"bytes_estimate", h.bytes_estimate}, {"dense_pairs_equivalent", h.dense_pairs_equivalent},
                      {"seconds", {{"tree", h.seconds_tree}, {"links", h.seconds_links}, {"total", h.seconds_total}}}};
  }
  if (r.row_check) {
    const formfactor::RowSumCheck& c = *r.row_check;
    j["row_sum_check"] = {{"patches_checked", c.patches_checked}, {"rows_skipped", c.rows_skipped}, {"rays", c.rays},
                          {"max_difference", c.max_difference}, {"max_ratio", c.max_ratio},
                          {"worst_patch", c.worst_patch}, {"worst_row_sum", c.worst_row_sum},
                          {"worst_estimate", c.worst_estimate}, {"worst_allowed", c.worst_allowed},
                          {"passed", c.passed}};
  }
  json checks = json::object();
  for (const Finding& f : findings) checks[f.key] = {{"value", f.value}, {"fatal", f.fatal}, {"message", f.message}};
  j["findings"] = checks;
  const ErrorBound b = error_bound(r);
  if (r.solution)
    j["error_bound"] = {{"exists", b.exists},
                        {"relative_radiance", b.exists ? json(b.total) : json(nullptr)},
                        {"form_factor_row", std::isfinite(b.form_factors) ? json(b.form_factors) : json(nullptr)},
                        {"solve_residual", b.solve},
                        {"visibility_3sigma", b.visibility},
                        {"visibility_estimated", b.visibility_estimated}};
  return j;
}

// The summary line of the rows above 1 (formfactor::Stats::rows_above_one), or nothing when no row is above 1.
std::string rows_above_one_line(const formfactor::RowsAboveOne& r) {
  if (r.worst_patch < 0) return "";
  return fmt::format("  rows above 1 largest excess 1 + {:.2e} (patch {}), {:.2g}x its admitted error{}\n",
                     r.worst_row_sum - 1, r.worst_patch, r.max_ratio,
                     r.rows ? fmt::format("; {} rows beyond it", r.rows) : "");
}

std::string ff_lines(const formfactor::Stats& s, const formfactor::RowSumCheck* check) {
  std::string out = fmt::format(
      "  pairs        {} ({} culled by orientation, {} proven unoccluded, {}{}{}{} ray-tested), rays {}\n"
      "  form factors {} rule, tolerance {:.1e} per entry; row sum min/mean/max {:.6f} / {:.6f} / {:.6f}\n",
      s.pairs_total, s.pairs_orientation_culled, s.pairs_shaft_culled,
      s.pairs_cell_hidden ? fmt::format("{} facing different cells ({} closed surfaces, {} cells), ", s.pairs_cell_hidden,
                                        s.enclosures, s.cells)
                          : "",
      s.pairs_plane_hidden ? fmt::format("{} proven hidden by a wall or slab, ", s.pairs_plane_hidden) : "",
      s.pairs_portal_hidden ? fmt::format("{} in different rooms with no portal between them ({} openings, {} rooms), ",
                                          s.pairs_portal_hidden, s.portals, s.rooms)
                            : "",
      s.pairs_ray_tested, s.rays_cast, s.rule,
      s.tolerance, s.row_sum_min, s.row_sum_mean, s.row_sum_max);
  const long long exact = s.pairs_exact_clear + s.pairs_exact_hidden + s.pairs_exact_integrated;
  if (exact > 0) {
    auto sec = [&](const char* k) { return s.seconds.count(k) ? s.seconds.at(k) : 0.0; };
    out += fmt::format("  visibility   {}: {} pairs exact ({} proven clear, {} hidden, {} integrated at {} points{}) in "
                       "{:.2f} s; {} by rays in {:.2f} s\n",
                       s.visibility_method, exact, s.pairs_exact_clear, s.pairs_exact_hidden, s.pairs_exact_integrated,
                       s.exact_points,
                       s.pairs_exact_over_tolerance ? fmt::format(", {} above tolerance", s.pairs_exact_over_tolerance) : "",
                       sec("visibility_exact"), s.pairs_ray_tested, sec("visibility_rays"));
  }
  out += rows_above_one_line(s.rows_above_one);
  if (s.reciprocity_check_pairs > 0)
    out += fmt::format("  reciprocity  {} pairs integrated independently in reverse: largest difference {:.2e} relative, "
                       "{:.2g}x its error bound ({})\n",
                       s.reciprocity_check_pairs, s.reciprocity_residual, s.reciprocity_bound_ratio,
                       s.reciprocity_worst_method.empty() ? "-" : s.reciprocity_worst_method);
  if (check && check->patches_checked > 0)
    out += fmt::format("  row sums     {} patches against {} rays cast from them: largest difference {:.2e}, {:.2g}x "
                       "the allowed (patch {})\n",
                       check->patches_checked, check->rays, check->max_difference, check->max_ratio, check->worst_patch);
  return out;
}

std::string summary(const Run& r, const PhaseTimer& timer, const std::vector<Finding>& findings,
                    const std::string& detail) {
  std::string s = fmt::format("lambert {} {}\n", r.command, r.options->scene) + scene_line(*r.scene);
  if (!r.op_kind.empty()) s += fmt::format("  operator     {} ({})\n", r.op_kind, r.op_reason);
  if (r.hierarchy) {
    const formfactor::HierarchyStats& h = *r.hierarchy;
    std::string per_level;
    for (size_t l = 0; l < h.far_links_per_level.size(); ++l)
      if (h.far_links_per_level[l]) per_level += fmt::format("{}{}:{}", per_level.empty() ? "" : " ", l, h.far_links_per_level[l]);
    s += fmt::format("  hierarchy    {} nodes, {} levels; {} cluster links, {} patch-pair entries ({:.3g}% of the {} "
                     "pairs); {} memory; visibility: cluster pairs {} ray-tested, {} proven clear, {} found blocked; "
                     "patch pairs {} ray-tested, {} proven clear; {} rays\n"
                     "  hierarchy    tolerance {:.1e} ({:.1e} per link after the reflectance's amplification); admitted row error {:.2e} (form factor), {:.2e} "
                     "(radiance, relative to the brightest), patch-pair visibility sigma {:.1e}; row sum min/mean/max "
                     "{:.6f} / {:.6f} / {:.6f}\n"
                     "  hierarchy    cluster links per level {}\n",
                     h.nodes, h.levels, h.far_links, h.leaf_links,
                     100.0 * double(h.far_links + h.leaf_links) / double(std::max(1LL, h.dense_pairs_equivalent)),
                     h.dense_pairs_equivalent, megabytes(h.bytes), h.links_ray_tested, h.links_shaft_clear, h.links_blocked, h.pairs_ray_tested,
                     h.pairs_shaft_clear, h.rays_cast,
                     h.tolerance, h.link_tolerance, h.row_error_max, h.radiance_error_max, h.row_visibility_sigma_max, h.row_sum_min, h.row_sum_mean, h.row_sum_max,
                     per_level.empty() ? "-" : per_level);
    s += rows_above_one_line(h.rows_above_one);
    if (h.enclosures > 0)
      s += fmt::format("  enclosures   {} closed surfaces ({} patches): {} cells{}; {} node pairs facing different cells "
                       "refused without rays ({:.2f} s)\n",
                       h.enclosures, h.enclosure_patches, h.cells,
                       h.cell_unknown ? fmt::format(" ({} patches of no known cell, {} of them crossing or touching a surface inside)",
                                                    h.cell_unknown, h.cell_crossed)
                                      : "",
                       h.pairs_cell_culled, h.seconds_enclosures);
    if (h.dark_patches > 0)
      s += fmt::format("  dark         {} patches that send nothing ({}); {} node pairs between them refused without a "
                       "link or a ray (their rows are not resolved: radiance 0 in any solution)\n",
                       h.dark_patches,
                       h.dark_patches == h.patches  // every patch dark: none emits (an emitter is bright)
                           ? std::string("nothing in the scene emits")
                           : fmt::format("black and not emitting, or in one of {} closed cells without an emitter",
                                         h.dark_cells),
                       h.pairs_dark_culled);
    if (h.portals > 0)
      s += fmt::format("  portals      {} openings closed by portals: {} rooms; {} node pairs in different rooms whose "
                       "shaft meets no portal between them refused without rays ({:.2f} s)\n",
                       h.portals, h.room_cells, h.pairs_portal_culled, h.seconds_portals);
    const long long exact = h.pairs_exact_clear + h.pairs_exact_hidden + h.pairs_exact_integrated;
    if (exact > 0)
      s += fmt::format("  visibility   {}: {} patch pairs exact ({} proven clear, {} hidden, {} integrated at {} points{}); "
                       "partly hidden cluster pairs refined to patch pairs\n",
                       r.options ? r.options->visibility : "exact", exact, h.pairs_exact_clear, h.pairs_exact_hidden,
                       h.pairs_exact_integrated, h.exact_points,
                       h.pairs_exact_over_tolerance ? fmt::format(", {} above tolerance", h.pairs_exact_over_tolerance) : "");
    if (r.row_check && r.row_check->patches_checked > 0)
      s += fmt::format("  row sums     {} patches against {} rays cast from them: largest difference {:.2e}, {:.2g}x "
                       "the allowed (patch {}){}\n",
                       r.row_check->patches_checked, r.row_check->rays, r.row_check->max_difference,
                       r.row_check->max_ratio, r.row_check->worst_patch,
                       r.row_check->rows_skipped ? fmt::format("; the {} dark rows not sampled", r.row_check->rows_skipped) : "");
  } else if (r.ff) {
    s += ff_lines(*r.ff, r.row_check);
  }
  s += detail;
  if (r.solution) {
    const solver::Solution& sol = *r.solution;
    int iterations = 0;
    double residual = 0;
    for (const auto& c : sol.channels) {
      iterations = std::max(iterations, c.iterations);
      residual = std::max(residual, c.residual);
    }
    s += fmt::format("  solve        {}, {} channel(s), iterations {}, residual {:.2e}\n", solver::to_string(sol.method),
                     sol.channels.size(), iterations, residual);
    s += fmt::format("  energy       emitted {} W, absorbed {} W, escaped {} W\n", rgb_str(sol.emitted),
                     rgb_str(sol.absorbed), rgb_str(sol.escaped));
    const ErrorBound b = error_bound(r);
    if (b.exists && b.visibility_estimated)
      s += fmt::format("  error bound  |dL|/max L <= {:.1e} (form factors {:.1e} per row, visibility 3 sigma {:.1e} per "
                       "row (a ray estimate), solve residual {:.1e})\n",
                       b.total, b.form_factors, b.visibility, b.solve);
    else if (b.exists)
      s += fmt::format("  error bound  |dL|/max L <= {:.1e} (form factors {:.1e} per row, solve residual {:.1e})\n",
                       b.total, b.form_factors, b.solve);
    else
      s += "  error bound  none (fixed form-factor rule, or reflectance x row sum >= 1)\n";
  }
  // Round-off entries are counted, not a problem: a note, not a warning.
  for (const Finding& f : findings)
    s += fmt::format("  {}  {}\n", f.fatal ? "FAILED     " : f.key == "entries_roundoff" ? "note       " : "warning    ",
                     f.message);
  s += fmt::format("  phases       {}\n", phases_line(timer));
  if (!r.scene->report.seconds.empty()) {
    std::string stages;
    for (const auto& [stage, sec] : r.scene->report.seconds) stages += fmt::format("{}{} {:.3g} s", stages.empty() ? "" : ", ", stage, sec);
    s += fmt::format("  prepare      {}\n", stages);
  }
  return s;
}

// Exit status of a run from its findings: 3 (with the reasons on stderr, nothing written) when a fatal one
// exists, else 0.
int verdict(const std::vector<Finding>& findings, const std::string& what) {
  std::string why;
  for (const Finding& f : findings)
    if (f.fatal) why += (why.empty() ? "" : "; ") + f.message;
  if (why.empty()) return 0;
  std::fprintf(stderr, "lambert: error: %s cannot be trusted: %s; no output written\n", what.c_str(), why.c_str());
  return 3;
}

}  // namespace

int run_info(const CommonOptions& o) {
  PhaseTimer timer;
  CommonOptions silent = o;
  silent.quiet = true;  // warnings are listed below instead
  mesh::Scene scene = load(silent, timer);
  const auto& g = scene.geometry;
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  for (const Vec3& p : g.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  double total_area = 0;
  for (double a : g.area) total_area += a;
  std::vector<long> faces_per_material(scene.materials.size(), 0);
  std::vector<double> area_per_material(scene.materials.size(), 0);
  for (int p = 0; p < scene.patches(); ++p) {
    area_per_material[scene.material[p]] += g.area[p];
  }
  {
    int last = -1;
    for (int p = 0; p < scene.patches(); ++p)
      if (scene.face_id[p] != last) faces_per_material[scene.material[p]]++, last = scene.face_id[p];
  }
  std::string out;
  out += fmt::format("scene        {}\n", scene.source);
  out += fmt::format("input faces  {}\n", scene.input_faces);
  out += fmt::format("patches      {}\n", scene.patches());
  out += fmt::format("vertices     {}\n", scene.mesh.n_vertices());
  out += fmt::format("groups       {}\n", scene.groups.size());
  out += fmt::format("bounding box ({:.6g}, {:.6g}, {:.6g}) .. ({:.6g}, {:.6g}, {:.6g}) m, size {:.6g} x {:.6g} x {:.6g} m\n", lo.x(),
                     lo.y(), lo.z(), hi.x(), hi.y(), hi.z(), hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z());
  out += fmt::format("total area   {:.6g} m^2\n", total_area);
  const RGB power = scene.emitted_power();
  out += fmt::format("emitted power {} W (R, G, B: pi * sum of area * Le)\n", rgb_str(power, "{:.6g}"));
  out += fmt::format("materials    {}{}\n", scene.materials.size(), scene.grey() ? " (all grey: one channel)" : "");
  out += fmt::format("  {:<20} {:>8} {:>12}  {:<28} {}\n", "name", "faces", "area m^2", "reflectance", "emission W m^-2 sr^-1");
  for (size_t m = 0; m < scene.materials.size(); ++m) {
    const auto& mat = scene.materials[m];
    if (faces_per_material[m] == 0 && m == 0) continue;  // unused built-in default
    out += fmt::format("  {:<20} {:>8} {:>12.6g}  {:<28} {}\n", mat.name, faces_per_material[m], area_per_material[m],
                       rgb_str(mat.reflectance), rgb_str(mat.emission));
  }
  if (scene.report.warnings.empty()) {
    out += "warnings     none\n";
  } else {
    out += fmt::format("warnings     {}\n", scene.report.warnings.size());
    for (const auto& w : scene.report.warnings) out += "  - " + w + "\n";
  }
  std::fputs(out.c_str(), stdout);
  return 0;
}

int run_formfactors(const CommonOptions& o) {
  PhaseTimer timer;
  mesh::Scene scene = load(o, timer, /*solving=*/false);
  const OperatorChoice choice = choose_operator(o, scene.patches(), max_reflectance(scene.materials));
  formfactor::Stats st;
  formfactor::HierarchyStats hs;
  std::unique_ptr<formfactor::TransportOperator> op;
  {
    Progress progress(choice.hierarchical ? "hierarchy" : "form factors", !o.quiet);
    timer.start("form_factors");
    if (choice.hierarchical) {
      // The form factors are the output, not a radiance: every entry counts whatever the surfaces' materials (a
      // view-factor file carries no emission; its user brings the emissivities). Refinement by geometry alone.
      formfactor::HierarchyOptions h = hierarchy_options(o, scene, &progress);
      h.brightness.clear();
      op = std::make_unique<formfactor::HierarchicalOperator>(formfactor::build_hierarchy(scene.geometry, h, &hs));
      st = stats_of(hs, h);
    } else {
      const formfactor::Options f = ff_options(o, max_reflectance(scene.materials), &progress);
      op = std::make_unique<formfactor::DenseMatrixOperator>(formfactor::assemble(scene.geometry, f, &st));
    }
  }
  timer.start("checks");
  const formfactor::RowSumCheck row_check = check_rows(o, scene, *op, st);
  // Dense: aggregated in memory; hierarchical: streamed face by face while writing (no N x N anything).
  std::vector<formfactor::FaceEntry> entries;
  if (!choice.hierarchical) {
    timer.start("aggregate");
    entries = formfactor::aggregate_to_faces(static_cast<const formfactor::DenseMatrixOperator&>(*op), scene.geometry,
                                             scene.face_id, scene.input_faces);
    if (o.min_factor > 0)
      entries.erase(std::remove_if(entries.begin(), entries.end(), [&](const auto& e) { return e.F < o.min_factor; }),
                    entries.end());
  }
  timer.stop();
  Run run{.command = "formfactors", .options = &o, .scene = &scene, .ff = &st, .row_check = &row_check,
          .op_kind = choice.hierarchical ? "hierarchical" : "dense", .op_reason = choice.reason,
          .hierarchy = choice.hierarchical ? &hs : nullptr};
  const std::vector<Finding> findings = assess(run);
  const int status = verdict(findings, "the form factors");
  long long written = 0;
  if (status == 0) {
    timer.start("write");
    write_output(o.output, [&](std::ostream& os) {
      std::string buf;
      buf.reserve(1 << 20);
      auto put = [&](int i, int j, double F) {
        fmt::format_to(std::back_inserter(buf), "{},{},{:.12g}\n", i, j, F);
        ++written;
        if (buf.size() > (1 << 20) - 64) {
          os.write(buf.data(), std::streamsize(buf.size()));
          buf.clear();
        }
      };
      if (choice.hierarchical)
        formfactor::stream_faces(static_cast<const formfactor::HierarchicalOperator&>(*op), scene.geometry,
                                 scene.face_id, scene.input_faces, o.min_factor, put);
      else
        for (const auto& e : entries) put(e.i, e.j, e.F);
      os.write(buf.data(), std::streamsize(buf.size()));
    });
    timer.stop();
    run.entries_written = written;
    if (!o.stats.empty()) write_json(o.stats, stats_json(run, timer, findings));
    commit_outputs();  // all outputs or none
  }
  if (!o.quiet) {
    std::string out = summary(run, timer, findings, "");
    if (status == 0)
      out += fmt::format("  output       {} ({} entries{})\n", o.output, written,
                         o.min_factor > 0 ? fmt::format(" >= {:g}", o.min_factor) : std::string(" nonzero"));
    std::fputs(out.c_str(), stderr);
  }
  return status;
}

// What both solve paths share: refuse an untrustworthy result, write the .vtu, stats and summary.
// `detail` (adaptive lines) goes into the summary.
int finish_solve(const Run& run, PhaseTimer& timer, const std::string& detail) {
  const CommonOptions& o = *run.options;
  for (const auto& w : run.solution->warnings) say(o, "lambert: warning: " + w);
  const std::vector<Finding> findings = assess(run);
  const int status = verdict(findings, "the solution");
  if (status == 0) {
    timer.start("write");
    if (run.daylight && run.daylight->active()) {
      ColorField irradiance = run.solution->irradiance;  // gains the direct sky
      const auto extra = run.daylight->cell_arrays(*run.scene, run.solution->radiance, irradiance);
      write_output(o.output, [&](std::ostream& os) {
        io::write_vtu(os, *run.scene, run.solution->radiance, irradiance, o.crease_deg, extra);
      });
      run.daylight->write_outputs();
    } else {
      write_output(o.output, [&](std::ostream& os) {
        io::write_vtu(os, *run.scene, run.solution->radiance, run.solution->irradiance, o.crease_deg);
      });
    }
    timer.stop();
    if (!o.stats.empty()) write_json(o.stats, stats_json(run, timer, findings));
    commit_outputs();  // all outputs or none
  }
  if (!o.quiet) {
    std::string s = summary(run, timer, findings, detail);
    if (run.daylight) s += run.daylight->summary();
    if (status == 0) s += fmt::format("  output       {}\n", o.output);
    std::fputs(s.c_str(), stderr);
  }
  return status;
}

// --adaptive-budget: solve coarse, split where the estimated error is (refine/adaptive.hpp), re-solve.
int run_solve_adaptive(const CommonOptions& o, const solver::Options& so, PhaseTimer& timer) {
  if (o.op == "hierarchical")
    throw InputError("--operator hierarchical: adaptive refinement (--adaptive-budget) reuses dense matrices between "
                     "rounds; use --operator dense or auto");
  check_adaptive_budget(o);  // before any work
  mesh::PolygonSoup soup = read_input(o, timer);
  timer.start("prepare");
  mesh::Report prep_report;
  soup = mesh::prepare(soup, o.prepare, prep_report);
  timer.start("adaptive");
  refine::AdaptiveOptions ao = o.adaptive;
  ao.max_patches = o.adaptive_budget;
  ao.ff = ff_options(o, max_reflectance(soup.materials), nullptr);
  ao.solve = so;
  refine::AdaptiveResult r = refine::solve_adaptive(soup, ao);
  timer.stop();
  // The final scene's report covers validation; put the preparation's counts and warnings first.
  for (const auto& [k, v] : prep_report.counts) r.scene.report.counts[k] += v;
  r.scene.report.seconds.insert(r.scene.report.seconds.begin(), prep_report.seconds.begin(), prep_report.seconds.end());
  r.scene.report.warnings.insert(r.scene.report.warnings.begin(), prep_report.warnings.begin(), prep_report.warnings.end());
  for (const auto& w : r.scene.report.warnings) say(o, "lambert: warning: " + w);
  std::string rounds;
  for (int p : r.patches_per_round) rounds += (rounds.empty() ? "" : " -> ") + std::to_string(p);
  long long reused = 0, pairs = 0;
  for (const auto& rd : r.rounds) {
    reused += rd.pairs_reused;
    pairs += rd.pairs_total;
  }
  const std::string detail = fmt::format(
      "  adaptive     patches per round {} (stop: {}), estimated error E {:.3g} (tolerance {:.3g}), "
      "form-factor pairs reused {:.0f}%\n",
      rounds, r.stop, r.error_estimate.empty() ? 0.0 : r.error_estimate.back(), ao.tolerance,
      pairs ? 100.0 * double(reused) / double(pairs) : 0.0);
  const formfactor::Stats* last = r.rounds.empty() ? nullptr : &r.rounds.back().ff;
  Run run{.command = "solve", .options = &o, .scene = &r.scene, .ff = last, .solution = &r.solution, .adaptive = &r,
          .op_kind = "dense", .op_reason = "adaptive refinement reuses dense matrices between rounds"};
  formfactor::RowSumCheck row_check;
  if (r.final_matrix) {
    timer.start("checks");
    row_check = check_rows(o, r.scene, *r.final_matrix, *last);
    timer.stop();
    run.row_check = &row_check;
  }
  return finish_solve(run, timer, detail);
}

int run_solve(const CommonOptions& o) {
  PhaseTimer timer;
  solver::Options so = o.solve;
  so.method = solver::parse_method(o.method);  // fail on a bad name before any work
  if (o.adaptive_budget > 0) return run_solve_adaptive(o, so, timer);
  DaylightRun day(o);  // --sky, sensors, --units (checked before any work)
  mesh::Scene scene = load(o, timer, /*solving=*/!day.sky_active());  // a sky is an emitter
  const OperatorChoice choice = choose_operator(o, scene.patches(), max_reflectance(scene.materials));

  // The sky's emission term: after a dense assembly (its rows tell the sky gatherer which patches each patch
  // sees), before a hierarchical one (whose links are weighed by the emission they carry).
  ColorField Le = scene.emission_field();
  const auto sky_emission = [&](const formfactor::DenseMatrixOperator* dense) {
    if (!day.sky_active()) return;
    timer.start("sky");
    Le = day.emission(scene, dense, o.quiet);  // rho E_sky / pi and tau E_outside / pi added to Le
  };
  if (choice.hierarchical) sky_emission(nullptr);

  formfactor::Stats st;
  formfactor::HierarchyStats hs;
  std::unique_ptr<formfactor::TransportOperator> F;
  {
    Progress progress(choice.hierarchical ? "hierarchy" : "form factors", !o.quiet);
    timer.start("form_factors");
    if (choice.hierarchical) {
      const formfactor::HierarchyOptions h = hierarchy_options(o, scene, &progress, &Le);
      F = std::make_unique<formfactor::HierarchicalOperator>(formfactor::build_hierarchy(scene.geometry, h, &hs));
      st = stats_of(hs, h);
    } else {
      const formfactor::Options opt = ff_options(o, max_reflectance(scene.materials), &progress);
      F = std::make_unique<formfactor::DenseMatrixOperator>(formfactor::assemble(scene.geometry, opt, &st));
    }
  }
  timer.start("checks");
  const formfactor::RowSumCheck row_check = check_rows(o, scene, *F, st);

  if (!choice.hierarchical) sky_emission(dynamic_cast<const formfactor::DenseMatrixOperator*>(F.get()));
  timer.start("solve");
  solver::Solution sol;
  {
    Progress progress("solve", !o.quiet);
    so.progress = [&](int channel, int iteration, double residual) {
      progress.note(fmt::format("channel {} iteration {} residual {:.2e}", channel, iteration, residual));
      progress.update(std::clamp(std::log10(std::max(residual, 1e-300)) / std::log10(so.tolerance), 0.0, 1.0));
    };
    sol = solver::solve(*F, scene.geometry.area, scene.reflectance_field(), Le, so);
    so.progress = nullptr;
  }
  if (day.sensors_requested()) {
    timer.start("sensors");
    day.sensors(scene, sol.radiance, o.quiet);
  }
  timer.stop();
  const Run run{.command = "solve", .options = &o, .scene = &scene, .ff = &st, .solution = &sol, .row_check = &row_check,
                .daylight = &day, .op_kind = choice.hierarchical ? "hierarchical" : "dense", .op_reason = choice.reason,
                 .hierarchy = choice.hierarchical ? &hs : nullptr};
  return finish_solve(run, timer, "");
}

int run_verify_sphere(const VerifyOptions& v, const CommonOptions&) {
  verify::SphereCase c = v.sphere;
  c.solve.method = solver::parse_method(v.method);
  const verify::VerifyReport r = verify::verify_sphere(c);
  std::fputs(r.table.c_str(), stdout);
  return r.passed ? 0 : 4;
}

int run_verify_furnace(const VerifyOptions& v, const CommonOptions&) {
  verify::FurnaceCase c = v.furnace;
  c.solve.method = solver::parse_method(v.method);
  const verify::VerifyReport r = verify::verify_furnace(c);
  std::fputs(r.table.c_str(), stdout);
  return r.passed ? 0 : 4;
}

}  // namespace lambert::app
