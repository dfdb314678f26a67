// lambert: command-line front end. Parses options, runs the stages, prints progress and a summary,
// writes --stats JSON. All numerical work lives in the libraries.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <limits>
#include <optional>
#include <thread>

#include "commands.hpp"
#include "daylight.hpp"
#include "outputs.hpp"
#include "study.hpp"
#include "lambert/formfactor/assemble.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/mesh/types.hpp"

#ifndef LAMBERT_VERSION
#define LAMBERT_VERSION "dev"
#endif

using namespace lambert;

namespace {

// Numeric option checks. CLI11's Range lets NaN through (every comparison with NaN is false) and prints
// its bounds with std::to_string (DBL_MAX as 309 digits); these reject NaN and infinities for every
// numeric option and print bounds with %g.
CLI::Validator number_in(double lo, double hi, bool lo_open, const std::string& what) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        const char* begin = text.c_str();
        char* end = nullptr;
        const double v = std::strtod(begin, &end);
        if (end == begin || *end != '\0') return "'" + text + "' is not a number";
        if (!std::isfinite(v)) return "'" + text + "' is not a finite number; expected " + what;
        if ((lo_open ? !(v > lo) : !(v >= lo)) || !(v <= hi)) return "value " + text + " is out of range; expected " + what;
        return {};
      },
      "", "");
}
const double kMax = std::numeric_limits<double>::max();
const CLI::Validator Positive = number_in(0, kMax, true, "a number > 0");
const CLI::Validator NonNegative = number_in(0, kMax, false, "a number >= 0");
CLI::Validator Between(double lo, double hi) {
  return number_in(lo, hi, false, fmt::format("a number in [{}, {}]", lo, hi));
}

}  // namespace

