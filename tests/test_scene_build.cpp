// build_scene: validation errors and warnings, patch construction, Scene helpers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "lambert/mesh/scene.hpp"
#include "soup_util.hpp"

using namespace lambert;
using namespace lambert::mesh;

namespace {

using lambert::mesh::test_util::soup_of;

// Unit square in z = 0 (normal +z) and a triangle beside it sharing the edge 1-2.
PolygonSoup square_and_triangle() {
  return soup_of({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0.5, 0}}, {{0, 1, 2, 3}, {1, 4, 2}});
}

int add_material(PolygonSoup& s, const std::string& name, RGB rho, RGB le, int line = 7) {
  Material m;
  m.name = name;
  m.reflectance = rho;
  m.emission = le;
  m.defined_at = SourceLoc{"test.mtl", line};
  s.materials.push_back(m);
  return static_cast<int>(s.materials.size()) - 1;
}

// The message of the InputError that build_scene throws, or "" if it does not throw.
std::string error_of(const PolygonSoup& s) {
  try {
    build_scene(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

bool any_warning_has(const Report& r, const std::string& part) {
  for (const auto& w : r.warnings)
    if (has(w, part)) return true;
  return false;
}

double tri_area(const Vec3& a, const Vec3& b, const Vec3& c) { return 0.5 * (b - a).cross(c - a).norm(); }

}  // namespace

// ---- materials ----------------------------------------------------------------------------------

TEST(SceneBuildMaterials, ReflectanceOneIsRejectedAsHavingNoSteadyState) {
  PolygonSoup s = square_and_triangle();
  s.faces[1].material = add_material(s, "mirror", RGB(0.5, 1.0, 0.5), RGB::Zero(), 12);
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "mirror") && has(msg, "test.mtl:12") && has(msg, "steady state") && has(msg, "face 1") &&
              has(msg, "test.obj:101"))
      << msg;
}

TEST(SceneBuildMaterials, ReflectanceNaNOrNegativeIsRejected) {
  for (double bad : {std::numeric_limits<double>::quiet_NaN(), -0.1}) {
    PolygonSoup s = square_and_triangle();
    s.faces[0].material = add_material(s, "odd", RGB(0.2, 0.2, bad), RGB::Zero(), 3);
    const std::string msg = error_of(s);
    EXPECT_TRUE(has(msg, "odd") && has(msg, "test.mtl:3") && has(msg, "reflectance")) << "rho_B=" << bad << ": " << msg;
  }
}

TEST(SceneBuildMaterials, NegativeOrNonFiniteEmissionIsRejected) {
  for (double bad : {-1.0, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
    PolygonSoup s = square_and_triangle();
    s.faces[0].material = add_material(s, "lamp", RGB::Constant(0.5), RGB(1, bad, 1), 9);
    const std::string msg = error_of(s);
    EXPECT_TRUE(has(msg, "lamp") && has(msg, "test.mtl:9") && has(msg, "emission")) << "Le_G=" << bad << ": " << msg;
  }
}

TEST(SceneBuildMaterials, UnusedInvalidMaterialIsAccepted) {
  PolygonSoup s = square_and_triangle();
  add_material(s, "unused", RGB::Constant(2.0), RGB::Constant(-1.0));
  EXPECT_NO_THROW(build_scene(s));
}

TEST(SceneBuildMaterials, MaterialIndexOutOfRangeIsRejected) {
  PolygonSoup s = square_and_triangle();
  s.faces[1].material = 5;
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "face 1") && has(msg, "test.obj:101") && has(msg, "material")) << msg;
}

// ---- face topology ------------------------------------------------------------------------------

TEST(SceneBuildFaces, FaceWithFewerThanThreeCornersIsRejected) {
  PolygonSoup s = square_and_triangle();
  s.faces[1].vertices = {1, 4};
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "face 1") && has(msg, "test.obj:101") && has(msg, "2 corners")) << msg;
}

TEST(SceneBuildFaces, CornerIndexOutOfRangeIsRejected) {
  for (int bad : {5, -1}) {
    PolygonSoup s = square_and_triangle();
    s.faces[1].vertices = {1, bad, 2};
    const std::string msg = error_of(s);
    EXPECT_TRUE(has(msg, "face 1") && has(msg, "test.obj:101") && has(msg, "out of range") &&
                has(msg, std::to_string(bad)))
        << "index " << bad << ": " << msg;
  }
}

