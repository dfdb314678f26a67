#pragma once
// Occlusion queries between patches. assemble() multiplies each unoccluded F_ij by a visible fraction it
// estimates with these queries; tests swap the Embree caster for the brute-force one.
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor {

class Visibility {
 public:
  virtual ~Visibility() = default;
  // For each k: hidden[k] = 1 if the open segment from[k] -> to[k] meets a patch other than ignore_a and
  // ignore_b (the source and target patches, so no self-hit epsilon is needed) and other than the patches
  // in their planes (coincident with them: the back of a two-sided face), else 0.
  // Precondition: from, to and hidden have the same size.
  virtual void occluded(std::span<const Vec3> from, std::span<const Vec3> to, int ignore_a, int ignore_b,
                        std::span<std::uint8_t> hidden) const = 0;
  bool occluded(const Vec3& from, const Vec3& to, int ignore_a, int ignore_b) const;
  // As above with a pair of ignored patches per segment (ignore_a[k], ignore_b[k]): rays between random patches
  // of two clusters, traced in one call. The default calls the one-pair version per segment.
  // Precondition: all five spans have the same size.
  virtual void occluded(std::span<const Vec3> from, std::span<const Vec3> to, std::span<const int> ignore_a,
                        std::span<const int> ignore_b, std::span<std::uint8_t> hidden) const;
};

// Embree 3 BVH over the triangles of the given patches (all patches if `occluders` is empty). Only patches
// that can block anything need to be in it (see assemble.hpp). Single precision inside Embree.
std::unique_ptr<Visibility> make_embree_visibility(const mesh::PatchGeometry& geometry,
                                                   const std::vector<int>& occluders = {});

// Tests every triangle of every patch, in double precision (Moller-Trumbore). O(triangles) per query.
std::unique_ptr<Visibility> make_brute_force_visibility(const mesh::PatchGeometry& geometry);

// Patches that can occlude anything: those with some corner of the scene strictly behind their plane (a
// segment between two scene points can only cross the plane of such a patch). Empty for a convex enclosure
// (closed box or sphere with inward normals). Uses the convex hull of all corners (CGAL).
std::vector<int> potential_occluders(const mesh::PatchGeometry& geometry);

// Per patch: 1 when the point just in front of it lies inside a closed surface of the scene (a shut room, an
// apartment closed by its window panes), so that no direction from its front reaches infinity, whatever lies
// between; 0 when it lies outside every closed surface or is not known (a patch crossing a surface). The closed
// surfaces and cells of the enclosure test both operators use (src/enclosures.hpp); deterministic.
std::vector<char> enclosed_patches(const mesh::PatchGeometry& geometry);

}  // namespace lambert::formfactor
