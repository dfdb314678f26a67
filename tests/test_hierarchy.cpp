// The hierarchical operator (formfactor/hierarchy.hpp) against the dense matrix and exact answers.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include "cli_util.hpp"

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
    // No row above 1 beyond its admitted error (the summary's `rows above 1`): closed scenes, rows of 1.
    EXPECT_EQ(st.rows_above_one.rows, 0) << c.name << ": row " << st.rows_above_one.worst_patch << " sums to 1 + "
                                         << st.rows_above_one.worst_row_sum - 1 << ", allowed "
                                         << st.rows_above_one.worst_allowed;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0, 1);
    for (int trial = 0; trial < 2; ++trial) {
      Eigen::VectorXd x(n), y0(n), y1(n);
      for (int i = 0; i < n; ++i) x[i] = trial == 0 ? 1.0 : U(rng);
      F.apply(x, y0);
      H.apply(x, y1);
      double worst = 0, worst_ratio = 0;
      int at = 0;
      for (int i = 0; i < n; ++i) {
        worst = std::max(worst, std::abs(y1[i] - y0[i]));
        // Per row: the difference against that row's admitted error (1e-12: summation order).
        const double ratio = std::abs(y1[i] - y0[i]) / (st.row_error[i] * x.maxCoeff() + 1e-12);
        if (ratio > worst_ratio) worst_ratio = ratio, at = i;
      }
      std::printf("%s: %d patches, %lld far links, %lld leaf links (dense pairs %lld), levels %d, admitted row error "
                  "%.2e, max |dFx| %.2e, worst ratio to the row's admitted error %.3f at %d (trial %d)\n",
                  c.name, n, st.far_links, st.leaf_links, st.dense_pairs_equivalent, st.levels, st.row_error_max, worst,
                  worst_ratio, at, trial);
      EXPECT_LE(worst_ratio, 1.0) << c.name << ": row " << at << " dense " << y0[at] << " hierarchical " << y1[at]
                                  << " admitted " << st.row_error[at] << " trial " << trial;
      EXPECT_LT(st.far_links + st.leaf_links, st.dense_pairs_equivalent) << c.name << ": no saving over dense";
    }
  }
}


// The dense operator (per-entry tolerance 1e-10) and the hierarchical one at `tolerance` (leaf entries at 1e-10)
// of one scene, for comparisons of F x. `g` must outlive the result (the hierarchy keeps it).
struct DenseAndHierarchy {
  DenseMatrixOperator F;
  HierarchicalOperator H;
  HierarchyStats st;
};
DenseAndHierarchy dense_and_hierarchy(const mesh::PatchGeometry& g, double tolerance) {
  Options fo;
  fo.tolerance = 1e-10;
  HierarchyOptions ho;
  ho.tolerance = tolerance;
  ho.entry_tolerance = 1e-10;
  DenseAndHierarchy r{assemble(g, fo), {}, {}};
  r.H = build_hierarchy(g, ho, &r.st);
  return r;
}

