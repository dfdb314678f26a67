#pragma once
// Adaptive refinement: solve coarse, refine only where the solution is under-resolved, re-solve.
//
// Each round builds a Scene from the current soup (mesh::build_scene), assembles F and solves; the
// indicators of indicators.hpp give eta_p per patch (the largest of those enabled).
// Error estimate and marking (as in adaptive finite elements): E = sqrt(sum_p A_p eta_p^2 /
// sum_p A_p R_p^2), R_p the patch's reflected radiance (largest channel, relative to its maximum): the
// relative L2 size of the radiance variation the patches do not resolve. Stop when E <= tolerance.
// Otherwise Doerfler marking: the patches with the largest A_p eta_p^2, until they carry mark_fraction of
// the sum, are split (mesh/split.hpp), largest share first, while the patch count stays within
// max_patches. Weighting by area makes large smooth patches win over tiny ones at a discontinuity (whose
// jump never shrinks), so refinement follows the L2 error, not the largest jump.
// Reuse between rounds: a patch that was not split keeps its polygon (same corners, same order), so its
// form factors to other unsplit patches are copied from the previous round's matrix, visibility included
// (formfactor::Options::reuse; splitting leaves every surface, hence every occluder, in place). Only pairs
// with a new patch are integrated. The previous radiance (each child taking its parent's value) is the
// solver's initial guess.
// Every round's solve is checked: a solve that does not converge ends the refinement (stop
// "solve_not_converged"; the result then has solution.converged == false), since indicators computed from
// it would be meaningless.
// Memory: the previous and the new matrix coexist while assembling (2 x 8 N^2 bytes).
#include <memory>
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/soup.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::refine {

struct AdaptiveOptions {
  int max_patches = 10000;     // patch budget (scene patches), >= the patches of the input soup
  double tolerance = 0.01;     // stop when the error estimate E (see above) is <= this, > 0
  double mark_fraction = 0.5;  // Doerfler parameter theta in (0, 1]: split patches carrying this share of E^2
  int max_rounds = 12;         // refinement rounds (solves = rounds + 1), >= 0; each round splits about half
                               // the estimated error, so 12 rounds reach budgets of ~10^4 patches
  bool direct_indicator = true;  // also use the within-patch direct-radiance oscillation
  bool gather_indicator = true;  // also use the kernel-variation (B F) estimate
  bool reuse = true;           // copy form factors of unchanged pairs from the previous round
  formfactor::Options ff;      // its `reuse` is ignored (set per round)
  solver::Options solve;       // its initial_guess is ignored (set from the previous round)
};

struct AdaptiveRound {
  int patches = 0;
  long long pairs_reused = 0;    // unordered pairs copied from the previous round
  long long pairs_total = 0;     // unordered pairs i < j
  double assemble_seconds = 0;   // form factors
  double solve_seconds = 0;
  double indicator_seconds = 0;  // all indicators
  double max_jump = 0;           // largest jump indicator
  double max_direct = 0;         // largest direct indicator (0 when disabled)
  double max_gather = 0;         // largest gather indicator (0 when disabled)
  double error_estimate = 0;     // E (see above)
  int marked = 0;                // patches marked (Doerfler)
  int split = 0;                 // of those, split (budget, convexity)
  bool solve_converged = false;  // this round's solve reached its tolerance
  double solve_residual = 0;     // its largest relative residual over channels
  formfactor::Stats ff;          // this round's assembly
};

struct AdaptiveResult {
  mesh::PolygonSoup soup;               // the refined soup of the last round
  mesh::Scene scene;                    // built from it
  solver::Solution solution;            // on scene
  std::shared_ptr<const formfactor::DenseMatrixOperator> final_matrix;  // the form factors of scene
  std::vector<int> patches_per_round;   // scene patches solved in each round
  std::vector<double> max_indicator;    // per round: largest local indicator eta_p (0 if nothing found)
  std::vector<double> error_estimate;   // per round: E
  std::vector<AdaptiveRound> rounds;    // per round: counts, timings, the assembly's statistics
  // "converged" | "budget" | "max_rounds" | "solve_not_converged"
  std::string stop;
  long not_splittable = 0;              // marked faces left whole (non-convex n-gons), last round
  double seconds = 0;                   // wall time, all rounds
};

// Throws InputError for invalid options or when the input soup's scene already exceeds max_patches,
// and whatever build_scene, assemble or solve throw.
AdaptiveResult solve_adaptive(const mesh::PolygonSoup& soup, const AdaptiveOptions& options);

}  // namespace lambert::refine
