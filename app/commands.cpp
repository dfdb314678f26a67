#include "commands.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/io/atomic_file.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/io/vtk.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/solver/adaptive.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/solver/verify.hpp"
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

json rgb_json(const RGB& c) { return json::array({c[0], c[1], c[2]}); }

// Reads the scene file and applies --materials.
mesh::PolygonSoup read_input(const CommonOptions& o, PhaseTimer& timer) {
  timer.start("load");
  mesh::PolygonSoup soup = io::read_soup(o.scene);
  if (!o.materials.empty()) io::apply_materials_json(soup, o.materials);
  return soup;
}

mesh::PrepareOptions prepare_options(const CommonOptions& o) {
  mesh::PrepareOptions prep;
  prep.repair = !o.no_repair;
  prep.max_edge = o.max_edge;
  prep.orient = mesh::parse_orientation(o.orient);
  return prep;
}

// Reads, applies --materials, prepares, validates. Prints validation warnings unless quiet.
mesh::Scene load(const CommonOptions& o, PhaseTimer& timer) {
  const mesh::PolygonSoup soup = read_input(o, timer);
  timer.start("prepare");
  mesh::Scene scene = mesh::prepare_and_build(soup, prepare_options(o));
  timer.stop();
  for (const auto& w : scene.report.warnings) say(o, "lambert: warning: " + w);
  return scene;
}

json report_json(const mesh::Report& r) {
  json j;
  j["counts"] = r.counts;
  j["messages"] = r.warnings;
  j["worst_nonplanarity_m"] = r.worst_nonplanarity;
  j["worst_nonplanar_face"] = r.worst_nonplanar_face;
  return j;
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
  io::write_file_atomically(path, [&](std::ostream& os) { os << j.dump(2) << '\n'; });
}

formfactor::Options ff_options(const CommonOptions& o, Progress* progress) {
  formfactor::Options f;
  f.visibility = !o.no_visibility;
  if (o.ff_tolerance > 0) f.tolerance = o.ff_tolerance;
  formfactor::parse_rule(o.ff_rule, f.rule, f.order);
  if (o.rays_per_pair > 0) f.rays_per_pair = o.rays_per_pair;
  f.threads = o.threads;
  if (progress) f.progress = [progress](double x) { progress->update(x); };
  return f;
}

json ff_json(const formfactor::Stats& s, const formfactor::Options& f) {
  json j;
  j["rule"] = formfactor::to_string(f.rule, f.order);
  j["tolerance"] = f.tolerance;
  j["pairs_reused"] = s.pairs_reused;
  j["visibility"] = f.visibility;
  j["rays_per_pair"] = f.rays_per_pair;
  j["pairs_total"] = s.pairs_total;
  j["pairs_orientation_culled"] = s.pairs_orientation_culled;
  j["pairs_shaft_culled"] = s.pairs_shaft_culled;
  j["pairs_ray_tested"] = s.pairs_ray_tested;
  j["pairs_by_method"] = s.pairs_by_method;
  j["rays_cast"] = s.rays_cast;
  j["scene_can_occlude"] = s.scene_can_occlude;
  j["row_sum"] = {{"min", s.row_sum_min}, {"max", s.row_sum_max}, {"mean", s.row_sum_mean}};
  j["reciprocity_residual"] = s.reciprocity_residual;
  j["entries_outside_unit"] = s.entries_outside_unit;
  j["seconds"] = s.seconds;
  j["bytes"] = s.bytes;
  return j;
}

std::string ff_summary(const formfactor::Stats& s) {
  return fmt::format(
      "  pairs        {} ({} culled by orientation, {} proven unoccluded, {} ray-tested), rays {}\n"
      "  form factors row sum min/mean/max {:.6f} / {:.6f} / {:.6f}, reciprocity residual {:.2e}, outside [0,1]: {}\n",
      s.pairs_total, s.pairs_orientation_culled, s.pairs_shaft_culled, s.pairs_ray_tested, s.rays_cast, s.row_sum_min,
      s.row_sum_mean, s.row_sum_max, s.reciprocity_residual, s.entries_outside_unit);
}

std::string scene_line(const mesh::Scene& scene) {
  std::string extra;
  if (scene.patches() != scene.input_faces)
    extra = fmt::format(", from {} input faces", scene.input_faces);
  return fmt::format("  patches      {}{}; {} vertices, {} materials\n", scene.patches(), extra, scene.mesh.n_vertices(),
                     scene.materials.size());
}

