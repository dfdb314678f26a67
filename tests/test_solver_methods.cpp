// Solver properties on synthetic reciprocal operators, compared with an independent LU solve.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "lambert/solver/solve.hpp"
#include "test_solver_util.hpp"

namespace lambert::solver {
namespace {

using testing::Synthetic;
using testing::make_synthetic;
using testing::direct_solve;
using testing::grey;
using testing::constant;
using Eigen::VectorXd;

constexpr Method kMethods[] = {Method::Jacobi, Method::GaussSeidel, Method::BiCGSTAB, Method::GMRES};

double max_rel_error(const VectorXd& got, const VectorXd& want, int* where = nullptr) {
  double worst = 0;
  for (Eigen::Index i = 0; i < got.size(); ++i) {
    const double e = std::abs(got[i] - want[i]) / std::abs(want[i]);
    if (e > worst) {
      worst = e;
      if (where) *where = int(i);
    }
  }
  return worst;
}

VectorXd random_vector(int n, unsigned seed, double lo, double hi) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  VectorXd v(n);
  for (auto& x : v) x = u(gen);
  return v;
}

TEST(SolverMethod, ParseAndPrintRoundTrip) {
  for (Method m : {Method::Auto, Method::Jacobi, Method::GaussSeidel, Method::BiCGSTAB, Method::GMRES})
    EXPECT_EQ(parse_method(to_string(m)), m) << to_string(m);
  EXPECT_EQ(parse_method("GMRES"), Method::GMRES);
  EXPECT_EQ(parse_method("sor"), Method::GaussSeidel);
  try {
    parse_method("cg");
    FAIL() << "parse_method accepted 'cg'";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'cg'"), std::string::npos) << msg;
    for (const char* name : {"auto", "jacobi", "gauss-seidel", "bicgstab", "gmres"})
      EXPECT_NE(msg.find(name), std::string::npos) << msg << " lacks " << name;
  }
}

// Every method reaches the LU answer. With relative residual tol, the error is at most
// ||(I - diag(rho) F)^-1|| tol ||L||; the inverse's norm is about 1/(1 - rho) (larger for the
// non-symmetric scaling of F by areas in [0.5, 2]), hence the bound 4 tol / (1 - rho).
TEST(SolverMethod, EveryMethodMatchesDirectSolve) {
  const int n = 300;
  const Synthetic s = make_synthetic(n, 7);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd Le = random_vector(n, 8, 0, 1);
  for (double rho0 : {0.5, 0.9, 0.99, 0.999}) {
    const VectorXd rho = random_vector(n, 9, 0.5 * rho0, rho0);
    const VectorXd exact = direct_solve(s.F, rho, Le);
    for (Method m : kMethods) {
      Options o;
      o.method = m;
      o.tolerance = 1e-10;
      o.max_iterations = 100000;
      const Solution sol = solve(F, s.area, grey(rho), grey(Le), o);
      ASSERT_EQ(sol.channels.size(), 1u);
      const ChannelReport& r = sol.channels[0];
      int at = -1;
      const double err = max_rel_error(sol.radiance.col(0), exact, &at);
      EXPECT_TRUE(sol.converged) << to_string(m) << " rho " << rho0 << " stop " << r.stop;
      EXPECT_LE(r.residual, o.tolerance) << to_string(m) << " rho " << rho0;
      EXPECT_LE(err, 4 * o.tolerance / (1 - rho0))
          << to_string(m) << " rho " << rho0 << " patch " << at << " got " << sol.radiance(at, 0) << " want "
          << exact[at];
      EXPECT_EQ(sol.method, m);
    }
  }
}

// Gauss-Seidel must handle F_ii != 0 (curved or clustered elements): the rank-one operator
// F_ij = A_j / A_total of an ideal sphere has a diagonal, and L = Le + rho Ebar / (1 - rhobar) exactly.
TEST(SolverMethod, IdealSphereOperatorMatchesClosedForm) {
  const int n = 200;
  const VectorXd area = random_vector(n, 1, 0.1, 3);
  const double total = area.sum();
  formfactor::DenseMatrixOperator::Matrix M(n, n);
  for (int i = 0; i < n; ++i) M.row(i) = area.transpose() / total;
  const formfactor::DenseMatrixOperator F(M);
  const VectorXd rho = random_vector(n, 2, 0.2, 0.95), Le = random_vector(n, 3, 0, 2);
  const double Ebar = area.dot(Le) / total, rhobar = area.dot(rho) / total;
  const std::vector<double> a(area.data(), area.data() + n);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.tolerance = 1e-12;
    const Solution sol = solve(F, a, grey(rho), grey(Le), o);
    for (int i = 0; i < n; ++i) {
      const double want = Le[i] + rho[i] * Ebar / (1 - rhobar);
      // 1e-12 residual, inverse norm <= 1 / (1 - 0.95) = 20: 1e-10 with margin.
      ASSERT_NEAR(sol.radiance(i, 0), want, 1e-10 * want) << to_string(m) << " patch " << i;
    }
  }
}

