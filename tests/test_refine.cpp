// mesh::prepare refinement (max_edge): area and face_id preserved, edge bound, conformity.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "soup_util.hpp"

using namespace lambert;
using namespace lambert::mesh;

namespace {

// test_util::soup_of with face k in group k % 2 (refinement must keep groups).
PolygonSoup soup_of(const std::vector<Vec3>& positions, const std::vector<std::vector<int>>& faces) {
  PolygonSoup s = test_util::soup_of(positions, faces);
  for (size_t k = 0; k < s.faces.size(); ++k) s.faces[k].group = static_cast<int>(k % 2);
  s.groups = {"even", "odd"};
  return s;
}

// Faces covering every refinement path, in the plane y = 0 unless said:
//  0 rectangle 2 x 1 (grid), 1 triangle sharing the rectangle's edge x = 2 (unequal edge pieces),
//  2 non-convex L-shaped hexagon, 3 sliver triangle 3 m x 1 cm, 4 non-planar quad (a corner 0.2 m
//  up), 5 trapezoid (bilinear grid), 6 regular 24-gon of radius 0.5 m (short edges, large diameter),
//  7 equilateral triangle of side 1 (uniform split).
PolygonSoup mixed_faces() {
  std::vector<Vec3> p = {{0, 0, 0}, {2, 0, 0}, {2, 0, 1}, {0, 0, 1}, {2.8, 0, 0.4},                  // 0-4
                         {0, 0, 2}, {2, 0, 2}, {2, 0, 2.5}, {0.5, 0, 2.5}, {0.5, 0, 4}, {0, 0, 4},  // 5-10
                         {3, 0, 5}, {6, 0, 5}, {6, 0, 5.01},                                       // 11-13
                         {7, 0, 0}, {8, 0, 0}, {8, 0.2, 1}, {7, 0, 1},                              // 14-17
                         {9, 0, 0}, {11, 0, 0}, {10.6, 0, 1}, {9.4, 0, 1},                          // 18-21
                         {0, 1, 0}, {1, 1, 0}, {0.5, 1, std::sqrt(0.75)}};                          // 22-24
  std::vector<std::vector<int>> f = {{0, 3, 2, 1}, {1, 2, 4}, {5, 10, 9, 8, 7, 6}, {11, 13, 12}, {14, 17, 16, 15},
                                     {18, 21, 20, 19}};
  std::vector<int> disk;
  for (int i = 0; i < 24; ++i) {
    const double a = -2 * std::numbers::pi * i / 24;  // clockwise in x-z: normal +y like the others
    p.push_back({5 + 0.5 * std::cos(a), 0, 2 + 0.5 * std::sin(a)});
    disk.push_back(static_cast<int>(p.size()) - 1);
  }
  f.push_back(disk);
  f.push_back({22, 23, 24});  // above the others, facing them (-y): no orientation repair needed
  return soup_of(p, f);
}

PolygonSoup refined(const PolygonSoup& s, double max_edge, Report& r, bool repair = true) {
  PrepareOptions o;
  o.max_edge = max_edge;
  o.repair = repair;
  return prepare(s, o, r);
}

// Area per input face from build_scene's patches (non-planar faces split as build_scene does).
std::vector<double> area_by_face(const Scene& scene) {
  std::vector<double> a(scene.input_faces, 0.0);
  for (int p = 0; p < scene.patches(); ++p) a[scene.face_id[p]] += scene.geometry.area[p];
  return a;
}

std::string all_warnings(const Report& r) {
  std::string s;
  for (const auto& w : r.warnings) s += "\n  " + w;
  return s;
}

long count(const Report& r, const std::string& key) {
  const auto it = r.counts.find(key);
  return it == r.counts.end() ? -1 : it->second;
}

double longest_edge(const PolygonSoup& s, const SoupFace& f, int* at = nullptr) {
  double worst = 0;
  const size_t m = f.vertices.size();
  for (size_t c = 0; c < m; ++c) {
    const double l = (s.positions[f.vertices[(c + 1) % m]] - s.positions[f.vertices[c]]).norm();
    if (l > worst) {
      worst = l;
      if (at) *at = static_cast<int>(c);
    }
  }
  return worst;
}

// Total length of the mesh's boundary edges (faces joined by shared vertices).
double boundary_length(const Scene& scene) {
  double sum = 0;
  for (auto e : scene.mesh.edges())
    if (scene.mesh.is_boundary(e)) sum += scene.mesh.calc_edge_length(e);
  return sum;
}

}  // namespace

