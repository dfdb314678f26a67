#pragma once
// Procedural shapes with known answers, for tests, verification and benchmarks. Lengths in metres.
// Every polygon's front side (right-hand-rule normal) is stated per function.
#include <vector>

#include "lambert/mesh/types.hpp"

namespace lambert::mesh::shapes {

using Polygons = std::vector<std::vector<Vec3>>;

// Parallelogram origin + s*u + t*v (s, t in [0,1]) split into nu x nv quads; normal along u x v.
Polygons grid(const Vec3& origin, const Vec3& u, const Vec3& v, int nu, int nv);

// Surface of the axis-aligned box [lo, hi], each face split into n x n quads. inward = true: normals
// point into the box (a closed room); false: out of it (a solid block). Face order: -x, +x, -y, +y, -z, +z.
Polygons box(const Vec3& lo, const Vec3& hi, int n, bool inward);

// Icosahedron subdivided `subdivisions` times (20 * 4^k triangles), vertices on the sphere of the given
// radius centred at the origin. inward = true: normals point to the centre (an enclosure).
Polygons icosphere(int subdivisions, double radius, bool inward);

// Closed unit room [0,1]^3 (n x n quads per face, inward) containing a floating block [lo, hi]
// (m x m quads per face, outward): a closed enclosure with occlusion.
Polygons room_with_block(int n, int m, const Vec3& lo = Vec3::Constant(0.35), const Vec3& hi = Vec3::Constant(0.65));

}  // namespace lambert::mesh::shapes
