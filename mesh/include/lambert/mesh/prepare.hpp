#pragma once
// Mesh preparation between the reader and build_scene: repairs what can be repaired, reports what
// leaks light, and refines large faces to a patch size. Every change is counted in the Report.
//
//   Report prep;
//   PolygonSoup ready = prepare(soup, options, prep);
//   Scene scene = build_scene(ready);   // or prepare_and_build(), which also merges the reports
//
// First, with or without repair, options.reverse_winding reverses every face's corner order (the first corner
// kept): a model exported inside out as a whole (mirrored by a handedness conversion).  "faces_reversed_as_asked"
// Repair (options.repair), in this order:
//  1. weld: used vertices closer than weld_tolerance * (bounding-box diagonal) become one (the lowest
//     index keeps its coordinates)                                            "vertices_merged"
//  2. repeated corners: consecutive repeats are dropped, a face that touches itself at a corner
//     ("pinched") is split into its loops            "repeated_corners_removed", "pinched_faces_split"
//     faces left with < 3 corners or zero area (build_scene's test) are removed
//                                                                      "degenerate_faces_removed"
//  3. orientation (options.orient; the file's winding is the truth, a valid model is never changed):
//     file        nothing is flipped
//     consistent  per connected surface (faces joined by manifold edges), the faces that disagree
//                 with the majority of the surface are flipped (ties: its first face)
//     visibility  (default) consistent, then a whole surface is flipped only on strong evidence of
//                 which of its sides the rest of the scene sees: from sample points on every face,
//                 8 rays into each hemisphere (cosine-distributed, fixed seeds); a ray that first
//                 hits another surface counts for the side it left, weighted by the face's area.
//                 A surface is flipped when at least 8 rays from its back reach other surfaces and
//                 its back gets >= 80 % of the weight (a room wound outward around its furniture; a
//                 block wound inward in a room). A surface nobody else sees (an empty closed room)
//                 keeps the file's winding; a closed object wound outward is never flipped. A ray
//                 that leaves through an opening of its own surface and ends, in the opening's
//                 plane, on what closes it (a block without a bottom on the floor; a counter open
//                 at the bottom and back against walls) stayed inside and counts for nothing.
//                 Then the surfaces left undecided (both sides see the scene: wall faces meshed on
//                 their own, a thin wall's two faces seeing each other's backs; furniture faces)
//                 take their side from the decided ones, in rounds: a ray between two surfaces is
//                 consistent when it leaves a front and arrives at a front, or a back at a back; an
//                 undecided surface whose rays to and from decided ones are >= 80 % inconsistent
//                 (by weight, at least 8) and none of whose sides sees decided ones mostly
//                 consistently is flipped; >= 80 % consistent, kept; decided either way from the next
//                 round. A valid model's rays are consistent; a light panel whose back faces the
//                 ceiling has a consistent side and keeps its winding. A model turned inside out
//                 (mirrored by a handedness conversion) comes out as the upright one (emitters
//                 facing a nearby ceiling or wall keep the file's side: no ray tells them apart).
//     "faces_reoriented" (faces flipped, all modes), "surfaces_flipped" (whole surfaces flipped by
//     visibility, each named with its input faces and evidence), "non_orientable_components".
//     Hint (all modes, when repair runs): "faces_seen_from_behind" counts one-sided faces whose back
//     reaches other faces' front sides with more rays than their front does (mark them two-sided?).
//     "emitters_facing_a_near_surface": one-sided emitters whose front rays (>= 90 %) end within a tenth of
//     the face's size over it and whose back rays (<= 10 %) do not (a light below a ceiling facing it).
// Detection (reported, never changed; also without repair, on the raw faces, since it changes
// nothing and tells where light can leak):
//  4. faces whose interiors cross, or coincide facing the same way (a duplicate, a decal); not faces
//     that merely touch along an edge or at a corner, shared or not (a block standing on a floor),
//     nor coincident faces back to back (one-sided surfaces that do not see each other: a two-sided
//     wall, a block's bottom on the floor); one count per pair of input faces   "self_intersections"
//  5. T-junctions (cracks): a vertex within the tolerance of the interior of an open edge (one face)
//     that it is not a corner of, itself ending an open edge along that line (a wall's bottom edge
//     split where the floor's edge is not). A vertex on an edge two faces share is contact, not a
//     crack (a table leg standing on a floor grid line); one count per (vertex, edge) "t_junctions"
// Without repair nothing is changed (detection still runs); build_scene then reports or rejects the
// raw problems itself. Non-planar faces are left to build_scene (it triangulates and reports them).
//
// Refinement (options.max_edge > 0, with or without repair): every edge is split into
// n = ceil(length / max_edge) equal pieces, the same for all faces sharing it, so refined neighbours
// still share every vertex (no new T-junctions; important for vertex output and for the mesh's own
// connectivity). Planar convex quads (the common architectural case) become a bilinear n x m grid
// of quads: exact tiling, planar pieces, half the patches of triangles; opposite edges of such a
// quad get the same n (the largest of the two, and so on along strips of quads). Triangles whose
// three edges get the same n are split uniformly into n^2 similar triangles. Other faces (triangles
// with unequal n, non-convex or non-planar polygons, n-gons) are triangulated: the split boundary
// plus an equilateral lattice of spacing max_edge inside, constrained Delaunay (CGAL), then longest-
// edge bisection (Rivara) of any interior edge still longer than max_edge. Non-planar faces are first
// triangulated as build_scene would. A face is refined when one of its edges gets n > 1, or when its
// diameter exceeds 2 * max_edge (n-gons with short edges). Pieces keep material, group, line and
// origin; they take the place of their face (face order is kept). Every output edge is
// <= max_edge * (1 + 1e-12); total area is preserved to round-off.   "faces_refined", "patches_added"
// The refined patch count is estimated before anything is split (exact for quads and uniformly split
// triangles, from the area for other faces) and checked against max_patches.
// (A face the mesher cannot refine, not expected for faces build_scene accepts, keeps its size and
// is warned about: "faces_not_refined".)
//
// Two-sided faces (last, with or without repair): a face whose material is two_sided becomes two
// patches, the face as given (side 0) and right after it its back (side 1: the corners reversed, on
// copies of the vertices), each with its own radiance; both keep the input face's origin. Visibility
// ignores a patch coplanar with the ray's source or target, so the two never shadow each other.
//                                                                                  "two_sided_faces"
//
// Each step records its count (0 too) in report.counts; a warning names up to 5 input faces.
#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/soup.hpp"