TEST(SceneBuildFaces, RepeatedCornerIsRejected) {
  PolygonSoup s = square_and_triangle();
  s.faces[0].vertices = {0, 1, 2, 1};
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "face 0") && has(msg, "test.obj:100") && has(msg, "twice") && has(msg, "vertex 1")) << msg;
}

TEST(SceneBuildFaces, NonFinitePositionUsedByAFaceIsRejected) {
  PolygonSoup s = square_and_triangle();
  s.positions[4].y() = std::numeric_limits<double>::infinity();
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "vertex 4") && has(msg, "test.obj:5") && has(msg, "non-finite") && has(msg, "face 1")) << msg;
}

TEST(SceneBuildFaces, NonFinitePositionNotUsedIsAccepted) {
  PolygonSoup s = square_and_triangle();
  s.positions.push_back(Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0));
  s.position_lines.push_back(6);
  EXPECT_NO_THROW(build_scene(s));
}

TEST(SceneBuildFaces, EmptySoupIsRejected) {
  const std::string msg = error_of(soup_of({{0, 0, 0}}, {}));
  EXPECT_TRUE(has(msg, "test.obj") && has(msg, "no faces")) << msg;
}

// ---- face geometry ------------------------------------------------------------------------------

TEST(SceneBuildGeometry, CollinearTriangleIsRejectedAsZeroArea) {
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 0}}, {{0, 1, 2, 3}, {0, 1, 4}});
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "face 1") && has(msg, "test.obj:101") && has(msg, "zero area")) << msg;
}

TEST(SceneBuildGeometry, SliverBelowRelativeAreaThresholdIsRejected) {
  // Area 0.5e-13 m^2 with a 1 m edge: below 1e-12 * L^2, i.e. round-off-sized.
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {0.5, 1e-13, 0}}, {{0, 1, 2}});
  const std::string msg = error_of(s);
  EXPECT_TRUE(has(msg, "face 0") && has(msg, "zero area") && has(msg, "5e-14")) << msg;
}

TEST(SceneBuildGeometry, TinyButWellShapedFaceIsAccepted) {
  // 1e-4 m square: area 1e-8 m^2 is small in absolute terms but not degenerate.
  PolygonSoup s = soup_of({{0, 0, 0}, {1e-4, 0, 0}, {1e-4, 1e-4, 0}, {0, 1e-4, 0}}, {{0, 1, 2, 3}});
  s.faces[0].material = add_material(s, "lamp", RGB::Constant(0.5), RGB::Constant(1.0));
  const Scene sc = build_scene(s);
  ASSERT_EQ(sc.patches(), 1);
  EXPECT_NEAR(sc.geometry.area[0], 1e-8, 1e-22);  // round-off level for this size
}

TEST(SceneBuildGeometry, SelfIntersectingPolygonIsRejected) {
  // Edges 2->3 and 3->4 cross edge 0->1; the signed area (2 m^2) is not zero, so only the crossing
  // test catches it.
  std::vector<Vec3> p = {{0, 0, 0}, {4, 0, 0}, {4, 2, 0}, {2, -1, 0}, {0, 2, 0}};
  for (double lift : {0.0, 0.3}) {  // planar and non-planar (which would otherwise be triangulated)
    p[4].z() = lift;
    const std::string msg = error_of(soup_of(p, {{0, 1, 2, 3, 4}}));
    EXPECT_TRUE(has(msg, "face 0") && has(msg, "test.obj:100") && has(msg, "self-intersecting"))
        << "lift " << lift << ": " << msg;
  }
}

TEST(SceneBuildGeometry, NonConvexPlanarPolygonIsOnePatchWithExactArea) {
  // L-shaped hexagon of area 3 (three unit squares).
  PolygonSoup s = soup_of({{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}}, {{0, 1, 2, 3, 4, 5}});
  const Scene sc = build_scene(s);
  ASSERT_EQ(sc.patches(), 1);
  EXPECT_EQ(sc.geometry.polygon(0).size(), 6u);
  EXPECT_NEAR(sc.geometry.area[0], 3.0, 1e-14);  // sums of exact small numbers
  EXPECT_EQ(sc.report.counts.count("nonplanar_faces_triangulated"), 0u);
}

// Twisted unit quad: corners 1 and 3 raised by h. By symmetry the best plane is z = h/2 (deviation h/2)
// and either diagonal splits it into two triangles of total area sqrt(1 + 2 h^2).
PolygonSoup twisted_quad(double h) {
  return soup_of({{0, 0, 0}, {1, 0, h}, {1, 1, 0}, {0, 1, h}}, {{0, 1, 2, 3}});
}

