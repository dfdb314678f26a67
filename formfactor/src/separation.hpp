#pragma once
// Proof that a wall or slab hides one region from another entirely (internal; docs/physics.md §6).
//
// A and B are convex regions given by points that span them (a patch's corners, a cluster box's eight
// corners). If a plane holds all of A strictly on one side and all of B strictly on the other (regions touching
// the plane are not decided: a point in it would cross it on its own patch), every segment
// from A to B crosses it exactly once, at a point inside the convex hull of the |A| x |B| crossings of the
// segments between the given points (a perspective image of a convex set is convex: fix a, the crossings over
// conv(B) are the hull of those towards B's points; then vary a the same way). So if the occluders lying in
// that plane cover that hull, no segment from A to B is free: B is hidden from A, exactly, whatever the
// occluders' shapes (a wall of many tiles, with holes elsewhere, a slab under several rooms).
//
// Coverage is decided in the plane's 2D frame with Clipper in integer coordinates: hull minus the union of
// the plane's occluders, the hull grown by two snapping units so that the test errs on "not proven". The snap
// is 2^-29 of the hull's size; cracks between occluder tiles narrower than that count as closed (round-off
// of shared edges). Units: metres. Deterministic; no state shared between calls except the caller's scratch.
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
int hidden_by_plane(std::span<const Vec3> a, std::span<const Vec3> b, const mesh::PatchGeometry& g,
                    std::span<const int> plane_of, std::span<const int> candidates, double eps,
                    SeparationScratch& scratch);

}  // namespace lambert::formfactor::detail
