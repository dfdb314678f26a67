#pragma once
// Where two triangles meet, for mesh::prepare's imprint and self-intersection steps. Which side of each triangle's
// plane every corner of the other lies on comes from CGAL's exact orientation predicate on the double-precision
// corners; the points (corners on the other plane, edge crossings) are constructed in double precision, and the two
// triangles' pieces of the planes' common line are overlapped on those points. CGAL's Epeck constructions gave the
// same points rounded, at ~120 us per touching pair (a wall standing on a slab: every filter fails and the lazy
// kernel computes in GMP rationals); with this, imprinting the 100k building took 2.5 s instead of 7.8 s.
#include <array>

#include "lambert/mesh/types.hpp"

namespace lambert::mesh::detail {

struct TriangleContact {
  enum Kind {
    kNone,        // disjoint
    kPoint,       // one point (a, = b)
    kSegment,     // the segment [a, b] of the planes' common line
    kNeedsExact,  // coplanar, or too close to it for double-precision points (the planes, or an edge crossing the
                  // other's plane, at less than 1e-4 rad): the caller uses exact constructions
  } kind = kNone;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
};

// Precondition: both triangles non-degenerate (finite corners). Points are within about 1e-12 of the triangles'
// size (plus rounding of the coordinates) of the exact intersection; the overlap of the two triangles' pieces of the
// common line is decided on those points, so an exact touch at one point may come out as a point, a segment that
// short, or nothing.
TriangleContact intersect_triangles(const std::array<Vec3, 3>& t, const std::array<Vec3, 3>& u);

}  // namespace lambert::mesh::detail