TEST(SolverMethod, AllMethodsAgreeOnColourScene) {
  const int n = 250;
  const Synthetic s = make_synthetic(n, 11, 0.05, 0.7, 1.0);  // open scene, some light escapes
  const formfactor::DenseMatrixOperator F(s.F);
  ColorField rho(n, 3), Le(n, 3);
  for (int c = 0; c < 3; ++c) {
    rho.col(c) = random_vector(n, 20 + c, 0.1, 0.6 + 0.15 * c);
    Le.col(c) = random_vector(n, 30 + c, 0, 1 + c);
  }
  Options o;
  o.tolerance = 1e-11;
  o.method = Method::GMRES;
  const Solution ref = solve(F, s.area, rho, Le, o);
  ASSERT_EQ(ref.channels.size(), 3u);
  for (Method m : {Method::Jacobi, Method::GaussSeidel, Method::BiCGSTAB, Method::Auto}) {
    o.method = m;
    const Solution sol = solve(F, s.area, rho, Le, o);
    ASSERT_TRUE(sol.converged) << to_string(m);
    for (int i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c)
        // both within 1e-11 relative residual, inverse norm < 1/(1 - 0.9) = 10: 1e-9 leaves margin
        ASSERT_NEAR(sol.radiance(i, c), ref.radiance(i, c), 1e-9 * ref.radiance(i, c))
            << to_string(m) << " patch " << i << " channel " << c;
  }
}

TEST(SolverMethod, OverRelaxedGaussSeidelConverges) {
  const int n = 200;
  const Synthetic s = make_synthetic(n, 5);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd rho = VectorXd::Constant(n, 0.95), Le = random_vector(n, 6, 0, 1);
  const VectorXd exact = direct_solve(s.F, rho, Le);
  for (double omega : {0.8, 1.0, 1.3, 1.7}) {
    Options o;
    o.method = Method::GaussSeidel;
    o.omega = omega;
    o.tolerance = 1e-10;
    const Solution sol = solve(F, s.area, grey(rho), grey(Le), o);
    EXPECT_TRUE(sol.converged) << "omega " << omega << " stop " << sol.channels[0].stop;
    EXPECT_LE(max_rel_error(sol.radiance.col(0), exact), 4e-10 / 0.05) << "omega " << omega;
  }
}

TEST(SolverMethod, ZeroReflectanceGivesDirectLightOnly) {
  const int n = 100;
  const Synthetic s = make_synthetic(n, 3);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd Le = random_vector(n, 4, 0, 5);
  for (Method m : {Method::Auto, Method::Jacobi, Method::GaussSeidel, Method::BiCGSTAB, Method::GMRES}) {
    Options o;
    o.method = m;
    const Solution sol = solve(F, s.area, constant(n, 0), grey(Le), o);
    ASSERT_TRUE(sol.converged) << to_string(m);
    const VectorXd H = M_PI * s.F * Le;
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(sol.radiance(i, 0), Le[i]) << to_string(m) << " patch " << i;  // exact: nothing reflects
      ASSERT_NEAR(sol.irradiance(i, 0), H[i], 1e-13 * H[i]) << to_string(m) << " patch " << i;
    }
    // All light is absorbed in a closed scene with rho = 0.
    EXPECT_NEAR(sol.absorbed[0], sol.emitted[0], 1e-12 * sol.emitted[0]) << to_string(m);
  }
  Options o;
  EXPECT_EQ(solve(F, s.area, constant(n, 0), grey(Le), o).method, Method::Jacobi) << "auto at rho = 0";
}

