// The tolerance guarantee: |F_ij - exact| <= tolerance for random pairs, near and far, through both the
// scalar path (polygon_to_polygon) and the SIMD assembly path, against independent references.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/exact.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "test_formfactor_util.hpp"

using namespace lambert;
using namespace lambert::formfactor;
using lambert::fftest::Poly;
using lambert::fftest::rect;

namespace {

// Reference for a pair that does not touch: collapsed m x m Gauss on each source triangle with the analytic
// inner integral; converges geometrically (checked against m = 48 where it is used).
double smooth_reference(const Poly& src, const Poly& tgt, int m = 64) {
  std::vector<double> x, w;
  fftest::gauss01(m, x, w);
  const Vec3 n = mesh::newell_normal(src).normalized();
  double total = 0, area = 0;
  for (size_t k = 1; k + 1 < src.size(); ++k) {  // fan: sources here are convex
    const Vec3 &a = src[0], &b = src[k], &c = src[k + 1];
    const double At = 0.5 * (b - a).cross(c - a).norm();
    double s = 0;
    for (int p = 0; p < m; ++p)
      for (int q = 0; q < m; ++q) {
        const double u = x[p], t = x[q];
        s += w[p] * w[q] * 2 * (1 - t) * point_to_polygon((1 - t) * ((1 - u) * a + u * b) + t * c, n, tgt);
      }
    total += s * At;
    area += At;
  }
  return total / area;
}

// F from both directions via the two public paths.
struct Both {
  double scalar_ij, scalar_ji, simd_ij, simd_ji;
  std::string method;
};
Both compute(const Poly& P, const Poly& Q, double tol) {
  Both b;
  const PairResult r = polygon_to_polygon(P, Q, tol);
  b.scalar_ij = r.F;
  b.scalar_ji = r.F_reverse;
  b.method = r.method;
  Options o;
  o.tolerance = tol;
  o.visibility = false;
  const auto F = assemble(mesh::PatchGeometry::from_polygons({P, Q}), o).matrix();
  b.simd_ij = F(0, 1);
  b.simd_ji = F(1, 0);
  return b;
}

double area(const Poly& p) { return 0.5 * mesh::newell_normal(p).norm(); }

}  // namespace

// Random aligned rectangles (parallel and perpendicular, any offset, touching or not) against the closed
// forms, at three tolerances: every result within the tolerance.
TEST(FormFactorAccuracy, RandomRectanglesWithinTolerance) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0, 1);
  for (double tol : {1e-6, 1e-8, 1e-10}) {
    double worst = 0;
    for (int trial = 0; trial < 60; ++trial) {
      const double s1 = 0.05 + U(rng), s2 = 0.05 + U(rng), t1 = 0.05 + U(rng), t2 = 0.05 + U(rng);
      const double ox = 2 * U(rng) - 1, oy = 2 * U(rng) - 1;
      double ref;
      Poly P, Q;
      if (trial % 2 == 0) {
        // Parallel, distance from 0.01 to 3 (log-uniform).
        const double c = 0.01 * std::pow(300.0, U(rng));
        P = rect(2, 0, 0, s1, 0, t1, true);
        Q = rect(2, c, ox, ox + s2, oy, oy + t2, false);
        ref = exact::parallel_rectangles(0, s1, 0, t1, ox, ox + s2, oy, oy + t2, c);
      } else {
        // Perpendicular, sharing the edge line; every third one touching it, others lifted off it.
        const double z0 = trial % 3 == 0 ? 0.0 : 0.3 * U(rng), y0 = trial % 3 == 0 ? 0.0 : 0.3 * U(rng);
        P = rect(1, 0, z0, z0 + t1, 0, s1, true);  // y = 0: z in [z0, z0+t1], x in [0, s1]
        Q = rect(2, 0, ox, ox + s2, y0, y0 + t2, true);
        ref = exact::perpendicular_rectangles(0, s1, z0, z0 + t1, ox, ox + s2, y0, y0 + t2);
      }
      const double ref_back = ref * area(P) / area(Q);
      const Both b = compute(P, Q, tol);
      EXPECT_NEAR(b.scalar_ij, ref, tol) << "trial " << trial << " method " << b.method;
      EXPECT_NEAR(b.scalar_ji, ref_back, tol) << "trial " << trial << " method " << b.method;
      EXPECT_NEAR(b.simd_ij, ref, tol) << "trial " << trial;
      EXPECT_NEAR(b.simd_ji, ref_back, tol) << "trial " << trial;
      worst = std::max({worst, std::abs(b.scalar_ij - ref), std::abs(b.simd_ij - ref)});
    }
    RecordProperty("worst_at_tol_" + std::to_string(tol), std::to_string(worst));
  }
}