// Two panels of size h facing each other, 1 m apart and 0.36 m aside (off axis: odd terms do not cancel), each four
// triangles with third moments of their own, two tree levels below the panel's node; "bent": one corner raised by
// 0.1 h (several normals, not flat: the vector kernel and the vector moments). At a tolerance that links the panels
// as clusters, the receiving panel's F x against dense (x on the sending panel only) is the far field's truncation
// error, of fourth order: 1/16 per halving of h. Tolerance: the ratio below 1/11 (the correct code gives 0.055-0.060;
// dropping the triangles' own third moments gives 0.090-0.095, the shift of the third moments up the tree without
// its second-moment terms 0.106-0.118, the push without C[a, a, .] 0.104-0.110); and the error at h = 0.05 below
// 1e-5 of the row (s^4 = (2 x 0.035 / 1.06)^4 = 1.9e-5 times the expansion's coefficients; a third-order error
// would be s^3 = 2.9e-4 times its coefficients).
TEST(Hierarchy, FarFieldErrorFallsWithTheFourthPowerOfTheClusterSize) {
  auto panel = [](const Vec3& c, double h, double bend, bool up) {
    // A skewed quadrilateral, one corner raised by `bend` h, cut in two across and each half by a diagonal: four
    // triangles of third moments of their own, two levels of the tree below the panel's node.
    const double sz = up ? -1 : 1;  // the raised corner behind the panel (the folds of the saddle may face each other)
    const Vec3 q0 = c + Vec3(-h / 2, -h / 2, 0), q1 = c + Vec3(h / 2, -0.3 * h, 0),
               q2 = c + Vec3(0.4 * h, h / 2, sz * bend * h), q3 = c + Vec3(-h / 2, 0.35 * h, 0);
    const Vec3 m01 = 0.55 * q0 + 0.45 * q1, m32 = 0.55 * q3 + 0.45 * q2;
    mesh::shapes::Polygons p{{q0, m01, m32}, {q0, m32, q3}, {m01, q1, q2}, {m01, q2, m32}};  // normals about +z
    if (!up)
      for (auto& t : p) std::swap(t[1], t[2]);
    return p;
  };
  struct Config {
    const char* name;
    double bend_receiver, bend_source;
  };
  for (const Config& cf : {Config{"flat", 0, 0}, Config{"bent source", 0, 0.1}, Config{"both bent", 0.1, 0.1}}) {
    double err[2] = {};
    for (int k = 0; k < 2; ++k) {
      const double h = k == 0 ? 0.1 : 0.05;
      mesh::shapes::Polygons p = panel(Vec3::Zero(), h, cf.bend_receiver, true),
                             src = panel(Vec3(0.3, 0.2, 1), h, cf.bend_source, false);
      p.insert(p.end(), src.begin(), src.end());
      const mesh::PatchGeometry g = polys(p);
      Options fo;
      fo.tolerance = 1e-14;  // entries of ~1e-3: the reference to ~1e-11 relative
      const DenseMatrixOperator F = assemble(g, fo);
      HierarchyOptions ho;
      ho.tolerance = 0.5;
      HierarchyStats st;
      const HierarchicalOperator H = build_hierarchy(g, ho, &st);
      ASSERT_GT(st.far_links, 0) << cf.name << " h " << h;
      Eigen::VectorXd x = Eigen::VectorXd::Zero(8), y0(8), y1(8);
      for (int i = 4; i < 8; ++i) x[i] = 0.3 + 0.1 * i;
      F.apply(x, y0);
      H.apply(x, y1);
      for (int i = 0; i < 4; ++i) err[k] = std::max(err[k], std::abs(y1[i] - y0[i]) / y0.head(4).maxCoeff());
    }
    std::printf("%s: max relative error %.3e at h = 0.1, %.3e at h = 0.05, ratio %.4f (1/16 = 0.0625)\n", cf.name,
                err[0], err[1], err[1] / err[0]);
    // (A far link's error, not the exact entries' ~1e-11: the panels are linked as clusters. Leaf links within a
    // bent panel, whose folds may face each other, do not touch the receiving rows.)
    ASSERT_GT(err[0], 1e-8) << cf.name << ": the panels were not linked as clusters";
    EXPECT_LT(err[1] / err[0], 1 / 11.0) << cf.name << ": errors " << err[0] << " and " << err[1];
    EXPECT_LT(err[1], 1e-5) << cf.name;
  }
}

