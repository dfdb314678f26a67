#pragma once
// Internal: patch triangles into an Embree scene (shared by the visibility caster and the row-sum check).
#include <embree3/rtcore.h>

#include <span>
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

// Adds the triangles of `patches` (every patch when empty) to `scene` as one triangle geometry, in single
// precision relative to `centre` (callers shift rays the same way: a scene far from the origin keeps its
// precision). Appends to tri_patch the patch of each Embree primitive, in primitive order.
void add_patch_triangles(RTCDevice device, RTCScene scene, const mesh::PatchGeometry& g, std::span<const int> patches,
                         const Vec3& centre, std::vector<int>& tri_patch);

}  // namespace lambert::formfactor::detail
