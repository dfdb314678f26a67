#pragma once
// The CLI's subcommands. Each returns the process exit status; bad input throws lambert::InputError.
#include <string>

namespace lambert::app {

struct CommonOptions {
  std::string scene, materials, output, stats;
  int threads = 0;  // 0 = all cores
  bool quiet = false;
  bool no_repair = false;  // skip mesh::prepare's repairs (detection still runs)
  double max_edge = 0;     // m; 0 = no refinement
  std::string orient = "visibility";  // mesh::parse_orientation: file | consistent | visibility
  // form factors (0 = module default)
  bool no_visibility = false;
  double ff_tolerance = 0;
  std::string ff_rule = "adaptive";  // formfactor::parse_rule: adaptive | point | gauss1..gauss8
  int rays_per_pair = 0;
  // solve
  std::string method = "auto";
  double solve_tolerance = 1e-8;
  int max_iterations = 0;
  double crease_deg = 30.0;
  // adaptive refinement (0 = off)
  int adaptive_budget = 0;
  double adaptive_tolerance = 0.01;  // E (estimated relative L2 error); 0.01 lets the budget decide
  int adaptive_rounds = 12;          // each round splits ~half the error: 12 rounds reach budgets of ~10^4
};

struct VerifyOptions {
  int subdivisions = -1;  // -1 = solver's default
  int divisions = -1;
  double rho = -1;
  std::string emission = "uniform";
  std::string method = "auto";
};

int run_solve(const CommonOptions& o);
int run_info(const CommonOptions& o);
int run_formfactors(const CommonOptions& o);
int run_verify_sphere(const VerifyOptions& v, const CommonOptions& o);
int run_verify_furnace(const VerifyOptions& v, const CommonOptions& o);

}  // namespace lambert::app
