#pragma once
// Radiosity solve: (I - diag(rho) F) L = Le for each colour channel, L in W m^-2 sr^-1.
// F is seen only through formfactor::TransportOperator (y = F x, rows, diagonal, row sums), so a
// sparse or hierarchical operator can replace the dense matrix without touching this code.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lambert/formfactor/operator.hpp"
#include "lambert/mesh/types.hpp"

namespace lambert::solver {

enum class Method {
  Auto,         // see choose_method()
  Jacobi,       // successive substitution L <- Le + rho F L (the Neumann series): ~ln(tol)/ln(rho_max) sweeps
  GaussSeidel,  // in-place sweeps in patch order; over-relaxed (SOR) when Options::omega != 1
  BiCGSTAB,     // van der Vorst's BiCGSTAB (written here on Eigen vectors), 2 products F x per iteration
  GMRES,        // restarted GMRES(Options::restart) from Eigen's unsupported IterativeSolvers, 1 product per iteration
};
// Names: "auto", "jacobi", "gauss-seidel" (also "gs", "sor"), "bicgstab", "gmres"; case-insensitive.
// Throws InputError listing the valid names.
Method parse_method(const std::string& name);
std::string to_string(Method method);

// Gauss-Seidel needs an operator with stored rows (TransportOperator::has_rows()); solve() refuses it otherwise
// (InputError). Auto never picks Gauss-Seidel.
// What Auto resolves to, from the largest reflectance and the patch count (GMRES needs fewer products F x
// than Jacobi at every rho > 0, increasingly so as rho -> 1: docs/benchmarks_solver.md; Gauss-Seidel sweeps
// are sequential):
//   rho_max == 0                                   -> Jacobi (L = Le, one product for the residual)
//   (restart + 1) * patches * 8 bytes > 2 GiB      -> BiCGSTAB (7 vectors, for huge matrix-free operators)
//   otherwise                                      -> GMRES
Method choose_method(double rho_max, int patches, int restart = 30);

struct Options {
  Method method = Method::Auto;
  // Stop when ||Le + rho F L - L||_2 / max(||L||_2, ||Le||_2) <= tolerance, per channel (the floor
  // ||Le|| only matters far from the solution: the exact L >= Le >= 0).
  double tolerance = 1e-8;
  // Per channel: sweeps (Jacobi, Gauss-Seidel) or Krylov iterations. Krylov needs ~20; Jacobi at
  // rho = 0.999 ~10^4 (raise it, or use Auto).
  int max_iterations = 10000;
  double omega = 1.0;          // Gauss-Seidel relaxation factor, in (0, 2); 1 = plain Gauss-Seidel
  int restart = 30;            // GMRES restart length (Krylov vectors kept), >= 1
  // Optional start (patches x 3, W m^-2 sr^-1), e.g. the radiance of a previous solve after a small
  // change of rho or Le. Empty: start from Le (the first Neumann term).
  ColorField initial_guess;
  // Called after each iteration (GMRES: each restart cycle) with the relative residual of the history.
  std::function<void(int channel, int iteration, double residual)> progress;
};

// A stop that is not "converged" leaves the best iterate found in the Solution and converged = false.
// Divergence: residual (absolute) above 1e4 x its smallest value so far, or not finite.
// Stagnation: the smallest relative residual improved by less than 0.1 % over the last
// 50 iterations (Jacobi, Gauss-Seidel, BiCGSTAB) or the last 2 restart cycles (GMRES).
struct ChannelReport {
  int iterations = 0;   // sweeps or Krylov iterations
  int matvecs = 0;      // products y = F x (Gauss-Seidel: start and convergence checks; sweeps use row_dot)
  double residual = 0;  // relative residual of the returned L, recomputed from it (as in Options::tolerance)
  // The same residual in the max norm: max_i |Le + rho F L - L|_i / max(max|L|, max|Le|); the solve's part of
  // the error bound of docs/physics.md §5.
  double residual_max = 0;
  std::string stop;     // "converged" | "max_iterations" | "stagnation" | "divergence"
  // Relative residuals: [0] of the start, then one per iteration (GMRES: per restart cycle). Exact for
  // Jacobi (entry k is that of iterate k) and GMRES; the running residual (each row at its update) for
  // Gauss-Seidel; the recurrence residual for BiCGSTAB. Convergence is always confirmed exactly.
  std::vector<double> history;
};

struct Solution {
  ColorField radiance;    // patches x 3, W m^-2 sr^-1
  ColorField irradiance;  // patches x 3, W m^-2: H = pi F L
  Method method = Method::Auto;  // the method actually used (never Auto)
  // One report per solved channel: 1 when grey (all three columns of rho and Le equal; the result
  // is copied to all three), else 3 (R, G, B; a channel equal to an earlier one reuses its result).
  std::vector<ChannelReport> channels;
  RGB emitted = RGB::Zero();   // W: pi sum_i A_i Le_i
  RGB absorbed = RGB::Zero();  // W: sum_i A_i (1 - rho_i) H_i
  RGB escaped = RGB::Zero();   // W: pi sum_i A_i L_i (1 - sum_j F_ij), the row-sum deficit of open scenes
  // max over channels with emission of |emitted - absorbed - escaped| / emitted (0 if nothing emits).
  // Non-zero from the solve residual and from any reciprocity error of F.
  double energy_residual = 0;
  bool converged = false;      // every channel stopped with "converged"
  double seconds = 0;          // wall time of the solve
  std::vector<std::string> warnings;  // e.g. rho_i * row sum_i >= 1 somewhere (Neumann series may diverge)
};

// Keeps F (and its row sums) so that a change of emission or reflectance re-solves without
// recomputing form factors. Thread-safe for concurrent solve() calls if F's methods are.
class Solver {
 public:
  // area: m^2 per patch, > 0, size F->size() (preconditions: InternalError via LAMBERT_CHECK otherwise).
  Solver(std::shared_ptr<const formfactor::TransportOperator> F, std::vector<double> area);

  // rho: patches x 3 in [0, 1); Le: patches x 3, >= 0 (W m^-2 sr^-1); all finite.
  // Throws InputError naming the patch and channel of the first bad value, or bad options.
  Solution solve(const ColorField& rho, const ColorField& Le, const Options& options = {}) const;

  int size() const { return static_cast<int>(area_.size()); }
  const formfactor::TransportOperator& transport() const { return *F_; }
  const std::vector<double>& area() const { return area_; }
  const std::vector<double>& row_sums() const { return row_sum_; }

 private:
  std::shared_ptr<const formfactor::TransportOperator> F_;
  std::vector<double> area_;
  std::vector<double> row_sum_;
};

// One-shot form of Solver(F, area).solve(rho, Le, options); F must outlive the call only.
Solution solve(const formfactor::TransportOperator& F, const std::vector<double>& area, const ColorField& reflectance,
               const ColorField& emission, const Options& options = {});

}  // namespace lambert::solver
