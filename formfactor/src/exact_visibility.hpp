#pragma once
// Exact (analytic) partial visibility (internal; docs/physics.md §6). For a receiving point x and a target
// polygon P, the occluders between x and P are clipped to the cone from x through P, projected from x onto
// P's plane, united (Clipper, integer coordinates) and the contour integral of their union is the form factor
// of the hidden part of P; F_visible(x -> P) = F(x -> P) - F_hidden. The patch-to-patch value integrates
// F_hidden over the source with an adaptive outer rule (an embedded degree-7/5 rule per element, bisected where they differ most), so penumbra
// kinks are resolved to a requested absolute tolerance.
//
// Units: metres; form factors dimensionless. Occluders are planar simple polygons (any orientation: both
// sides block). The caller chooses the occluders (a BVH or shaft query); occluders lying in the plane of the
// source or the target must be left out by the caller (they cannot block, see visibility.hpp).
// Deterministic: no state is shared between calls except the caller's scratch buffers.
#include <cstdint>
#include <memory>
#include <span>
#include <unordered_map>
#include <vector>

#include "internal.hpp"

namespace lambert::formfactor::detail {

struct ExactScratch;  // per-thread buffers (Clipper, clipped polygons); exact_visibility.cpp
struct ExactScratchDeleter {
  void operator()(ExactScratch* s) const;
};
using ExactScratchPtr = std::unique_ptr<ExactScratch, ExactScratchDeleter>;
ExactScratchPtr make_exact_scratch();

// An occluder: its corners and whether it is convex (enables the "covers the whole cone" shortcut).
struct Occluder {
  std::span<const Vec3> poly;
  bool convex = false;
  int solid = -1;  // >= 0: a face of that closed convex solid (convex_solids), whose faces' union is its silhouette
  // With cull: inner . y >= inner_offset for y on the solid's side of the face's plane (a face x sees from behind).
  bool cull = false;
  Vec3 inner = Vec3::Zero();
  double inner_offset = 0;
  // poly's unit normal (Newell's; zero if it has no area) and unit . poly[0]: set by the exact path's first
  // classification of the pair, and carried with the copies it hands to the pair's elements.
  bool has_unit = false;
  Vec3 unit = Vec3::Zero();
  double unit_offset = 0;
  // A non-convex poly's convex pieces (edge to edge, their corners poly's own; empty if none were made): its
  // projection is united from theirs, without a general Boolean operation.
  std::span<const std::vector<Vec3>> parts = {};
};

// F(x -> hidden part of target): x a point with unit normal n; target a planar simple polygon with unit
// normal nt (front side towards x) lying in x's closed front half-space (clip it first), target_convex true
// only if it is convex. Returns a value in [0, F(x -> target)] (up to rounding of the snapped 2D union,
// ~1e-9 relative to the target's size). 0 if x is not strictly in front of the target's plane. kind, if given: 0 if
// nothing is hidden (up to 1e-9 of the target's area), 1 if all of it is, 2 if part of it, -1 if not determined
// (compare the value with F(x -> target) then).
double hidden_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> target, const Vec3& nt,
                               bool target_convex, std::span<const Occluder> occluders, ExactScratch& scratch,
                               int* kind = nullptr);

// True if every segment between a corner of a and a corner of b crosses the convex polygon q (unit normal `unit`,
// q's winding; offset = unit . q[0]) strictly inside its plane's eps-slab on both ends and inside or on q's edges:
// then every segment between the convex hulls of a and b meets q, and q hides them from each other (exact). False if
// a or b is empty.
bool convex_hides(std::span<const Vec3> a, std::span<const Vec3> b, std::span<const Vec3> q, const Vec3& unit,
                  double offset, double eps);

// Convenience for callers outside the assembly (hierarchical links, tests): the visible point-to-polygon
// form factor, point_to_polygon(x, n, target) minus its hidden part; target may straddle x's plane.
double visible_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> target,
                                std::span<const Occluder> occluders);

// The hidden part of the pair (s -> t): H = (1/A_s) integral over s of F_hidden(x -> t) dA(x), so that
// F_st(visible) = F_st(unoccluded) - H.
struct ExactPairResult {
  enum Outcome { kClear = 0, kHidden = 1, kIntegrated = 2 };
  Outcome outcome = kClear;  // clear: no candidate meets the convex hull of s and t (H = 0, exact);
                             // hidden: one convex occluder meets every segment between them (H = F_st);
                             // integrated: adaptive outer rule
  double H = 0;              // hidden part of F_st (integrated only)
  double error = 0;          // estimated absolute error of H
  long long points = 0;      // point evaluations
  bool over_tolerance = false;  // stopped at the evaluation limit above the tolerance
};
// s, t: polygons with unit normals and areas; s_convex / t_convex as for hidden_point_to_polygon. candidates:
// occluders that may lie between them (others are culled here against the convex hull of s and t). tol: the
// absolute error allowed on H. scale: the scene's size (plane tolerances are relative to it).
ExactPairResult exact_hidden_pair(std::span<const Vec3> s, const Vec3& ns, double area_s, bool s_convex,
                                  std::span<const Vec3> t, const Vec3& nt, bool t_convex,
                                  std::span<const Occluder> candidates, double tol, double scale,
                                  ExactScratch& scratch);

