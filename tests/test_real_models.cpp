// Issue 11: real models solve correctly. Orientation that never breaks a valid model, translation
// invariance, two-sided faces, contact lines and crossings imprinted. Small generated scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <fstream>
#include <unistd.h>

#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "lambert/daylight/daylight.hpp"
#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/io/vtk.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"
#include "cli_util.hpp"
#include "soup_util.hpp"

using namespace lambert;
using namespace lambert::mesh;

namespace {

// Indexed soup from polygons, identical coordinates sharing one vertex; material per polygon.
PolygonSoup soup_from(const shapes::Polygons& polys, const std::vector<int>& material = {}) {
  std::map<std::array<double, 3>, int> index;
  std::vector<Vec3> pos;
  std::vector<std::vector<int>> faces;
  for (const auto& poly : polys) {
    faces.emplace_back();
    for (const Vec3& p : poly) {
      const auto [it, fresh] = index.try_emplace({p.x(), p.y(), p.z()}, static_cast<int>(pos.size()));
      if (fresh) pos.push_back(p);
      faces.back().push_back(it->second);
    }
  }
  PolygonSoup s = test_util::soup_of(pos, faces);
  for (size_t k = 0; k < material.size() && k < s.faces.size(); ++k) s.faces[k].material = material[k];
  return s;
}

int add_material(PolygonSoup& s, const std::string& name, double rho, double emission, bool two_sided = false) {
  Material m;
  m.name = name;
  m.reflectance = RGB::Constant(rho);
  m.emission = RGB::Constant(emission);
  m.two_sided = two_sided;
  s.materials.push_back(m);
  return static_cast<int>(s.materials.size()) - 1;
}

long count(const Report& r, const std::string& key) {
  const auto it = r.counts.find(key);
  return it == r.counts.end() ? -1 : it->second;
}

std::string all_warnings(const Report& r) {
  std::string s;
  for (const auto& w : r.warnings) s += "\n  " + w;
  return s;
}

// Signed volume of the faces with origin in [first, last] (> 0: normals point outward).
double signed_volume(const PolygonSoup& s, int first, int last) {
  double v = 0;
  for (size_t k = 0; k < s.faces.size(); ++k) {
    const int o = s.faces[k].origin >= 0 ? s.faces[k].origin : static_cast<int>(k);
    if (o < first || o > last) continue;
    const auto& f = s.faces[k].vertices;
    for (size_t t = 1; t + 1 < f.size(); ++t)
      v += s.positions[f[0]].dot(s.positions[f[t]].cross(s.positions[f[t + 1]])) / 6;
  }
  return v;
}

// Radiance (grey, channel 0) of every patch: form factors with Embree visibility, direct-accuracy solve.
Eigen::VectorXd solve_grey(const Scene& scene, int rays = 16) {
  formfactor::Options fo;
  fo.rays_per_pair = rays;
  const auto F = formfactor::assemble(scene.geometry, fo);
  solver::Options so;
  so.tolerance = 1e-12;
  const auto sol = solver::solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field(), so);
  return sol.radiance.col(0);
}

std::string shared_model(const std::string& name) {
  return std::string(LAMBERT_SOURCE_DIR) + "/../shared/models/" + name;
}

// Open box [0,2]^3 without its -z wall (the open front), faces inward, the ceiling (+y) emits;
// a closed icosphere (radius 0.5, outward) in the middle.
PolygonSoup sphere_in_open_box(bool sphere_outward) {
  auto box = shapes::box(Vec3::Zero(), Vec3::Constant(2), 1, true);
  box.erase(box.begin() + 4);  // -z: open front
  shapes::Polygons polys = box;
  auto sphere = shapes::icosphere(1, 0.5, !sphere_outward);
  for (auto& t : sphere)
    for (Vec3& p : t) p += Vec3::Constant(1);
  polys.insert(polys.end(), sphere.begin(), sphere.end());
  PolygonSoup s = soup_from(polys);
  const int white = add_material(s, "white", 0.7, 0);
  const int lamp = add_material(s, "lamp", 0.5, 10);
  for (auto& f : s.faces) f.material = white;
  s.faces[3].material = lamp;  // +y of the box: the ceiling
  return s;
}

}  // namespace

// ---- orientation -----------------------------------------------------------------------------------

TEST(RealModelsOrient, ClosedSphereInOpenBoxKeepsOutwardWindingAndItsRadiance) {
  const PolygonSoup s = sphere_in_open_box(true);
  const int nsphere = static_cast<int>(s.faces.size()) - 5;
  for (auto mode : {Orientation::visibility, Orientation::consistent, Orientation::file}) {
    PrepareOptions o;
    o.orient = mode;
    Report r;
    const PolygonSoup out = prepare(s, o, r);
    EXPECT_EQ(count(r, "faces_reoriented"), 0) << int(mode) << all_warnings(r);
    EXPECT_EQ(count(r, "surfaces_flipped"), 0) << int(mode) << all_warnings(r);
    EXPECT_GT(signed_volume(out, 5, 5 + nsphere - 1), 0) << "sphere turned inside out, mode " << int(mode);
  }
  // The repaired solve equals the unrepaired solve of the same (correct) file: same patches, same
  // geometry, same seeds, so the same numbers up to the solve's tolerance (1e-12 relative).
  const Scene repaired = prepare_and_build(s, {});
  PrepareOptions raw;
  raw.repair = false;
  const Scene unrepaired = prepare_and_build(s, raw);
  ASSERT_EQ(repaired.patches(), unrepaired.patches());
  const Eigen::VectorXd a = solve_grey(repaired), b = solve_grey(unrepaired);
  double sphere_mean = 0;
  for (int p = 5; p < repaired.patches(); ++p) {
    EXPECT_NEAR(a[p], b[p], 1e-9 * b.maxCoeff()) << "patch " << p;
    sphere_mean += a[p] / nsphere;
  }
  // And the sphere is lit: its mean radiance is a sizeable share of the emitter's reflected light.
  EXPECT_GT(sphere_mean, 0.05 * 10) << "sphere black";
}

TEST(RealModelsOrient, SurfaceSeenOnlyFromBehindIsTurnedRoundOnlyByVisibility) {
  // The same scene with the sphere wound inward (a common export error): visibility turns it round
  // (one surface, all its faces), consistent and file keep the file's winding.
  const PolygonSoup s = sphere_in_open_box(false);
  const long nsphere = static_cast<long>(s.faces.size()) - 5;
  for (auto mode : {Orientation::visibility, Orientation::consistent, Orientation::file}) {
    PrepareOptions o;
    o.orient = mode;
    Report r;
    const PolygonSoup out = prepare(s, o, r);
    const bool vis = mode == Orientation::visibility;
    EXPECT_EQ(count(r, "surfaces_flipped"), vis ? 1 : 0) << int(mode) << all_warnings(r);
    EXPECT_EQ(count(r, "faces_reoriented"), vis ? nsphere : 0) << int(mode) << all_warnings(r);
    EXPECT_EQ(signed_volume(out, 5, 5 + int(nsphere) - 1) > 0, vis) << int(mode);
  }
}

