#pragma once
// Shared by the mesh tests: a PolygonSoup as an OBJ reader would produce it.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lambert/mesh/soup.hpp"

namespace lambert::mesh::test_util {

// Positions on lines 1..n, face k on line 100 + k, every face with the default material.
inline PolygonSoup soup_of(const std::vector<Vec3>& positions, const std::vector<std::vector<int>>& faces) {
  PolygonSoup s = make_empty_soup("test.obj");
  for (size_t i = 0; i < positions.size(); ++i) {
    s.positions.push_back(positions[i]);
    s.position_lines.push_back(static_cast<int>(i) + 1);
  }
  for (size_t k = 0; k < faces.size(); ++k) {
    SoupFace f;
    f.vertices = faces[k];
    f.line = 100 + static_cast<int>(k);
    s.faces.push_back(f);
  }
  return s;
}

// Everything a reader produces that a writer can carry, and the face origins mesh::prepare sets, compared exactly.
inline void expect_same_soup(const PolygonSoup& a, const PolygonSoup& b, bool compare_groups = true) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t i = 0; i < a.positions.size(); ++i)
    EXPECT_TRUE(a.positions[i] == b.positions[i])
        << "position " << i << ": " << a.positions[i].transpose() << " vs " << b.positions[i].transpose();
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (std::size_t k = 0; k < a.faces.size(); ++k) {
    EXPECT_EQ(a.faces[k].vertices, b.faces[k].vertices) << "face " << k;
    EXPECT_EQ(a.faces[k].material, b.faces[k].material) << "face " << k;
    EXPECT_EQ(a.faces[k].origin, b.faces[k].origin) << "face " << k;
    if (compare_groups) {
      std::string ga = a.faces[k].group < 0 ? "" : a.groups.at(a.faces[k].group);
      std::string gb = b.faces[k].group < 0 ? "" : b.groups.at(b.faces[k].group);
      EXPECT_EQ(ga, gb) << "face " << k;
    }
  }
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t m = 0; m < a.materials.size(); ++m) {
    EXPECT_EQ(a.materials[m].name, b.materials[m].name) << "material " << m;
    EXPECT_TRUE((a.materials[m].reflectance == b.materials[m].reflectance).all())
        << "material " << m << ": " << a.materials[m].reflectance.transpose() << " vs "
        << b.materials[m].reflectance.transpose();
    EXPECT_TRUE((a.materials[m].emission == b.materials[m].emission).all())
        << "material " << m << ": " << a.materials[m].emission.transpose() << " vs "
        << b.materials[m].emission.transpose();
  }
  EXPECT_EQ(a.faces_without_material, b.faces_without_material);
}

}  // namespace lambert::mesh::test_util
