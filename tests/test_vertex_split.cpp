// split_vertices and average_to_vertices: per-vertex output topology across creases and materials.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "lambert/mesh/scene.hpp"
#include "soup_util.hpp"

using namespace lambert;
using namespace lambert::mesh;

namespace {

using lambert::mesh::test_util::soup_of;

// Unit cube, vertex index x + 2y + 4z, six quads with outward normals (consistently oriented).
Scene unit_cube() {
  std::vector<Vec3> p;
  for (int i = 0; i < 8; ++i) p.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  return build_scene(soup_of(p, {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}));
}

// Flat grid of 2 x 2 quads in z = 0 with x lines xs and y lines ys; cell (i, j) is patch i + 2 j.
PolygonSoup grid_2x2(const std::vector<double>& xs, const std::vector<double>& ys) {
  std::vector<Vec3> p;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) p.emplace_back(xs[i], ys[j], 0);
  auto v = [](int i, int j) { return i + 3 * j; };
  std::vector<std::vector<int>> f;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) f.push_back({v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)});
  return soup_of(p, f);
}

// Output vertex of patch p's corner at position x (-1 if p has no corner there).
int vertex_at(const Scene& sc, const VertexSplit& split, int p, const Vec3& x) {
  for (int c = sc.geometry.offsets[p]; c < sc.geometry.offsets[p + 1]; ++c)
    if (sc.geometry.points[c] == x) return split.corner_vertex[c];
  return -1;
}

void expect_consistent(const Scene& sc, const VertexSplit& split) {
  ASSERT_EQ(split.corner_vertex.size(), sc.geometry.points.size());
  for (size_t c = 0; c < split.corner_vertex.size(); ++c) {
    const int v = split.corner_vertex[c];
    ASSERT_TRUE(v >= 0 && v < static_cast<int>(split.points.size())) << "corner " << c;
    EXPECT_EQ(split.points[v], sc.geometry.points[c]) << "corner " << c << " -> vertex " << v;
  }
}

}  // namespace

TEST(VertexSplit, UnitCubeSplitsAtSharpCreaseAndMergesAtWideCrease) {
  const Scene sc = unit_cube();
  ASSERT_EQ(sc.report.counts.count("nonmanifold_faces_detached"), 0u);
  ASSERT_EQ(sc.report.counts.count("inconsistent_orientation_edges"), 0u);
  const VertexSplit sharp = split_vertices(sc, 30.0);  // 90 deg edges are creases
  expect_consistent(sc, sharp);
  EXPECT_EQ(sharp.points.size(), 24u);
  const VertexSplit smooth = split_vertices(sc, 100.0);  // 90 deg edges are smooth
  expect_consistent(sc, smooth);
  EXPECT_EQ(smooth.points.size(), 8u);
}

TEST(VertexSplit, BentStripSplitsOnlyWhenTheBendExceedsTheCrease) {
  // Two unit quads sharing the edge x = z = 0, the second tilted up by 45 deg.
  const double c = std::cos(std::numbers::pi / 4), s = std::sin(std::numbers::pi / 4);
  const Scene sc = build_scene(soup_of({{-1, 0, 0}, {0, 0, 0}, {0, 1, 0}, {-1, 1, 0}, {c, 0, s}, {c, 1, s}},
                                       {{0, 1, 2, 3}, {1, 4, 5, 2}}));
  EXPECT_EQ(split_vertices(sc, 30.0).points.size(), 8u);
  EXPECT_EQ(split_vertices(sc, 45.0).points.size(), 6u) << "an angle equal to the crease is smooth";
  EXPECT_EQ(split_vertices(sc, 60.0).points.size(), 6u);
}