int main(int argc, char** argv) {
  io::remove_temporaries_on_signal();  // an interrupted run leaves no temporary behind
  CLI::App app{
      "lambert " LAMBERT_VERSION " - radiosity (diffuse interreflection) solver.\n"
      "Reads OBJ+MTL / PLY / OFF scenes (metres; MTL Kd = diffuse reflectance, Ke = emitted radiance in\n"
      "W m^-2 sr^-1), computes form factors, solves L = Le + rho F L per colour channel and writes VTK\n"
      "(.vtu) for ParaView. See README.md for the conventions and every output array."};
  app.set_version_flag("--version", LAMBERT_VERSION);
  app.require_subcommand(1);
  app.fallthrough(false);

  app::CommonOptions common;  // every default comes from the libraries' options structs (commands.hpp)
  auto add_common = [&](CLI::App* sub, bool with_output) {
    sub->add_option("scene", common.scene, "Scene file: .obj (+ .mtl), .ply, .off or .stl (binary or ASCII; other extensions by content)")->required()->check(CLI::ExistingFile);
    sub->add_option("--materials", common.materials,
                    "JSON file mapping material names or input-face ranges to reflectance and emission "
                    "(overrides MTL values; see README)")
        ->check(CLI::ExistingFile);
    sub->add_option("--threads", common.threads, "Worker threads (default: all cores)")->check(Positive);
    sub->add_flag("--quiet,-q", common.quiet, "No progress lines, warnings or summary on stderr (errors still print)");
    if (with_output) sub->add_option("--stats", common.stats, "Write run statistics as JSON to this file");
    sub->add_flag("--no-repair", common.no_repair,
                  "Use the mesh as it is: no welding, degenerate-face removal or re-orientation "
                  "(self-intersections and T-junctions are still reported)");
    sub->add_option("--orient", common.orient,
                    "Face orientation repair: file (keep the file's winding), consistent (faces of a connected "
                    "surface agree with its majority), visibility (also turn a whole surface round when the rest "
                    "of the scene sees its back)")
        ->check(CLI::IsMember({"file", "consistent", "visibility"}))
        ->capture_default_str();
    sub->add_flag("--reverse-winding", common.prepare.reverse_winding,
                  "Reverse every face's winding as read, before any repair: a model exported inside out (mirrored "
                  "by a handedness conversion). The repair turns most of such a model back by itself, but not one "
                  "that is a single connected surface, nor lights facing a ceiling close by");
    sub->add_option("--max-edge", common.prepare.max_edge,
                    "Refine: split every edge longer than this (metres) so no patch edge exceeds it; 0 = off")
        ->check(NonNegative)
        ->capture_default_str();
  };
  auto add_formfactor = [&](CLI::App* sub, const char* tolerance_flag) {
    sub->add_flag("--no-visibility", common.no_visibility, "Ignore occlusion (every pair sees each other fully)");
    sub->add_option(tolerance_flag, common.ff.tolerance,
                    "Absolute error bound on each unoccluded form factor F_ij; 0 = automatic: 1e-8 when the "
                    "largest reflectance is <= 0.9, 9e-8 (1 - rho)/rho above (errors of one sign add up along rows "
                    "and the solve amplifies them by rho/(1 - rho))")
        ->check(NonNegative)
        ->capture_default_str();
    sub->add_option(std::string(tolerance_flag) == "--tolerance" ? "--rule" : "--ff-rule", common.ff_rule,
                    "Form-factor rule: adaptive (error-controlled by the tolerance), or a fixed rule for comparison: "
                    "point (centroid to centroid, the textbook one-point rule), gauss1..gauss8 (NxN source points, "
                    "exact inner integral); see docs/accuracy.md")
        ->check(CLI::IsMember({"adaptive", "point", "gauss1", "gauss2", "gauss3", "gauss4", "gauss5", "gauss6",
                               "gauss7", "gauss8"}))
        ->capture_default_str();
    sub->add_option("--visibility", common.visibility,
                    "Partially occluded pairs: exact (occluders clipped out of the contour integral, adaptive outer "
                    "rule to the form-factor tolerance), rays (ray estimate, --rays per pair), auto (exact, rays "
                    "only for pairs whose whole form factor is below the tolerance)")
        ->check(CLI::IsMember({"auto", "exact", "rays"}))
        ->capture_default_str();
    sub->add_option("--rays", common.ff.rays_per_pair,
                    "Visibility rays per pair that may be partially occluded (the rays path of --visibility; 16x / 81x for pairs "
                    "carrying 2 % / 10 % of a row, a quarter for those carrying less than 1/(64 N) of it)")
        ->check(Positive)
        ->capture_default_str();
    sub->add_option("--operator", common.op,
                    "Form-factor operator: dense (the N x N matrix, 8 N^2 bytes), hierarchical (clustered links, "
                    "memory and time below N^2, error set by --hierarchy-tolerance), auto (dense where it is faster "
                    "and fits in memory; the choice and why are printed)")
        ->check(CLI::IsMember({"dense", "hierarchical", "auto"}))
        ->capture_default_str();
    sub->add_option("--hierarchy-tolerance", common.hierarchy.tolerance,
                    "Hierarchical operator: radiance error admitted per link, relative to the brightest patch (links "
                    "from dark surfaces are accepted coarser); the summary reports the error admitted per row")
        ->check(number_in(0, 1, true, "a number in (0, 1)"))
        ->capture_default_str();
    sub->add_option("--enclosures", common.enclosures,
                    "Find the closed surfaces (rooms, apartments, shut boxes) and set pairs whose patches face "
                    "different cells to zero without rays (both operators), or ray-test them (off)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub->add_option("--portals", common.portals,
                    "With --enclosures on: close the openings (holes in the patches of a plane: doors, open "
                    "windows) by virtual portals, so the closed surfaces split into rooms, and set pairs in different "
                    "rooms whose shaft meets no portal between them to zero without rays (both operators; off: "
                    "apartments only)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
  };

  // solve
  auto* solve = app.add_subcommand("solve", "Solve the radiosity problem and write a .vtu for ParaView");
  add_common(solve, true);
  solve->add_option("-o,--output", common.output, "Output file (.vtu)")->required();
  add_formfactor(solve, "--ff-tolerance");
  solve->add_option("--method", common.method, "Solver: auto, jacobi, gauss-seidel, bicgstab, gmres")->capture_default_str();
  solve->add_option("--tolerance", common.solve.tolerance, "Relative residual at which the solve stops")
      ->check(Positive)
      ->capture_default_str();
  solve->add_option("--max-iterations", common.solve.max_iterations, "Iteration limit per channel")
      ->check(Positive)
      ->capture_default_str();
  solve->add_option("--crease", common.crease_deg,
                    "Per-vertex averages never cross an edge whose normals differ by more than this (degrees)")
      ->check(Between(0.0, 180.0))
      ->capture_default_str();
  solve->add_option("--adaptive-budget", common.adaptive_budget,
                    "Adaptive refinement up to this many patches: solve, estimate per patch the radiance variation "
                    "it does not resolve (jumps to neighbours, direct light and shadow edges across it, B.F "
                    "gather), split the patches carrying half of the estimated error, re-solve (docs/adaptive.md); "
                    "0 = off")
      ->check(NonNegative)
      ->capture_default_str();
  solve->add_option("--adaptive-tol", common.adaptive.tolerance,
                    "Stop refining when the estimated relative L2 error of the radiance is at most this")
      ->check(Positive)
      ->capture_default_str();
  solve->add_option("--adaptive-rounds", common.adaptive.max_rounds, "Refinement rounds at most (solves = rounds + 1)")
      ->check(NonNegative)
      ->capture_default_str();

  // solve: daylight and photometry (app/daylight.hpp, daylight/)
  solve->add_option("--sky", common.sky,
                    "Sky at infinity lighting the scene through every direction in which it sees no geometry: "
                    "uniform[:L] or cie-overcast[:Lz] (L, Lz the (zenith) radiance in W m^-2 sr^-1, or luminance in "
                    "cd m^-2 with --units photometric; default: 10,000 lx on an unobstructed horizontal plane)");
  solve->add_option("--up", common.up, "Zenith direction of the sky: x, y, z, -x, -y or -z")->capture_default_str();
  solve->add_option("--ground-reflectance", common.ground_reflectance,
                    "Reflectance of the external ground seen below the horizon (lit by the unobstructed sky)")
      ->check(Between(0.0, 1.0))
      ->capture_default_str();
  solve->add_option("--units", common.units,
                    "radiometric (W m^-2, W m^-2 sr^-1) or photometric (lux, cd m^-2: 179 lm/W x (0.265 R + 0.670 G + "
                    "0.065 B)); photometric adds 'illuminance' and 'luminance' to the .vtu")
      ->check(CLI::IsMember({"radiometric", "photometric"}))
      ->capture_default_str();
  solve->add_option("--sensors", common.sensors, "Sensor points: CSV x,y,z,nx,ny,nz (metres; a header line allowed)")
      ->check(CLI::ExistingFile);
  solve->add_option("--work-plane", common.work_plane,
                    "Sensors on a work plane this high (m) above the floors (with --grid; see README)")
      ->check(Positive);
  solve->add_option("--grid", common.grid, "Work-plane grid spacing (m)")->check(Positive);
  solve->add_option("--grid-inset", common.grid_inset,
                    "Work-plane nodes keep this distance (m) from walls and anything at work-plane height")
      ->check(NonNegative)
      ->capture_default_str();
  solve->add_option("--sensors-out", common.sensors_out,
                    "Sensor results: CSV x,y,z,illuminance,daylight_factor (input order) and a .vtu of points beside it");
  solve->add_option("--sensor-rays", common.sensor_rays,
                    "Visibility rays from a sensor to each patch that may be partly hidden")
      ->check(Positive)
      ->capture_default_str();

  // info
  auto* info = app.add_subcommand("info", "Print patches, materials, bounding box, emitted power and validation warnings");
  add_common(info, false);

  // formfactors
  auto* ff = app.add_subcommand("formfactors", "Compute form factors and write i,j,F_ij per nonzero entry (input-face indices)");
  add_common(ff, true);
  ff->add_option("-o,--output", common.output, "Output file (.csv): one line i,j,F_ij per nonzero entry, no header")->required();
  add_formfactor(ff, "--tolerance");
  ff->add_option("--min-factor", common.min_factor, "Write only entries F_IJ >= this (0 = every nonzero entry)")
      ->check(NonNegative)
      ->capture_default_str();

  // verify
  auto* verify = app.add_subcommand("verify", "Solve cases with exact answers and compare");
  verify->require_subcommand(1);
  app::VerifyOptions vo;
  auto* sphere = verify->add_subcommand("sphere", "Closed icosphere with inward normals: exact answer E0/(1-rho), or the continuum formula");
  sphere->add_option("--subdivisions", vo.sphere.subdivisions, "Icosphere subdivision level K (20*4^K triangles)")
      ->check(Between(0, 6))
      ->capture_default_str();
  sphere->add_option("--rho", vo.sphere.rho, "Reflectance in [0,1)")->check(Between(0.0, 0.999999999))->capture_default_str();
  sphere->add_option("--emission", vo.sphere.emission, "uniform | cap | linear")
      ->check(CLI::IsMember({"uniform", "cap", "linear"}))
      ->capture_default_str();
  sphere->add_option("--method", vo.method, "auto, jacobi, gauss-seidel, bicgstab, gmres")->capture_default_str();
  sphere->add_option("--threads", common.threads, "Worker threads (default: all cores)")->check(Positive);
  auto* furnace = verify->add_subcommand("furnace", "Closed room with an occluding block, uniform E0 and rho: exact answer E0/(1-rho)");
  furnace->add_option("--divisions", vo.furnace.divisions, "Quads per room face edge")
      ->check(Between(1, 64))
      ->capture_default_str();
  furnace->add_option("--rho", vo.furnace.rho, "Reflectance in [0,1)")->check(Between(0.0, 0.999999999))->capture_default_str();
  furnace->add_option("--method", vo.method, "auto, jacobi, gauss-seidel, bicgstab, gmres")->capture_default_str();
  furnace->add_option("--threads", common.threads, "Worker threads (default: all cores)")->check(Positive);
  std::string furnace_visibility = "rays";
  furnace->add_option("--visibility", furnace_visibility,
                      "Partially occluded pairs: rays (--rays per pair, default 256 here), exact (occluders clipped "
                      "out of the contour integral), auto")
      ->check(CLI::IsMember({"auto", "exact", "rays"}))
      ->capture_default_str();
  furnace->add_option("--rays", vo.furnace.ff.rays_per_pair, "Visibility rays per pair (the rays path)")
      ->check(Positive)
      ->capture_default_str();

  // study
  app::StudyOptions so;
  auto* study = app.add_subcommand(
      "study", "Accuracy against cost for every knob on cases with exact answers: writes DIR/study.csv "
               "(plots: scripts/plot_study.py; see docs/accuracy.md)");
  study->add_option("--out", so.out, "Output directory")->capture_default_str();
  study->add_flag("--quick", so.quick, "The small grid CI runs (under 2 minutes on 2 cores)");
  study->add_option("--threads", common.threads, "Worker threads (default: all cores)")->check(Positive);
  study->add_flag("--quiet,-q", so.quiet, "No per-run lines on stderr");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every command-line error is bad input: exit 1 (not CLI11's 104..109).
    return app.exit(e) == 0 ? 0 : 1;
  }

  common.prepare.repair = !common.no_repair;
  common.prepare.max_patches = app::max_patches_in_memory(common);  // refuse a --max-edge whose patches cannot be solved
  common.prepare.orient = mesh::parse_orientation(common.orient);

  std::optional<tbb::global_control> threads;
  if (common.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, size_t(common.threads));

  try {
    if (solve->parsed() || ff->parsed()) app::declare_files(common);  // refuse bad output paths before any work
    if (solve->parsed()) app::declare_daylight_files(common);
    if (solve->parsed()) return app::run_solve(common);
    if (info->parsed()) return app::run_info(common);
    if (ff->parsed()) return app::run_formfactors(common);
    if (sphere->parsed()) return app::run_verify_sphere(vo, common);
    if (furnace->parsed()) {
      vo.furnace.ff.visibility_method = formfactor::parse_visibility_method(furnace_visibility);
      return app::run_verify_furnace(vo, common);
    }
    if (study->parsed()) return app::run_study(so);
  } catch (const InternalError& e) {
    std::fprintf(stderr, "lambert: internal error: %s\n", e.what());
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "lambert: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "lambert: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lambert: internal error: %s\n", e.what());
    return 2;
  }
  return 0;
}
