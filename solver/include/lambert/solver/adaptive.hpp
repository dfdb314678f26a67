#pragma once
// Adaptive refinement: solve coarse, refine only where the solution is under-resolved, re-solve.
//
// Each round builds a Scene from the current soup (mesh::build_scene), assembles F and solves. Three
// local indicators per patch estimate the range of the radiance over it (relative to the largest
// reflected radiance L - Le in the scene); the patch's indicator eta_p is the largest of them:
//  - jump: max over its edge neighbours q of the same material and smooth surface (normals within
//    30 degrees) of max_channel |L_p - L_q| (gradients, shadow edges between patches). Neighbours are
//    patches whose edges overlap along a segment of positive length (found geometrically, so hanging
//    nodes count).
//  - direct (`direct_indicator`): the oscillation of the direct radiance within the patch,
//    max_k D(x_k) - min_k D(x_k) over sample points x_k inside it (3 per triangle of its
//    triangulation), D(x) = rho_p sum_e Le_e F(dA_x -> e) V(x, e): the exact point-to-polygon kernel
//    to each emitter patch e times the fraction of 3 points per emitter triangle visible from x
//    (Embree rays, only through patches that can occlude at all). It finds shadow edges that cross a
//    patch, which the jump misses when neighbours are equally shadowed (e.g. a coarse start).
//    Cost: samples x emitter patches x rays, skipped where an emitter is behind the sample point.
//  - gather (`gather_indicator`), a B.F criterion as in hierarchical radiosity: rho_p sum_j F_pj L_j
//    min(1, diam_p / |c_p - c_j|), the light gathered from each patch j times the relative variation
//    of the kernel across p (~ p's size over the distance). It needs no neighbour and no emitter, so
//    a single large patch lit only indirectly (a ceiling) still gets refined. Cost: one pass over F.
// Error estimate and marking (as in adaptive finite elements): E = sqrt(sum_p A_p eta_p^2 /
// sum_p A_p R_p^2), R_p the patch's reflected radiance (largest channel), the relative L2 size of the
// radiance variation the patches do not resolve. Stop when E <= `tolerance` ("converged"). Otherwise
// Doerfler marking: the patches with the largest A_p eta_p^2, until they carry `mark_fraction` of the
// sum, are split. Weighting by area makes large smooth patches win over tiny ones at a discontinuity
// (whose jump never shrinks), so refinement follows the L2 error, not the largest jump.
// Marked patches are split, largest share first, while the patch count stays within
// `max_patches`: a triangle into 4 by its edge midpoints, a convex quad whose two opposite edges are
// both more than twice as long as the other two into 2 across its length (so long strips, common in
// architectural models, become squarer), another convex polygon with m >= 4 corners into m quads
// (corner, edge midpoints, centroid); non-convex n-gons are not split. Split faces keep
// material, group, line and origin; neighbours keep their corner lists, so hanging nodes
// (T-junctions) appear, which piecewise-constant radiosity does not mind. New corners are welded by
// exact position (midpoints are computed symmetrically), so neighbours share vertices: no duplicate
// vertices are created.
// Reuse between rounds: a patch that was not split keeps its polygon (same corners, same order), so
// its form factors to other unsplit patches are copied from the previous round's matrix, visibility
// included (formfactor::Options::reuse; splitting leaves every surface, hence every occluder, in
// place). Only pairs with a new patch are integrated. The previous radiance (each child taking its
// parent's value) is the solver's initial guess.
// Stops when E <= tolerance ("converged"), when no marked patch fits the budget
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
  double tolerance = 0.05;  // stop when the error estimate E (see above) is <= this, > 0
  double mark_fraction = 0.5;  // Doerfler parameter theta in (0, 1]: split patches carrying this share of E^2
  int max_rounds = 4;       // refinement rounds (solves = rounds + 1), >= 0
  bool direct_indicator = true;  // also use the within-patch direct-radiance oscillation (see above)
  bool gather_indicator = true;  // also use the kernel-variation (B F) estimate (see above)
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
  double max_gather = 0;         // largest gather indicator (0 when disabled)
  double error_estimate = 0;     // E (see above)
  int marked = 0;                // patches marked (Doerfler)
  int split = 0;                 // of those, split (budget, convexity)
};

struct AdaptiveResult {
  mesh::PolygonSoup soup;               // the refined soup of the last round
  mesh::Scene scene;                    // built from it
  Solution solution;                    // on scene
  std::vector<int> patches_per_round;   // scene patches solved in each round
  std::vector<double> max_indicator;    // per round: largest local indicator eta_p (0 if nothing found)
  std::vector<double> error_estimate;   // per round: E
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
std::vector<double> gather_indicator(const mesh::Scene& scene, const formfactor::DenseMatrixOperator& F,
                                     const ColorField& radiance);
// `caster` null: Embree over formfactor::potential_occluders (no rays if there are none).
std::vector<double> direct_indicator(const mesh::Scene& scene, const ColorField& radiance,
                                     const formfactor::Visibility* caster = nullptr);

}  // namespace lambert::solver