TEST(SolverMethod, ZeroEmissionGivesZero) {
  const int n = 80;
  const Synthetic s = make_synthetic(n, 3);
  const formfactor::DenseMatrixOperator F(s.F);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.initial_guess = constant(n, 3.0);  // a non-zero start must not leak into the answer
    const Solution sol = solve(F, s.area, constant(n, 0.9), constant(n, 0), o);
    EXPECT_TRUE(sol.converged);
    EXPECT_EQ(sol.radiance.cwiseAbs().maxCoeff(), 0.0) << to_string(m);
    EXPECT_EQ(sol.irradiance.cwiseAbs().maxCoeff(), 0.0) << to_string(m);
    EXPECT_EQ(sol.energy_residual, 0.0);
    EXPECT_EQ(sol.emitted.maxCoeff(), 0.0);
  }
}

// Open scene: rows sum to 0.3..0.9, reciprocal. emitted = absorbed + escaped up to the solve
// residual (1e-12) times the amplification 1/(1 - rho) = 10, and the Sinkhorn reciprocity error (~1e-14).
TEST(SolverMethod, OpenSceneBalancesEnergy) {
  const int n = 300;
  const Synthetic s = make_synthetic(n, 17, 0.1, 0.3, 0.9);
  const formfactor::DenseMatrixOperator F(s.F);
  ColorField rho(n, 3), Le(n, 3);
  for (int c = 0; c < 3; ++c) {
    rho.col(c) = random_vector(n, 40 + c, 0.0, 0.9);
    Le.col(c) = random_vector(n, 50 + c, 0, 1) * (c + 1.0);
  }
  Options o;
  o.tolerance = 1e-12;
  const Solution sol = solve(F, s.area, rho, Le, o);
  ASSERT_TRUE(sol.converged);
  for (int c = 0; c < 3; ++c) {
    EXPECT_GT(sol.escaped[c], 0.05 * sol.emitted[c]) << "channel " << c << ": an open scene loses light";
    EXPECT_NEAR(sol.emitted[c], sol.absorbed[c] + sol.escaped[c], 1e-10 * sol.emitted[c]) << "channel " << c;
  }
  EXPECT_LE(sol.energy_residual, 1e-10);
}

TEST(SolverMethod, ClosedSceneEscapesNothing) {
  const int n = 150;
  const Synthetic s = make_synthetic(n, 19);
  const formfactor::DenseMatrixOperator F(s.F);
  Options o;
  o.tolerance = 1e-12;
  const Solution sol = solve(F, s.area, constant(n, 0.8), grey(random_vector(n, 2, 0, 1)), o);
  // Row sums are 1 to Sinkhorn precision (1e-15 per row) times the radiance: relative 1e-13 is ample.
  EXPECT_LE(std::abs(sol.escaped[0]), 1e-13 * sol.emitted[0]);
  EXPECT_NEAR(sol.absorbed[0], sol.emitted[0], 1e-10 * sol.emitted[0]);
}

TEST(SolverMethod, GreySceneSolvesOneChannelAndColourThree) {
  const int n = 120;
  const Synthetic s = make_synthetic(n, 23);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd rho = random_vector(n, 1, 0.2, 0.8), Le = random_vector(n, 2, 0, 1);
  Options o;
  o.tolerance = 1e-12;
  const Solution g = solve(F, s.area, grey(rho), grey(Le), o);
  EXPECT_EQ(g.channels.size(), 1u);
  EXPECT_EQ(g.radiance.col(1), g.radiance.col(0));
  EXPECT_EQ(g.radiance.col(2), g.radiance.col(0));
  // Colour: each channel equals the grey solve of its own column (independence of channels).
  ColorField rho3 = grey(rho), Le3 = grey(Le);
  rho3.col(1) *= 0.5;
  Le3.col(2) *= 3;
  const Solution c = solve(F, s.area, rho3, Le3, o);
  ASSERT_EQ(c.channels.size(), 3u);
  for (int ch = 0; ch < 3; ++ch) {
    const Solution one = solve(F, s.area, grey(rho3.col(ch)), grey(Le3.col(ch)), o);
    for (int i = 0; i < n; ++i)
      ASSERT_NEAR(c.radiance(i, ch), one.radiance(i, 0), 1e-14 * one.radiance(i, 0)) << "patch " << i << " ch " << ch;
  }
  // R equal to a previous channel reuses it: G and B differ, R == grey.
  EXPECT_EQ(c.radiance.col(0), g.radiance.col(0));
}