TEST(Refine, RefinementPreservesAreaAndFaceId) {
  const PolygonSoup s = mixed_faces();
  const Scene before = build_scene(s);
  const auto area_before = area_by_face(before);
  for (double L : {1.0, 0.3, 0.07}) {
    Report r;
    const PolygonSoup out = refined(s, L, r);
    const Scene after = build_scene(out);
    ASSERT_EQ(after.input_faces, 8);
    EXPECT_GT(after.patches(), before.patches()) << "L " << L;
    // Pieces of input face k come where face k was, and keep its attributes.
    for (size_t k = 0; k < out.faces.size(); ++k) {
      const int o = out.faces[k].origin;
      ASSERT_TRUE(o >= 0 && o < 8) << k;
      if (k > 0) {
        EXPECT_GE(o, out.faces[k - 1].origin) << "face " << k << ", L " << L;
      }
      EXPECT_EQ(out.faces[k].line, 100 + o);
      EXPECT_EQ(out.faces[k].group, o % 2);
      EXPECT_EQ(out.faces[k].material, s.faces[o].material);
    }
    for (int p = 0; p < after.patches(); ++p) EXPECT_EQ(after.group[p], after.face_id[p] % 2) << p;
    // Area per input face: the pieces tile it exactly, so only summation round-off remains
    // (at most ~1e4 pieces of relative error 1e-16 each).
    const auto area_after = area_by_face(after);
    for (int k = 0; k < 8; ++k)
      EXPECT_NEAR(area_after[k], area_before[k], 1e-12 * area_before[k]) << "input face " << k << ", L " << L;
    EXPECT_EQ(count(r, "faces_refined"), L == 1.0 ? 5 : 8) << all_warnings(r);  // at 1 m: 1, 6, 7 stay
    EXPECT_EQ(count(r, "patches_added"), static_cast<long>(out.faces.size()) - 8);
    EXPECT_EQ(count(r, "faces_not_refined"), -1) << all_warnings(r);
  }
}

TEST(Refine, RefinementRespectsMaxEdge) {
  const PolygonSoup s = mixed_faces();
  for (double L : {1.0, 0.3, 0.07}) {
    Report r;
    const PolygonSoup out = refined(s, L, r);
    for (size_t k = 0; k < out.faces.size(); ++k) {
      int c = 0;
      // 1e-12: the edge counts allow 1e-13 of round-off above L (2.7 / 0.3 = 9.000000000000002).
      const double l = longest_edge(out, out.faces[k], &c);
      EXPECT_LE(l, L * (1 + 1e-12)) << "piece " << k << " of input face " << out.faces[k].origin << ", corner " << c
                                    << ", L " << L;
    }
  }
}

TEST(Refine, RefinedNeighboursStillShareEveryVertex) {
  // Rectangle and triangle share an edge whose pieces both must use; a second pass of detection
  // must find no T-junction, and the mesh's boundary is the union's outline (no cracks).
  const PolygonSoup s = mixed_faces();
  const double outline = boundary_length(build_scene(s));
  for (double L : {0.3, 0.07}) {
    Report r;
    const PolygonSoup out = refined(s, L, r);
    Report again;
    PrepareOptions detect_only;
    detect_only.repair = false;
    prepare(out, detect_only, again);
    EXPECT_EQ(count(again, "t_junctions"), 0) << all_warnings(again);
    EXPECT_EQ(count(again, "self_intersections"), 0) << all_warnings(again);
    const Scene scene = build_scene(out);
    EXPECT_EQ(scene.report.counts.count("nonmanifold_faces_detached"), 0u) << all_warnings(scene.report);
    // Tolerance: sums of ~1e3 edge lengths, each exact to round-off.
    EXPECT_NEAR(boundary_length(scene), outline, 1e-12 * outline) << "L " << L;
  }
}

