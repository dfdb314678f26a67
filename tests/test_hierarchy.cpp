// The hierarchical operator (formfactor/hierarchy.hpp) against the dense matrix and exact answers.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::formfactor {
namespace {

mesh::PatchGeometry polys(const mesh::shapes::Polygons& p) { return mesh::PatchGeometry::from_polygons(p); }

mesh::Scene cornell(double max_edge) {
  mesh::PolygonSoup soup = io::read_soup(std::string(LAMBERT_SOURCE_DIR) + "/examples/cornell_box.obj");
  mesh::PrepareOptions po;
  po.max_edge = max_edge;
  return mesh::prepare_and_build(soup, po);
}

struct Case {
  const char* name;
  mesh::PatchGeometry g;
};

std::vector<Case>& cases() {
  static std::vector<Case> c = [] {
    std::vector<Case> v;
    v.push_back({"sphere", polys(mesh::shapes::icosphere(3, 1.0, true))});
    v.push_back({"furnace_box", polys(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), 12, true))});
    v.push_back({"room_with_block", polys(mesh::shapes::room_with_block(10, 4))});
    v.push_back({"cornell_box", cornell(0.12).geometry});
    return v;
  }();
  return c;
}

// |F~ x - F x| <= (admitted row error) max|x| for every row, x >= 0: each far link's relative error estimate
// bounds its entries' errors, and the leaf entries are the dense ones (same kernel, same ray seeds).
// Tolerance: the admitted row error itself (plus 1e-12 for summation order), the property under test.
TEST(Hierarchy, MatchesDenseWithinAdmittedError) {
  for (Case& c : cases()) {
    const int n = c.g.size();
    Options fo;
    fo.tolerance = 1e-10;
    const DenseMatrixOperator F = assemble(c.g, fo);
    HierarchyOptions ho;
    ho.tolerance = 1e-2;
    ho.entry_tolerance = 1e-10;
    HierarchyStats st;
    const HierarchicalOperator H = build_hierarchy(c.g, ho, &st);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0, 1);
    for (int trial = 0; trial < 2; ++trial) {
      Eigen::VectorXd x(n), y0(n), y1(n);
      for (int i = 0; i < n; ++i) x[i] = trial == 0 ? 1.0 : U(rng);
      F.apply(x, y0);
      H.apply(x, y1);
      double worst = 0;
      int at = 0;
      for (int i = 0; i < n; ++i)
        if (std::abs(y1[i] - y0[i]) > worst) worst = std::abs(y1[i] - y0[i]), at = i;
      std::printf("%s: %d patches, %lld far links, %lld leaf links (dense pairs %lld), levels %d, admitted row error "
                  "%.2e, max |dFx| %.2e at %d (trial %d)\n",
                  c.name, n, st.far_links, st.leaf_links, st.dense_pairs_equivalent, st.levels, st.row_error_max, worst,
                  at, trial);
      EXPECT_LE(worst, st.row_error_max * x.maxCoeff() + 1e-12)
          << c.name << ": row " << at << " dense " << y0[at] << " hierarchical " << y1[at] << " trial " << trial;
      EXPECT_LT(st.far_links + st.leaf_links, st.dense_pairs_equivalent) << c.name << ": no saving over dense";
    }
  }
}

}  // namespace
}  // namespace lambert::formfactor