TEST(SolverMethod, SolverObjectResolvesWithoutNewFormFactors) {
  const int n = 200;
  const Synthetic s = make_synthetic(n, 29);
  auto F = std::make_shared<formfactor::DenseMatrixOperator>(s.F);
  const Solver solver(F, s.area);
  EXPECT_EQ(solver.size(), n);
  const VectorXd rho = VectorXd::Constant(n, 0.95), Le = random_vector(n, 3, 0, 1);
  Options o;
  o.method = Method::GMRES;
  o.tolerance = 1e-10;
  const Solution first = solver.solve(grey(rho), grey(Le), o);
  // A new emission: same answer as a fresh one-shot solve, and the warm start from the old answer
  // after a small change needs fewer iterations than a cold start.
  VectorXd Le2 = Le;
  Le2[0] += 0.01;
  const Solution cold = solver.solve(grey(rho), grey(Le2), o);
  o.initial_guess = first.radiance;
  const Solution warm = solver.solve(grey(rho), grey(Le2), o);
  const VectorXd exact = direct_solve(s.F, rho, Le2);
  EXPECT_LE(max_rel_error(cold.radiance.col(0), exact), 4e-10 / 0.05);
  EXPECT_LE(max_rel_error(warm.radiance.col(0), exact), 4e-10 / 0.05);
  EXPECT_LT(warm.channels[0].matvecs, cold.channels[0].matvecs);
}

TEST(SolverMethod, InvalidInputIsRejectedWithPatchAndChannel) {
  const int n = 10;
  const Synthetic s = make_synthetic(n, 1);
  const formfactor::DenseMatrixOperator F(s.F);
  auto expect_error = [&](const ColorField& rho, const ColorField& Le, const Options& o, const std::string& needle) {
    try {
      solve(F, s.area, rho, Le, o);
      ADD_FAILURE() << "no error, expected '" << needle << "'";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what() << " lacks " << needle;
    }
  };
  ColorField rho = constant(n, 0.5), Le = constant(n, 1);
  const Options ok;
  ColorField bad = rho;
  bad(3, 1) = 1.0;
  expect_error(bad, Le, ok, "patch 3 channel G");
  bad(3, 1) = -0.1;
  expect_error(bad, Le, ok, "outside [0, 1)");
  bad = Le;
  bad(7, 2) = -1;
  expect_error(rho, bad, ok, "patch 7 channel B");
  bad(7, 2) = std::nan("");
  expect_error(rho, bad, ok, "not finite");
  EXPECT_THROW(solve(F, s.area, constant(n - 1, 0.5), Le, ok), InternalError) << "a field of the wrong size is a caller bug";
  Options o;
  o.tolerance = 0;
  expect_error(rho, Le, o, "tolerance");
  o = ok;
  o.omega = 2;
  expect_error(rho, Le, o, "omega");
  o = ok;
  o.max_iterations = 0;
  expect_error(rho, Le, o, "max_iterations");
  o = ok;
  o.initial_guess = constant(n + 1, 1);
  expect_error(rho, Le, o, "initial guess");
  std::vector<double> area = s.area;
  area[4] = 0;  // areas come from validated geometry: a bad one is a broken invariant, not bad input
  EXPECT_THROW(solve(F, area, rho, Le), InternalError);
  area.pop_back();
  EXPECT_THROW(solve(F, area, rho, Le), InternalError);
}

// Row sums 1.5 with rho 0.9: rho * row sum = 1.35 > 1, the Neumann series diverges. The solver must
// stop (not loop to max_iterations) and say so.
TEST(SolverMethod, DivergenceIsDetectedAndReported) {
  const int n = 60;
  Synthetic s = make_synthetic(n, 2);
  s.F *= 1.5;
  const formfactor::DenseMatrixOperator F(s.F);
  for (Method m : {Method::Jacobi, Method::GaussSeidel}) {
    Options o;
    o.method = m;
    o.max_iterations = 100000;
    const Solution sol = solve(F, s.area, constant(n, 0.9), constant(n, 1), o);
    EXPECT_FALSE(sol.converged) << to_string(m);
    EXPECT_EQ(sol.channels[0].stop, "divergence") << to_string(m);
    EXPECT_LT(sol.channels[0].iterations, 1000) << to_string(m);
    ASSERT_FALSE(sol.warnings.empty());
    EXPECT_NE(sol.warnings[0].find("Neumann"), std::string::npos) << sol.warnings[0];
  }
}

