#pragma once
// Unoccluded form factors between planar polygons. Lengths in metres; form factors are dimensionless.
// Conventions (see docs/physics.md): a polygon's front side is given by the right-hand rule on its corner
// order; only the front emits and receives (one-sided), so a polygon seen from behind contributes 0.
#include <span>
#include <string>
#include <vector>

#include "lambert/mesh/types.hpp"

namespace lambert::formfactor {

// F(dA_x -> P) = (1/pi) * integral over P of cos(theta_x) cos(theta_y) / r^2 dA_y: the point-to-polygon form
// factor from a differential area at x with unit normal n (its front side) to the planar polygon P (>= 3
// corners, simple, convex or not), by Lambert's contour formula after clipping P against x's tangent plane.
// 0 when x is behind or in P's plane, or P is entirely behind x. Never NaN or Inf for finite input.
double point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> polygon);

// Patch-to-patch F_ij = (1/A_i) * double integral of the kernel over P_i x P_j, unoccluded, one-sided.
// Same method selection as assemble() (see assemble.hpp): from the smaller polygon, by a rule chosen a
// priori from size/distance, or for near pairs (shared edges or corners, closer than their size) by an
// adaptive double contour integral, until the estimated absolute error on F_ij is <= tolerance.
// Preconditions: planar simple polygons, >= 3 corners, non-zero area (else lambert::InputError).
struct PairResult {
  double F = 0;           // F_ij (from i to j)
  double F_reverse = 0;   // F_ji, from reciprocity A_i F_ij = A_j F_ji
  std::string method;     // "orientation_culled", "far_field", "centroid_hessian", "gauss4", "gauss9", "gauss16",
                          // "contour" (see assemble.hpp)
  double error_estimate = 0;  // estimated absolute error of F (a priori bound or adaptive estimate)
};
PairResult polygon_to_polygon(std::span<const Vec3> Pi, std::span<const Vec3> Pj, double tolerance = 1e-8);

// With occluders (exact visibility, docs/physics.md §6): the same quantities counting only what x (or each
// point of P_i) sees past the occluders, planar simple polygons that block on both sides (an occluder in the
// plane of x or of a patch blocks nothing). The hidden part is computed exactly per point (occluders clipped
// to the cone from x through P, projected on P's plane, united in integer coordinates of ~1e-9 of P's size,
// contour-integrated) and integrated over P_i adaptively to `tolerance`. Results are in [0, unoccluded].
double visible_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> polygon,
                                const std::vector<std::vector<Vec3>>& occluders);
// method: the unoccluded integral's method; error_estimate adds the hidden part's error estimate.
PairResult visible_polygon_to_polygon(std::span<const Vec3> Pi, std::span<const Vec3> Pj,
                                      const std::vector<std::vector<Vec3>>& occluders, double tolerance = 1e-8);

}  // namespace lambert::formfactor