// Random triangles and quads at random poses, 0.5 to 30 sizes apart, facing each other: the a-priori rule
// selection (far field, Hessian-corrected centroid, Gauss 2x2..4x4) and the contour method stay within the
// tolerance. This is the check on the calibrated error-model constants.
TEST(FormFactorAccuracy, RandomPolygonPairsWithinTolerance) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> U(-1, 1);
  int checked = 0;
  std::map<std::string, int> methods;
  for (int trial = 0; checked < 120 && trial < 2000; ++trial) {
    auto make = [&](const Vec3& c, const Vec3& n, double size, int corners) {
      const Vec3 e1 = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized(), e2 = n.cross(e1);
      Poly p;
      if (corners == 4) {  // parallelogram
        const double sk = 0.4 * U(rng), w = 0.6 + 0.4 * U(rng), h = 0.6 + 0.4 * U(rng);
        for (auto [a, b] : {std::pair{-1.0, -1.0}, {1.0, -1.0}, {1.0, 1.0}, {-1.0, 1.0}})
          p.push_back(c + size * ((a * w + sk * b) * e1 + b * h * e2));
      } else {
        for (int k = 0; k < 3; ++k) {
          const double t = 2 * M_PI * k / 3 + 0.5 * U(rng), r = 0.7 + 0.3 * U(rng);
          p.push_back(c + size * r * (std::cos(t) * e1 + std::sin(t) * e2));
        }
      }
      return p;
    };
    const Vec3 nP = Vec3(0, 0, 1);
    const Poly P = make(Vec3::Zero(), nP, 1.0, trial % 2 ? 4 : 3);
    const double dist = 0.5 * std::pow(60.0, (U(rng) + 1) / 2);
    const Vec3 dir = Vec3(U(rng), U(rng), 0.3 + std::abs(U(rng))).normalized();
    Vec3 nQ = Vec3(U(rng), U(rng), U(rng)).normalized();
    if (nQ.dot(dir) > -0.2) nQ = (nQ - 2 * nQ.dot(dir) * dir).normalized();
    const Poly Q = make(dist * dir, nQ, 0.5 + 1.5 * (U(rng) + 1) / 2, trial % 3 ? 4 : 3);
    // Both strictly in front of each other (straddling pairs are tested elsewhere).
    bool ok = true;
    for (const Vec3& v : Q) ok = ok && nP.dot(v) > 1e-3;
    for (const Vec3& v : P) ok = ok && nQ.dot(v - Q[0]) > 1e-3;
    if (!ok) continue;
    ++checked;
    const double tol = 1e-8;
    const bool p_smaller = area(P) <= area(Q);
    const Poly& S = p_smaller ? P : Q;
    const Poly& T = p_smaller ? Q : P;
    const double ref_st = smooth_reference(S, T);
    ASSERT_NEAR(smooth_reference(S, T, 48), ref_st, 1e-12) << "reference not converged, trial " << trial;
    const double ref_PQ = p_smaller ? ref_st : ref_st * area(S) / area(T);
    const double ref_QP = ref_PQ * area(P) / area(Q);
    const Both b = compute(P, Q, tol);
    ++methods[b.method];
    EXPECT_NEAR(b.scalar_ij, ref_PQ, tol) << "trial " << trial << " dist " << dist << " method " << b.method;
    EXPECT_NEAR(b.scalar_ji, ref_QP, tol) << "trial " << trial << " dist " << dist << " method " << b.method;
    EXPECT_NEAR(b.simd_ij, ref_PQ, tol) << "trial " << trial << " dist " << dist;
    EXPECT_NEAR(b.simd_ji, ref_QP, tol) << "trial " << trial << " dist " << dist;
  }
  EXPECT_EQ(checked, 120);
  EXPECT_GE(methods.size(), 4u) << "the sample should exercise several methods";
}

