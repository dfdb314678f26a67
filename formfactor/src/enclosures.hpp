#pragma once
// Internal: the closed surfaces of a scene (rooms, apartments, shut boxes) and the cells they split space into.
//
// Around every edge (T-junctions allowed: edges are cut into pieces where other edges along the same line end),
// the faces are sorted by angle; the two face sides that look into the wedge between consecutive faces bound the
// same region of space, so they are joined (an edge of one face only joins that face's front and back: light goes
// round it). The faces with exactly one side on a joined boundary form a closed surface mod 2 (every edge piece is
// covered an even number of times), which separates space: a segment between points of different parity (the
// crossings of a ray to infinity) crosses it. So a patch whose front lies inside a closed surface and one whose front
// lies outside it cannot see each other, whatever lies between, and the hierarchy refuses such node pairs without a
// ray (a building's apartments are closed: doors join its rooms, glass closes its windows). Junk does not open a
// room: a fin, a leftover fragment under a sofa, a light panel join their own two sides, not the room's walls.
//
// Each patch's cell is the set of surfaces whose inside holds a point just in front of it, by the parity of one ray
// (retried in other directions when it passes within eps of an edge or grazes a face; cell -1 when all do). A patch
// that crosses a patch of a surface, or is crossed by one (an edge through the other), or that a surface's edge
// touches inside (a box standing on a floor that was not split there), as in a model that was not repaired, gets
// cell -1 too: its front lies on both sides. Cell -1 never refuses anything.
#include <array>
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

struct Enclosures {
  std::vector<int> cell;            // per patch: its cell (>= 0), or -1 (not known: it may see any patch)
  int surfaces = 0;                 // closed surfaces (non-empty)
  long long crossed = 0;            // patches crossing a patch of a surface, or crossed by one (cell -1)
  long long surface_patches = 0;    // patches on a closed surface
  int cells = 0;                    // distinct cell ids
  long long unknown = 0;            // patches with cell -1
  double seconds = 0;
  std::vector<std::array<int, 2>> surfaces_of;   // per patch: the surfaces of its two sides (-1: none)
  std::vector<std::vector<int>> cell_surfaces;   // per cell: the surfaces whose inside holds it (sorted)
};

// eps: contact distance (m, > 0): edge points within eps of another edge's line are on it, pieces of edges shorter
// than eps and gaps narrower than eps do not count. Deterministic (any thread count).
Enclosures find_enclosures(const mesh::PatchGeometry& g, double eps);

// The contact distance both operators use, relative to the scene's bounding-box diagonal (mesh::prepare's default
// weld tolerance: edges this close are one edge, gaps this narrow are closed).
constexpr double kEnclosureEps = 1e-6;
// find_enclosures with eps = kEnclosureEps x the bounding-box diagonal of g.
Enclosures find_enclosures(const mesh::PatchGeometry& g);

}  // namespace lambert::formfactor::detail
