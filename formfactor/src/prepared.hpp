#pragma once
// Assembly-wide patch data (internal): the scalar PatchData, its structure-of-arrays copy for the SIMD
// kernels (padded for 8-wide loads), reference rules for the largest tiers, and bounding boxes for shafts.
#include <array>
#include <vector>

#include "batch.hpp"
#include "internal.hpp"
#include "shaft.hpp"

namespace lambert::formfactor::detail {

struct Prepared {
  PatchData P;
  PointSoA points;  // normals and corners (the columns the point kernel reads), shared with soa
  std::vector<std::vector<double>> store;
  std::array<Rule2D, 9> square_rule, triangle_rule;  // reference rules for m = 6, 8
  std::vector<Box> box;
  SoA soa{};

  explicit Prepared(const mesh::PatchGeometry& g);

 private:
  double* column(size_t n);
};

}  // namespace lambert::formfactor::detail
