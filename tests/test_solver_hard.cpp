// Hard geometry for the whole chain (form factors + solve): extreme area ratios, slivers, nearly
// touching plates. Exact answers: the white furnace (closed box, E0 / (1 - rho)) and two opposed
// plates with the catalogue form factor.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <Eigen/Dense>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::solver {
namespace {

using Polygons = mesh::shapes::Polygons;

// Replaces face `index` of `faces` by `parts`, oriented like the face (same Newell normal direction).
Polygons replace_face(Polygons faces, int index, Polygons parts) {
  const Vec3 n = mesh::newell_normal(faces[index]);
  for (auto& p : parts)
    if (mesh::newell_normal(p).dot(n) < 0) std::reverse(p.begin(), p.end());
  faces.erase(faces.begin() + index);
  faces.insert(faces.end(), parts.begin(), parts.end());
  return faces;
}

struct Furnace {
  int patches = 0;
  double max_rel_error = 0;
  int worst = -1;
  double bound = 0;  // rho max|1 - s| / (1 - rho max s) from the row sums s
  Solution solution;
};

// Uniform Le = 1 and rho in a closed scene: exact L = 1 / (1 - rho).
Furnace furnace(const Polygons& polygons, double rho, Method method = Method::Auto) {
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(polygons);
  formfactor::Options fo;
  fo.tolerance = 1e-10;
  auto F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(g, fo));
  const Solver solver(F, g.area);
  Options o;
  o.method = method;
  o.tolerance = 1e-12;
  Furnace f;
  f.patches = g.size();
  f.solution = solver.solve(ColorField::Constant(g.size(), 3, rho), ColorField::Constant(g.size(), 3, 1.0), o);
  const auto [lo, hi] = std::minmax_element(solver.row_sums().begin(), solver.row_sums().end());
  f.bound = rho * std::max(1 - *lo, *hi - 1) / (1 - rho * *hi);
  for (int i = 0; i < g.size(); ++i) {
    const double e = std::abs(f.solution.radiance(i, 0) * (1 - rho) - 1);
    if (e > f.max_rel_error) f.max_rel_error = e, f.worst = i;
  }
  return f;
}

// A 1e-6 m^2 patch in the corner of a 1e3 m^2 floor of a closed box (area ratio 1e9).
TEST(SolverHardGeometry, TinyPatchBesideHugeOnes) {
  const double a = std::sqrt(1000.0), s = 1e-3;
  Polygons box = mesh::shapes::box(Vec3::Zero(), Vec3::Constant(a), 1, true);
  const Polygons floor = {{Vec3(0, 0, 0), Vec3(s, 0, 0), Vec3(s, s, 0), Vec3(0, s, 0)},
                          {Vec3(s, 0, 0), Vec3(a, 0, 0), Vec3(a, a, 0), Vec3(0, a, 0), Vec3(0, s, 0), Vec3(s, s, 0)}};
  box = replace_face(box, 4, floor);  // face 4 is -z
  const int tiny = static_cast<int>(box.size()) - 2;
  for (double rho : {0.9, 0.99}) {
    const Furnace f = furnace(box, rho);
    std::printf("tiny patch, rho %g: max rel error %.2e (patch %d), tiny patch error %.2e, row-sum bound %.2e\n", rho,
                f.max_rel_error, f.worst, std::abs(f.solution.radiance(tiny, 0) * (1 - rho) - 1), f.bound);
    // The row-sum bound plus the solve error (1e-12 / (1 - rho)) covers the error; and form factors at
    // tolerance 1e-10 must make it small in absolute terms too.
    EXPECT_LE(f.max_rel_error, f.bound + 1e-9) << "patch " << f.worst;
    EXPECT_LE(f.max_rel_error, 1e-6) << "patch " << f.worst;
    EXPECT_TRUE(f.solution.converged);
  }
}