// A ground of 16 x 16 patches (8 m) lit by a distant emitter (4 x 4 patches, 24 m) through a 0.5 m window in a wall
// between them: a few ground patches see the emitter, the rest do not. Cluster links accepted as blocked miss some
// of that light (the hierarchy gives 0 where dense has up to 1.5e-3); what their rays may have missed must be in
// the rows' admitted error (kRayConfidence / rays in src/hierarchy.cpp). Twelve window positions, each a different
// draw of rays. Tolerance: the row's admitted error, as above (1e-12: summation order); the dense reference's
// visibility is its own ray estimate per pair, the same as the hierarchy's leaf pairs'. Fails in every window if
// blocked links admit nothing; it does not tell 3/rays from 1/rays (the worst ratio is 0.19 with 3/rays).
TEST(Hierarchy, GapInAWallWithinAdmittedError) {
  using mesh::shapes::grid;
  int failures = 0;
  for (int k = 0; k < 12; ++k) {
    mesh::shapes::Polygons p = grid(Vec3(0, 0, 0), Vec3(8, 0, 0), Vec3(0, 8, 0), 16, 16);  // ground, normal +z
    const double y0 = 1.0 + 0.5 * k, z0 = 1.0 + 0.2 * k, w = 0.5;                      // the window
    auto wall = [&](double ya, double yb, double za, double zb) {                      // at x = 12, normal -x
      if (yb > ya && zb > za) p.push_back({Vec3(12, ya, za), Vec3(12, ya, zb), Vec3(12, yb, zb), Vec3(12, yb, za)});
    };
    wall(-10, 18, 0, z0);
    wall(-10, 18, z0 + w, 12);
    wall(-10, y0, z0, z0 + w);
    wall(y0 + w, 18, z0, z0 + w);
    for (const auto& q : grid(Vec3(40, -8, 0), Vec3(0, 0, 24), Vec3(0, 24, 0), 4, 4)) p.push_back(q);  // emitter, -x
    const mesh::PatchGeometry g = polys(p);
    const int n = g.size();
    const auto [F, H, st] = dense_and_hierarchy(g, 1e-3);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n), y0v(n), y1v(n);
    for (int i = n - 16; i < n; ++i) x[i] = 1;  // the emitter
    F.apply(x, y0v);
    H.apply(x, y1v);
    double worst_ratio = 0;
    int at = 0;
    for (int i = 0; i < 256; ++i) {
      const double ratio = std::abs(y1v[i] - y0v[i]) / (st.row_error[i] + 1e-12);  // x: 0 or 1
      if (ratio > worst_ratio) worst_ratio = ratio, at = i;
    }
    std::printf("window %d: max ground F from the emitter %.2e, worst ratio to the admitted error %.3f at %d "
                "(dense %.3e, hierarchical %.3e)\n", k, y0v.head(256).maxCoeff(), worst_ratio, at, y0v[at], y1v[at]);
    failures += worst_ratio > 1.0;
    EXPECT_LE(worst_ratio, 1.0) << "window " << k << ": ground patch " << at << " dense " << y0v[at]
                                << " hierarchical " << y1v[at] << " admitted " << st.row_error[at];
  }
  std::printf("windows whose ground gets more error than admitted: %d of 12\n", failures);
}

// A blocked cluster link must be blocked for each of its receiving patches, not on its node's area average: a large
// ground patch under a roof and a small one beside the roof's edge, in one node, lit by a distant emitter. The rays
// of the link between that node and the emitter once went to its patches by area (the small one: 1 in 800), all
// found the roof and certified the link as blocked: the small patch lost its whole form factor to the emitter, 1.25e-2
// against an admitted 1.7e-3, in every position. Now each patch of a node takes its turn, and the small one's rays
// see the emitter: the link is refined.
// Property and tolerance as above: the hierarchical F x against the dense one within each row's admitted error
// (1e-12: summation order), for a few positions of the small patch (each another draw of rays).
TEST(Hierarchy, BlockedLinksHoldForEachReceivingPatch) {
  for (int k = 0; k < 6; ++k) {
    const double y = 0.5 + 0.9 * k;
    mesh::shapes::Polygons p;
    p.push_back({Vec3(0, 0, 0), Vec3(5.5, 0, 0), Vec3(5.5, 6, 0), Vec3(0, 6, 0)});                  // ground, +z
    p.push_back({Vec3(6.05, y, 0), Vec3(6.25, y, 0), Vec3(6.25, y + 0.2, 0), Vec3(6.05, y + 0.2, 0)});  // small, +z
    p.push_back({Vec3(-20, -20, 0.5), Vec3(-20, 26, 0.5), Vec3(6, 26, 0.5), Vec3(6, -20, 0.5)});      // roof, -z
    p.push_back({Vec3(-20, -17, 200), Vec3(-20, 23, 200), Vec3(20, 23, 200), Vec3(20, -17, 200)});    // emitter, -z
    const mesh::PatchGeometry g = polys(p);  // outlives the operator (build_hierarchy)
    const auto [F, H, st] = dense_and_hierarchy(g, 1e-2);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(4), yd(4), yh(4);
    x[3] = 1;  // the emitter
    F.apply(x, yd);
    H.apply(x, yh);
    std::printf("small patch at y %.1f: F to the emitter dense %.4e hierarchical %.4e (admitted %.2e); ground %.4e "
                "%.4e; %lld cluster links, %lld blocked\n", y, yd[1], yh[1], st.row_error[1], yd[0], yh[0],
                st.far_links, st.links_blocked);
    EXPECT_GT(yd[1], 1e-2) << "the small patch sees the emitter";
    for (int i = 0; i < 2; ++i)
      EXPECT_LE(std::abs(yh[i] - yd[i]), st.row_error[i] + 1e-12)
          << "position " << k << ", patch " << i << ": dense " << yd[i] << " hierarchical " << yh[i] << " admitted "
          << st.row_error[i];
  }
}