TEST(RealModelsOrient, RoomWoundOutwardAroundABlockIsTurnedRound) {
  // Closed room [0,4]^3 wound outward (wrong) with a block inside wound outward (right): the block
  // sees the room's back, so the room is turned round; the block is kept.
  const auto room = shapes::box(Vec3::Zero(), Vec3::Constant(4), 1, false);
  const auto block = shapes::box(Vec3::Constant(1.5), Vec3::Constant(2.5), 1, false);
  shapes::Polygons polys = room;
  polys.insert(polys.end(), block.begin(), block.end());
  Report r;
  const PolygonSoup out = prepare(soup_from(polys), {}, r);
  EXPECT_EQ(count(r, "surfaces_flipped"), 1) << all_warnings(r);
  EXPECT_EQ(count(r, "faces_reoriented"), 6) << all_warnings(r);
  EXPECT_DOUBLE_EQ(signed_volume(out, 0, 5), -64.0);  // exact: integer corners
  EXPECT_DOUBLE_EQ(signed_volume(out, 6, 11), 1.0);
}

TEST(RealModelsOrient, PublicModelsAreNotReoriented) {
  // The public Cornell box (open front, two closed boxes) and the shipped floor plan are valid:
  // nothing is turned round.
  for (const std::string& path : {shared_model("CornellBox-Original.obj"),
                                 std::string(LAMBERT_SOURCE_DIR) + "/examples/floorplan.obj"}) {
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not found (../shared/models is outside the repository)";
    Report r;
    prepare(io::read_obj(path), {}, r);
    EXPECT_EQ(count(r, "faces_reoriented"), 0) << path << all_warnings(r);
    EXPECT_EQ(count(r, "surfaces_flipped"), 0) << path << all_warnings(r);
  }
}

// ---- translation invariance ------------------------------------------------------------------------

TEST(RealModelsShift, GeoreferencedSceneHasTheSameFormFactors) {
  // A 4 m room with a block (occlusion: rays), 4 x 4 quads per wall, corners on a 1/16 m grid so that
  // the shift by (5e5, 5e6, 0) m is exact in double. Same patches, same samples: every F_ij must agree
  // within 1e-9 (the issue's bound; float rays at 5e6 m without recentring miss it by ~1e-2).
  shapes::Polygons polys = shapes::room_with_block(4, 2, Vec3(0.3125, 0.25, 0.375), Vec3(0.625, 0.5, 0.6875));
  for (auto& poly : polys)
    for (Vec3& p : poly) p *= 4.0;
  const Vec3 shift(5e5, 5e6, 0);
  shapes::Polygons shifted = polys;
  for (auto& poly : shifted)
    for (Vec3& p : poly) p += shift;
  const Scene a = prepare_and_build(soup_from(polys), {});
  const Scene b = prepare_and_build(soup_from(shifted), {});
  ASSERT_EQ(a.patches(), b.patches());
  formfactor::Options fo;
  formfactor::Stats sa, sb;
  const auto Fa = formfactor::assemble(a.geometry, fo, &sa);
  const auto Fb = formfactor::assemble(b.geometry, fo, &sb);
  ASSERT_GT(sa.rays_cast, 0) << "the scene must exercise visibility";
  EXPECT_EQ(sa.pairs_ray_tested, sb.pairs_ray_tested);
  double worst = 0;
  int wi = -1, wj = -1;
  for (int i = 0; i < a.patches(); ++i)
    for (int j = 0; j < a.patches(); ++j) {
      const double d = std::abs(Fa.matrix()(i, j) - Fb.matrix()(i, j));
      if (d > worst) worst = d, wi = i, wj = j;
    }
  EXPECT_LE(worst, 1e-9) << "F(" << wi << ", " << wj << ") = " << Fa.matrix()(wi, wj) << " unshifted, "
                         << Fb.matrix()(wi, wj) << " shifted";
}

// ---- two-sided surfaces ----------------------------------------------------------------------------

namespace {

// Two closed 2 x 2 x 2.5 m rooms side by side (A: x in [0, 2], B: x in [2, 4]), each with its own five
// walls (2 x 2 quads each: faces 0-19 A, 20-39 B), sharing one partition polygon in x = 2 (face 40),
// its front facing A. y is up; the ceilings (+y) emit lamp_a and lamp_b.
PolygonSoup two_rooms_with_partition(double lamp_a, double lamp_b, bool two_sided) {
  shapes::Polygons polys;
  for (int r = 0; r < 2; ++r) {
    auto box = shapes::box(Vec3(2.0 * r, 0, 0), Vec3(2.0 * r + 2, 2.5, 2), 2, true);  // 2x2 quads per side
    // shapes::box order: -x, +x, -y, +y, -z, +z, each 4 quads; drop the side facing the partition.
    const int drop = r == 0 ? 1 : 0;
    for (int side = 0; side < 6; ++side)
      if (side != drop)
        for (int q = 0; q < 4; ++q) polys.push_back(box[4 * side + q]);
  }
  polys.push_back({{2, 0, 0}, {2, 0, 2}, {2, 2.5, 2}, {2, 2.5, 0}});  // normal -x: into A
  PolygonSoup s = soup_from(polys);
  const int white = add_material(s, "white", 0.6, 0);
  const int lamp_mat_a = add_material(s, "lamp_a", 0.6, lamp_a);
  const int lamp_mat_b = add_material(s, "lamp_b", 0.6, lamp_b);
  const int wall = add_material(s, "partition", 0.6, 0, two_sided);
  for (auto& f : s.faces) f.material = white;
  for (int q = 0; q < 4; ++q) s.faces[4 * 2 + q].material = lamp_mat_a;  // A's +y (ceiling): its 3rd kept side
  for (int q = 0; q < 4; ++q) s.faces[20 + 4 * 2 + q].material = lamp_mat_b;  // B's +y: its 3rd kept side
  s.faces.back().material = wall;
  return s;
}

// A closed room next to a room open at the top, under a uniform sky (ground of the same radiance): the closed room's
// 24 patches face the inside of a closed surface, so their sky is 0 exactly and none of them is clipped (the sky
// phase counts them); the open room's floor quads get pi L F(centroid -> opening), the point-to-polygon closed
// form, within 1e-7. Without the enclosure test every patch is clipped (points = 44).
TEST(RealModelsDaylight, ClosedRoomGetsNoSkyAndIsNotClipped) {
  shapes::Polygons polys = shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 2, true);
  shapes::Polygons open = shapes::box(Vec3(2, 0, 0), Vec3(3, 1, 1), 2, true);
  open.erase(open.begin() + 12, open.begin() + 16);  // +y (the ceiling): open to the sky
  const size_t closed_patches = polys.size();
  polys.insert(polys.end(), open.begin(), open.end());
  PrepareOptions keep_winding;  // the closed room has no light: the visibility rule would turn it into a solid block
  keep_winding.orient = Orientation::file;
  const Scene scene = prepare_and_build(soup_from(polys), keep_winding);
  ASSERT_EQ(scene.geometry.size(), int(polys.size()));
  daylight::Sky sky;
  sky.kind = daylight::Sky::Kind::Uniform;
  sky.radiance = 3;
  sky.ground_reflectance = 1;
  const daylight::Gatherer gather(scene.geometry, 16);
  daylight::PatchSkyStats st;
  const std::vector<double> E = daylight::patch_sky_irradiance(scene, sky, gather, &st);
  EXPECT_EQ(st.enclosed, int(closed_patches));
  EXPECT_EQ(st.points, (long long)(polys.size() - closed_patches));
  const std::vector<Vec3> opening{Vec3(2, 1, 0), Vec3(3, 1, 0), Vec3(3, 1, 1), Vec3(2, 1, 1)};
  int floors = 0;
  for (int p = 0; p < scene.geometry.size(); ++p) {
    const Vec3& c = scene.geometry.centroid[p];
    if (c.x() < 1.5) {
      EXPECT_EQ(E[size_t(p)], 0.0) << "closed room's patch " << p << " at " << c.transpose();
    } else if (c.y() == 0) {
      const double want = std::numbers::pi * sky.radiance * formfactor::point_to_polygon(c, scene.geometry.normal[p], opening);
      EXPECT_NEAR(E[size_t(p)], want, 1e-7 * want) << "open room's floor patch " << p << " at " << c.transpose();
      ++floors;
    }
  }
  EXPECT_EQ(floors, 4);
}