TEST(SolverMethod, IterationLimitIsReported) {
  const int n = 100;
  const Synthetic s = make_synthetic(n, 4);
  const formfactor::DenseMatrixOperator F(s.F);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.max_iterations = 3;
    o.tolerance = 1e-14;
    const Solution sol = solve(F, s.area, constant(n, 0.999), grey(random_vector(n, 5, 0, 1)), o);
    EXPECT_FALSE(sol.converged) << to_string(m);
    EXPECT_EQ(sol.channels[0].stop, "max_iterations") << to_string(m);
    EXPECT_LE(sol.channels[0].iterations, 3) << to_string(m);
    // The reported residual is that of the returned radiance.
    const VectorXd L = sol.radiance.col(0);
    const VectorXd r = grey(random_vector(n, 5, 0, 1)).col(0) + 0.999 * (s.F * L) - L;
    EXPECT_NEAR(sol.channels[0].residual, r.norm() / L.norm(), 1e-9 * sol.channels[0].residual) << to_string(m);
  }
}

// A tolerance below round-off can never be met: the solver must notice that progress stopped.
TEST(SolverMethod, StagnationIsDetectedBelowRoundOff) {
  const int n = 100;
  const Synthetic s = make_synthetic(n, 4);
  const formfactor::DenseMatrixOperator F(s.F);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.tolerance = 1e-30;
    o.max_iterations = 100000;
    const Solution sol = solve(F, s.area, constant(n, 0.5), grey(random_vector(n, 5, 0, 1)), o);
    std::printf("tolerance 1e-30: %-12s stop %-10s after %4d iterations, residual %.2e\n", to_string(m).c_str(),
                sol.channels[0].stop.c_str(), sol.channels[0].iterations, sol.channels[0].residual);
    // Jacobi may instead land on a floating-point fixed point, where the residual is exactly 0.
    const bool fixed_point = sol.channels[0].stop == "converged" && sol.channels[0].residual == 0;
    EXPECT_TRUE(sol.channels[0].stop == "stagnation" || fixed_point)
        << to_string(m) << " stopped by " << sol.channels[0].stop << ", residual " << sol.channels[0].residual;
    EXPECT_LT(sol.channels[0].iterations, 2000) << to_string(m);
    EXPECT_LT(sol.channels[0].residual, 1e-13) << to_string(m) << ": the best iterate is returned";
  }
}

TEST(SolverMethod, AutoChoosesFromReflectanceAndSize) {
  const int n = 50;
  const Synthetic s = make_synthetic(n, 4);
  const formfactor::DenseMatrixOperator F(s.F);
  const ColorField Le = constant(n, 1);
  EXPECT_EQ(solve(F, s.area, constant(n, 0), Le).method, Method::Jacobi);
  EXPECT_EQ(solve(F, s.area, constant(n, 0.3), Le).method, Method::GMRES);
  EXPECT_EQ(solve(F, s.area, constant(n, 0.999), Le).method, Method::GMRES);
  EXPECT_EQ(choose_method(0.9, 100000), Method::GMRES);
  EXPECT_EQ(choose_method(0.9, 10000000), Method::BiCGSTAB);  // 31 Krylov vectors would take 2.5 GB
  EXPECT_EQ(choose_method(0.0, 10000000), Method::Jacobi);
}

TEST(SolverMethod, ProgressSeesEveryHistoryEntry) {
  const int n = 100;
  const Synthetic s = make_synthetic(n, 4);
  const formfactor::DenseMatrixOperator F(s.F);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    std::vector<double> seen;
    int last_iteration = -1;
    bool ordered = true;
    o.progress = [&](int channel, int iteration, double residual) {
      EXPECT_EQ(channel, 0);
      ordered = ordered && iteration >= last_iteration;
      last_iteration = iteration;
      seen.push_back(residual);
    };
    const Solution sol = solve(F, s.area, constant(n, 0.9), constant(n, 1), o);
    EXPECT_EQ(seen, sol.channels[0].history) << to_string(m);
    EXPECT_TRUE(ordered) << to_string(m);
    EXPECT_LE(sol.channels[0].history.back(), o.tolerance) << to_string(m);
  }
}

