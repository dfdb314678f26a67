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
  const double *px, *py, *pz, *pw;  // outer-rule points (all tiers concatenated), weights sum to 1 per rule
  double eps;          // plane classification tolerance
};
constexpr int kBatchPad = 16;

// Pair codes written by classify(): 0 = culled by orientation, 1 + t = rule tier t (0 far field, 1 centroid +
// Hessian, 2..4 m x m Gauss) with i as source, plus kCodeSwap when j is the source (smaller area),
// kCodeSlow = scalar path (near, straddling or general polygon).
enum : std::int8_t { kCodeCulled = 0, kCodeSlow = 6, kCodeSwap = 8 };

// A-priori error model constants: 4 x the worst ratio |error| / (S r^p) seen on 40,000 random pairs of
// triangles, parallelograms and convex quads (target 1-3x the source, r = rho_s/d from 0.004 to 0.4, grazing
// angles included); index [tier][source centrally symmetric]. See tier_error() in internal.hpp.
constexpr double kTierConstant[5][2] = {{0.8, 1.3}, {0.6, 2.5}, {0.4, 0.5}, {0.06, 0.08}, {0.006, 0.011}};
constexpr double kMaxAreaRatio = 0.4;  // rho_s / d above this: always the scalar path (contour)

struct BatchKernels {
  const char* name;
  // Pairs (i, j), j in [j0, j1): val[j - j0] = F_ij (from i to j, whichever patch was the source) for tier
  // 0, else 0. Pairs needing more work (tiers 1-4, scalar path) are listed in rest_code / rest_j (capacity
  // j1 - j0); returns their number. counts[0..1] += pairs culled, tier 0. Reads up to 15
  // entries past j1 in the SoA (padding).
  int (*classify)(const SoA& s, int i, int j0, int j1, double tol, double* val, std::int8_t* rest_code, int* rest_j,
                  long long* counts);
  // out[k] = pw[p] * F(x_p -> quad t) for p = pidx[k], source normal of patch sidx[k], t = tidx[k].
  void (*eval_points)(const SoA& s, const int* pidx, const int* sidx, const int* tidx, int count, double* out);
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