TEST(SceneBuildGeometry, NonPlanarQuadIsTriangulatedPreservingArea) {
  const double h = 0.1;
  const Scene sc = build_scene(twisted_quad(h));
  ASSERT_EQ(sc.patches(), 2);
  EXPECT_EQ(sc.face_id, (std::vector<int>{0, 0}));
  EXPECT_EQ(sc.input_faces, 1);
  for (int p = 0; p < 2; ++p) {
    auto t = sc.geometry.polygon(p);
    ASSERT_EQ(t.size(), 3u) << "patch " << p;
    EXPECT_NEAR(sc.geometry.area[p], tri_area(t[0], t[1], t[2]), 1e-15) << "patch " << p;
    EXPECT_GT(sc.geometry.normal[p].z(), 0.9) << "patch " << p << ": winding of the quad kept";
  }
  // Round-off only: a handful of operations on O(1) numbers.
  EXPECT_NEAR(sc.geometry.area[0] + sc.geometry.area[1], std::sqrt(1 + 2 * h * h), 1e-14);
  EXPECT_EQ(sc.report.counts.at("nonplanar_faces_triangulated"), 1);
  EXPECT_EQ(sc.report.worst_nonplanar_face, 0);
  EXPECT_NEAR(sc.report.worst_nonplanarity, h / 2, 1e-15);
  EXPECT_TRUE(any_warning_has(sc.report, "1 non-planar face") && any_warning_has(sc.report, "0.05 m") &&
              any_warning_has(sc.report, "face 0"));
}

// A non-planar pentagon with three corners nearly in a line (b bulges 1e-7 m out of the segment a-c, as corners rounded
// to single precision do where a cut piece of a wall has a corner inside an edge): ear clipping from b takes the ear
// (a, b, c), a triangle 0.4 m long and 1e-7 m wide, whose form factors divided by its area leave [0, 1]. The
// constrained Delaunay triangulation has no triangle narrower than 0.1 m here; the area is kept.
TEST(SceneBuildGeometry, NonPlanarFaceIsSplitWithoutSlivers) {
  const std::vector<Vec3> pos{{0.2, -1e-7, 0}, {0.4, 0, 0}, {0.4, 0.3, 1e-5}, {0, 0.3, 0}, {0, 0, 0}};  // b c d e a
  const Scene sc = build_scene(soup_of(pos, {{0, 1, 2, 3, 4}}));
  ASSERT_EQ(sc.report.counts.count("nonplanar_faces_triangulated"), 1u);
  double total = 0;
  for (int p = 0; p < sc.patches(); ++p) {
    const auto t = sc.geometry.polygon(p);
    ASSERT_EQ(t.size(), 3u);
    const double longest = std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
    EXPECT_GT(2 * sc.geometry.area[p] / longest, 0.1) << "patch " << p << ": a sliver";
    total += sc.geometry.area[p];
  }
  // The rectangle plus the bulge's triangle (2e-8 m^2); the lift tilts the triangles by 3e-5 rad (area 4e-11 more).
  EXPECT_NEAR(total, 0.4 * 0.3 + 0.5 * 0.4 * 1e-7, 1e-9);
}

TEST(SceneBuildGeometry, QuadWithinPlanarityToleranceStaysOnePatch) {
  // Deviation 5e-10 m < 1e-6 * sqrt(1 m^2).
  const Scene sc = build_scene(twisted_quad(1e-9));
  EXPECT_EQ(sc.patches(), 1);
  EXPECT_EQ(sc.report.counts.count("nonplanar_faces_triangulated"), 0u);
}

TEST(SceneBuildGeometry, PatchOrderFollowsInputOrderWithTrianglesInPlace) {
  // face 0: triangle, face 1: twisted quad (-> 2 triangles), face 2: planar quad.
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0.2}, {1, 1, 0}, {0, 1, 0.2}, {-1, 0, 0}, {5, 0, 0}, {6, 0, 0},
                           {6, 1, 0}, {5, 1, 0}},
                          {{4, 0, 3}, {0, 1, 2, 3}, {5, 6, 7, 8}});
  s.groups = {"a", "b"};
  const int red = add_material(s, "red", RGB(0.8, 0.1, 0.1), RGB::Zero());
  s.faces[1].material = red;
  s.faces[1].group = 1;
  s.faces[2].group = 0;
  const Scene sc = build_scene(s);
  EXPECT_EQ(sc.face_id, (std::vector<int>{0, 1, 1, 2}));
  EXPECT_EQ(sc.material, (std::vector<int>{0, red, red, 0}));
  EXPECT_EQ(sc.group, (std::vector<int>{-1, 1, 1, 0}));
  EXPECT_EQ(sc.groups, s.groups);
  EXPECT_EQ(sc.materials.size(), s.materials.size());
  EXPECT_EQ(sc.source, "test.obj");
  EXPECT_EQ(sc.input_faces, 3);
}

