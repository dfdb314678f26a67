// Point-to-polygon kernel (Lambert's contour formula): conventions, degenerate inputs, clipping.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "../formfactor/src/internal.hpp"
#include "lambert/formfactor/exact.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/mesh/geometry.hpp"
#include "test_formfactor_util.hpp"

using namespace lambert;
using namespace lambert::formfactor;
using lambert::fftest::Poly;
using lambert::fftest::rect;

namespace {

// Brute-force point-to-polygon: midpoint rule on a fine grid of a convex quad (bilinear map), with both
// cosines clipped at zero. Error ~ 1/M^2 away from the tangent plane, ~1/M where the plane cuts the quad.
double brute_point_quad(const Vec3& x, const Vec3& n, const Poly& q, int M) {
  const Vec3 N = mesh::newell_normal(q).normalized();
  double s = 0;
  for (int a = 0; a < M; ++a)
    for (int b = 0; b < M; ++b) {
      const double u = (a + 0.5) / M, v = (b + 0.5) / M;
      const Vec3 X = (1 - u) * (1 - v) * q[0] + u * (1 - v) * q[1] + u * v * q[2] + (1 - u) * v * q[3];
      const Vec3 du = (1 - v) * (q[1] - q[0]) + v * (q[2] - q[3]), dv = (1 - u) * (q[3] - q[0]) + u * (q[2] - q[1]);
      const Vec3 d = X - x;
      const double r2 = d.squaredNorm(), cx = n.dot(d), cy = -N.dot(d);
      if (cx > 0 && cy > 0) s += cx * cy / (M_PI * r2 * r2) * du.cross(dv).norm() / (double(M) * M);
    }
  return s;
}

}  // namespace

// A point on the axis of a directly opposed square: closed form by symmetry from four corner rectangles
// (catalogue B-? differential element to a parallel rectangle, corner-aligned): F = sum of 4 identical
// terms with a = b = 0.5, c = 1. The tolerance is rounding (contour formula is exact).
TEST(FormFactorKernel, DifferentialElementToParallelSquareMatchesCatalogue) {
  const Poly P = rect(2, 1.0, -0.5, 0.5, -0.5, 0.5, /*front_positive=*/false);  // faces -z, towards the origin
  const double A = 0.5, B = 0.5, C = 1.0, X = A / C, Y = B / C;
  const double corner = (X / std::sqrt(1 + X * X) * std::atan(Y / std::sqrt(1 + X * X)) +
                         Y / std::sqrt(1 + Y * Y) * std::atan(X / std::sqrt(1 + Y * Y))) /
                        (2 * M_PI);
  EXPECT_NEAR(point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), P), 4 * corner, 1e-14);
}

TEST(FormFactorKernel, BackFacingIsZero) {
  const Poly facing_up = rect(2, 1.0, -0.5, 0.5, -0.5, 0.5, /*front_positive=*/true);  // front away from origin
  EXPECT_EQ(point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), facing_up), 0.0);
  const Poly facing_down = rect(2, 1.0, -0.5, 0.5, -0.5, 0.5, false);
  // The receiver looks away from the polygon: it is entirely behind the receiver's tangent plane.
  EXPECT_EQ(point_to_polygon(Vec3::Zero(), -Vec3::UnitZ(), facing_down), 0.0);
}

TEST(FormFactorKernel, CoplanarIsZero) {
  const Poly P = rect(2, 0.0, 1.0, 2.0, 0.0, 1.0, true);
  // Receiver in the polygon's plane, normal along the plane's normal or inside the plane.
  EXPECT_EQ(point_to_polygon(Vec3(0, 0.5, 0), Vec3::UnitZ(), P), 0.0);
  EXPECT_EQ(point_to_polygon(Vec3(0, 0.5, 0), Vec3::UnitX(), P), 0.0);
}

TEST(FormFactorKernel, FullyCoveringPolygonGivesOne) {
  // A huge square 1e-6 above the point covers the whole hemisphere but a sliver: F -> 1.
  const Poly P = rect(2, 1e-6, -1e3, 1e3, -1e3, 1e3, false);
  const double F = point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), P);
  EXPECT_NEAR(F, 1.0, 1e-12);
  EXPECT_LE(F, 1.0);
}

