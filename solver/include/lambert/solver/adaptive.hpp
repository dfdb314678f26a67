#pragma once
// Adaptive refinement: solve coarse, refine only where the solution is under-resolved, re-solve.
//
// Each round builds a Scene from the current soup (mesh::build_scene), assembles F and solves. Two
// error indicators per patch, both relative to the largest reflected radiance (L - Le) in the scene;
// a patch is marked when the larger of the two exceeds `tolerance`:
//  - jump: max over its edge neighbours q of the same material and smooth surface (normals within
//    30 degrees) of max_channel |L_p - L_q| (gradients, shadow edges between patches). Neighbours are
//    patches whose edges overlap along a segment of positive length (found geometrically, so hanging
//    nodes count).
//  - direct (optional, `direct_indicator`): the oscillation of the direct radiance within the patch,
//    max_k D(x_k) - min_k D(x_k) over sample points x_k inside it (3 per triangle of its
//    triangulation), D(x) = rho_p sum_e Le_e F(dA_x -> e) V(x, e): the exact point-to-polygon kernel
//    to each emitter patch e times the fraction of 3 points per emitter triangle visible from x
//    (Embree rays, only through patches that can occlude at all). A piecewise-constant element's
//    L-infinity error is about half this oscillation; it finds shadow edges that cross a patch, which
//    the jump misses when neighbours are equally shadowed (e.g. a coarse start). Cost: samples x
//    emitter patches x rays, skipped where an emitter is behind the sample point.
// Marked patches are split, largest indicator first, while the patch count stays within
// `max_patches`: a triangle into 4 by its edge midpoints, a convex polygon with m >= 4 corners into m
// quads (corner, edge midpoints, centroid); non-convex n-gons are not split. Split faces keep
// material, group, line and origin; neighbours keep their corner lists, so hanging nodes
// (T-junctions) appear, which piecewise-constant radiosity does not mind. New corners are welded by
// exact position (midpoints are computed symmetrically), so neighbours share vertices: no duplicate
// vertices are created.
// Reuse between rounds: a patch that was not split keeps its polygon (same corners, same order), so
// its form factors to other unsplit patches are copied from the previous round's matrix, visibility
// included (formfactor::Options::reuse; splitting leaves every surface, hence every occluder, in
// place). Only pairs with a new patch are integrated. The previous radiance (each child taking its
// parent's value) is the solver's initial guess.
// Stops when no patch is above tolerance ("converged"), when no marked patch fits the budget
// ("budget"), or after max_rounds refinements ("max_rounds").
// Memory: the previous and the new matrix coexist while assembling (2 x 8 N^2 bytes).
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/soup.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::solver {

struct AdaptiveOptions {
  int max_patches = 10000;  // patch budget (scene patches), >= the patches of the input soup
  double tolerance = 0.05;  // relative radiance jump / direct oscillation above which a patch is split, > 0
  int max_rounds = 4;       // refinement rounds (solves = rounds + 1), >= 0
  bool direct_indicator = true;  // also use the within-patch direct-radiance oscillation (see above)
  bool reuse = true;        // copy form factors of unchanged pairs from the previous round
  formfactor::Options ff;   // its `reuse` is ignored (set per round)
  Options solve;            // its initial_guess is ignored (set from the previous round)
};

struct AdaptiveRound {
  int patches = 0;
  long long pairs_reused = 0;    // unordered pairs copied from the previous round
  long long pairs_total = 0;     // unordered pairs i < j
  double assemble_seconds = 0;   // form factors
  double solve_seconds = 0;
  double indicator_seconds = 0;  // both indicators
  double max_jump = 0;           // largest jump indicator
  double max_direct = 0;         // largest direct indicator (0 when disabled)
  int marked = 0;                // patches above tolerance
  int split = 0;                 // of those, split (budget, convexity)
};

struct AdaptiveResult {
  mesh::PolygonSoup soup;               // the refined soup of the last round
  mesh::Scene scene;                    // built from it
  Solution solution;                    // on scene
  std::vector<int> patches_per_round;   // scene patches solved in each round
  std::vector<double> max_indicator;    // per round: largest indicator (max of both; 0 if nothing found)
  std::vector<AdaptiveRound> rounds;    // per round: counts and timings
  std::string stop;                     // "converged" | "budget" | "max_rounds"
  long not_splittable = 0;              // marked faces left whole (non-convex n-gons), last round
  double seconds = 0;                   // wall time, all rounds
};

// Throws InputError for invalid options or when the input soup's scene already exceeds max_patches,
// and whatever build_scene, assemble or solve throw.
AdaptiveResult solve_adaptive(const mesh::PolygonSoup& soup, const AdaptiveOptions& options);

// The indicators above for a solved scene: one value per patch (exposed for tests and output).
std::vector<double> jump_indicator(const mesh::Scene& scene, const ColorField& radiance);
// `caster` null: Embree over formfactor::potential_occluders (no rays if there are none).
std::vector<double> direct_indicator(const mesh::Scene& scene, const ColorField& radiance,
                                     const formfactor::Visibility* caster = nullptr);

}  // namespace lambert::solver