json base_stats(const mesh::Scene& scene) {
  json j;
  j["version"] = LAMBERT_VERSION;
  j["scene"] = scene.source;
  j["patches"] = scene.patches();
  j["input_faces"] = scene.input_faces;
  j["vertices"] = scene.mesh.n_vertices();
  j["materials"] = scene.materials.size();
  j["warnings"] = report_json(scene.report);
  return j;
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
  mesh::Scene scene = load(o, timer);
  formfactor::Stats st;
  Progress progress("form factors", !o.quiet);
  const formfactor::Options f = ff_options(o, &progress);
  timer.start("form_factors");
  const formfactor::DenseMatrixOperator F = formfactor::assemble(scene.geometry, f, &st);
  progress.done();
  timer.start("aggregate");
  const auto entries = formfactor::aggregate_to_faces(F, scene.geometry, scene.face_id, scene.input_faces);
  timer.start("write");
  io::write_file_atomically(o.output, [&](std::ostream& os) {
    std::string buf;
    buf.reserve(1 << 20);
    for (const auto& e : entries) {
      fmt::format_to(std::back_inserter(buf), "{},{},{:.12g}\n", e.i, e.j, e.F);
      if (buf.size() > (1 << 20) - 64) {
        os.write(buf.data(), std::streamsize(buf.size()));
        buf.clear();
      }
    }
    os.write(buf.data(), std::streamsize(buf.size()));
  });
  timer.stop();
  if (!o.stats.empty()) {
    json j = base_stats(scene);
    j["phases"] = phases_json(timer);
    j["form_factors"] = ff_json(st, f);
    j["entries_written"] = entries.size();
    j["iterations"] = 0;
    j["residual"] = 0.0;
    write_json(o.stats, j);
  }
  if (!o.quiet) {
    std::string s = fmt::format("lambert formfactors {}\n", o.scene) + scene_line(scene) + ff_summary(st);
    s += fmt::format("  phases       {}\n  output       {} ({} nonzero entries)\n", phases_line(timer), o.output, entries.size());
    std::fputs(s.c_str(), stderr);
  }
  if (st.entries_outside_unit > 0) {
    std::fprintf(stderr, "lambert: error: %lld form factors outside [0, 1] (written unclamped; see --stats)\n",
                 st.entries_outside_unit);
    return 3;
  }
  return 0;
}

// What the two solve paths share: refuse a non-converged result, write the .vtu, stats and summary.
// `extra` goes into the stats JSON, `detail` (form-factor or adaptive lines) into the summary.
int finish_solve(const CommonOptions& o, const mesh::Scene& scene, const solver::Solution& sol,
                 const solver::Options& so, PhaseTimer& timer, json extra, const std::string& detail) {
  for (const auto& w : sol.warnings) say(o, "lambert: warning: " + w);
  if (!sol.converged) {
    std::string why;
    for (size_t c = 0; c < sol.channels.size(); ++c)
      why += fmt::format(" channel {}: {} after {} iterations, residual {:.3e};", c, sol.channels[c].stop,
                         sol.channels[c].iterations, sol.channels[c].residual);
    std::fprintf(stderr, "lambert: error: the solve did not reach the tolerance %g:%s no output written (try "
                 "--method bicgstab or a larger --max-iterations)\n", so.tolerance, why.c_str());
    return 3;
  }
  timer.start("write");
  io::write_vtu(o.output, scene, sol.radiance, sol.irradiance, o.crease_deg);
  timer.stop();

  int max_iterations = 0;
  double max_residual = 0;
  json channels = json::array();
  for (const auto& c : sol.channels) {
    max_iterations = std::max(max_iterations, c.iterations);
    max_residual = std::max(max_residual, c.residual);
    channels.push_back({{"iterations", c.iterations}, {"matvecs", c.matvecs}, {"residual", c.residual}, {"stop", c.stop}});
  }
  if (!o.stats.empty()) {
    json j = base_stats(scene);
    j.update(extra);
    j["output"] = o.output;
    j["phases"] = phases_json(timer);
    j["method"] = solver::to_string(sol.method);
    j["tolerance"] = so.tolerance;
    j["iterations"] = max_iterations;
    j["residual"] = max_residual;
    j["channels"] = channels;
    j["solver_warnings"] = sol.warnings;
    j["energy"] = {{"emitted_W", rgb_json(sol.emitted)},
                   {"absorbed_W", rgb_json(sol.absorbed)},
                   {"escaped_W", rgb_json(sol.escaped)},
                   {"balance_residual", sol.energy_residual}};
    write_json(o.stats, j);
  }
  if (!o.quiet) {
    std::string s = fmt::format("lambert solve {}\n", o.scene) + scene_line(scene) + detail;
    s += fmt::format("  solve        {}, {} channel(s), iterations {}, residual {:.2e}\n", solver::to_string(sol.method),
                     sol.channels.size(), max_iterations, max_residual);
    s += fmt::format("  energy       emitted {} W, absorbed {} W, escaped {} W, balance residual {:.1e}\n",
                     rgb_str(sol.emitted), rgb_str(sol.absorbed), rgb_str(sol.escaped), sol.energy_residual);
    s += fmt::format("  phases       {}\n  output       {}\n", phases_line(timer), o.output);
    std::fputs(s.c_str(), stderr);
  }
  return 0;
}