// ---- warnings -----------------------------------------------------------------------------------

TEST(SceneBuildWarnings, DuplicateVerticesAreCountedNotMerged) {
  // Two squares sharing an edge through separate copies of its two vertices (4, 5 copy 1, 2);
  // vertex 8 also copies vertex 0 but no face uses it, so it does not count.
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0}, {2, 0, 0}, {2, 1, 0},
                           {0, 0, 0}},
                          {{0, 1, 2, 3}, {4, 6, 7, 5}});
  const Scene sc = build_scene(s);
  EXPECT_EQ(sc.report.counts.at("duplicate_vertices"), 2);
  EXPECT_TRUE(any_warning_has(sc.report, "2 vertices duplicate") && any_warning_has(sc.report, "test.obj:5"));
  EXPECT_EQ(sc.mesh.n_vertices(), 8u);  // not merged
}

TEST(SceneBuildWarnings, InconsistentOrientationIsCountedAndFaceDetachedSilently) {
  // Face 1 runs the shared edge 1 -> 2 in the same direction as face 0.
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0.5, 0}}, {{0, 1, 2, 3}, {1, 2, 4}});
  testing::internal::CaptureStderr();
  const Scene sc = build_scene(s);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "") << "OpenMesh must not print";
  EXPECT_EQ(sc.report.counts.at("inconsistent_orientation_edges"), 1);
  EXPECT_TRUE(any_warning_has(sc.report, "inconsistent orientation") && any_warning_has(sc.report, "face 1"));
  EXPECT_EQ(sc.report.counts.at("nonmanifold_faces_detached"), 1);
  EXPECT_EQ(sc.mesh.n_faces(), 2u);
  EXPECT_EQ(sc.mesh.n_vertices(), 8u);  // 5 shared + 3 copies for the detached triangle
}

TEST(SceneBuildWarnings, NonManifoldEdgeFaceIsDetachedSilently) {
  // Three triangles on the edge 0-1 (a fin): at most two can share it in a manifold mesh.
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}},
                          {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  testing::internal::CaptureStderr();
  const Scene sc = build_scene(s);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "") << "OpenMesh must not print";
  EXPECT_EQ(sc.report.counts.at("nonmanifold_faces_detached"), 1);
  EXPECT_TRUE(any_warning_has(sc.report, "face 2") && any_warning_has(sc.report, "non-manifold"));
  EXPECT_EQ(sc.mesh.n_faces(), 3u);
}

TEST(SceneBuildWarnings, ConsistentMeshHasNoTopologyWarnings) {
  const Scene sc = build_scene(square_and_triangle());
  for (const char* key : {"duplicate_vertices", "inconsistent_orientation_edges", "nonmanifold_faces_detached"})
    EXPECT_EQ(sc.report.counts.count(key), 0u) << key;
  EXPECT_EQ(sc.mesh.n_vertices(), 5u);
  EXPECT_EQ(sc.mesh.n_edges(), 6u);  // 4 + 3 - 1 shared
}

TEST(SceneBuildWarnings, NoEmitterIsReported) {
  const Scene sc = build_scene(square_and_triangle());
  EXPECT_EQ(sc.report.counts.at("no_emitter"), 1);
  EXPECT_TRUE(any_warning_has(sc.report, "no emitter: the solution will be zero"));
  PolygonSoup s = square_and_triangle();
  s.faces[1].material = add_material(s, "lamp", RGB::Constant(0.5), RGB(0, 0, 2));
  EXPECT_EQ(build_scene(s).report.counts.count("no_emitter"), 0u);
}

TEST(SceneBuildWarnings, FacesWithoutMaterialAndReaderWarningsAreReported) {
  PolygonSoup s = square_and_triangle();
  s.faces_without_material = 2;
  s.warnings = {"test.obj:3: ignored statement 'vt'"};
  const Scene sc = build_scene(s);
  EXPECT_EQ(sc.report.counts.at("faces_without_material"), 2);
  EXPECT_TRUE(any_warning_has(sc.report, "2 faces have no material"));
  EXPECT_TRUE(any_warning_has(sc.report, "ignored statement 'vt'"));
}

// ---- scene contents -----------------------------------------------------------------------------

