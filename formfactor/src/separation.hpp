#pragma once
// Proof that a wall or slab hides one region from another entirely (internal; docs/physics.md §6).
//
// A and B are convex regions given by points that span them (a patch's corners, a cluster box's eight
// corners). If a plane holds all of A strictly on one side and all of B strictly on the other (or one of them
// touching it, see hidden_by_plane), every segment from A to B crosses it once, at a point inside the convex
// hull of the |A| x |B| crossings of the segments between the given points (a central projection of a convex
// set is convex: fix a, the crossings over conv(B) are the hull of those towards B's points; then vary a). So
// if the occluders lying in that plane cover that hull, no segment from A to B is free: B is hidden from A,
// exactly, whatever the occluders' shapes (a wall of many tiles with holes elsewhere, a slab under rooms).
//
// Coverage is decided in the plane's 2D frame with Clipper in integer coordinates (2^29 units across the hull's
// half-size): hull minus the union of the plane's occluders must leave nothing but slivers of mean width <= 2
// units (the snapping), so cracks narrower than ~4e-9 of the hull count as closed (round-off of shared edges)
// and wider ones as open. Units: metres. Deterministic; no state shared between calls except the scratch.
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

struct SeparationScratch;  // per-thread buffers; separation.cpp
struct SeparationScratchDeleter {
  void operator()(SeparationScratch* s) const;
};
using SeparationScratchPtr = std::unique_ptr<SeparationScratch, SeparationScratchDeleter>;
SeparationScratchPtr make_separation_scratch();

// Plane id per patch: patches in one plane (either orientation) share an id; -1 for patches not in `occluders`.
// scale: the scene's size (m); planes closer than 1e-9 of it in offset and 1e-9 in normal are one plane.
std::vector<int> occluder_planes(const mesh::PatchGeometry& g, std::span<const int> occluders, double scale);

// The plane id (plane_of) of a proof, or -1 if there is none: whether the occluder patches `candidates` (ids into g; any that may lie between A and B, e.g. from
// OccluderTree::collect) include a set lying in one plane (plane_of: occluder_planes) that strictly separates
// A from B (by more than `eps` metres) and covers every segment between them. -1 means "not proven" (B may
// be partly or wholly visible). a and b: at least one point each.
//
// Regions touching the plane: a point of A in the plane "crosses" it where it starts. That is harmless where the
// point is on an edge or corner of a patch that otherwise lies on A's side (measure zero), and wrong for a patch
// of A lying in the plane and facing B (a wall's own surface). With `touching_ok`, one region may touch the
// plane (the other strictly off it) if touching_ok(n, o) is true, n the unit normal pointing from A's side to
// B's and o = n.x on the plane: the caller checks that no patch of A lying in it faces +n and no patch of B
// lying in it faces -n. Without it, both regions must lie strictly off the plane.
using TouchingCheck = std::function<bool(const Vec3& n, double o)>;
// For touching checks: whether patch p lies in the plane n.x = o (every corner within eps) and faces +n.
bool lies_in_plane_facing(const mesh::PatchGeometry& g, int p, const Vec3& n, double o, double eps);
int hidden_by_plane(std::span<const Vec3> a, std::span<const Vec3> b, const mesh::PatchGeometry& g,
                    std::span<const int> plane_of, std::span<const int> candidates, double eps,
                    SeparationScratch& scratch, const TouchingCheck& touching_ok = {});

}  // namespace lambert::formfactor::detail