// Solves with the hierarchical operator; returns the radiance (channel 0) and the error bound of
// docs/physics.md §5 from the hierarchy's admitted row error, its visibility (3 sigma) and the residual.
struct HSolve {
  Eigen::VectorXd L;
  double bound = 0;
  HierarchyStats st;
};
HSolve solve_h(const mesh::PatchGeometry& g, double rho, const Eigen::VectorXd& Le, double tol) {
  const int n = g.size();
  HierarchyOptions ho;
  ho.tolerance = tol;
  ho.entry_tolerance = 1e-12;
  ho.max_reflectance = rho;
  HSolve r;
  const HierarchicalOperator H = build_hierarchy(g, ho, &r.st);
  solver::Options so;
  so.tolerance = 1e-12;
  so.max_iterations = 2000;
  ColorField E(n, 3);
  for (int c = 0; c < 3; ++c) E.col(c) = Le;
  const solver::Solution sol = solver::solve(H, g.area, ColorField::Constant(n, 3, rho), E, so);
  EXPECT_TRUE(sol.converged);
  r.L = sol.radiance.col(0);
  const double delta = r.st.row_error_max + 3 * r.st.row_visibility_sigma_max;
  r.bound = (rho * delta + sol.channels[0].residual_max) / (1 - rho * std::max(1.0, r.st.row_sum_max));
  return r;
}

// White furnace: a closed room with a floating block, uniform E0 and rho: L = E0 / (1 - rho) everywhere.
// Push-pull must neither lose nor create energy beyond the admitted error. Tolerance: the bound above.
// The hierarchy's tolerance is 2e-3: since blocked cluster links admit what each receiving patch's share of their
// rays may have missed (not the node's average), the bound at 1e-2 is 6.9e-2 (was 2.7e-2), above the 5 % this test
// takes as too loose to guard anything; at 2e-3 it is 3.7e-2 for an error of 1.8e-3.
TEST(Hierarchy, ClosedFurnaceStaysAtClosedForm) {
  const mesh::PatchGeometry g = polys(mesh::shapes::room_with_block(12, 4));
  const double rho = 0.5, E0 = 1;
  const HSolve r = solve_h(g, rho, Eigen::VectorXd::Constant(g.size(), E0), 2e-3);
  const double exact = E0 / (1 - rho);
  double worst = 0;
  int at = 0;
  for (int i = 0; i < g.size(); ++i)
    if (std::abs(r.L[i] - exact) / exact > worst) worst = std::abs(r.L[i] - exact) / exact, at = i;
  std::printf("furnace: %lld far links, worst relative error %.2e at %d, bound %.2e (row error %.2e, visibility sigma %.2e)\n", r.st.far_links, worst, at, r.bound, r.st.row_error_max, r.st.row_visibility_sigma_max);
  EXPECT_GT(r.st.far_links, 0) << "no cluster link: the test would not exercise push-pull";
  EXPECT_LE(worst, r.bound) << "patch " << at << " L " << r.L[at] << " exact " << exact;
  EXPECT_LT(r.bound, 0.05) << "bound too loose to guard anything";
}

