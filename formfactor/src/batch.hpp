#pragma once
// SIMD kernels over many pairs at once, compiled once per instruction set (src/isa/batch.cpp) and picked at
// run time, so the default build runs AVX-512 or AVX2 code where the CPU has it.
#include <cstdint>

namespace lambert::formfactor::detail {

// Per-patch arrays (structure of arrays), padded with kBatchPad readable entries after the last patch.
// Quads: corners q*[0..3]; triangles repeat corner 2 as corner 3 (a zero-length edge adds nothing).
struct SoA {
  const double *cx, *cy, *cz, *nx, *ny, *nz, *off, *area, *rho;
  const double *qx[4], *qy[4], *qz[4];
  const double* M[6];  // second moments / area: xx yy zz xy xz yz
  const double* fast;  // 1 for triangles and convex quads, 0 for polygons that need the scalar path
  const double* sym;   // 1 for parallelograms (centrally symmetric)
  double eps;          // plane classification tolerance
};
constexpr int kBatchPad = 16;

// Pair codes written by classify(): 0 = culled by orientation, 1 + t = rule tier t (0 far field, 1 centroid +
// Hessian, 2..6 m x m Gauss with m = kTierM[t]) with i as source, plus kCodeSwap when j is the source
// (smaller area), kCodeSlow = scalar path (near, straddling or general polygon).
enum : std::int8_t { kCodeCulled = 0, kCodeSlow = 15, kCodeSwap = 16 };
constexpr int kTiers = 7;
constexpr int kTierM[kTiers] = {0, 1, 2, 3, 4, 6, 8};  // Gauss points per direction for tiers 2..6

// A-priori error model constants: 4 x the worst ratio |error| / (S r^p) seen on 40,000 random pairs of
// triangles, parallelograms and convex quads (target 1-3x the source, r = rho_s/d from 0.004 to 0.6, grazing
// angles included); index [tier][source centrally symmetric]. For 6x6 and 8x8 Gauss, whose errors mostly sat
// at rounding level, 7x and 70x the worst measurable ratio. See tier_error() in internal.hpp.
constexpr double kTierConstant[kTiers][2] = {{0.8, 1.3}, {0.6, 2.5}, {0.4, 0.5},   {0.07, 0.09},
                                             {0.008, 0.012}, {1e-4, 1e-4}, {1e-6, 1e-6}};
constexpr double kMaxAreaRatio = 0.5;  // rho_s / d above this: always the scalar path (contour)

struct BatchKernels {
  const char* name;
  // Pairs (i, j), j in [j0, j1): val[j - j0] = F_ij (from i to j, whichever patch was the source) for tier
  // 0, else 0. Pairs needing more work (tiers 1-4, scalar path) are listed in rest_code / rest_j (capacity
  // j1 - j0); returns their number. counts[0..1] += pairs culled, tier 0. Reads up to 15
  // entries past j1 in the SoA (padding).
  int (*classify)(const SoA& s, int i, int j0, int j1, double tol, double* val, std::int8_t* rest_code, int* rest_j,
                  long long* counts);
  // out[k] = w[k] * F(x_k -> quad t) for the point x_k = (x[k], y[k], z[k]) with the normal of patch sidx[k],
  // t = tidx[k] (outer-rule points with their weights).
  void (*eval_points)(const SoA& s, const double* x, const double* y, const double* z, const double* w,
                      const int* sidx, const int* tidx, int count, double* out);
  // out[k] = F(c_s -> quad t) + Hessian correction (tier 1), s = sidx[k], t = tidx[k].
  void (*eval_centroid)(const SoA& s, const int* sidx, const int* tidx, int count, double* out);
  // F(j, i) = F(i, j) A_i / A_j for i in [i0, i1), j in [j0, j1) (j > i if diag) in a row-major matrix with
  // the given row stride; row_i / row_j accumulate row sums of rows i / j, outside counts entries outside
  // [0, 1], recip is the running maximum of |A_i F_ij - A_j F_ji| / max(A_i F_ij, A_j F_ji).
  void (*transpose)(const double* area, double* F, long long stride, int i0, int i1, int j0, int j1, bool diag,
                    double* row_i, double* row_j, long long* outside, double* recip);
};

const BatchKernels& batch_kernels();  // the best variant this CPU supports
const BatchKernels& batch_kernels_avx512();
const BatchKernels& batch_kernels_avx2();
const BatchKernels& batch_kernels_generic();

}  // namespace lambert::formfactor::detail
