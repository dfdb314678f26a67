#pragma once
// Shared by the mesh::prepare steps: prepare.cpp (driver, weld, cleaning), prepare_orient.cpp and
// prepare_imprint.cpp (repair), prepare_detect.cpp (detection), prepare_refine.cpp (refinement).
#include <cstdint>
#include <string>
#include <vector>

#include "lambert/mesh/prepare.hpp"

namespace lambert::mesh::detail {

// Input face index of soup face k.
inline int origin_of(const PolygonSoup& s, int k) { return s.faces[k].origin >= 0 ? s.faces[k].origin : k; }

// Corners of face k (precondition: indices in range).
std::vector<Vec3> corners(const PolygonSoup& s, int k);

// build_scene's zero-area test: area <= 1e-12 * (longest edge)^2 or not finite.
bool zero_area(const std::vector<Vec3>& poly);

// A face build_scene accepts geometrically: >= 3 distinct corners, non-zero area, and (for more than
// three corners) a triangulation that tiles it. Faces failing this are left alone (build_scene reports).
bool usable_face(const PolygonSoup& s, int k);

// "3, 5, 8, 13, 21 and 4 more" (sorted, distinct).
std::string id_list(std::vector<int> ids, int shown = 5);

std::string num(double x);

// Scene sizes (bounding-box diagonal of the used vertices, m) with exact form factors and visibility.
constexpr double kMinSceneSize = 1e-10, kMaxSceneSize = 1e12;
// Throws InputError naming the size when it lies outside [kMinSceneSize, kMaxSceneSize] (scale_check.cpp).
void check_geometric_scale(const PolygonSoup& s);

// "3 faces" / "1 face".
std::string plural(long n, const char* one, const char* many);

// "vertex 7 (scene.obj:9)".
std::string vertex_at(const PolygonSoup& s, int v);

// Undirected edge key (lower index in the high half).
std::uint64_t edge_key(int a, int b);

// relative * bounding-box diagonal of the used vertices (0 for an empty soup).
double length_tolerance(const PolygonSoup& s, double relative);

double distance_to_segment(const Vec3& p, const Vec3& a, const Vec3& b);
double distance_to_boundary(const Vec3& p, const std::vector<Vec3>& poly);

// Repair steps (see prepare.hpp for what each does and reports).
// tol (m): how far a ray's end may lie off the plane of a surface's planar opening and still close it.
void orient(PolygonSoup& s, Orientation mode, double tol, Report& report);
// Contact lines and crossings imprinted, hidden fragments removed (prepare_imprint.cpp).
//                                                      "faces_imprinted", "hidden_fragments_removed"
void imprint(PolygonSoup& s, double tol, Report& report);
// Last step, with or without repair: each face whose material is two-sided gets a back copy (reversed,
// side 1, own vertex copies) right after it.                                      "two_sided_faces"
void duplicate_two_sided(PolygonSoup& s, Report& report);

// Detection steps: usable[k] = usable_face(s, k); tol in metres.
void detect_self_intersections(const PolygonSoup& s, const std::vector<char>& usable, double tol, Report& report);
void detect_t_junctions(const PolygonSoup& s, const std::vector<char>& usable, double tol, Report& report);

// Refinement step (prepare_refine.cpp): splits faces in place, appends positions, counts.
// Throws InputError before changing anything when the estimated patch count exceeds max_patches (> 0).
void refine(PolygonSoup& soup, double max_edge, Report& report, long long max_patches = 0);

}  // namespace lambert::mesh::detail