// The emitting sphere at rho = 0.999 (convex: no visibility): L = E0 / (1 - rho) = 1000 E0. The solve amplifies
// a row error 1000-fold; the knob is in radiance terms, so the links refine to tolerance (1 - rho) / rho. Without
// that factor the same tolerance admits row sums above 1 / rho and the solution is wrong by 100% or diverges.
// Tolerance of the check: the knob (1e-2) on the relative radiance, and the stated bound.
TEST(Hierarchy, SphereAtRho0999WithinTolerance) {
  const mesh::PatchGeometry g = polys(mesh::shapes::icosphere(3, 1.0, true));
  const double rho = 0.999, E0 = 1;
  const HSolve r = solve_h(g, rho, Eigen::VectorXd::Constant(g.size(), E0), 1e-2);
  const double exact = E0 / (1 - rho);
  double worst = 0;
  int at = 0;
  for (int i = 0; i < g.size(); ++i)
    if (std::abs(r.L[i] - exact) / exact > worst) worst = std::abs(r.L[i] - exact) / exact, at = i;
  std::printf("sphere rho 0.999: link tolerance %.1e, %lld far links, %lld leaf links, admitted %.2e, worst %.2e, "
              "bound %.2e\n", r.st.link_tolerance, r.st.far_links, r.st.leaf_links, r.st.row_error_max, worst, r.bound);
  EXPECT_LE(worst, 1e-2) << "patch " << at << " L " << r.L[at];
  EXPECT_GT(r.bound, 0) << "rho x row sum >= 1: no bound";
  EXPECT_LE(worst, r.bound) << "patch " << at << " L " << r.L[at];
}

// Exact visibility inside the hierarchy: a closed room with a floating block sums every row to 1 within the
// row error the build admits (its links' expansion error plus the exact pairs' integration bounds: no ray
// noise left). With ray visibility the same rows miss 1 by more than the admitted error (the rays' sigma is
// not in it), which is what this test sees when the exact path is bypassed.
TEST(Hierarchy, ExactVisibilityRowSumsWithinAdmittedError) {
  const mesh::PatchGeometry g = polys(mesh::shapes::room_with_block(4, 2));
  HierarchyOptions o;
  o.tolerance = 1e-3;
  o.max_reflectance = 0.5;
  o.visibility_method = VisibilityMethod::Exact;
  HierarchyStats st;
  const HierarchicalOperator H = build_hierarchy(g, o, &st);
  EXPECT_GT(st.pairs_exact_integrated + st.pairs_exact_hidden, 0) << "no pair took the exact path";
  EXPECT_EQ(st.pairs_ray_tested, 0);
  EXPECT_EQ(st.links_ray_tested, 0) << "partly hidden cluster pairs must be refined, not ray-tested";
  double worst = 0;
  for (int i = 0; i < g.size(); ++i) {
    const double dev = std::abs(H.row_sum(i) - 1);
    worst = std::max(worst, dev);
    EXPECT_LE(dev, st.row_error[size_t(i)] + 1e-9) << "row " << i << " sums to " << H.row_sum(i);
  }
  EXPECT_EQ(st.rows_above_one.rows, 0) << "row " << st.rows_above_one.worst_patch << " ratio "
                                       << st.rows_above_one.max_ratio;
  std::printf("exact visibility in the hierarchy: max |row sum - 1| %.2e, admitted %.2e\n", worst, st.row_error_max);
}

// apply() gives bit-identical results for any thread count (and so does the build).
TEST(Hierarchy, DeterministicForAnyThreadCount) {
  const mesh::PatchGeometry g = polys(mesh::shapes::room_with_block(8, 3));
  const int n = g.size();
  Eigen::VectorXd x(n);
  for (int i = 0; i < n; ++i) x[i] = 1 + std::sin(0.37 * i);
  Eigen::VectorXd y[2];
  for (int t = 0; t < 2; ++t) {
    tbb::task_arena arena(t + 1);
    arena.execute([&] {
      HierarchyOptions ho;
      ho.tolerance = 1e-2;
      const HierarchicalOperator H = build_hierarchy(g, ho);
      y[t].resize(n);
      H.apply(x, y[t]);
    });
  }
  for (int i = 0; i < n; ++i) ASSERT_EQ(y[0][i], y[1][i]) << "row " << i << ": 1 thread vs 2 threads";
}

