#pragma once
// Shared by the mesh tests: a PolygonSoup as an OBJ reader would produce it.
#include <vector>

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

}  // namespace lambert::mesh::test_util