// The proof exact_hidden_pair uses for elements hidden by several occluders together (occluder fusion by extended
// projections, docs/physics.md section 6): a bound on F(x -> the part of `target` the occluders may leave visible)
// that holds for every x in the convex hull of `corners` (a convex polygon in the plane with unit normal ns, in front
// of the target); INFINITY if no proof is found. 0 up to rounding (~1e-16) means hidden from all of it. The target
// (unit normal nt, facing the corners) must lie in front of the corners' plane.
double fused_hidden_bound(std::span<const Vec3> corners, const Vec3& ns, std::span<const Vec3> target, const Vec3& nt,
                          std::span<const Occluder> occluders, double scale, ExactScratch& scratch);

// For tests: the critical lines exact_hidden_pair splits the pair (s -> t) on, as p + u d for u in [t0, t1] on the
// source's plane (d a unit vector; infinite ends allowed). Empty if the pair is clear, hidden by one occluder, or
// has too many occluders or lines for them.
struct CriticalSegment {
  Vec3 p, d;
  double t0, t1;
};
std::vector<CriticalSegment> pair_critical_lines(std::span<const Vec3> s, const Vec3& ns, std::span<const Vec3> t,
                                                const Vec3& nt, std::span<const Occluder> candidates, double scale);

// Occluders lying in one plane and touching or overlapping each other (a wall or a block face meshed into a grid,
// both sides of a two-sided face) block exactly what their union blocks: they are merged into one polygon per
// connected region of the union (Clipper, in the plane's integer frame: corners move by <= 1e-9 of the region's
// size), where the plane's union has no hole. Fewer, larger occluders: fewer clips per point, and a region that
// hides a pair alone can prove it hidden. Deterministic (planes in order of first appearance, mesh::plane_ids).
struct MergedOccluders {
  std::vector<std::vector<Vec3>> polys;
  std::vector<std::uint8_t> convex;
  std::vector<std::vector<std::vector<Vec3>>> parts;  // per merged polygon: its convex pieces if it is not convex
  // The patches neither merged nor convex (keys; nothing stored for the others): their triangles.
  std::unordered_map<int, std::vector<std::vector<Vec3>>> patch_parts;
  std::vector<int> solid;     // per merged polygon: the convex solid of all the members of its plane, or -1
  std::vector<int> of_patch;  // per patch of the geometry: its merged polygon, or -1 (the patch is used as it is)
  std::vector<int> solid_of_patch;  // per patch: convex_solids
  std::vector<Vec3> solid_centre;   // per solid id: the mean of its faces' centroids (inside it)
  std::vector<std::vector<std::array<double, 4>>> solid_open;  // per solid id: ConvexSolids::open
};

// Convex solids among the occluders (docs/physics.md section 6): a connected set of occluder faces on the boundary
// of a convex polytope P, wound outward. Faces are joined where they touch (a corner of one within 1e-9 * scale of
// the other's boundary: shared corners and T-junctions alike) and each lies behind the other's plane, or where they
// lie in one plane facing the same way; the component is a solid if every corner of it lies behind or on every
// face's plane (within 1e-9 * scale) and it is not flat. P is the convex hull of its corners. A facet of P its faces
// do not cover entirely (a box's bottom standing on the floor, its back against a wall, a door cut in a wall) is
// *open*: such a solid hides exactly its silhouette only as seen from points behind every open facet's plane, so it is
// used as a solid only for pairs whose corners all lie there (solid_usable); a closed solid (no open facet) for
// every pair. From such points, a segment that meets P enters it through a face that is present: the faces hide
// P's silhouette, a convex region whose corners are P's, so the hidden part changes its structure only on critical
// lines (no EEE events) and hidden_point_to_polygon takes the convex hull of the projected faces instead of their
// Boolean union.
struct ConvexSolids {
  std::vector<int> of_patch;  // per patch of g: solid id, or -1
  std::vector<std::vector<std::array<double, 4>>> open;  // per solid: open facets (outward unit normal n, offset o)
};
ConvexSolids find_convex_solids(const mesh::PatchGeometry& g, const std::vector<int>& occluders, double scale);
std::vector<int> convex_solids(const mesh::PatchGeometry& g, const std::vector<int>& occluders, double scale);
// True if every corner of a and b lies behind or on (within eps) every open facet's plane n . q <= o.
bool solid_usable(const std::vector<std::array<double, 4>>& open, std::span<const Vec3> a, std::span<const Vec3> b,
                  double eps);
MergedOccluders merge_coplanar_occluders(const mesh::PatchGeometry& g, const std::vector<int>& occluders, double scale);

// True if patch p lies in the plane of patch i (either facing, within 1e-9 * scale): it blocks nothing between i and
// another patch.
bool in_plane_of(const PatchData& P, double scale, int p, int i);

// The occluders of the pair (i, j) for exact_hidden_pair, from shaft candidates (OccluderTree::collect, or
// collect_grouped_from with the groups of merged.of_patch): those in the plane of i or of j are left out (they block
// nothing); occluders merged with coplanar neighbours enter once, as their merged polygon. convex: per patch,
// convex polygon. merged_ids: scratch.
void pair_occluders(const mesh::PatchGeometry& g, const PatchData& P, double scale, std::span<const int> candidates,
                    int i, int j, const MergedOccluders& merged, const std::vector<std::uint8_t>& convex,
                    std::vector<int>& merged_ids, std::vector<Occluder>& occ);

}  // namespace lambert::formfactor::detail
