// The contour kernels of formfactor/src/batch.hpp against the same formulas in long double with the C library's logl
// and atan2l: edge_log, the near-pair contour's inner edge integral int_0^1 ln |w0 + s u - t v| dt in closed form (up
// to 8 points at a time, the kernels' own logarithm), and contour_sum, Lambert's contour sum of a polygon seen from a
// point (its edges in the lanes).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "batch_kernels_util.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert {
namespace {

namespace fd = formfactor::detail;

using batchtest::supported_kernels;

// The reference and the size of its terms (what rounding in double is relative to).
struct Ref {
  long double value, scale;
};
Ref reference(const Vec3& w0, const Vec3& u, const Vec3& v, double s) {
  const long double wx = (long double)w0.x() + (long double)s * u.x(), wy = (long double)w0.y() + (long double)s * u.y(),
                    wz = (long double)w0.z() + (long double)s * u.z();
  const long double vx = v.x(), vy = v.y(), vz = v.z();
  const long double L = sqrtl(vx * vx + vy * vy + vz * vz);
  const long double wv = (wx * vx + wy * vy + wz * vz) / L;
  const long double cx = wy * vz - wz * vy, cy = wz * vx - wx * vz, cz = wx * vy - wy * vx;
  const long double d2 = (cx * cx + cy * cy + cz * cz) / (L * L), d = sqrtl(d2);
  auto G = [&](long double sg) {
    long double g = -2 * sg;
    if (sg != 0) g += sg * logl(sg * sg + d2);
    if (d > 0) g += 2 * d * atan2l(sg, d);
    return g;
  };
  const long double hi = G(L - wv), lo = G(-wv);
  return {(hi - lo) / (2 * L), (fabsl(hi) + fabsl(lo) + 2 * L) / (2 * L)};
}

// Random edges at unit scale (as contour_pair scales them) and at 1e-3 and 1e3 of it, points on the line of v
// (d = 0), at its ends (sigma = 0) and far from it. Tolerance 1.5e-14 of the terms' size: the same formula in double
// with the C library's log (the scalar code this kernel replaced) is 4.3e-15 off on these inputs, and the AVX2 and
// AVX-512 builds 7.6e-15 (FMA contraction); a logarithm wrong in its last digits of ln 2 is 1e-5 off.
TEST(ContourKernel, EdgeLogMatchesTheAntiderivativeInLongDouble) {
  for (const fd::BatchKernels* K : supported_kernels()) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(-1, 1);
    double worst = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      const double scale = trial % 3 == 0 ? 1.0 : trial % 3 == 1 ? 1e-3 : 1e3;
      Vec3 u(U(rng), U(rng), U(rng)), v(U(rng), U(rng), U(rng)), w0(U(rng), U(rng), U(rng));
      const int kind = (trial / 3) % 4;
      if (kind == 1) w0 = 0.37 * v, u = -0.8 * v;  // on the line of v: d = 0, sigma through 0
      if (kind == 2) w0 = v, u = Vec3(U(rng), U(rng), U(rng));  // starts at v's far end
      if (kind == 3) w0 *= 40;                                     // far away
      u *= scale, v *= scale, w0 *= scale;
      const double L = v.norm();
      const int count = 1 + trial % 16;
      std::vector<double> s(static_cast<size_t>(count)), out(static_cast<size_t>(count));
      for (int k = 0; k < count; ++k) s[size_t(k)] = k == 0 && kind != 3 ? 0.0 : 0.5 * (U(rng) + 1);
      K->edge_log(w0.data(), u.data(), v.data(), L, 1.0 / L, s.data(), count, out.data());
      for (int k = 0; k < count; ++k) {
        const Ref r = reference(w0, u, v, s[size_t(k)]);
        const double err = double(fabsl((long double)out[size_t(k)] - r.value) / r.scale);
        worst = std::max(worst, err);
        if (!(err <= 1.5e-14))
          ADD_FAILURE() << K->name << " trial " << trial << " kind " << kind << " point " << k << " of " << count
                        << ": s = " << s[size_t(k)] << ", got " << out[size_t(k)] << ", want " << double(r.value)
                        << " (relative to the terms " << err << ")";
      }
    }
    std::printf("%s: largest error %.2e of the terms' size\n", K->name, worst);
  }
}