// A lattice city (a ground of 3.7 m quads, 3 x 3 blocks on it) built where it is and moved by (512345.37, 4123456.81,
// 31.3) m, as GIS coordinates come: the corners of the moved copy are rounded by ~1e-9 m, so coordinates equal in the
// first (rows of blocks, the ground's grid lines) are unequal by that much in the second. The tree must not follow those
// differences: the same links (counted; visibility off, so that only the tree and the links' tests decide) and row
// sums within 1e-5. Ordering centroids by their exact values, the two trees differed: 19,806 against 19,056 links,
// row sums 1.2e-4 apart. With the tree the same they are 1.8e-6 apart (the dense rows 1e-11): the links' own tests
// (orientation, the expansion's error against the tolerance) still meet knife edges in a lattice, and moving the
// city by (30, 20, 0) m exactly does as much; 1e-5 is 100x below the link tolerance (1e-3).
TEST(Hierarchy, TreeDoesNotDependOnWhereTheModelSits) {
  mesh::shapes::Polygons city;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j)
      city.push_back({Vec3(3.7 * i, 3.7 * j, 0), Vec3(3.7 * (i + 1), 3.7 * j, 0), Vec3(3.7 * (i + 1), 3.7 * (j + 1), 0),
                      Vec3(3.7 * i, 3.7 * (j + 1), 0)});
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (auto& q : mesh::shapes::box(Vec3(11.1 + 22.2 * i, 11.1 + 22.2 * j, 0), Vec3(22.2 + 22.2 * i, 18.5 + 22.2 * j, 9.3 + 3.1 * i), 4,
                                       false))
        city.push_back(q);
  mesh::shapes::Polygons moved = city;
  const Vec3 shift(512345.37, 4123456.81, 31.3);
  for (auto& q : moved)
    for (Vec3& v : q) v += shift;
  const mesh::PatchGeometry a = polys(city), b = polys(moved);
  HierarchyOptions ho;
  ho.visibility = false;
  HierarchyStats sa, sb;
  const HierarchicalOperator Ha = build_hierarchy(a, ho, &sa), Hb = build_hierarchy(b, ho, &sb);
  EXPECT_EQ(sa.far_links, sb.far_links);
  EXPECT_EQ(sa.leaf_links, sb.leaf_links);
  EXPECT_GT(sa.far_links, 100);
  double worst = 0;
  int at = -1;
  for (int i = 0; i < a.size(); ++i) {
    const double d = std::abs(Ha.row_sum(i) - Hb.row_sum(i));
    if (d > worst) worst = d, at = i;
  }
  std::printf("%d patches, %lld / %lld cluster links, largest row-sum difference %.2e (patch %d)\n", a.size(), sa.far_links,
              sb.far_links, worst, at);
  EXPECT_LE(worst, 1e-5) << "patch " << at;
}

// A build that cannot fit is refused before anything large is allocated, naming the estimate and what to change.
TEST(Hierarchy, RefusesWhenEstimateExceedsMemory) {
  const mesh::PatchGeometry g = polys(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), 20, true));
  HierarchyOptions ho;
  ho.max_bytes = 1 << 20;  // 1 MB for 2,400 patches (estimate ~125 MB)
  try {
    build_hierarchy(g, ho);
    FAIL() << "no refusal";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("estimated to need"), std::string::npos) << m;
    EXPECT_NE(m.find("--hierarchy-tolerance"), std::string::npos) << m;
    EXPECT_NE(m.find("--max-edge"), std::string::npos) << m;
  }
}

// Gauss-Seidel sweeps rows; the hierarchical operator stores none: refused by name, and auto never picks it.
TEST(Hierarchy, GaussSeidelRefusedWithoutRows) {
  const mesh::PatchGeometry g = polys(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), 3, true));
  const HierarchicalOperator H = build_hierarchy(g);
  EXPECT_FALSE(H.has_rows());
  const int n = g.size();
  solver::Options so;
  so.method = solver::Method::GaussSeidel;
  EXPECT_THROW(solver::solve(H, g.area, ColorField::Constant(n, 3, 0.5), ColorField::Constant(n, 3, 1.0), so), InputError);
  so.method = solver::Method::Auto;
  const solver::Solution sol = solver::solve(H, g.area, ColorField::Constant(n, 3, 0.5), ColorField::Constant(n, 3, 1.0), so);
  EXPECT_NE(sol.method, solver::Method::GaussSeidel);
  EXPECT_TRUE(sol.converged);
}

}  // namespace

// `lambert formfactors --operator hierarchical` streams i,j,F_ij aggregated to input faces; it must equal the
// dense output within the admitted row error (an entry's error is at most its row's), and --min-factor must drop
// exactly the entries below it.
class HierarchyCli : public test::Cli {};