TEST(Refine, ParallelogramQuadBecomesAGridAndEqualEdgedTriangleSplitsUniformly) {
  // 2.7 m x 1 m wall at 0.3 m: 9 x 4 quads (2.7 / 0.3 rounds to 9.000000000000002: still 9 pieces),
  // equilateral triangle of side 1 at 0.25 m: 4^2 = 16 triangles.
  const PolygonSoup s = soup_of({{0, 0, 0}, {2.7, 0, 0}, {2.7, 1, 0}, {0, 1, 0}, {5, 0, 0}, {6, 0, 0}, {5.5, std::sqrt(0.75), 0}},
                                {{0, 1, 2, 3}, {4, 5, 6}});
  Report r;
  const PolygonSoup wall = refined(s, 0.3, r);
  int quads = 0;
  for (const auto& f : wall.faces) quads += f.origin == 0 && f.vertices.size() == 4;
  EXPECT_EQ(quads, 36);
  const PolygonSoup tri = refined(s, 0.25, r);
  int tris = 0;
  for (const auto& f : tri.faces) tris += f.origin == 1 && f.vertices.size() == 3;
  EXPECT_EQ(tris, 16);
}

TEST(Refine, ShortEdgedFacesAreLeftAlone) {
  const PolygonSoup s = mixed_faces();
  Report r;
  const PolygonSoup out = refined(s, 10.0, r);  // every edge and diameter well below
  ASSERT_EQ(out.faces.size(), s.faces.size());
  for (size_t k = 0; k < s.faces.size(); ++k) EXPECT_EQ(out.faces[k].vertices, s.faces[k].vertices) << k;
  EXPECT_EQ(out.positions.size(), s.positions.size());
  EXPECT_EQ(count(r, "faces_refined"), 0);
  EXPECT_EQ(count(r, "patches_added"), 0);
}

TEST(Refine, RefinementIsDeterministicAndWorksWithoutRepair) {
  const PolygonSoup s = mixed_faces();
  Report r1, r2, r3;
  const PolygonSoup a = refined(s, 0.1, r1), b = refined(s, 0.1, r2), c = refined(s, 0.1, r3, false);
  EXPECT_EQ(a.positions, b.positions);
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (size_t k = 0; k < a.faces.size(); ++k) EXPECT_EQ(a.faces[k].vertices, b.faces[k].vertices) << k;
  // The crafted soup needs no repair, so refining the raw faces gives the same result.
  ASSERT_EQ(c.faces.size(), a.faces.size());
  for (size_t k = 0; k < a.faces.size(); ++k) EXPECT_EQ(c.faces[k].vertices, a.faces[k].vertices) << k;
}

TEST(Refine, FurnishedRoomExampleRefinesToQuarterMetre) {
  const PolygonSoup s = io::read_obj(std::string(LAMBERT_SOURCE_DIR) + "/examples/room.obj");
  const Scene before = build_scene(s);
  const auto t0 = std::chrono::steady_clock::now();
  PrepareOptions o;
  o.max_edge = 0.25;
  o.imprint = false;  // areas per input face are compared: imprinting removes the hidden area under furniture
  const Scene after = prepare_and_build(s, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("room.obj: %d -> %d patches at 0.25 m in %.2f s\n", before.patches(), after.patches(), seconds);
  const auto a0 = area_by_face(before), a1 = area_by_face(after);
  for (int k = 0; k < before.input_faces; ++k) EXPECT_NEAR(a1[k], a0[k], 1e-12 * a0[k]) << "input face " << k;
  for (int p = 0; p < after.patches(); ++p) {
    const auto poly = after.geometry.polygon(p);
    for (size_t c = 0; c < poly.size(); ++c)
      ASSERT_LE((poly[(c + 1) % poly.size()] - poly[c]).norm(), 0.25 * (1 + 1e-12)) << "patch " << p;
  }
  EXPECT_EQ(count(after.report, "t_junctions"), 0) << all_warnings(after.report);
}
