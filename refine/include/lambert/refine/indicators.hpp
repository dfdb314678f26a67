#pragma once
// Local error indicators for adaptive refinement: one value per patch of a solved scene, each an estimate
// of the range of the radiance over the patch relative to the largest reflected radiance L - Le in the
// scene (dimensionless, >= 0; all zero when nothing is reflected).
#include <vector>

#include "lambert/formfactor/dense.hpp"
#include "lambert/formfactor/visibility.hpp"
#include "lambert/mesh/scene.hpp"

namespace lambert::refine {

// jump: max over p's edge neighbours q of the same material and smooth surface (normals within 30 degrees)
// of max_channel |L_p - L_q| (gradients, shadow edges between patches). Neighbours are patches whose
// edges overlap along a segment of positive length (found geometrically, so hanging nodes count).
// radiance: patches x 3, W m^-2 sr^-1.
std::vector<double> jump_indicator(const mesh::Scene& scene, const ColorField& radiance);

// direct: the oscillation of the direct radiance within the patch, max_k D(x_k) - min_k D(x_k) over
// sample points x_k inside it (3 per triangle of its triangulation), D(x) = rho_p sum_e Le_e F(dA_x -> e)
// V(x, e): the exact point-to-polygon kernel to each emitter patch e times the fraction of 3 points per
// emitter triangle visible from x. It finds shadow edges that cross a patch, which the jump misses when
// neighbours are equally shadowed. Cost: samples x emitter patches x rays.
// caster null: Embree over formfactor::potential_occluders (no rays if there are none).
std::vector<double> direct_indicator(const mesh::Scene& scene, const ColorField& radiance,
                                     const formfactor::Visibility* caster = nullptr);

// gather, a B.F criterion as in hierarchical radiosity: rho_p sum_j F_pj L_j min(1, diam_p / |c_p - c_j|),
// the light gathered from each patch j times the relative variation of the kernel across p. It needs no
// neighbour and no emitter, so a large patch lit only indirectly still gets refined. Cost: one pass over F.
std::vector<double> gather_indicator(const mesh::Scene& scene, const formfactor::DenseMatrixOperator& F,
                                     const ColorField& radiance);

}  // namespace lambert::refine