TEST(VertexSplit, FlatGridSplitsExactlyAlongTheMaterialBoundary) {
  PolygonSoup s = grid_2x2({0, 1, 2}, {0, 1, 2});
  Material red;
  red.name = "red";
  red.reflectance = RGB(0.8, 0.1, 0.1);
  s.materials.push_back(red);
  s.faces[1].material = s.faces[3].material = 1;  // column i = 1 is red, column 0 default
  const Scene sc = build_scene(s);
  const VertexSplit split = split_vertices(sc, 0.0);  // flat: crease 0 must still keep it smooth
  expect_consistent(sc, split);
  EXPECT_EQ(split.points.size(), 12u);  // 9 grid vertices, the 3 on x = 1 doubled
  // Every pair of corners at one position: same output vertex iff same material.
  const auto& g = sc.geometry;
  for (int p = 0; p < sc.patches(); ++p)
    for (int q = 0; q < sc.patches(); ++q)
      for (int a = g.offsets[p]; a < g.offsets[p + 1]; ++a)
        for (int b = g.offsets[q]; b < g.offsets[q + 1]; ++b) {
          if (g.points[a] != g.points[b]) continue;
          EXPECT_EQ(split.corner_vertex[a] == split.corner_vertex[b], sc.material[p] == sc.material[q])
              << "patches " << p << ", " << q << " at (" << g.points[a].transpose() << ")";
        }
}

TEST(VertexSplit, AverageOfConstantFieldIsThatConstant) {
  const Scene cube = unit_cube();
  ColorField f(cube.patches(), 3);
  f.rowwise() = Eigen::RowVector3d(0.3, 0.5, 0.7);
  for (double crease : {30.0, 100.0}) {
    const VertexSplit split = split_vertices(cube, crease);
    const ColorField avg = average_to_vertices(cube, split, f);
    ASSERT_EQ(avg.rows(), static_cast<Eigen::Index>(split.points.size()));
    // A weighted mean of equal values: only rounding in the sums (a few ulps).
    for (Eigen::Index v = 0; v < avg.rows(); ++v)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(avg(v, c), f(0, c), 1e-15) << "crease " << crease << " vertex " << v;
  }
}

TEST(VertexSplit, AverageAtInteriorVertexIsAreaWeightedMean) {
  // Cells of widths {1, 2} and heights {2, 0.5}: areas 2, 4, 0.5, 1 (patches 0..3).
  const Scene sc = build_scene(grid_2x2({0, 1, 3}, {0, 2, 2.5}));
  ColorField f(4, 3);
  f << 10, 1, -1,  //
      20, 1, -2,   //
      30, 1, -3,   //
      40, 1, -4;
  const VertexSplit split = split_vertices(sc);
  const ColorField avg = average_to_vertices(sc, split, f);
  EXPECT_EQ(split.points.size(), 9u);
  // Hand-computed: (2*10 + 4*20 + 0.5*30 + 1*40) / 7.5 = 155 / 7.5; channel 2 is -1/10 of it.
  const int centre = vertex_at(sc, split, 0, Vec3(1, 2, 0));
  ASSERT_GE(centre, 0);
  for (int p = 1; p < 4; ++p) EXPECT_EQ(vertex_at(sc, split, p, Vec3(1, 2, 0)), centre) << "patch " << p;
  EXPECT_NEAR(avg(centre, 0), 155.0 / 7.5, 1e-13);  // rounding of 4 products and a division
  EXPECT_NEAR(avg(centre, 1), 1.0, 1e-15);
  EXPECT_NEAR(avg(centre, 2), -15.5 / 7.5, 1e-14);
  // Edge vertex (1, 0): patches 0 and 1 only, (2*10 + 4*20) / 6. Corner (3, 0): patch 1 alone.
  EXPECT_NEAR(avg(vertex_at(sc, split, 0, Vec3(1, 0, 0)), 0), 100.0 / 6.0, 1e-13);
  EXPECT_NEAR(avg(vertex_at(sc, split, 1, Vec3(3, 0, 0)), 0), 20.0, 1e-14);
}

TEST(VertexSplit, AverageRejectsFieldOfWrongSize) {
  const Scene sc = unit_cube();
  const VertexSplit split = split_vertices(sc);
  EXPECT_THROW(average_to_vertices(sc, split, ColorField::Zero(5, 3)), std::invalid_argument);
}
