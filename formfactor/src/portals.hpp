#pragma once
// Internal: the openings of a scene (doors, windows without glass, gaps in a wall) as portal polygons.
//
// An opening is a hole in the union of the patches that lie in one plane: the wall around a window, seen in the
// wall's plane, is a ring of patches. A door reaches the floor, so in its wall's plane it is a notch; the edges that
// other faces lay in the plane (the threshold's, the floor's along the wall's base) are added to the union as strips
// eps / 4 wide and close it. A hole counts only if at least half of a ring half an eps wide around it lies on the
// plane's own patches (a door: its wall on three sides), not on other faces' edges (the walls' edges around a table
// top's plane). Each opening becomes a virtual polygon closing it. With the portals added as faces, the closed
// surfaces of enclosures.hpp split an apartment into its rooms (and the door's tunnel between them); light from one
// room to another must pass through a portal of each surface that separates them (a segment from inside a closed
// surface to outside crosses it; a crossing at a real face is a hit), which both operators test on a pair's shaft
// before casting a ray. A portal is never an occluder; any set of portals gives correct answers, a spurious one only
// refuses less.
//
// Holes are found on integer coordinates (Clipper): corners snapped to eps / 16 in the plane, coincident edges
// (T-junctions included) join. Slivers narrower than ~8 eps are dropped, and holes the ear clipping refuses (a hole
// touching itself at a corner) stay open. Edges in a plane are looked up for the 32 plane directions with the most
// patches (any orientation: a building turned in GIS coordinates too). Deterministic: planes in order of first
// appearance, Clipper's output.
#include <vector>

#include "lambert/mesh/geometry.hpp"
#include "shaft.hpp"

namespace lambert::formfactor::detail {

// eps: contact distance (m, > 0), as enclosures.hpp. Returns each hole as a planar simple polygon (corners in
// order, no repeated corner), in metres.
std::vector<std::vector<Vec3>> find_openings(const mesh::PatchGeometry& g, double eps);

// The rooms of a scene: the cells of its closed surfaces once every opening is closed by a portal.
struct Rooms {
  std::vector<int> cell;                          // per patch: its room (>= 0), or -1 (not known)
  int rooms = 0;                                  // distinct rooms
  std::vector<std::vector<Vec3>> portals;         // the openings' polygons
  std::vector<Box> portal_box;
  std::vector<std::vector<int>> room_surfaces;    // per room: the surfaces whose inside holds it (sorted)
  std::vector<std::vector<int>> surface_portals;  // per surface: its portals
  double seconds = 0;
  bool empty() const { return surface_portals.empty(); }
  // Rooms ra != rb (both >= 0): false when the shaft (from the two sides' boxes and planes, as the rays between them
  // would run) meets no portal of some surface that holds one room and not the other: no light passes.
  bool path(const Shaft& shaft, int ra, int rb) const;
};
// Openings closed by portals, then the closed surfaces again (enclosures.hpp). eps as find_openings. Empty (no
// rooms) when there is no opening.
Rooms find_rooms(const mesh::PatchGeometry& g, double eps);

}  // namespace lambert::formfactor::detail