// An open-top room whose floor is an L (arms 0.2 m wide) around a low solid block: the L's centroid (0.322, 0, 0.322)
// lies off the patch, inside the block, where every direction is covered. The sky is evaluated at the centroid of
// the patch's largest triangle instead (docs/physics.md section 9), which sees the opening over the block: under a
// uniform sky it gets pi L F(point -> opening) within 1e-7 (the point-to-polygon closed form). Evaluated at the
// centroid, it got ~0.
TEST(RealModelsDaylight, NonConvexPatchTakesItsSkyFromAPointOnIt) {
  shapes::Polygons polys = shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 1, true);
  polys.erase(polys.begin() + 2, polys.begin() + 4);  // no floor (-y), no ceiling (+y): open to the sky
  polys.push_back({Vec3(0, 0, 0), Vec3(0, 0, 1), Vec3(0.2, 0, 1), Vec3(0.2, 0, 0.2), Vec3(1, 0, 0.2), Vec3(1, 0, 0)});
  const size_t floor_l = polys.size() - 1;
  shapes::Polygons block = shapes::box(Vec3(0.2, 0, 0.2), Vec3(1, 0.05, 1), 1, false);
  block.erase(block.begin() + 2);  // standing on the floor: no bottom
  polys.insert(polys.end(), block.begin(), block.end());
  PrepareOptions keep_winding;
  keep_winding.orient = Orientation::file;
  const Scene scene = prepare_and_build(soup_from(polys), keep_winding);
  const mesh::PatchGeometry& g = scene.geometry;
  int L = -1;
  ASSERT_EQ(scene.face_id.size(), size_t(g.size()));
  for (int p = 0; p < g.size(); ++p)
    if (scene.face_id[size_t(p)] == int(floor_l)) L = p;
  ASSERT_GE(L, 0) << "the L-shaped floor patch";
  EXPECT_NEAR(g.centroid[L].x(), 0.29 / 0.9, 1e-9);  // (0.5 - 0.64 x 0.6) / 0.36
  daylight::Sky sky;
  sky.kind = daylight::Sky::Kind::Uniform;
  sky.radiance = 2;
  sky.ground_reflectance = 1;
  const daylight::Gatherer gather(g, 16);
  const std::vector<double> E = daylight::patch_sky_irradiance(scene, sky, gather, nullptr);
  int largest = -1;
  double area = 0;
  for (int t = g.triangle_offsets[L]; t < g.triangle_offsets[L + 1]; ++t) {
    const auto& T = g.triangles[t];
    const double a = (g.points[T[1]] - g.points[T[0]]).cross(g.points[T[2]] - g.points[T[0]]).norm();
    if (a > area) area = a, largest = t;
  }
  ASSERT_GE(largest, 0);
  const auto& T = g.triangles[largest];
  const Vec3 q = (g.points[T[0]] + g.points[T[1]] + g.points[T[2]]) / 3;
  const std::vector<Vec3> opening{Vec3(0, 1, 0), Vec3(1, 1, 0), Vec3(1, 1, 1), Vec3(0, 1, 1)};
  const double want = std::numbers::pi * sky.radiance * formfactor::point_to_polygon(q, Vec3::UnitY(), opening);
  EXPECT_GT(want, 0.1);
  EXPECT_NEAR(E[size_t(L)], want, 1e-7 * want) << "point " << q.transpose() << ", centroid " << g.centroid[L].transpose();
}

// The open sky on udales_shape.obj (buildings on a ground plane, z up) at every 16th patch's centroid: found nearest
// first through the tree, a batch at a time with the seams dropped, it equals the union of every polygon subtracted
// at once (every patch hinted) within 1e-7 of the hemisphere's irradiance. Fails when a cone plane of the tree's
// culling is turned round; it failed too for a tried variant (coplanar patches united in chunks of 256, thin holes
// dropped like thin open pieces): ground patch 1800 got 1.9 % too much sky. A third order, the polygons of a random
// half of the plane groups subtracted first (as a hint that is half wrong), must give the same: Clipper's difference
// once came out malformed (an outer boundary wound as a hole) and left covered directions open, only in some orders:
// wall patch 3703 got 13 % more sky with such a hint, 3701 with every patch hinted (while polygons with holes were
// being changed), each caught here.
TEST(RealModelsDaylight, OpenSkyNearestFirstEqualsOneUnionOnUdales) {
  const std::string path = shared_model("udales_shape.obj");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not found (../shared/models is outside the repository)";
  const Scene scene = prepare_and_build(io::read_obj(path), {});
  const mesh::PatchGeometry& g = scene.geometry;
  const daylight::Gatherer gather(g, 16);
  const std::vector<char> all(size_t(g.size()), 1);
  daylight::Sky sky;
  sky.up = Vec3::UnitZ();
  const double scale = daylight::irradiance(sky, daylight::hemisphere_moments(sky.up, sky.up));
  std::vector<int> points;
  for (int p = 0; p < g.size(); p += 16) points.push_back(p);
  for (int p : {1800, 3701, 3703}) points.push_back(p);
  std::vector<char> half(size_t(g.size()));
  for (int p : points) {
    std::mt19937 random(static_cast<unsigned>(p));
    for (char& c : half) c = char(random() % 2);
    const double tree = daylight::irradiance(sky, gather.open(g.centroid[p], g.normal[p], sky.up, p, {}));
    const double once = daylight::irradiance(sky, gather.open(g.centroid[p], g.normal[p], sky.up, p, all));
    const double mixed = daylight::irradiance(sky, gather.open(g.centroid[p], g.normal[p], sky.up, p, half));
    EXPECT_NEAR(tree, once, 1e-7 * scale) << "patch " << p << " at " << g.centroid[p].transpose();
    EXPECT_NEAR(tree, mixed, 1e-7 * scale) << "patch " << p << " at " << g.centroid[p].transpose() << ", half hinted";
  }
}

}  // namespace

