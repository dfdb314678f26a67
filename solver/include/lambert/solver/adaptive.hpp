#pragma once
// Adaptive refinement: solve coarse, refine only where the solution is under-resolved, re-solve.
//
// Each round builds a Scene from the current soup (mesh::build_scene), assembles F and solves. The
// error indicator of patch p is max over its edge neighbours q of the same material of
// max_channel |L_p - L_q|, relative to the largest reflected radiance (L - Le) in the scene: a
// radiance jump between neighbours (gradients, shadow boundaries). Neighbours are patches whose
// edges overlap along a segment of positive length (found geometrically, so hanging nodes count).
// Patches above `tolerance` are split, largest indicator first, while the patch count stays within
// `max_patches`: a triangle into 4 by its edge midpoints, a convex polygon with m >= 4 corners into m
// quads (corner, edge midpoints, centroid); non-convex n-gons are not split. Split faces keep
// material, group, line and origin; neighbours keep their corners, so hanging nodes (T-junctions)
// appear, which piecewise-constant radiosity does not mind. Edge midpoints are shared, so a face split
// after its neighbour reuses the neighbour's midpoint vertex.
// Reuse between rounds: only the soup and the previous radiance, which (each child taking its
// parent's value) is the solver's initial guess. Form factors are recomputed from scratch each round.
// Stops when no patch is above tolerance ("converged"), when no marked patch fits the budget
// ("budget"), or after max_rounds refinements ("max_rounds").
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/soup.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::solver {

struct AdaptiveOptions {
  int max_patches = 10000;  // patch budget (scene patches), >= the patches of the input soup
  double tolerance = 0.05;  // relative radiance jump above which a patch is split, > 0
  int max_rounds = 4;       // refinement rounds (solves = rounds + 1), >= 0
  formfactor::Options ff;
  Options solve;            // its initial_guess is ignored (set from the previous round)
};

struct AdaptiveResult {
  mesh::PolygonSoup soup;               // the refined soup of the last round
  mesh::Scene scene;                    // built from it
  Solution solution;                    // on scene
  std::vector<int> patches_per_round;   // scene patches solved in each round
  std::vector<double> max_indicator;    // per round: largest relative jump found (0 if no neighbours)
  std::string stop;                     // "converged" | "budget" | "max_rounds"
  long not_splittable = 0;              // marked faces left whole (non-convex n-gons), last round
  double seconds = 0;                   // wall time, all rounds
};

// Throws InputError for invalid options or when the input soup's scene already exceeds max_patches,
// and whatever build_scene, assemble or solve throw.
AdaptiveResult solve_adaptive(const mesh::PolygonSoup& soup, const AdaptiveOptions& options);

// The indicator above for a solved scene: one value per patch (exposed for tests and output).
std::vector<double> jump_indicator(const mesh::Scene& scene, const ColorField& radiance);

}  // namespace lambert::solver