// Adjacent pairs: triangles sharing an edge at dihedral angles from 30 to 150 degrees, and sharing only a
// corner, against the graded high-order reference (outer integral graded towards the shared edge/corner,
// analytic inner: independent of the contour method). Tolerance: the default 1e-8 plus the reference's own
// error (~1e-10).
TEST(FormFactorAccuracy, AdjacentPairsMatchHighOrderReference) {
  const double tol = 1e-8;
  const Vec3 a(0, 0, 0), b(1, 0, 0);
  for (double deg : {30.0, 60.0, 90.0, 120.0, 150.0}) {
    const double t = deg * M_PI / 180;
    // Source in z = 0 facing +z; target hinged on the x axis, opened by the dihedral angle, facing the source.
    const Poly S = {a, b, Vec3(0.3, 0.8, 0)};
    const Vec3 dirT(0, std::cos(t), std::sin(t));
    const Poly T = {b, a, Vec3(0.6, 0, 0) + 0.9 * dirT};
    const Vec3 nT = mesh::newell_normal(T).normalized();
    ASSERT_GT(nT.dot(S[2] - a), 0) << "target must face the source";
    const double ref = fftest::graded_triangle_source(S[0], S[1], S[2], T);
    const PairResult r = polygon_to_polygon(S, T, tol);
    const double Fst = area(S) <= area(T) ? r.F : r.F;  // r.F is always F from the first argument
    EXPECT_NEAR(Fst, ref, tol + 1e-10) << deg << " deg, method " << r.method;
    EXPECT_EQ(r.method, "contour");
  }
  // Corner-sharing: the target touches the source only at a.
  for (double deg : {45.0, 90.0, 135.0}) {
    const double t = deg * M_PI / 180;
    const Poly S = {b, Vec3(0.3, 0.8, 0), a};  // corner a last: graded_triangle_source grades at edge (S0,S1)
                                               // and corner S2
    const Vec3 dirT(0, std::cos(t), std::sin(t));
    const Poly T = {a, Vec3(-0.8, 0, 0) + 0.1 * dirT, Vec3(-0.2, 0, 0) + 0.9 * dirT};
    const Vec3 nT = mesh::newell_normal(T).normalized();
    const Poly Tf = nT.dot(Vec3(0.4, 0.3, 0) - a) > 0 ? T : Poly{T[0], T[2], T[1]};
    const double ref = fftest::graded_triangle_source(S[0], S[1], S[2], Tf);
    const PairResult r = polygon_to_polygon(S, Tf, tol);
    EXPECT_NEAR(r.F, ref, tol + 1e-10) << deg << " deg corner, method " << r.method;
  }
}

// Pairs whose planes cut each other (each straddles the other's plane): only the parts in front count.
// Reference: the source clipped exactly at the target's plane (the line y = 0.5), then the graded outer
// rule with point_to_polygon (which clips the target by each receiver's plane) on the two triangles of the
// clipped part, graded towards the cut. Independent of the contour method; agrees to ~1e-12.
TEST(FormFactorAccuracy, StraddlingPairsMatchBruteForce) {
  const Vec3 O(0, 0, 0), X(1, 0, 0), A(0.25, 0.5, 0), B(0.75, 0.5, 0);
  const Poly S = {O, X, Vec3(0.5, 1, 0)};  // area 1/2, facing +z; the part y < 0.5 is the quad O X B A
  for (double tilt : {0.3, 1.0, 2.0}) {
    const Vec3 n = Vec3(0, -1, tilt).normalized();  // target plane through the line y = 0.5, z = 0
    const Poly T = fftest::regular_polygon(Vec3(0.5, 0.5, 0), n, 0.9, 4, 0.2);
    const double f1 = fftest::graded_triangle_source(B, A, O, T), a1 = 0.5 * (A - B).cross(O - B).norm();
    const double f2 = fftest::graded_triangle_source(O, X, B, T), a2 = 0.5 * (X - O).cross(B - O).norm();
    const double ref = (f1 * a1 + f2 * a2) / 0.5;
    const PairResult r = polygon_to_polygon(S, T);
    EXPECT_NEAR(r.F, ref, default_tolerance(-1)) << "tilt " << tilt << " method " << r.method;
    EXPECT_GT(r.F, 1e-3);
  }
}