TEST(SceneContents, MeshFaceKHasTheCornersOfPatchK) {
  const Scene sc = build_scene(twisted_quad(0.1));  // 2 triangles sharing a diagonal
  ASSERT_EQ(sc.mesh.n_faces(), 2u);
  EXPECT_EQ(sc.mesh.n_vertices(), 4u);
  for (int p = 0; p < 2; ++p) {
    std::vector<Vec3> corners;
    for (auto v : sc.mesh.fv_range(sc.mesh.face_handle(p))) {
      const auto& x = sc.mesh.point(v);
      corners.emplace_back(x[0], x[1], x[2]);
    }
    auto poly = sc.geometry.polygon(p);
    ASSERT_EQ(corners.size(), poly.size());
    // Same cyclic sequence: find the rotation.
    bool match = false;
    for (size_t r = 0; r < poly.size() && !match; ++r) {
      match = true;
      for (size_t k = 0; k < poly.size(); ++k) match = match && corners[(k + r) % poly.size()] == poly[k];
    }
    EXPECT_TRUE(match) << "patch " << p;
  }
}

TEST(SceneContents, EmittedPowerIsPiTimesAreaTimesRadiance) {
  PolygonSoup s = soup_of({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2, 3}});
  s.faces[0].material = add_material(s, "lamp", RGB::Constant(0.5), RGB::Constant(1.0));
  const RGB phi = build_scene(s).emitted_power();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(phi[c], std::numbers::pi, 1e-14) << "channel " << c;  // pi W, exact area
  // Coloured emitter on the square plus a non-emitting triangle of area 0.5.
  PolygonSoup t = square_and_triangle();
  t.faces[0].material = add_material(t, "lamp", RGB::Constant(0.5), RGB(1, 2, 3));
  const RGB phi2 = build_scene(t).emitted_power();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(phi2[c], std::numbers::pi * (c + 1), 1e-13) << "channel " << c;
}

TEST(SceneContents, GreyOnlyWhenEveryUsedMaterialIsGrey) {
  PolygonSoup s = square_and_triangle();
  EXPECT_TRUE(build_scene(s).grey());
  add_material(s, "unused red", RGB(0.9, 0.1, 0.1), RGB::Zero());
  EXPECT_TRUE(build_scene(s).grey()) << "an unused coloured material does not matter";
  s.faces[0].material = add_material(s, "warm lamp", RGB::Constant(0.5), RGB(1, 1, 0.9));
  EXPECT_FALSE(build_scene(s).grey()) << "coloured emission";
  s.faces[0].material = add_material(s, "grey lamp", RGB::Constant(0.3), RGB::Constant(2));
  EXPECT_TRUE(build_scene(s).grey());
  s.faces[1].material = 1;  // unused red, now used
  EXPECT_FALSE(build_scene(s).grey()) << "coloured reflectance";
}

TEST(SceneContents, ReflectanceAndEmissionFieldsFollowPatchMaterials) {
  PolygonSoup s = square_and_triangle();
  s.faces[1].material = add_material(s, "lamp", RGB(0.1, 0.2, 0.3), RGB(4, 5, 6));
  const Scene sc = build_scene(s);
  const ColorField rho = sc.reflectance_field(), le = sc.emission_field();
  ASSERT_EQ(rho.rows(), 2);
  ASSERT_EQ(le.rows(), 2);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(rho(0, c), 0.5);
    EXPECT_EQ(le(0, c), 0.0);
    EXPECT_EQ(rho(1, c), s.materials[1].reflectance[c]);
    EXPECT_EQ(le(1, c), 4.0 + c);
  }
}

TEST(SceneContents, FromPolygonsRejectsSelfIntersectingPolygonThatEarClippingAccepts) {
  // Edges 1->2 and 3->4 cross; ear clipping still returns triangles (area 2.5) but the Newell area is 1.
  const std::vector<Vec3> p = {{1, 3, 0}, {4, 4, 0}, {0, 4, 0}, {3, 1, 0}, {2, 1, 0}};
  try {
    PatchGeometry::from_polygons({p});
    ADD_FAILURE() << "accepted a self-intersecting polygon";
  } catch (const InputError& e) {
    EXPECT_TRUE(has(e.what(), "polygon 0") && has(e.what(), "self-intersecting")) << e.what();
  }
  const std::string msg = error_of(soup_of(p, {{0, 1, 2, 3, 4}}));
  EXPECT_TRUE(has(msg, "face 0") && has(msg, "self-intersecting")) << msg;
}