// Slivers of aspect ratio 1e4 (length 1, height 1e-4) fanned into the floor of the unit room.
TEST(SolverHardGeometry, SliverTriangles) {
  Polygons room = mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), 2, true);
  // The -z face is split 2 x 2: replace its first quad [0, 0.5]^2 by slivers and a remainder.
  int first = -1;
  for (int i = 0; i < int(room.size()) && first < 0; ++i) {
    bool ok = true;
    for (const Vec3& p : room[i]) ok = ok && p.z() == 0 && p.x() <= 0.5 && p.y() <= 0.5;
    if (ok) first = i;
  }
  ASSERT_GE(first, 0);
  const double w = 0.5, h = 0.5e-4;  // aspect w / h = 1e4
  Polygons parts;
  for (int k = 0; k < 3; ++k) parts.push_back({Vec3(0, 0, 0), Vec3(w, k * h, 0), Vec3(w, (k + 1) * h, 0)});
  parts.push_back({Vec3(0, 0, 0), Vec3(w, 3 * h, 0), Vec3(w, w, 0), Vec3(0, w, 0)});
  room = replace_face(room, first, parts);
  const Furnace f = furnace(room, 0.9);
  const int n = f.patches;
  double sliver_error = 0;
  for (int i = n - 4; i < n - 1; ++i) sliver_error = std::max(sliver_error, std::abs(f.solution.radiance(i, 0) * 0.1 - 1));
  std::printf("slivers, rho 0.9: max rel error %.2e (patch %d), slivers %.2e, row-sum bound %.2e\n", f.max_rel_error,
              f.worst, sliver_error, f.bound);
  EXPECT_LE(f.max_rel_error, f.bound + 1e-9) << "patch " << f.worst;
  EXPECT_LE(f.max_rel_error, 1e-6) << "patch " << f.worst;
}

// Catalogue (Howell C-11): directly opposed parallel rectangles a x b at distance c.
double opposed_rectangles(double a, double b, double c) {
  const long double X = a / c, Y = b / c;
  const long double x1 = std::sqrt(1 + X * X), y1 = std::sqrt(1 + Y * Y);
  const long double v = std::log(x1 * y1 / std::sqrt(1 + X * X + Y * Y)) + X * y1 * std::atan(X / y1) +
                        Y * x1 * std::atan(Y / x1) - X * std::atan(X) - Y * std::atan(Y);
  return double(2 * v / (3.14159265358979323846264338327950288L * X * Y));
}

// Two unit squares 1e-4 apart facing each other (an open scene). Square 1 emits E0 = 1; with F the
// mutual form factor, L1 = 1 / (1 - rho^2 F^2) and L2 = rho F L1.
TEST(SolverHardGeometry, NearlyTouchingParallelPlates) {
  const double gap = 1e-4;
  const Polygons plates = {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)},          // normal +z
                           {Vec3(0, 0, gap), Vec3(0, 1, gap), Vec3(1, 1, gap), Vec3(1, 0, gap)}};  // normal -z
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(plates);
  formfactor::Options fo;
  fo.tolerance = 1e-10;
  const formfactor::DenseMatrixOperator F = formfactor::assemble(g, fo);
  const double Fx = opposed_rectangles(1, 1, gap);
  std::printf("plates gap 1e-4: F12 %.12f assembled, %.12f catalogue\n", F.matrix()(0, 1), Fx);
  // Form factor first: absolute tolerance 1e-10 requested, 1e-9 allowed for the catalogue's own rounding.
  EXPECT_NEAR(F.matrix()(0, 1), Fx, 1e-9);
  for (double rho : {0.5, 0.9, 0.99}) {
    ColorField Le = ColorField::Zero(2, 3);
    Le.row(0).setConstant(1);
    Options o;
    o.tolerance = 1e-12;
    const Solution sol = solve(F, g.area, ColorField::Constant(2, 3, rho), Le, o);
    const double L1 = 1 / (1 - rho * rho * Fx * Fx), L2 = rho * Fx * L1;
    // dL/dF = O(1 / (1 - rho^2 F^2)^2) ~ 2500 at rho 0.99: 1e-9 in F gives ~3e-6 in L.
    EXPECT_NEAR(sol.radiance(0, 0), L1, 5e-6 * L1) << "rho " << rho;
    EXPECT_NEAR(sol.radiance(1, 0), L2, 5e-6 * L2) << "rho " << rho;
    // Open: what is not absorbed escapes through the 1e-4 slit.
    EXPECT_NEAR(sol.emitted[0], sol.absorbed[0] + sol.escaped[0], 1e-9 * sol.emitted[0]) << "rho " << rho;
    EXPECT_GT(sol.escaped[0], 0) << "rho " << rho;
  }
}