// Random polygons of 3 to 21 corners (star-shaped about a centre, in a random plane, some corners repeated: zero-length
// edges) seen from random points in front, behind, in the polygon's plane (|c| = 0 for edges on a line through x) and
// far away. Reference: sum_k atan2(|c_k|, a_k . b_k) n . c_k / |c_k| in long double. Tolerance 1e-14 of the sum of the
// terms' magnitudes plus 0.04 (each term within a few ulp of its size, and within a few ulp of pi where its angle
// comes from an atan2 of two rounded numbers: a point in the polygon's plane, whose terms cancel to 1e-17, came out
// 1.2e-16, 4e-16 absolute at most). A polygon whose closing edge is left out is 0.9 off.
TEST(ContourKernel, ContourSumMatchesLambertsFormulaInLongDouble) {
  for (const fd::BatchKernels* K : supported_kernels()) {
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> U(-1, 1);
    double worst = 0;
    for (int trial = 0; trial < 4000; ++trial) {
      const int m = 3 + trial % 19;
      const Vec3 c(U(rng), U(rng), U(rng)), t1 = Vec3(U(rng), U(rng), U(rng)).normalized();
      const Vec3 t2 = t1.cross(Vec3(U(rng), U(rng), U(rng))).normalized();
      std::vector<Vec3> poly;
      for (int k = 0; k < m; ++k) {
        if (k > 0 && trial % 5 == 0 && k % 4 == 0) {
          poly.push_back(poly.back());
          continue;
        }
        const double ang = 2 * 3.14159265358979 * (k + 0.4 * (U(rng) + 1) / 2) / m, r = 0.3 + 0.7 * (U(rng) + 1) / 2;
        poly.push_back(c + r * (std::cos(ang) * t1 + std::sin(ang) * t2));
      }
      const Vec3 nrm = t1.cross(t2);
      const int kind = trial % 4;
      Vec3 x = c + 0.5 * U(rng) * t1 + 0.5 * U(rng) * t2 + (0.1 + (U(rng) + 1)) * nrm;
      if (kind == 1) x = c + 0.8 * U(rng) * t1 - (0.1 + (U(rng) + 1)) * nrm;  // behind
      if (kind == 2) x = poly[0] + 0.5 * (poly[0] - poly[1]);                  // on the line of the first edge
      if (kind == 3) x = c + 50 * Vec3(U(rng), U(rng), U(rng));               // far
      const Vec3 n = Vec3(U(rng), U(rng), U(rng)).normalized();
      const double got = K->contour_sum(x.data(), n.data(), poly.data()->data(), m);
      long double want = 0, mag = 0;
      for (int k = 0; k < m; ++k) {
        const Vec3 &p = poly[size_t(k)], &q = poly[size_t((k + 1) % m)];
        const long double ax = (long double)p.x() - x.x(), ay = (long double)p.y() - x.y(), az = (long double)p.z() - x.z();
        const long double ex = (long double)q.x() - p.x(), ey = (long double)q.y() - p.y(), ez = (long double)q.z() - p.z();
        const long double bx = (long double)q.x() - x.x(), by = (long double)q.y() - x.y(), bz = (long double)q.z() - x.z();
        const long double cx = ay * ez - az * ey, cy = az * ex - ax * ez, cz = ax * ey - ay * ex;
        const long double cn = sqrtl(cx * cx + cy * cy + cz * cz);
        if (!(cn > 0)) continue;
        const long double term = atan2l(cn, ax * bx + ay * by + az * bz) * (n.x() * cx + n.y() * cy + n.z() * cz) / cn;
        want += term;
        mag += fabsl(term);
      }
      const double err = double(fabsl((long double)got - want) / (mag + 0.04L));
      worst = std::max(worst, err);
      if (!(err <= 1e-14))
        ADD_FAILURE() << K->name << " trial " << trial << " kind " << kind << " (" << m << " corners): got " << got
                      << ", want " << double(want) << " (relative to the terms " << err << ")";
    }
    std::printf("%s: largest error %.2e of the terms' size\n", K->name, worst);
  }
}

}  // namespace
}  // namespace lambert
