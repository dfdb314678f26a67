// The near-pair contour's inner edge integral (formfactor/src/batch.hpp, edge_log): int_0^1 ln |w0 + s u - t v| dt
// in closed form, evaluated up to 8 points at a time with the kernels' own logarithm, against the same antiderivative
// in long double with the C library's logl and atan2l.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "../formfactor/src/batch.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert {
namespace {

namespace fd = formfactor::detail;

std::vector<const fd::BatchKernels*> supported_kernels() {
  std::vector<const fd::BatchKernels*> v{&fd::batch_kernels_generic()};
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) v.push_back(&fd::batch_kernels_avx2());
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")) v.push_back(&fd::batch_kernels_avx512());
  return v;
}

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

}  // namespace
}  // namespace lambert