// --adaptive-budget: solve coarse, split where the estimated error is (solver/adaptive.hpp), re-solve.
int run_solve_adaptive(const CommonOptions& o, const solver::Options& so, PhaseTimer& timer) {
  mesh::PolygonSoup soup = read_input(o, timer);
  timer.start("prepare");
  mesh::Report prep_report;
  soup = mesh::prepare(soup, prepare_options(o), prep_report);
  timer.start("adaptive");
  solver::AdaptiveOptions ao;
  ao.max_patches = o.adaptive_budget;
  ao.tolerance = o.adaptive_tolerance;
  ao.max_rounds = o.adaptive_rounds;
  ao.ff = ff_options(o, nullptr);
  ao.solve = so;
  solver::AdaptiveResult r = solver::solve_adaptive(soup, ao);
  timer.stop();
  // The final scene's report covers validation; put the preparation's counts and warnings first.
  for (const auto& [k, v] : prep_report.counts) r.scene.report.counts[k] += v;
  r.scene.report.warnings.insert(r.scene.report.warnings.begin(), prep_report.warnings.begin(), prep_report.warnings.end());
  for (const auto& w : r.scene.report.warnings) say(o, "lambert: warning: " + w);
  json extra;
  json per_round = json::array();
  for (const auto& rd : r.rounds)
    per_round.push_back({{"patches", rd.patches}, {"pairs_total", rd.pairs_total}, {"pairs_reused", rd.pairs_reused},
                         {"error_estimate", rd.error_estimate}, {"marked", rd.marked}, {"split", rd.split},
                         {"seconds", {{"form_factors", rd.assemble_seconds}, {"solve", rd.solve_seconds},
                                      {"indicators", rd.indicator_seconds}}}});
  extra["adaptive"] = {{"patches_per_round", r.patches_per_round}, {"max_indicator", r.max_indicator},
                       {"error_estimate", r.error_estimate}, {"rounds", per_round},
                       {"stop", r.stop}, {"not_splittable", r.not_splittable}, {"budget", ao.max_patches},
                       {"tolerance", ao.tolerance}};
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
  return finish_solve(o, r.scene, r.solution, so, timer, extra, detail);
}

int run_solve(const CommonOptions& o) {
  PhaseTimer timer;
  solver::Options so;
  so.method = solver::parse_method(o.method);  // fail on a bad name before any work
  so.tolerance = o.solve_tolerance;
  if (o.max_iterations > 0) so.max_iterations = o.max_iterations;
  if (o.adaptive_budget > 0) return run_solve_adaptive(o, so, timer);
  mesh::Scene scene = load(o, timer);

  formfactor::Stats st;
  formfactor::DenseMatrixOperator F;
  const formfactor::Options f = [&] {
    Progress progress("form factors", !o.quiet);
    formfactor::Options opt = ff_options(o, &progress);
    timer.start("form_factors");
    F = formfactor::assemble(scene.geometry, opt, &st);
    opt.progress = nullptr;
    return opt;
  }();

  timer.start("solve");
  solver::Solution sol;
  {
    Progress progress("solve", !o.quiet);
    so.progress = [&](int channel, int iteration, double residual) {
      progress.note(fmt::format("channel {} iteration {} residual {:.2e}", channel, iteration, residual));
      progress.update(std::clamp(std::log10(std::max(residual, 1e-300)) / std::log10(so.tolerance), 0.0, 1.0));
    };
    sol = solver::solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field(), so);
    so.progress = nullptr;
  }
  timer.stop();
  json extra;
  extra["form_factors"] = ff_json(st, f);
  return finish_solve(o, scene, sol, so, timer, extra, ff_summary(st));
}

int run_verify_sphere(const VerifyOptions& v, const CommonOptions&) {
  solver::SphereCase c;
  if (v.subdivisions >= 0) c.subdivisions = v.subdivisions;
  if (v.rho >= 0) c.rho = v.rho;
  c.emission = v.emission;
  c.method = solver::parse_method(v.method);
  const solver::VerifyReport r = solver::verify_sphere(c);
  std::fputs(r.table.c_str(), stdout);
  return r.passed ? 0 : 4;
}

int run_verify_furnace(const VerifyOptions& v, const CommonOptions&) {
  solver::FurnaceCase c;
  if (v.divisions > 0) c.divisions = v.divisions;
  if (v.rho >= 0) c.rho = v.rho;
  c.method = solver::parse_method(v.method);
  const solver::VerifyReport r = solver::verify_furnace(c);
  std::fputs(r.table.c_str(), stdout);
  return r.passed ? 0 : 4;
}

}  // namespace lambert::app