// rho = 0.999 in the occluded room (a realistic spectrum, unlike the nearly rank-one sphere): the
// Krylov methods converge in well under 100 products; Jacobi and Gauss-Seidel sweeps are printed for
// contrast. All agree with an LU solve of the same F (the furnace's exact answer would also measure
// the form factors' row-sum error, amplified 1000x here).
TEST(SolverHardCase, ReflectanceNearOneInOccludedRoom) {
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(mesh::shapes::room_with_block(6, 3));
  const formfactor::DenseMatrixOperator F = formfactor::assemble(g);
  const int n = g.size();
  const double rho = 0.999;
  Eigen::VectorXd Le = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; i += 11) Le[i] = 1;  // scattered emitters
  const Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n) - rho * Eigen::MatrixXd(F.matrix());
  const Eigen::VectorXd exact = A.partialPivLu().solve(Le);
  for (Method m : {Method::Jacobi, Method::GaussSeidel, Method::BiCGSTAB, Method::GMRES, Method::Auto}) {
    Options o;
    o.method = m;
    o.max_iterations = 40000;
    ColorField E(n, 3);
    E.col(0) = E.col(1) = E.col(2) = Le;
    const Solution sol = solve(F, g.area, ColorField::Constant(n, 3, rho), E, o);
    const ChannelReport& c = sol.channels[0];
    double err = 0;
    for (int i = 0; i < n; ++i) err = std::max(err, std::abs(sol.radiance(i, 0) - exact[i]) / exact[i]);
    std::printf("room %d patches, rho 0.999: %-12s %6d iterations %6d products, %.3f s, max rel error vs LU %.1e\n", n,
                to_string(sol.method).c_str(), c.iterations, c.matvecs, sol.seconds, err);
    EXPECT_TRUE(sol.converged) << to_string(m) << " " << c.stop;
    // tol 1e-8 times the inverse's norm ~ 1 / (1 - rho) = 1000; 4x margin for the non-uniform areas
    EXPECT_LE(err, 4e-5) << to_string(m);
    if (m == Method::BiCGSTAB || m == Method::GMRES || m == Method::Auto) {
      EXPECT_LT(c.matvecs, 100) << to_string(m);
    }
  }
}

}  // namespace
}  // namespace lambert::solver

#include "lambert/verify/verify.hpp"

namespace lambert::solver {
using namespace lambert::verify;
namespace {

// A 1 km furnace room with a 1 mm cube floating in it (the study's `scale` case) must solve like the 1 m
// room: every quantity is scale-free, the speck's patches are added after the room's (so the ray seeds of
// the room's pairs are unchanged), and it blocks almost nothing. Tolerance: 2% of the 1 m error (the
// speck's own rays and rounding), and the speck's patches themselves within the room's error bound.
TEST(SolverHardCase, FurnaceSpanningMillimetreToKilometreSolvesLikeTheMetreRoom) {
  FurnaceCase unit;
  unit.divisions = 4;
  unit.block_divisions = 2;
  unit.rho = 0.9;
  unit.ff.rays_per_pair = 16;
  FurnaceCase huge = unit;
  huge.size = 1e3;
  huge.speck = 1e-3;
  const VerifyReport a = verify_furnace(unit), b = verify_furnace(huge);
  ASSERT_TRUE(a.converged && b.converged);
  EXPECT_EQ(b.patches, a.patches + 6);
  EXPECT_NEAR(b.max_rel_error, a.max_rel_error, 0.02 * a.max_rel_error) << a.table << b.table;
  EXPECT_NEAR(b.row_sum_max, a.row_sum_max, 1e-3) << "speck rows must sum to 1 like the room's";
  EXPECT_LE(b.max_rel_error, std::max(b.error_bound, a.max_rel_error) * 1.05) << b.table;
}

TEST(SolverHardCase, FurnaceScaleParametersAreValidated) {
  FurnaceCase c;
  c.size = 0;
  EXPECT_THROW(verify_furnace(c), InputError);
  c.size = 1;
  c.speck = 0.5;  // larger than 0.1 size: would not fit between the block and the walls
  EXPECT_THROW(verify_furnace(c), InputError);
}

}  // namespace
}  // namespace lambert::solver
