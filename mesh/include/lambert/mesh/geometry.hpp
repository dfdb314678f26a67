#pragma once
// Flat, cache-friendly patch geometry: what the form-factor kernel and the ray tracer read.
// Each patch is a planar simple polygon (convex or not) with a planar triangulation.
#include <array>
#include <span>
#include <vector>

#include "lambert/mesh/types.hpp"

namespace lambert::mesh {

struct PatchGeometry {
  std::vector<Vec3> points;        // polygon corners of all patches, concatenated (metres)
  std::vector<int> offsets;        // patch p has corners points[offsets[p] .. offsets[p+1])
  std::vector<Vec3> normal;        // unit normal of the front (emitting/receiving) side:
                                   // right-hand rule on the corner order (counter-clockwise seen from the front)
  std::vector<Vec3> centroid;      // area centroid (metres)
  std::vector<double> area;        // m^2, > 0
  std::vector<std::array<int, 3>> triangles;  // indices into points; planar triangulation of patches
  std::vector<int> triangle_offsets;           // patch p owns triangles[triangle_offsets[p] .. [p+1])

  int size() const { return static_cast<int>(area.size()); }
  std::span<const Vec3> polygon(int p) const {
    return {points.data() + offsets[p], static_cast<size_t>(offsets[p + 1] - offsets[p])};
  }

  // Builds everything from polygons given by their corners. Precondition: each polygon is planar,
  // simple and has non-zero area (throws InputError naming the polygon index otherwise).
  static PatchGeometry from_polygons(const std::vector<std::vector<Vec3>>& polygons);
};

// Newell normal of a polygon: direction = normal (right-hand rule), length = 2 * area for planar ones.
Vec3 newell_normal(std::span<const Vec3> polygon);

// Largest distance (m) of a corner from the polygon's best plane (Newell normal through the centroid).
double planarity_deviation(std::span<const Vec3> polygon);

// Plane of each listed patch as an id (-1 for patches not listed): patches lying in one plane, facing either way,
// share an id. The unoriented plane (normal with its largest component positive, offset) is quantised to 1e-9 in
// the normal and 1e-9 * scale in the offset (scale: the scene's size, m): a rounding boundary can only split a
// plane's group, never join different planes. Ids are dense, in order of first appearance in `patches`.
std::vector<int> plane_ids(const PatchGeometry& g, std::span<const int> patches, double scale);

// Ear-clipping triangulation of a simple polygon (planar or nearly so), projected on the plane
// with the given normal. Returns corner-index triples in the polygon's winding order; empty if the
// polygon is degenerate (self-intersecting or zero area).
std::vector<std::array<int, 3>> triangulate_polygon(std::span<const Vec3> polygon, const Vec3& normal);

// The rotation taking the normal direction with the most area within 1 degree of it to z, and the direction across
// it with the most such area (counting the one at right angles to both too) to x; the identity if both lie within 1
// degree of an axis already. Candidates: the normals of the 64 largest patches and of 192 spread over the patches.
// A building turned in its site's coordinates is turned back so that its walls and floors lie along the axes (the
// form factors' shafts and boxes and the daylight's hemicubes are axis-aligned).
Eigen::Matrix3d alignment(const PatchGeometry& g);

// A copy of g moved by -centre and then, if R is given, turned by it: corners and centroids x -> R (x - centre),
// normals n -> R n (the frame the form factors and the daylight clipping work in for a far or turned model).
PatchGeometry moved_and_turned(const PatchGeometry& g, const Vec3& centre, const Eigen::Matrix3d* R);

}  // namespace lambert::mesh
