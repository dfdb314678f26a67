// End-to-end checks against exact answers: icosphere enclosures and the white furnace, with form
// factors from formfactor::assemble.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <cstdio>
#include <memory>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/verify/verify.hpp"

namespace lambert::solver {
using namespace lambert::verify;
namespace {

struct Enclosure {
  mesh::PatchGeometry geometry;
  std::shared_ptr<formfactor::DenseMatrixOperator> F;
};

const Enclosure& sphere(int subdivisions) {
  static std::map<int, Enclosure> cache;
  auto it = cache.find(subdivisions);
  if (it == cache.end()) {
    Enclosure e;
    e.geometry = mesh::PatchGeometry::from_polygons(mesh::shapes::icosphere(subdivisions, 1.0, true));
    formfactor::Options o;
    o.tolerance = 1e-10;
    e.F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(e.geometry, o));
    it = cache.emplace(subdivisions, std::move(e)).first;
  }
  return it->second;
}

// Uniform emission on a closed polyhedron: every row of F sums to 1, so E0 / (1 - rho) is the exact
// discrete answer and any deviation is form-factor or solver error. Required: 1e-6 relative.
TEST(SolverSphere, EmittingSphereMatchesClosedForm) {
  const Enclosure& e = sphere(2);
  const int n = e.geometry.size();
  const Solver solver(e.F, e.geometry.area);
  const auto [lo, hi] = std::minmax_element(solver.row_sums().begin(), solver.row_sums().end());
  const double E0 = 2.5;
  for (double rho : {0.5, 0.9, 0.99, 0.999}) {
    for (Method m : {Method::Auto, Method::GaussSeidel, Method::BiCGSTAB, Method::GMRES}) {
      Options o;
      o.method = m;
      o.tolerance = 1e-11;  // solve error <= tol / (1 - rho) = 1e-8 at rho = 0.999, far below 1e-6
      o.max_iterations = 20000;
      const Solution sol = solver.solve(ColorField::Constant(n, 3, rho), ColorField::Constant(n, 3, E0), o);
      const double exact = E0 / (1 - rho);
      double worst = 0;
      int at = 0;
      for (int i = 0; i < n; ++i) {
        const double err = std::abs(sol.radiance(i, 0) - exact) / exact;
        if (err > worst) worst = err, at = i;
      }
      std::printf("sphere K=2 rho %-6g %-12s %5d iterations %5d products  max rel error %.2e (row sums 1%+.1e..1%+.1e)\n",
                  rho, to_string(sol.method).c_str(), sol.channels[0].iterations, sol.channels[0].matvecs, worst,
                  *lo - 1, *hi - 1);
      EXPECT_TRUE(sol.converged) << to_string(m) << " rho " << rho;
      EXPECT_LE(worst, 1e-6) << to_string(m) << " rho " << rho << " patch " << at << ": " << sol.radiance(at, 0)
                             << " vs " << exact;
      // Closed: the emitted power is all absorbed (nothing escapes).
      EXPECT_NEAR(sol.absorbed[0], sol.emitted[0], 1e-6 * sol.emitted[0]) << to_string(m) << " rho " << rho;
    }
  }
}

// Varying emission and reflectance (the "linear" and "cap" fields of verify.hpp, rho0 = 0.8): the
// polyhedron converges to the continuum answer Le + rho Ebar / (1 - rhobar). Measured order in the
// edge length h (halved per level): ~1 for the max error (face normals tilt O(h) from the sphere normal
// at the centroids, and the kernel's cosines are first order in it). Required: order >= 0.8 per
// level and error <= 0.2 h/R (verify's tolerance; measured <= 0.06 h/R).
TEST(SolverSphere, VaryingEmissionConvergesAtMeasuredRate) {
  for (const std::string emission : {"linear", "cap"}) {
    std::vector<double> errors;
    for (int k = 1; k <= 3; ++k) {
      const Enclosure& e = sphere(k);
      const mesh::PatchGeometry& g = e.geometry;
      const int n = g.size();
      Eigen::VectorXd rho(n), Le(n), area = Eigen::Map<const Eigen::VectorXd>(g.area.data(), n);
      for (int i = 0; i < n; ++i) {
        const Vec3& x = g.centroid[i];
        Le[i] = emission == "cap" ? (x.z() > 0.5 ? 1.0 : 0.0) : (1 + x.z()) / 2;
        rho[i] = emission == "cap" ? 0.8 : 0.8 * (0.75 + 0.25 * x.x());
      }
      const double Ebar = area.dot(Le) / area.sum(), rhobar = area.dot(rho) / area.sum();
      ColorField R(n, 3), E(n, 3);
      R.col(0) = R.col(1) = R.col(2) = rho;
      E.col(0) = E.col(1) = E.col(2) = Le;
      Options o;
      o.tolerance = 1e-12;
      const Solution sol = Solver(e.F, g.area).solve(R, E, o);
      ASSERT_TRUE(sol.converged);
      double worst = 0;
      for (int i = 0; i < n; ++i) {
        const double want = Le[i] + rho[i] * Ebar / (1 - rhobar);
        worst = std::max(worst, std::abs(sol.radiance(i, 0) - want) / want);
      }
      const double h = 1.0514622242382672 / std::pow(2.0, k);
      std::printf("sphere %-6s K=%d %5d patches: max rel error %.3e = %.4f h/R\n", emission.c_str(), k, n, worst,
                  worst / h);
      EXPECT_LE(worst, 0.2 * h) << emission << " K=" << k;
      errors.push_back(worst);
    }
    for (size_t k = 1; k < errors.size(); ++k) {
      const double order = std::log2(errors[k - 1] / errors[k]);
      std::printf("sphere %-6s order K=%zu -> %zu: %.2f\n", emission.c_str(), k, k + 1, order);
      EXPECT_GE(order, 0.8) << emission << " between K=" << k << " and K=" << k + 1;
    }
  }
}

// White furnace with an occluding block: error within the row-sum bound rho max|delta| / (1 - rho max s)
// (plus 1e-8 for the solve: the solver adds nothing to the form factors' error) and within the case's
// fixed tolerance 5e-3 (visibility is ray-estimated with 256 rays; see verify.hpp).
TEST(SolverFurnace, OccludedRoomMatchesClosedForm) {
  for (double rho : {0.9, 0.99}) {
    FurnaceCase c;
    c.rho = rho;
    const VerifyReport r = verify_furnace(c);
    std::fputs(r.table.c_str(), stdout);
    EXPECT_TRUE(r.converged) << r.table;
    EXPECT_LE(r.max_rel_error, r.error_bound + 1e-8) << r.table;
    EXPECT_TRUE(r.passed) << r.table;
  }
}

TEST(SolverVerify, DefaultsPassAndPrintTheirTolerance) {
  const VerifyReport s = verify_sphere({});
  EXPECT_TRUE(s.passed) << s.table;
  EXPECT_NE(s.table.find("PASS"), std::string::npos) << s.table;
  EXPECT_NE(s.table.find("tolerance"), std::string::npos) << s.table;
  EXPECT_EQ(s.patches, 1280);
  const VerifyReport f = verify_furnace({});
  EXPECT_TRUE(f.passed) << f.table;
  for (const char* phase : {"mesh", "form_factors", "solve", "total"}) {
    EXPECT_TRUE(s.seconds.count(phase)) << phase;
    EXPECT_TRUE(f.seconds.count(phase)) << phase;
  }
}

// The pass threshold is a fixed number, not 5e-4 rho/(1 - rho) (50 % at rho = 0.999): the same threshold at
// 0.9 and 0.999, and at 0.999 ray-estimated visibility on a coarse room is not accurate enough, so the case
// fails (the defect is reported, not hidden by a threshold that grows with it).
TEST(SolverVerify, FurnacePassThresholdDoesNotGrowWithReflectance) {
  FurnaceCase c;
  c.divisions = 4;
  c.block_divisions = 2;
  c.rho = 0.9;
  const VerifyReport a = verify_furnace(c);
  c.rho = 0.999;
  const VerifyReport b = verify_furnace(c);
  EXPECT_EQ(a.tolerance, b.tolerance) << a.table << b.table;
  EXPECT_TRUE(a.passed) << a.table;
  EXPECT_FALSE(b.passed) << "ray visibility at rho = 0.999 cannot meet a fixed threshold\n" << b.table;
  EXPECT_TRUE(b.within_bound) << "the a-posteriori bound must still hold\n" << b.table;
}

// The a-posteriori bound (row sums and the max-norm residual, computed without the exact answer) must
// contain the actual error, also when the solve stops early (loose tolerance: the residual term matters).
TEST(SolverVerify, UniformSphereErrorStaysWithinItsAPosterioriBound) {
  for (double solve_tol : {1e-3, 1e-6, 1e-10}) {
    SphereCase c;
    c.subdivisions = 2;
    c.rho = 0.99;
    c.solve.tolerance = solve_tol;
    c.solve.method = Method::Jacobi;  // the slowest contraction: the iterate is far from converged at 1e-3
    c.solve.max_iterations = 100000;
    c.tolerance = 1;  // this test checks the bound, not the threshold
    const VerifyReport r = verify_sphere(c);
    EXPECT_TRUE(r.within_bound) << "solve tolerance " << solve_tol << "\n" << r.table;
    EXPECT_GT(r.error_bound, 0) << r.table;
  }
}

TEST(SolverVerify, BadParametersAreInputErrors) {
  SphereCase s;
  s.emission = "spiral";
  EXPECT_THROW(verify_sphere(s), InputError);
  s = {};
  s.rho = 1;
  EXPECT_THROW(verify_sphere(s), InputError);
  s = {};
  s.subdivisions = -1;
  EXPECT_THROW(verify_sphere(s), InputError);
  FurnaceCase f;
  f.divisions = 0;
  EXPECT_THROW(verify_furnace(f), InputError);
}

}  // namespace
}  // namespace lambert::solver
