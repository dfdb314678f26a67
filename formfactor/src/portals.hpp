#pragma once
// Internal: the openings of a scene (doors, windows without glass, gaps in a wall) as portal polygons.
//
// An opening is a hole in the union of the patches that lie in one plane: the wall around a door, seen in the
// wall's plane, is a ring of patches. Each hole becomes a virtual polygon closing it. With the portals added as
// faces, the closed surfaces of enclosures.hpp split an apartment into its rooms (and the door's tunnel between
// them); light from one room to another must pass through a portal of each surface that separates them, which the
// hierarchy tests on a node pair's shaft before casting a ray (hierarchy.cpp). A portal is never an occluder.
//
// Holes are found exactly on integer coordinates (Clipper): corners snapped to eps in the plane, so gaps narrower
// than eps close and coincident edges (T-junctions included) join. Holes whose area is below eps x their perimeter
// x 4 (slivers from rounding) are dropped. Deterministic: planes in order of first appearance, Clipper's output.
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

// eps: contact distance (m, > 0), as enclosures.hpp. Returns each hole as a planar simple polygon (corners in
// order, no repeated corner), in metres.
std::vector<std::vector<Vec3>> find_openings(const mesh::PatchGeometry& g, double eps);

}  // namespace lambert::formfactor::detail