namespace lambert::mesh {

// How step 3 orients faces (see above). visibility is the default: it repairs the common export
// errors (a room or an object wound the wrong way round) and never flips a consistently wound
// surface that the rest of the scene sees from its front.
enum class Orientation { file, consistent, visibility };

// "file" | "consistent" | "visibility" -> Orientation; throws InputError otherwise.
Orientation parse_orientation(const std::string& name);

struct PrepareOptions {
  bool reverse_winding = false;  // every face reversed first, as asked (--reverse-winding)
  bool repair = true;
  Orientation orient = Orientation::visibility;
  bool imprint = true;  // with repair: contact lines and crossings imprinted, hidden fragments removed
  double max_edge = 0;  // metres; 0 = no refinement; must be >= 0 and finite
  // Weld, T-junction and touching distance, relative to the bounding-box diagonal of the used
  // vertices. 1e-6 (7 um in a 5 x 4 x 2.7 m room): above the rounding of files written with 6 digits,
  // far below any modelled detail. 0: exact duplicates only.
  double weld_tolerance = 1e-6;
  // Refinement refuses (InputError with the estimate and a max_edge that would fit) before splitting
  // anything when the refined scene would have more patches than this; 0 = no limit (the split counts
  // must still fit an int).
  long long max_patches = 0;
};

// Throws InputError (naming file, line and face) for corners out of range and non-finite positions
// used by a face, or an invalid option. Input faces with origin >= 0 keep that origin.
PolygonSoup prepare(const PolygonSoup& soup, const PrepareOptions& options, Report& report);

// prepare + build_scene; the scene's report starts with the preparation's counts and warnings.
Scene prepare_and_build(const PolygonSoup& soup, const PrepareOptions& options, const BuildOptions& build = {});

}  // namespace lambert::mesh
