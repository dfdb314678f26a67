#pragma once
// Shared by the tests that compare two hierarchical operators of one scene (an option on and off that may change
// the operator only within its admitted error).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lambert/formfactor/hierarchy.hpp"

namespace lambert::htest {

// y = H[k] x for both operators; every row within the sum of the two runs' admitted row errors and 3 sigma of their
// patch-pair ray estimates, times max x (the admitted errors are per unit radiance). Failures name the row, its
// centroid, both values and the bound; returns the worst |y_1 - y_0| / bound.
inline double expect_products_within_admitted(const mesh::PatchGeometry& g,
                                              const std::vector<formfactor::HierarchicalOperator>& H,
                                              const formfactor::HierarchyStats (&st)[2], const Eigen::VectorXd& x,
                                              const std::string& what) {
  const int n = g.size();
  Eigen::VectorXd y[2];
  for (int k = 0; k < 2; ++k) {
    y[k].resize(n);
    H[size_t(k)].apply(x, y[k]);
  }
  double worst = 0;
  for (int i = 0; i < n; ++i) {
    const size_t k = size_t(i);
    const double bound = (st[0].row_error[k] + st[1].row_error[k] +
                          3 * (st[0].row_visibility_sigma[k] + st[1].row_visibility_sigma[k]) + 1e-12) * x.maxCoeff();
    const double d = std::abs(y[1][i] - y[0][i]);
    worst = std::max(worst, d / bound);
    EXPECT_LE(d, bound) << what << ", row " << i << " (centroid " << g.centroid[k].transpose() << "): "
                        << y[1][i] << " against " << y[0][i] << ", admitted " << bound;
  }
  return worst;
}

}  // namespace lambert::htest