TEST(FormFactorKernel, DegenerateInputsStayFinite) {
  const Poly P = rect(2, 1.0, -0.5, 0.5, -0.5, 0.5, false);
  const double ref = point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), P);
  // Zero-length edge (repeated corner): same polygon, same value.
  Poly dup = P;
  dup.insert(dup.begin() + 2, dup[2]);
  EXPECT_NEAR(point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), dup), ref, 1e-15);
  // Receivers level with an edge or a corner of a perpendicular polygon (an edge's line can only pass
  // through x when x is in the polygon's plane, which is culled first; the |c| = 0 guard covers rounding).
  const Poly side = rect(0, 0.0, -1, 1, 0.5, 1.5, true);  // in the plane x = 0, facing +x
  for (const Vec3& x : {Vec3(1, -1, 0.5), Vec3(1, 1, 1.5), Vec3(1, 0, 0.5), Vec3(0.5, 0, 0.5)}) {
    const double F = point_to_polygon(x, -Vec3::UnitX(), side);
    EXPECT_TRUE(std::isfinite(F)) << x.transpose();
    EXPECT_GE(F, 0.0);
    EXPECT_LE(F, 1.0);
  }
  // Receiver exactly at a corner / on an edge of a perpendicular polygon.
  const Poly wall = rect(1, 0.0, 0, 1, 0, 1, true);  // plane y = 0, z and x in [0, 1], facing +y
  for (const Vec3& x : {Vec3(0, 0, 0), Vec3(0.5, 0, 0), Vec3(1, 0, 0)}) {
    const double F = point_to_polygon(x, Vec3::UnitY(), wall);
    EXPECT_TRUE(std::isfinite(F));
    EXPECT_GE(F, 0.0);
    EXPECT_LE(F, 1.0);
  }
  // Tiny and huge distances: relative accuracy against the far-field limit A cos cos / (pi r^2).
  for (double dist : {1e-9, 1e-3, 1e3, 1e8}) {
    const double h = 1e-4;
    const Poly small = rect(2, dist, -h / 2, h / 2, -h / 2, h / 2, false);
    const double F = point_to_polygon(Vec3::Zero(), Vec3::UnitZ(), small);
    EXPECT_TRUE(std::isfinite(F)) << dist;
    if (dist >= 1e3) {
      EXPECT_NEAR(F / (h * h / (M_PI * dist * dist)), 1.0, 1e-9) << dist;
    }
    if (dist <= 1e-9) {
      EXPECT_NEAR(F, 1.0, 1e-4) << dist;  // 1e-9 above a 1e-4 square: almost the hemisphere
    }
  }
  // NaN input does not propagate.
  EXPECT_EQ(point_to_polygon(Vec3(NAN, 0, 0), Vec3::UnitZ(), P), 0.0);
}

// Polygons straddling the receiver's tangent plane: the contour formula after clipping against a brute-force
// midpoint rule (2000^2 points; its error is dominated by the cut cells, ~1/M: tolerance 2e-4).
TEST(FormFactorKernel, StraddlingPolygonsMatchBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 6; ++trial) {
    const Vec3 x(U(rng) * 0.3, U(rng) * 0.3, U(rng) * 0.3);
    const Vec3 n = Vec3(U(rng), U(rng), 1.0).normalized();
    // A tilted quad above, facing down, cutting the receiver's tangent plane for most trials.
    Poly q = {{-1.5, -1.5, 0.2}, {-1.5, 1.5, 1.4}, {1.5, 1.5, 0.2}, {1.5, -1.5, -1.0}};
    const Vec3 off(U(rng), U(rng), 0.3);
    for (auto& v : q) v += off;
    const double F = point_to_polygon(x, n, q);
    const double ref = brute_point_quad(x, n, q, 2000);
    EXPECT_NEAR(F, ref, 2e-4) << "trial " << trial << " x " << x.transpose() << " n " << n.transpose();
  }
}