TEST(RealModelsTwoSided, PartitionSidesEachSeeOnlyTheirOwnRoom) {
  const int partition = 40;  // input face
  for (bool lit_a : {true, false}) {
    const PolygonSoup s = two_rooms_with_partition(lit_a ? 10 : 0, lit_a ? 0 : 10, true);
    Report r;
    const Scene scene = prepare_and_build(s, {});
    ASSERT_EQ(scene.patches(), 42) << all_warnings(scene.report);
    EXPECT_EQ(count(scene.report, "two_sided_faces"), 1);
    EXPECT_EQ(scene.face_id[40], partition);
    EXPECT_EQ(scene.face_id[41], partition);
    EXPECT_EQ(scene.side[40], 0);
    EXPECT_EQ(scene.side[41], 1);
    EXPECT_NEAR(scene.geometry.normal[41].dot(scene.geometry.normal[40]), -1, 1e-15);
    const Eigen::VectorXd L = solve_grey(scene);
    // Lit room: patches with x-centroid < 2 (A) or > 2 (B); the partition's front is in A, back in B.
    double lit_mean = 0, dark_max = 0;
    int lit_n = 0;
    for (int p = 0; p < 40; ++p) {
      const bool in_a = scene.geometry.centroid[p].x() < 2;
      if (in_a == lit_a) lit_mean += L[p], ++lit_n;
      else dark_max = std::max(dark_max, std::abs(L[p]));
    }
    lit_mean /= lit_n;
    const double front = L[40], back = L[41];
    const double lit_side = lit_a ? front : back, dark_side = lit_a ? back : front;
    dark_max = std::max(dark_max, std::abs(dark_side));
    // Dark room: no light reaches it (the partition blocks every ray; no leak through its own back).
    EXPECT_LE(dark_max, 1e-9 * lit_mean) << (lit_a ? "A lit" : "B lit") << ", front " << front << ", back " << back;
    // The lit side is as bright as a wall of the lit room (within a factor 3: geometry differs).
    EXPECT_GT(lit_side, lit_mean / 3) << (lit_a ? "A lit" : "B lit");
  }
}

TEST(RealModelsTwoSided, OneSidedPartitionSeenFromBehindStaysBlack) {
  // The same partition one-sided: lit from B (its back) it stays black; the rest as before.
  const Scene scene = prepare_and_build(two_rooms_with_partition(0, 10, false), {});
  ASSERT_EQ(scene.patches(), 41);
  const Eigen::VectorXd L = solve_grey(scene);
  // Nothing arrives: only the solver's round-off (GMRES at 1e-12) is left.
  EXPECT_LE(std::abs(L[40]), 1e-12 * L.maxCoeff()) << "a one-sided face seen from behind receives nothing";
}

TEST(RealModelsTwoSided, FacesSeenFromBehindAreCounted) {
  // One quad of A's far wall (input face 0, x = 0) wound the wrong way: its front faces out of the
  // room (rays escape), its back into the lit room. --orient file keeps it and counts it as seen from
  // behind; consistent and visibility turn it back (the wall's majority) and count nothing.
  PolygonSoup s = two_rooms_with_partition(10, 0, false);
  std::reverse(s.faces[0].vertices.begin(), s.faces[0].vertices.end());
  for (auto mode : {Orientation::file, Orientation::consistent, Orientation::visibility}) {
    PrepareOptions o;
    o.orient = mode;
    Report r;
    prepare(s, o, r);
    const bool file = mode == Orientation::file;
    EXPECT_EQ(count(r, "faces_seen_from_behind"), file ? 1 : 0) << int(mode) << all_warnings(r);
    EXPECT_EQ(count(r, "faces_reoriented"), file ? 0 : 1) << int(mode) << all_warnings(r);
  }
}

// ---- contact lines and crossings imprinted ---------------------------------------------------------

