#pragma once
// Shared by prepare.cpp (repair, detection) and prepare_refine.cpp (refinement).
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

// Refinement step (prepare_refine.cpp): splits faces in place, appends positions, counts.
// Throws InputError before changing anything when the estimated patch count exceeds max_patches (> 0).
void refine(PolygonSoup& soup, double max_edge, Report& report, long long max_patches = 0);

}  // namespace lambert::mesh::detail