// clip_front's tolerance is a distance in the clipped polygon's plane from the line where it meets the clipping
// plane. A quad 0.5 m x 0.4 m tilted 6e-7 rad from the plane z = 0, crossing it along y = 0.1, with the corner at
// y = 0.1 - 1.7e-3 only 1e-9 behind (within eps = 2e-9): the part kept must be the part in front (area 0.5 x 0.3 m,
// analytic), to 1e-9 of it. Tested against eps as a height, that corner was kept and with it a triangle 1.7 mm wide
// and 0.5 m long behind the plane (area +2.5e-3 relative), whose negative cosines gave two wall patches of a model
// rounded to single precision F = -2.9e-9 against an error estimate of 7.7e-10 (the solve was refused). A quad
// crossing the plane at right angles keeps a corner 1e-9 behind as before (no sliver cut).
TEST(FormFactorKernel, ClipToleranceIsADistanceInThePolygonsPlane) {
  const double tilt = 6e-7, eps = 2e-9;
  const Vec3 n(0, 0, 1);
  auto height = [&](double y) { return (y - 0.1) * tilt; };  // z over the plane, 0 at y = 0.1
  const double y_near = 0.1 - 1e-9 / tilt;                      // 1e-9 behind
  const Poly quad = {{0, y_near, height(y_near)}, {0.5, -0.3, height(-0.3)}, {0.5, 0.4, height(0.4)},
                     {0, 0.4, height(0.4)}};
  std::vector<Vec3> kept;
  detail::clip_front(quad, n, 0.0, eps, kept);
  ASSERT_GE(kept.size(), 3u);
  const double area = 0.5 * mesh::newell_normal(kept).norm();
  // The part with y >= 0.1 of the quad (x from 0 to 0.5): the trapezoid's edge from (0, y_near) to (0.5, -0.3)
  // lies below y = 0.1, so the kept part is the rectangle [0, 0.5] x [0.1, 0.4] (up to the tilt's cosine, 1e-13).
  EXPECT_NEAR(area, 0.5 * 0.3, 1e-9 * 0.15) << "kept " << kept.size() << " corners";
  for (const Vec3& v : kept) EXPECT_GE(v.z(), -1e-15) << "corner " << v.transpose() << " behind the plane";
  // At right angles: a corner 1e-9 behind is on the plane, nothing is cut.
  const Poly wall = {{0, 0, -1e-9}, {1, 0, -1e-9}, {1, 0, 1}, {0, 0, 1}};
  detail::clip_front(wall, n, 0.0, eps, kept);
  EXPECT_EQ(kept.size(), 4u);
}

// A 2 cm triangle and a ceiling patch 5.5 m away that crosses the triangle's plane by about 1.4e-6 m at one corner
// (the floor plan turned and stored as a single-precision STL): clipped to the triangle's front, the patch is a few
// micrometres across. Its double contour integral cancels ln r over nearly equal distances, so its value is noise of
// ~1e-13 from the corners' last bits: in the STL it came out as F = -6.5e-14 with an error estimate of 4e-14, which
// the checks took as a wrong entry, refusing the model. The pair lies within A' / (pi d^2) (both cosines at most 1),
// below 1e-12 here: over 400 placements of the patch (its corners moved by whole ulps), F must lie in [0, 1e-12]
// within its own error estimate.
TEST(FormFactorKernel, TinyClippedPieceFarAwayStaysWithinItsBound) {
  const Poly s = {{-1.924999832582624, -0.950000255732520, 0.930000036954880},
                  {-1.899999673577085, -0.950000254141446, 0.930000036954880},
                  {-1.899999673577055, -0.950000254141446, 0.907894636989832}};
  int wrong = 0;
  for (int k = 0; k < 400; ++k) {
    const double dy = std::ldexp(double(k % 20 - 10), -52), dx = std::ldexp(double(k / 20 - 10), -50);
    const Poly t = {{3.625000488820581 + dx, -0.949998885682143 + dy, 1.350000023841858},
                    {3.625000665922767, -1.049999005512983, 1.350000023841858},
                    {3.400000652545947, -1.049999138981497, 1.350000023841858}};
    const auto r = polygon_to_polygon(s, t, 1e-8);
    if ((r.F + r.error_estimate < 0 || r.F - r.error_estimate > 1e-12) && wrong++ < 5)
      ADD_FAILURE() << "placement " << k << ": F " << r.F << " +- " << r.error_estimate << " (" << r.method << ")";
  }
  EXPECT_EQ(wrong, 0) << "of 400 placements";
}

TEST(FormFactorKernel, NonConvexPolygonEqualsSumOfItsParts) {
  // L-shaped hexagon = union of two rectangles; the contour formula is additive (tolerance: rounding).
  const Poly L = {{0, 0, 1}, {0, 2, 1}, {1, 2, 1}, {1, 1, 1}, {2, 1, 1}, {2, 0, 1}};  // faces -z
  const Poly A = {{0, 0, 1}, {0, 2, 1}, {1, 2, 1}, {1, 0, 1}};
  const Poly B = {{1, 0, 1}, {1, 1, 1}, {2, 1, 1}, {2, 0, 1}};
  for (const Vec3& x : {Vec3(0.3, 0.4, 0), Vec3(1.5, 1.5, 0.5), Vec3(-1, 3, 0.9)}) {
    for (const Vec3& n : {Vec3(0, 0, 1), Vec3(0.6, 0, 0.8)}) {
      EXPECT_NEAR(point_to_polygon(x, n, L), point_to_polygon(x, n, A) + point_to_polygon(x, n, B), 1e-14)
          << x.transpose();
    }
  }
}

