#pragma once
// Splitting soup faces into children, for adaptive refinement (refine/). Conforming refinement of whole
// scenes by edge length (`--max-edge`) is mesh::prepare's job (prepare.hpp); this splits single faces and
// leaves hanging nodes (T-junctions) at their neighbours, which piecewise-constant radiosity does not mind.
//
// How a face splits (planar faces only; children keep material, group, line and origin):
//  - a convex quad whose two opposite edges are both more than twice as long as the other two: into 2
//    across its length (long strips, common in architectural models, become squarer);
//  - a triangle: into 4 by its edge midpoints;
//  - another convex polygon with m >= 4 corners: into m quads (corner, edge midpoints, centroid);
//  - a non-convex polygon: not split.
// New corners are welded by exact position to the vertices already in the soup (0.5 (a + b) is symmetric
// in a and b, so the two faces of an edge compute the same midpoint): no duplicate vertices are created.
#include <array>
#include <map>
#include <span>
#include <vector>

#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/soup.hpp"

namespace lambert::mesh {

// Children the split of a polygon with unit normal n makes, or 0 if it is not splittable (non-convex).
int split_children(std::span<const Vec3> poly, const Vec3& n);

class FaceSplitter {
 public:
  // Indexes the positions of `soup` by exact value; split() appends new positions to it. `soup` must
  // outlive the splitter.
  explicit FaceSplitter(PolygonSoup& soup);
  // The children of face f (corner indices into the soup), in the order described above. Precondition:
  // split_children(polygon of f, n) > 0.
  std::vector<SoupFace> split(const SoupFace& f, const Vec3& n);

 private:
  int vertex_at(const Vec3& x);
  PolygonSoup& soup_;
  std::map<std::array<double, 3>, int> index_;
};

// One soup face per scene patch, corners welded by exact position: a soup whose faces map one to one to
// the patches of `scene` (build_scene triangulates non-planar polygons, so the input soup may not).
// Materials, groups and file come from `in`; origin = the patch's face_id.
PolygonSoup soup_from_scene(const PolygonSoup& in, const Scene& scene);

}  // namespace lambert::mesh
