#pragma once
// The CLI's subcommands. Each returns the process exit status; bad input throws lambert::InputError.
// Every default lives in the libraries' options structs below; the CLI binds its flags to their fields
// (and shows those defaults in --help), so the CLI and the library never disagree.
#include <string>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/refine/adaptive.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/verify/verify.hpp"

namespace lambert::app {

struct CommonOptions {
  std::string scene, materials, output, stats;
  int threads = 0;  // 0 = all cores
  bool quiet = false;
  bool no_repair = false;      // --no-repair: prepare.repair = false (detection still runs)
  std::string orient = "visibility";  // --orient: prepare.orient = mesh::parse_orientation(orient)
  bool no_visibility = false;  // --no-visibility: ff.visibility = false
  std::string ff_rule = "adaptive";  // formfactor::parse_rule: adaptive | point | gauss1..gauss8
  std::string visibility = "rays";   // --visibility: formfactor::parse_visibility_method: auto | exact | rays
  std::string method = "auto";       // solver::parse_method
  double crease_deg = mesh::VertexSplit::kDefaultCreaseDeg;
  int adaptive_budget = 0;           // 0 = no adaptive refinement; else adaptive.max_patches
  mesh::PrepareOptions prepare;      // --max-edge
  formfactor::Options ff;            // --ff-tolerance / --tolerance (formfactors), --rays
  solver::Options solve;             // --tolerance (solve), --max-iterations
  refine::AdaptiveOptions adaptive;  // --adaptive-tol, --adaptive-rounds
  std::string enclosures = "on";     // --enclosures: on | off (Options and HierarchyOptions::enclosures)
  std::string portals = "on";        // --portals: on | off (HierarchyOptions::portals)
  std::string op = "auto";           // --operator: dense | hierarchical | auto (commands.cpp: choose_operator)
  formfactor::HierarchyOptions hierarchy;  // --hierarchy-tolerance
  double min_factor = 0;             // formfactors --min-factor: entries below are not written
  // Daylight and photometry (app/daylight.hpp): --sky, --up, --ground-reflectance, --units, --sensors,
  // --work-plane, --grid, --grid-inset, --sensors-out, --sensor-rays
  std::string sky, up = "y", units = "radiometric", sensors, sensors_out;
  double ground_reflectance = 0.2, work_plane = 0, grid = 0, grid_inset = 0.5;
  int sensor_rays = 16;
};

struct VerifyOptions {
  verify::SphereCase sphere;
  verify::FurnaceCase furnace;
  std::string method = "auto";  // solver::parse_method, for both cases
};

int run_solve(const CommonOptions& o);
int run_info(const CommonOptions& o);
int run_formfactors(const CommonOptions& o);
int run_verify_sphere(const VerifyOptions& v, const CommonOptions& o);
int run_verify_furnace(const VerifyOptions& v, const CommonOptions& o);

}  // namespace lambert::app