// The kernel's own atan2 (internal.hpp, the SIMD kernels' rational approximation) against long-double atan2l:
// within 2 ulp of the true angle for z >= 0 over 12 decades of |z| and |w| and both signs of w, and exact at the
// axes. 2 ulp, because the approximation is ~1 ulp and the kernel's contour sums are checked to 1e-12 elsewhere;
// a wrong coefficient or branch gives errors of 1e-10 or more.
TEST(Kernel, Atan2WithinTwoUlpOfLongDouble) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  double worst = 0;
  double wz = 0, ww = 0;
  for (int k = 0; k < 2000000; ++k) {
    const double z = std::abs(u(rng)) * std::pow(10.0, 6 * u(rng)), w = u(rng) * std::pow(10.0, 6 * u(rng));
    const long double ref = atan2l(static_cast<long double>(z), static_cast<long double>(w));
    const double err = double(std::abs(static_cast<long double>(detail::atan2_pos(z, w)) - ref) / ref);
    if (err > worst) worst = err, wz = z, ww = w;
  }
  EXPECT_LE(worst, 2 * 0x1.0p-52) << "worst at z = " << wz << ", w = " << ww;
  EXPECT_EQ(detail::atan2_pos(0, 1), 0.0);
  EXPECT_EQ(detail::atan2_pos(1, 0), M_PI / 2);
  EXPECT_EQ(detail::atan2_pos(0, -1), M_PI);
  EXPECT_EQ(detail::atan2_pos(0, 0), 0.0);
}

// The hierarchy's leaf pairs evaluate the outer Gauss rules with the SIMD point kernel (detail::PointSoA); the scalar
// path sums the same points one at a time. Random triangles, parallelograms, trapezoids and an L-shaped hexagon
// (scalar only) at distances from touching to far, at a loose and a tight tolerance (rules of 4 to 64 points,
// prepared and mapped per pair): the same method, and F within 1e-13 relative (the two evaluate the same analytic
// contour sum with atan2 implementations that differ by a few ulp).
TEST(Kernel, LeafRulesInSimdMatchThePointsOneAtATime) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1), Us(0.2, 1.5);
  std::vector<std::vector<Vec3>> polys;
  for (int k = 0; k < 40; ++k) {
    // On spheres of radius 1.5 to 6 about the origin, facing it (most pairs see each other).
    const Vec3 dir = Vec3(U(rng), U(rng), U(rng)).normalized();
    const Vec3 c = dir * (1.5 + 4.5 * (U(rng) + 1) / 2);
    Vec3 a = dir.cross(Vec3(U(rng), U(rng), U(rng))).normalized() * Us(rng);
    Vec3 b = a.cross(dir).normalized() * Us(rng);  // (a, b, -dir) right-handed: the front faces the origin
    switch (k % 4) {
      case 0: polys.push_back({c, c + a, c + b}); break;
      case 1: polys.push_back({c, c + a, c + a + b, c + b}); break;
      case 2: polys.push_back({c, c + a, c + 0.6 * a + b, c + 0.3 * a + b}); break;
      default: {
        const Vec3 u = a.normalized(), v = b.normalized();
        polys.push_back({c, c + 2 * u, c + 2 * u + v, c + u + v, c + u + 2 * v, c + 2 * v});
      }
    }
  }
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(polys);
  const detail::PatchData P = detail::prepare(g);
  const detail::PointSoA soa(P);
  long long compared = 0, simd = 0;
  std::array<long long, detail::kMethodCount> by{};
  for (const double tol : {1e-3, 1e-9})
    for (int s = 0; s < g.size(); ++s)
      for (int t = 0; t < g.size(); ++t) {
        if (s == t) continue;
        const detail::PairEval a = detail::pair_scalar(P, s, t, tol), b = detail::pair_scalar(P, soa, s, t, tol);
        ASSERT_EQ(a.method, b.method) << "pair " << s << ", " << t;
        EXPECT_NEAR(b.F, a.F, 1e-13 * std::abs(a.F)) << "pair " << s << ", " << t << " method "
                                                      << detail::kMethodNames[a.method] << " tolerance " << tol;
        ++by[size_t(a.method)];
        ++compared;
        simd += a.method >= detail::kGauss4 && a.method <= detail::kGauss64 && P.kind[size_t(t)] <= 2;
      }
  for (int m : {detail::kGauss4, detail::kGauss9, detail::kGauss16, detail::kGauss36, detail::kGauss64})
    EXPECT_GT(by[size_t(m)], 0) << detail::kMethodNames[m] << " never taken";
  EXPECT_GT(simd, 500) << "of " << compared;
}