namespace {

std::vector<Vec3> quad(Vec3 a, Vec3 b, Vec3 c, Vec3 d) { return {a, b, c, d}; }

// Storey modelled as architects do: one floor polygon (y = 0, up) and one ceiling polygon (y = 2.5,
// down) under two rooms A (x < 2) and B (x > 2.2), outer walls one polygon per side running past both
// rooms (inward), and a closed wall block [2, 2.2] x [0, 2.5] x [0, 2] (outward) standing on the floor
// and touching the ceiling and both long walls. A lamp quad hangs in A (y = 2.4, facing down).
PolygonSoup storey_with_wall() {
  const double X = 4.2, H = 2.5, Z = 2;
  shapes::Polygons p;
  p.push_back(quad({0, 0, 0}, {0, 0, Z}, {X, 0, Z}, {X, 0, 0}));  // floor, +y
  p.push_back(quad({0, H, 0}, {X, H, 0}, {X, H, Z}, {0, H, Z}));  // ceiling, -y
  p.push_back(quad({0, 0, 0}, {0, H, 0}, {0, H, Z}, {0, 0, Z}));  // x = 0, +x
  p.push_back(quad({X, 0, 0}, {X, 0, Z}, {X, H, Z}, {X, H, 0}));  // x = X, -x
  p.push_back(quad({0, 0, 0}, {X, 0, 0}, {X, H, 0}, {0, H, 0}));  // z = 0, +z
  p.push_back(quad({0, 0, Z}, {0, H, Z}, {X, H, Z}, {X, 0, Z}));  // z = Z, -z
  for (const auto& f : shapes::box(Vec3(2, 0, 0), Vec3(2.2, H, Z), 1, false)) p.push_back(f);  // faces 6-11
  p.push_back(quad({0.8, 2.4, 0.8}, {1.2, 2.4, 0.8}, {1.2, 2.4, 1.2}, {0.8, 2.4, 1.2}));     // lamp, -y
  PolygonSoup s = soup_from(p);
  const int white = add_material(s, "white", 0.7, 0);
  const int lamp = add_material(s, "lamp", 0.5, 20);
  for (auto& f : s.faces) f.material = white;
  s.faces.back().material = lamp;
  return s;
}



TEST(RealModelsImprint, WallStandingOnSlabLeaksNoLight) {
  const PolygonSoup s = storey_with_wall();
  const Scene scene = prepare_and_build(s, {});
  const Report& r = scene.report;
  // The floor, the ceiling and the two long walls are split where the block touches them; the parts
  // under / against the block, and the block's own bottom, top and ends, are hidden and removed.
  EXPECT_EQ(count(r, "faces_imprinted"), 4) << all_warnings(r);
  EXPECT_EQ(count(r, "hidden_fragments_removed"), 8) << all_warnings(r);
  EXPECT_EQ(count(r, "self_intersections"), 0) << all_warnings(r);
  for (int p = 0; p < scene.patches(); ++p) {  // no patch straddles the wall
    double lo = 1e9, hi = -1e9;
    for (const Vec3& v : scene.geometry.polygon(p)) lo = std::min(lo, v.x()), hi = std::max(hi, v.x());
    EXPECT_FALSE(lo < 2 - 1e-9 && hi > 2.2 + 1e-9) << "patch " << p << " of input face " << scene.face_id[p];
  }
  const Eigen::VectorXd L = solve_grey(scene);
  double lit_mean = 0, dark_max = 0;
  int lit_n = 0;
  for (int p = 0; p < scene.patches(); ++p) {
    const double x = scene.geometry.centroid[p].x();
    if (x < 2 && scene.face_id[p] != 12) lit_mean += L[p], ++lit_n;
    if (x > 2.2 - 1e-9) dark_max = std::max(dark_max, std::abs(L[p]));
  }
  lit_mean /= lit_n;
  // The issue's bound: the shut room's largest radiance <= 1e-6 x the lit room's mean (before: 0.62).
  EXPECT_LE(dark_max, 1e-6 * lit_mean) << "lit mean " << lit_mean;
  EXPECT_GT(lit_mean, 0.1);
}

TEST(RealModelsImprint, FaceCrossingWallsGivesFormFactorsInUnitRangeAndRowSumsOfOne) {
  // Closed room [0,2]^3 (one polygon per wall, inward, ceiling emitting) cut by a two-sided plate at
  // y = 1 that runs through all four walls (x, z in [-0.5, 2.5]): two closed sub-rooms. Every F in
  // [0, 1]; every patch inside the room has a row sum of 1 within 1e-6 (per-entry tolerance 1e-8 over
  // ~20 entries; visibility here is all or nothing, so rays add no error).
  shapes::Polygons p = shapes::box(Vec3::Zero(), Vec3::Constant(2), 1, true);
  p.push_back(quad({-0.5, 1, -0.5}, {-0.5, 1, 2.5}, {2.5, 1, 2.5}, {2.5, 1, -0.5}));  // +y
  PolygonSoup s = soup_from(p);
  const int white = add_material(s, "white", 0.7, 0);
  const int lamp = add_material(s, "lamp", 0.5, 1);
  const int plate = add_material(s, "plate", 0.7, 0, true);
  for (auto& f : s.faces) f.material = white;
  s.faces[3].material = lamp;
  s.faces[6].material = plate;
  for (bool imprint : {true}) {
    PrepareOptions o;
    o.imprint = imprint;
    const Scene scene = prepare_and_build(s, o);
    formfactor::Stats st;
    const auto F = formfactor::assemble(scene.geometry, {}, &st);
    EXPECT_EQ(st.entries_outside_unit, 0) << all_warnings(scene.report);
    const auto& M = F.matrix();
    for (int i = 0; i < scene.patches(); ++i) {
      const Vec3 c = scene.geometry.centroid[i];
      const bool inside = (c.array() > 1e-9).all() && (c.array() < 2 - 1e-9).all();
      double row = 0;
      for (int j = 0; j < scene.patches(); ++j) {
        EXPECT_TRUE(M(i, j) >= 0 && M(i, j) <= 1) << "F(" << i << ", " << j << ") = " << M(i, j);
        row += M(i, j);
      }
      EXPECT_LE(row, 1 + 1e-6) << "patch " << i << " (input face " << scene.face_id[i] << ")";
      if (inside) {
        EXPECT_GE(row, 1 - 1e-6) << "patch " << i << " (input face " << scene.face_id[i] << ")";
      }
    }
  }
}

// A roof triangle overhanging a building's corner by 3 mm (uDALES, input faces 2839, 3295, 3348): the two walls'
// top edges lie in the roof's plane and cut the triangle from one edge to the corner and back, leaving a sliver
// of eave outside the walls. Once, whether the cut's ends fell on the roof's edge or 1e-16 inside it decided
// whether the roof was split, so the model split 73 faces at the origin and 80 others when moved by
// (5e5, 4e6) m. Wherever the model sits, the roof is split in two along the walls, with the same pieces.
// Two rooms (x < 2 and x > 2.2) of one floor, one ceiling and four walls (inward), split by a closed partition block
// standing on the floor, touching the ceiling and both long walls (so every one of those faces is split and tested
// for hiding). Under each room's ceiling hangs a light panel 2 cm below it, covering all but a 5 cm margin of the
// room's ceiling piece (91-92 % of it): the ceiling above is partly seen and must stay, or the room would open into the
// space behind it. In room B's corner (x = 4, z = 0) stands a counter without back, bottom or left end: the floor,
// wall and wall pieces inside it face a cavity bounded by the counter's backs and by each other's fronts, and are
// hidden. Materials by part; the polygons are moved by `offset`.
struct PanelRoom {
  shapes::Polygons polys;
  std::vector<std::string> part;  // per polygon
};
PanelRoom panel_room(const Vec3& offset) {
  const double X = 4, H = 2.5, Z = 3, h = H - 0.02, m = 0.05;
  PanelRoom r;
  auto add = [&](const std::string& part, std::vector<Vec3> q) {
    for (Vec3& v : q) v += offset;
    r.polys.push_back(q);
    r.part.push_back(part);
  };
  add("floor", quad({0, 0, 0}, {0, 0, Z}, {X, 0, Z}, {X, 0, 0}));    // +y
  add("ceiling", quad({0, H, 0}, {X, H, 0}, {X, H, Z}, {0, H, Z}));  // -y
  add("wall", quad({0, 0, 0}, {0, H, 0}, {0, H, Z}, {0, 0, Z}));     // x = 0, +x
  add("wall", quad({X, 0, 0}, {X, 0, Z}, {X, H, Z}, {X, H, 0}));     // x = X, -x
  add("wall", quad({0, 0, 0}, {X, 0, 0}, {X, H, 0}, {0, H, 0}));     // z = 0, +z
  add("wall", quad({0, 0, Z}, {0, H, Z}, {X, H, Z}, {X, 0, Z}));     // z = Z, -z
  for (const auto& f : shapes::box(Vec3(2, 0, 0), Vec3(2.2, H, Z), 1, false)) add("partition", f);
  for (const auto& [x0, x1] : {std::pair{0.0, 2.0}, std::pair{2.2, X}})  // facing -y
    add("panel", quad({x0 + m, h, m}, {x1 - m, h, m}, {x1 - m, h, Z - m}, {x0 + m, h, Z - m}));
  add("counter", quad({3.4, 0, 0}, {3.4, 0, 1.5}, {3.4, 0.9, 1.5}, {3.4, 0.9, 0}));      // front, -x
  add("counter", quad({3.4, 0.9, 0}, {3.4, 0.9, 1.5}, {X, 0.9, 1.5}, {X, 0.9, 0}));      // top, +y
  add("counter", quad({3.4, 0, 1.5}, {X, 0, 1.5}, {X, 0.9, 1.5}, {3.4, 0.9, 1.5}));      // end, +z
  return r;
}

// Area per part (and per copy: the offset's x / 10) of a prepared scene of panel rooms.
std::map<std::pair<int, std::string>, double> part_areas(const Scene& scene) {
  std::map<std::pair<int, std::string>, double> a;
  for (int k = 0; k < scene.patches(); ++k) {
    const int copy = static_cast<int>(std::floor(scene.geometry.centroid[k].x() / 10));
    a[{copy, scene.materials[scene.material[k]].name}] += scene.geometry.area[k];
  }
  return a;
}

PolygonSoup soup_of_rooms(const std::vector<PanelRoom>& rooms) {
  shapes::Polygons polys;
  std::vector<std::string> part;
  for (const PanelRoom& r : rooms) {
    polys.insert(polys.end(), r.polys.begin(), r.polys.end());
    part.insert(part.end(), r.part.begin(), r.part.end());
  }
  PolygonSoup s = soup_from(polys);
  std::map<std::string, int> mat;
  for (const char* name : {"floor", "ceiling", "wall", "partition", "panel", "counter"})
    mat[name] = add_material(s, name, 0.5, std::string(name) == "panel" ? 10 : 0);
  for (size_t k = 0; k < s.faces.size(); ++k) s.faces[k].material = mat.at(part[k]);
  return s;
}

// What is hidden is exactly what the partition and the counter cover (areas from the construction above), and
// nothing of the ceilings above the panels. Tolerance 1e-9 m^2: the pieces tile their faces exactly but for
// rounding. Before the fix, fragments were hidden when 15 of 16 random rays met a back face first, with the
// generator seeded by the face's index: here the cavity's pieces (each seeing the others' fronts) stayed (floor
// 11.4 m^2 instead of 10.5, walls 34 instead of 32.11); the ceilings above the panels went in some copies (next test).
TEST(RealModelsImprint, CeilingAboveALightPanelStaysAndTheCavityBehindACounterGoes) {
  const Scene scene = prepare_and_build(soup_of_rooms({panel_room(Vec3::Zero())}), {});
  const auto a = part_areas(scene);
  const std::map<std::string, double> expected = {
      {"floor", 12 - 0.6 - 0.9},                       // minus the partition's and the counter's footprints
      {"ceiling", 12 - 0.6},                           // minus the partition's top: the panels hide nothing
      {"wall", 2 * 7.5 + 2 * 10 - 2 * 0.5 - 1.35 - 0.54},  // minus the partition's ends, the counter's back and side
      {"partition", 2 * 3 * 2.5},                      // its two long sides (bottom, top and ends hidden)
      {"panel", (1.9 + 1.7) * 2.9},
      {"counter", 1.35 + 0.9 + 0.54}};
  for (const auto& [part, area] : expected)
    EXPECT_NEAR(a.count({0, part}) ? a.at({0, part}) : 0.0, area, 1e-9) << part << all_warnings(scene.report);
}

// The same rooms, four copies 10 m apart in one file (listed in reverse order), and one copy 10^6 m away: every
// copy keeps exactly the same areas (the rays depend on a face's shape and surroundings, not on its index in the
// file or its position). Before the fix the copies differed (index-seeded rays).
TEST(RealModelsImprint, HiddenFragmentsAreTheSameInEveryCopyWhereverItSits) {
  const Scene one = prepare_and_build(soup_of_rooms({panel_room(Vec3::Zero())}), {});
  const auto ref = part_areas(one);
  std::vector<PanelRoom> rooms;
  for (int c = 3; c >= 0; --c) rooms.push_back(panel_room(Vec3(10.0 * c, 0, 0)));
  const Scene four = prepare_and_build(soup_of_rooms(rooms), {});
  const auto a4 = part_areas(four);
  const Scene far = prepare_and_build(soup_of_rooms({panel_room(Vec3(1e6, 0, -1e6))}), {});
  const auto af = part_areas(far);
  for (const auto& [key, area] : ref) {
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(a4.count({c, key.second}) ? a4.at({c, key.second}) : 0.0, area, 1e-9) << key.second << " copy " << c;
    // 10^6 m away a corner is held to ~1e-10 m: areas agree to ~1e-9 m^2.
    EXPECT_NEAR(af.count({100000, key.second}) ? af.at({100000, key.second}) : 0.0, area, 1e-8) << key.second << " far";
  }
}

TEST(RealModelsImprint, RoofOverhangingACornerIsSplitWhereverTheModelSits) {
  const std::vector<Vec3> roof = {{87.5, 52.169872, 20}, {87.113091, 51.96846, 20}, {87.423149, 51.649048, 20}};
  const std::vector<Vec3> wall_a = {{87.568123, 52.225899, 10}, {87.269951, 52.044968, 20}, {87.866295, 52.406834, 20}};
  const std::vector<Vec3> wall_b = {{87.269951, 52.044968, 10}, {86.545082, 51.744717, 20}, {87.269951, 52.044968, 20}};
  const std::vector<Vec3> offsets = {{0, 0, 0}, {5e5, 4e6, 0}, {-3.7e5, 1.234567e6, 0}, {1e6, -1e6, 0},
                                     {123456.789, 9876543.21, 0}, {0.1, 0.2, 0}};
  for (const Vec3& off : offsets) {
    shapes::Polygons p;
    for (const auto* f : {&roof, &wall_a, &wall_b}) {
      std::vector<Vec3> q;
      // As a file would hold them: the moved coordinates printed with 6 decimals and read back.
      for (const Vec3& v : *f) {
        char buf[3][64];
        for (int a = 0; a < 3; ++a) std::snprintf(buf[a], sizeof buf[a], "%.6f", v[a] + off[a]);
        q.emplace_back(std::strtod(buf[0], nullptr), std::strtod(buf[1], nullptr), std::strtod(buf[2], nullptr));
      }
      p.push_back(q);
    }
    const PolygonSoup s = soup_from(p);
    const Scene scene = prepare_and_build(s, {});
    int roof_pieces = 0;
    double roof_area = 0;
    for (int k = 0; k < scene.patches(); ++k)
      if (scene.face_id[k] == 0) ++roof_pieces, roof_area += scene.geometry.area[k];
    EXPECT_EQ(roof_pieces, 2) << "offset " << off.transpose() << ": " << all_warnings(scene.report);
    EXPECT_EQ(count(scene.report, "faces_imprinted"), 1) << "offset " << off.transpose() << ": " << all_warnings(scene.report);
    // The pieces tile the roof (0.0930164 m^2; the moved corners are the same decimals, held to ~1e-9 m near
    // 1e7 m, which moves the area by < 1e-8 m^2).
    EXPECT_NEAR(roof_area, 0.0930163897, 1e-7) << "offset " << off.transpose();
  }
}

// A wall standing on a roof triangle of udales_shape.obj (face 5235) across its corner b: the cut it leaves runs from
// edge ab to edge bc, and its ends, placed on the edges, land within rounding of them, on either side. Where the end
// on bc landed outside, the sliver between it and bc was taken as inside the roof when its rounded centroid fell
// inside, and became a piece of its own (a zero-area sliver dropped, with a warning). The cut is the one the
// double-precision contact (tri_tri.cpp) gave there; with it the old centroid test made the sliver. Now the triangles
// along the outline are inside or outside by the side of its edge they lie on: two pieces, the corner and the rest.
TEST(RealModelsImprint, CutEndingOnAnEdgeLeavesNoSliver) {
  const Vec3 a(203.73777799999999, 47.432746999999999, 20), b(203.54399100000001, 46.606566999999998, 20),
      c(204.13041699999999, 47.015366, 20);
  const Vec3 on_ab(203.54858634474422, 46.626158520178201, 20), on_bc(203.5687847828942, 46.623850806743491, 20);
  shapes::Polygons p;
  p.push_back({a, b, c});  // the roof, facing +z
  p.push_back({on_ab, on_bc, on_bc + Vec3(0, 0, 1), on_ab + Vec3(0, 0, 1)});
  const Scene scene = prepare_and_build(soup_from(p), {});
  EXPECT_EQ(count(scene.report, "imprint_slivers_dropped"), 0) << all_warnings(scene.report);
  int roof_pieces = 0;
  double area = 0;
  for (int k = 0; k < scene.patches(); ++k)
    if (scene.face_id[k] == 0) ++roof_pieces, area += scene.geometry.area[k];
  EXPECT_EQ(roof_pieces, 2) << all_warnings(scene.report);
  // The pieces tile the roof (relative 1e-12: rounding of the areas of polygons 2e2 m from the origin).
  EXPECT_NEAR(area, 0.5 * (b - a).cross(c - a).norm(), 1e-12 * area);
}

// Two coplanar faces that overlap (a slab drawn twice, shifted: CAD exports have them) are split along each other's
// edges, so that no patch is partly under the other; a coplanar neighbour that meets one along an edge without
// sharing its corners (a T-junction) is not split. The first part fails when the coplanar case is skipped, the
// second when a neighbour along an edge counts as an overlap. Wherever the model sits.
TEST(RealModelsImprint, OverlappingCoplanarFacesAreSplitAlongEachOthersEdgesNeighboursAreNot) {
  for (const Vec3& off : {Vec3(0, 0, 0), Vec3(5e5, 4e6, 30)}) {
    shapes::Polygons p;
    auto at = [&](double x, double y) -> Vec3 { return off + Vec3(x, y, 0); };
    p.push_back(quad(at(0, 0), at(2, 0), at(2, 2), at(0, 2)));      // A, facing +z
    p.push_back(quad(at(1, 1), at(3, 1), at(3, 3), at(1, 3)));      // B, overlaps A in [1, 2]^2
    p.push_back(quad(at(-2, 0.5), at(0, 0.5), at(0, 1.5), at(-2, 1.5)));  // D, meets A along x = 0 only
    const PolygonSoup s = soup_from(p);
    const Scene scene = prepare_and_build(s, {});
    EXPECT_EQ(count(scene.report, "faces_imprinted"), 2) << "offset " << off.transpose() << all_warnings(scene.report);
    // Per input face: its pieces tile it, and exactly one piece is the overlap [1, 2]^2 (area 1, every corner in it).
    for (int face : {0, 1, 2}) {
      double area = 0;
      int pieces = 0, overlap_pieces = 0;
      for (int k = 0; k < scene.patches(); ++k) {
        if (scene.face_id[k] != face) continue;
        ++pieces;
        area += scene.geometry.area[k];
        bool inside = true;
        for (const Vec3& v : scene.geometry.polygon(k)) {
          const Vec3 q = v - off;
          inside = inside && q.x() >= 1 - 1e-9 && q.x() <= 2 + 1e-9 && q.y() >= 1 - 1e-9 && q.y() <= 2 + 1e-9;
        }
        if (inside) {
          ++overlap_pieces;
          EXPECT_NEAR(scene.geometry.area[k], 1.0, 1e-9) << "face " << face << " offset " << off.transpose();
        }
      }
      EXPECT_NEAR(area, face == 2 ? 2.0 : 4.0, 1e-8) << "face " << face << " offset " << off.transpose();
      EXPECT_EQ(pieces, face == 2 ? 1 : 2) << "face " << face << " offset " << off.transpose() << all_warnings(scene.report);
      EXPECT_EQ(overlap_pieces, face == 2 ? 0 : 1) << "face " << face << " offset " << off.transpose();
    }
  }
}

// ---- the example storey ----------------------------------------------------------------------------

TEST(RealModelsExample, StoreyShutRoomStaysDarkFromObjAndFromStl) {
  // examples/storey.obj (and the same storey as binary STL + storey_stl.json): room C (x > 4.2,
  // z > 2.5) has no lamp and is shut by the wall block and the two-sided partition.
  const std::string dir = std::string(LAMBERT_SOURCE_DIR) + "/examples/";
  for (bool stl : {false, true}) {
    PolygonSoup s = io::read_soup(dir + (stl ? "storey.stl" : "storey.obj"));
    if (stl) io::apply_materials_json(s, dir + "storey_stl.json");
    const Scene scene = prepare_and_build(s, {});
    EXPECT_EQ(count(scene.report, "faces_reoriented"), 0) << all_warnings(scene.report);
    EXPECT_GT(count(scene.report, "faces_imprinted"), 0);
    EXPECT_GT(count(scene.report, "two_sided_faces"), 0);
    const Eigen::VectorXd L = solve_grey(scene);
    double lit_mean = 0, dark_max = 0;
    int lit_n = 0;
    for (int p = 0; p < scene.patches(); ++p) {
      const Vec3 c = scene.geometry.centroid[p];
      if (c.x() < 4 - 1e-6) lit_mean += L[p], ++lit_n;
      if (c.x() > 4.2 + 1e-6 && c.z() > 2.5 + 1e-6) dark_max = std::max(dark_max, std::abs(L[p]));
    }
    lit_mean /= lit_n;
    EXPECT_LE(dark_max, 1e-6 * lit_mean) << (stl ? "stl" : "obj") << ": lit mean " << lit_mean;
  }
}

TEST(RealModelsTwoSided, FlagFromMtlAndJsonAndSideArrayInVtu) {
  const auto dir = std::filesystem::temp_directory_path() / ("lambert_two_sided_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string obj = (dir / "p.obj").string(), mtl = (dir / "p.mtl").string(), json = (dir / "m.json").string();
  std::ofstream(mtl) << "newmtl thin\nKd 0.5\ntwo_sided 1\nnewmtl lamp\nKe 1\ntwo_sided 0\nnewmtl bad\n";
  std::ofstream(obj) << "mtllib p.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n"
                        "usemtl thin\nf 1 2 3 4\nusemtl lamp\nf 5 6 7\n";
  PolygonSoup s = io::read_obj(obj);
  ASSERT_EQ(s.materials.size(), 4u);
  EXPECT_TRUE(s.materials[s.faces[0].material].two_sided);
  EXPECT_FALSE(s.materials[s.faces[1].material].two_sided);
  // --materials: a material made two-sided by name, and a face range made two-sided inline.
  std::ofstream(json) << R"({"materials": {"lamp": {"two_sided": true}}, "faces": [{"range": [0, 0], "two_sided": false}]})";
  io::apply_materials_json(s, json);
  EXPECT_FALSE(s.materials[s.faces[0].material].two_sided);
  EXPECT_TRUE(s.materials[s.faces[1].material].two_sided);
  // A value other than true/false, or two_sided with a bad value in the MTL: errors naming the place.
  std::ofstream(json) << R"({"materials": {"lamp": {"two_sided": 1}}})";
  try {
    io::apply_materials_json(s, json);
    ADD_FAILURE() << "two_sided: 1 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("two_sided"), std::string::npos) << e.what();
  }
  std::ofstream(mtl) << "newmtl thin\ntwo_sided yes\n";
  try {
    io::read_obj(obj);
    ADD_FAILURE() << "two_sided yes accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("p.mtl:2"), std::string::npos) << e.what();
  }
  // The .vtu says which side a cell is: the lamp (face 1) is now two-sided -> patches 1 (front), 2 (back).
  const Scene scene = prepare_and_build(s, {});
  ASSERT_EQ(scene.patches(), 3);
  const std::string vtu = (dir / "p.vtu").string();
  io::write_vtu(vtu, scene, ColorField::Zero(3, 3), ColorField::Zero(3, 3));
  auto reader = vtkSmartPointer<vtkXMLUnstructuredGridReader>::New();
  reader->SetFileName(vtu.c_str());
  reader->Update();
  vtkDataArray* side = reader->GetOutput()->GetCellData()->GetArray("side");
  ASSERT_NE(side, nullptr);
  EXPECT_EQ(side->GetTuple1(0), 0);
  EXPECT_EQ(side->GetTuple1(1), 0);
  EXPECT_EQ(side->GetTuple1(2), 1);
  std::filesystem::remove_all(dir);
}

TEST(RealModelsCli, OrientFlagIsAcceptedAndCheckedAndNothingIsTurnedRoundInTheStorey) {
  auto run = [](const std::string& args, std::string& out) {
    const std::string cmd = std::string(LAMBERT_BINARY) + " " + args + " 2>&1";
    FILE* p = popen(cmd.c_str(), "r");
    out.clear();
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    const int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  };
  const std::string storey = std::string(LAMBERT_SOURCE_DIR) + "/examples/storey.obj";
  std::string out;
  for (const char* mode : {"file", "consistent", "visibility"}) {
    EXPECT_EQ(run("info " + storey + " --orient " + mode, out), 0) << mode << "\n" << out;
    EXPECT_EQ(out.find("reoriented"), std::string::npos) << mode << "\n" << out;
    EXPECT_EQ(out.find("inconsistent orientation"), std::string::npos) << "contact lines are not orientation errors\n" << out;
  }
  EXPECT_NE(run("info " + storey + " --orient sideways", out), 0) << out;
  EXPECT_NE(out.find("--orient"), std::string::npos) << out;
}

// ---- duplicate faces ----------------------------------------------------------------------------------

// A face modelled twice with the same winding is one surface: the copy is removed (counted, both named), so
// nothing facing it counts it twice. A copy wound the other way is a second surface (a sheet seen from both
// sides) and stays.
TEST(RealModelsDuplicates, RepeatedFaceIsRemovedAndNamedReversedCopyStays) {
  const shapes::Polygons quad = {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}};
  shapes::Polygons polys = {quad[0], {quad[0][1], quad[0][2], quad[0][3], quad[0][0]},   // same cycle, rotated
                            {quad[0][3], quad[0][2], quad[0][1], quad[0][0]}};           // reversed
  PrepareOptions o;
  o.imprint = false;  // this test is about the duplicate rule alone
  Report r;
  const PolygonSoup out = prepare(soup_from(polys), o, r);
  EXPECT_EQ(count(r, "duplicate_faces_removed"), 1) << all_warnings(r);
  ASSERT_EQ(out.faces.size(), 2u) << all_warnings(r);
  EXPECT_EQ(out.faces[0].origin, 0);
  EXPECT_EQ(out.faces[1].origin, 2) << "the reversed copy is a surface of its own";
  EXPECT_NE(all_warnings(r).find("input face 1 repeats input face 0"), std::string::npos) << all_warnings(r);
  Report none;
  PrepareOptions no_repair = o;
  no_repair.repair = false;
  EXPECT_EQ(prepare(soup_from(polys), no_repair, none).faces.size(), 3u) << "--no-repair changes nothing";
}

// The public Cornell box repeats a side of each block as its "bottom": counted twice, the facing patches'
// row sums reached 1.28 and the independent ray check refused the run (exit 3). With the copies removed it
// solves and every sampled row agrees with the rays cast from it.
TEST(RealModelsDuplicates, PublicCornellBoxSolvesAndPassesTheRowSumCheck) {
  const std::string path = shared_model("CornellBox-Original.obj");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not found (../shared/models is outside the repository)";
  char dir[] = "/tmp/lambert_cbo_XXXXXX";
  ASSERT_NE(mkdtemp(dir), nullptr);
  const std::string vtu = std::string(dir) + "/cbo.vtu", stats = std::string(dir) + "/cbo.json";
  const auto r = lambert::test::run("solve " + path + " -o " + vtu + " --stats " + stats);
  const std::string& out = r.output;
  EXPECT_EQ(r.status, 0) << out;
  std::ifstream in(stats);
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(json.find("\"duplicate_faces_removed\": 2"), std::string::npos) << json.substr(0, 2000);
  EXPECT_NE(out.find("row sums"), std::string::npos) << out;
  EXPECT_EQ(out.find("FAILED"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

}  // namespace