TEST_F(HierarchyCli, FormfactorsStreamingMatchesDense) {
  const std::string scene = std::string(LAMBERT_SOURCE_DIR) + "/examples/cornell_box.obj";
  const auto d = test::run("formfactors " + scene + " --max-edge 0.06 -o " + path("d.csv") + " --operator dense -q");
  ASSERT_EQ(d.status, 0) << d.output;
  const auto h = test::run("formfactors " + scene + " --max-edge 0.06 -o " + path("h.csv") +
                           " --operator hierarchical --hierarchy-tolerance 1e-2 --stats " + path("h.json") + " -q");
  ASSERT_EQ(h.status, 0) << h.output;
  const nlohmann::json js = nlohmann::json::parse(std::ifstream(path("h.json")));
  ASSERT_EQ(js["operator"]["kind"], "hierarchical");
  const double admitted = js["hierarchy"]["row_error_max"].get<double>() + 3 * js["hierarchy"]["row_visibility_sigma_max"].get<double>();
  const auto D = test::read_form_factors(path("d.csv")), H = test::read_form_factors(path("h.csv"));
  ASSERT_GT(D.size(), 100u);
  double worst = 0;
  std::pair<int, int> at{-1, -1};
  for (const auto& [k, v] : D) {
    const auto it = H.find(k);
    const double e = std::abs((it == H.end() ? 0.0 : it->second) - v);
    if (e > worst) worst = e, at = k;
  }
  for (const auto& [k, v] : H)
    if (!D.count(k) && v > worst) worst = v, at = k;
  std::printf("formfactors: %zu dense entries, %zu hierarchical, worst difference %.2e at (%d, %d), admitted %.2e, "
              "%lld cluster links\n",
              D.size(), H.size(), worst, at.first, at.second, admitted, js["hierarchy"]["far_links"].get<long long>());
  EXPECT_GT(js["hierarchy"]["far_links"].get<long long>(), 100) << "too few cluster links to test the streaming";
  EXPECT_LE(worst, admitted) << "entry (" << at.first << ", " << at.second << ")";
  // --min-factor: only entries >= 0.01, and all of them.
  const auto m = test::run("formfactors " + scene + " --max-edge 0.06 -o " + path("m.csv") +
                           " --operator hierarchical --hierarchy-tolerance 1e-2 --min-factor 0.01 -q");
  ASSERT_EQ(m.status, 0) << m.output;
  const auto M = test::read_form_factors(path("m.csv"));
  for (const auto& [k, v] : M) EXPECT_GE(v, 0.01) << k.first << "," << k.second;
  size_t expected = 0;
  for (const auto& [k, v] : H) expected += v >= 0.01;
  EXPECT_EQ(M.size(), expected);
  EXPECT_GT(M.size(), 0u);
  EXPECT_LT(M.size(), H.size());
}

// A view-factor file is geometry: the hierarchy behind `formfactors` refines by geometry alone, so the same model
// with its light switched off and a wall made black (what a thermal engineer's model looks like: no emitters) gives
// the same entries to the bit. (Refined by the materials' brightness, the unlit model was linked as if nothing
// mattered: udales_shape.obj's row sums were 0.084 off the dense ones.)
TEST_F(HierarchyCli, FormfactorsDoNotDependOnTheMaterials) {
  const std::string scene = std::string(LAMBERT_SOURCE_DIR) + "/examples/cornell_box.obj";
  {
    std::ofstream m(path("unlit.json"));
    m << R"({"materials": {"light": {"reflectance": 0.78, "emission": 0}, "red": {"reflectance": 0}}})";
  }
  const std::string common = " --max-edge 0.06 --operator hierarchical --hierarchy-tolerance 1e-2 -q";
  const auto lit = test::run("formfactors " + scene + " -o " + path("lit.csv") + " --stats " + path("lit.json") + common);
  ASSERT_EQ(lit.status, 0) << lit.output;
  const auto unlit = test::run("formfactors " + scene + " --materials " + path("unlit.json") + " -o " + path("unlit.csv") +
                               " --stats " + path("unlit.json.out") + common);
  ASSERT_EQ(unlit.status, 0) << unlit.output;
  const auto A = test::read_form_factors(path("lit.csv")), B = test::read_form_factors(path("unlit.csv"));
  ASSERT_GT(A.size(), 100u);
  EXPECT_EQ(A.size(), B.size());
  long long differ = 0;
  for (const auto& [k, v] : A) {
    const auto it = B.find(k);
    if (it != B.end() && it->second == v) continue;
    if (++differ <= 5)
      ADD_FAILURE() << "entry (" << k.first << ", " << k.second << "): lit " << v << ", unlit "
                    << (it == B.end() ? 0.0 : it->second);
  }
  EXPECT_EQ(differ, 0);
  const nlohmann::json a = nlohmann::json::parse(std::ifstream(path("lit.json"))),
                       b = nlohmann::json::parse(std::ifstream(path("unlit.json.out")));
  EXPECT_EQ(a["hierarchy"]["row_error_max"], b["hierarchy"]["row_error_max"]);
  EXPECT_EQ(a["hierarchy"]["far_links"], b["hierarchy"]["far_links"]);
}