// rho = 0.999 on a slowly mixing closed operator: the Krylov methods converge in well under 100
// products; the stationary sweeps are printed for contrast (Jacobi needs ~ln(1e-8)/ln(0.999) = 18,400).
TEST(SolverHardCase, ReflectanceNearOneConvergesQuickly) {
  const int n = 400;
  const Synthetic s = make_synthetic(n, 31, 0.05);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd rho = VectorXd::Constant(n, 0.999), Le = random_vector(n, 32, 0, 1);
  const VectorXd exact = direct_solve(s.F, rho, Le);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.max_iterations = 50000;
    const Solution sol = solve(F, s.area, grey(rho), grey(Le), o);
    const ChannelReport& r = sol.channels[0];
    std::printf("rho 0.999, %d patches: %-12s %6d iterations %6d products  residual %.2e  error %.2e\n", n,
                to_string(m).c_str(), r.iterations, r.matvecs, r.residual, max_rel_error(sol.radiance.col(0), exact));
    EXPECT_TRUE(sol.converged) << to_string(m) << " " << r.stop;
    // tol 1e-8 times inverse norm ~ 1/(1 - rho) = 1000, times 4 for the area scaling
    EXPECT_LE(max_rel_error(sol.radiance.col(0), exact), 4e-8 / 0.001) << to_string(m);
    if (m == Method::BiCGSTAB || m == Method::GMRES) {
      EXPECT_LT(r.matvecs, 100) << to_string(m);
    }
  }
}

// Patches of 1e-6 m^2 next to 1e3 m^2 (a 1e9 area ratio): the iteration must not lose the small ones.
TEST(SolverHardCase, AreasSpanningNineDecades) {
  const int n = 200;
  const Synthetic s = make_synthetic(n, 37, 0.1, 1, 1, 1e-6, 1e3);
  const formfactor::DenseMatrixOperator F(s.F);
  const VectorXd rho = random_vector(n, 38, 0.5, 0.95), Le = random_vector(n, 39, 0, 1);
  const VectorXd exact = direct_solve(s.F, rho, Le);
  for (Method m : kMethods) {
    Options o;
    o.method = m;
    o.tolerance = 1e-10;
    const Solution sol = solve(F, s.area, grey(rho), grey(Le), o);
    int at = -1;
    const double err = max_rel_error(sol.radiance.col(0), exact, &at);
    EXPECT_TRUE(sol.converged) << to_string(m);
    EXPECT_LE(err, 4e-10 / 0.05) << to_string(m) << " patch " << at << " area " << s.area[at];
    EXPECT_LE(sol.energy_residual, 1e-8) << to_string(m);
  }
}

}  // namespace
}  // namespace lambert::solver

namespace lambert::solver {
namespace {

// Radiance below zero is never clamped. From form factors far above 1 (F_12 = F_21 = 3, invalid on purpose)
// the exact solution of L = Le + rho F L is negative: L1 = -0.8, L2 = -1.2 for Le = (1, 0), rho = 0.5. The
// warning must call that inaccurate, give the most negative value, and the values must stay as solved.
TEST(SolverReport, NegativeRadianceIsReportedNotClamped) {
  formfactor::DenseMatrixOperator::Matrix M(2, 2);
  M << 0, 3, 3, 0;
  auto F = std::make_shared<formfactor::DenseMatrixOperator>(M);
  const Solver S(F, {1.0, 1.0});
  ColorField rho = ColorField::Constant(2, 3, 0.5), Le = ColorField::Zero(2, 3);
  Le.row(0).setConstant(1.0);
  Options o;
  o.method = Method::GMRES;
  const Solution s = S.solve(rho, Le, o);
  ASSERT_TRUE(s.converged);
  EXPECT_NEAR(s.radiance(0, 0), -0.8, 1e-7);
  EXPECT_NEAR(s.radiance(1, 0), -1.2, 1e-7);
  bool found = false;
  for (const auto& w : s.warnings)
    found |= w.find("negative radiance") != std::string::npos && w.find("inaccurate") != std::string::npos &&
             w.find("-1.2") != std::string::npos;
  EXPECT_TRUE(found) << (s.warnings.empty() ? std::string("no warnings") : s.warnings.front());
}

}  // namespace
}  // namespace lambert::solver