// A scene where nothing emits: the solve says so, and the summary's dark line names that as the reason (it called
// every grey surface "black and not emitting").
TEST_F(HierarchyCli, SceneWithoutEmittersIsNamedAsSuch) {
  const std::string scene = std::string(LAMBERT_SOURCE_DIR) + "/examples/cornell_box.obj";
  {
    std::ofstream m(path("off.json"));
    m << R"({"materials": {"light": {"emission": 0}}})";
  }
  const auto r = test::run("solve " + scene + " --materials " + path("off.json") + " -o " + path("off.vtu") +
                           " --operator hierarchical --max-edge 0.1");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("no emitter"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("patches that send nothing (nothing in the scene emits)"), std::string::npos) << r.output;
  const auto lit = test::run("solve " + scene + " -o " + path("lit.vtu") + " --operator hierarchical --max-edge 0.1");
  ASSERT_EQ(lit.status, 0) << lit.output;
  EXPECT_EQ(lit.output.find("nothing in the scene emits"), std::string::npos) << lit.output;
}

// --operator auto prints its choice and why; an impossible request is refused with the estimate (exit 1).
TEST_F(HierarchyCli, OperatorChoicePrintedAndUnsupportedCombinationsRefused) {
  const std::string scene = std::string(LAMBERT_SOURCE_DIR) + "/examples/cornell_box.obj";
  const auto a = test::run("solve " + scene + " -o " + path("a.vtu"));
  ASSERT_EQ(a.status, 0) << a.output;
  EXPECT_NE(a.output.find("operator     dense (auto: "), std::string::npos) << a.output;
  const auto b = test::run("solve " + scene + " -o " + path("b.vtu") + " --operator hierarchical --adaptive-budget 500");
  EXPECT_EQ(b.status, 1) << b.output;
  EXPECT_NE(b.output.find("adaptive refinement"), std::string::npos) << b.output;
  const auto c = test::run("solve " + scene + " -o " + path("c.vtu") + " --operator hierarchical --method gauss-seidel");
  EXPECT_EQ(c.status, 1) << c.output;
  EXPECT_NE(c.output.find("does not store"), std::string::npos) << c.output;
  const auto d = test::run("solve " + scene + " -o " + path("d.vtu") + " --operator sparse");
  EXPECT_EQ(d.status, 1) << d.output;
  // --visibility reaches the hierarchy's patch pairs (it was silently ray-traced): counted in --stats.
  const auto f = test::run("solve " + scene + " -o " + path("f.vtu") + " --operator hierarchical --visibility exact" +
                           " --stats " + path("f.json") + " -q");
  EXPECT_EQ(f.status, 0) << f.output;
  std::ifstream fj(path("f.json"));
  const std::string fs((std::istreambuf_iterator<char>(fj)), std::istreambuf_iterator<char>());
  EXPECT_NE(fs.find("\"pairs_exact_integrated\""), std::string::npos) << fs.substr(0, 2000);
  EXPECT_NE(fs.find("\"visibility_method\": \"exact\""), std::string::npos) << fs.substr(0, 2000);
  // Too many patches for the memory available: refused before refining, with the patch count that fits.
  for (const char* op : {"dense", "hierarchical"}) {
    const auto e = test::run("solve " + scene + " -o " + path("e.vtu") + " --max-edge 0.0003 --operator " + op);
    EXPECT_EQ(e.status, 1) << op << ": " << e.output;
    EXPECT_NE(e.output.find("fit in memory"), std::string::npos) << op << ": " << e.output;
    EXPECT_NE(e.output.find("use a larger --max-edge"), std::string::npos) << op << ": " << e.output;
  }
}

}  // namespace lambert::formfactor
