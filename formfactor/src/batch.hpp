#pragma once
// SIMD kernels over many pairs at once, compiled once per instruction set (src/isa/batch.cpp) and picked at
// run time, so the default build runs AVX-512 or AVX2 code where the CPU has it.
#include <cstdint>

#include "tiers.hpp"

namespace lambert::formfactor::detail {

// Per-patch arrays (structure of arrays), padded with kBatchPad readable entries after the last patch.
// Quads: corners q*[0..3]; triangles repeat corner 2 as corner 3 (a zero-length edge adds nothing).
struct SoA {
  const double *cx, *cy, *cz, *nx, *ny, *nz, *off, *area, *radius;  // radius: circumradius about the centroid
  const double *qx[4], *qy[4], *qz[4];
  const double* M[6];  // second moments / area: xx yy zz xy xz yz
  const double* fast;  // 1 for triangles and convex quads, 0 for polygons that need the scalar path
  const double* sym;   // 1 for parallelograms (centrally symmetric)
  const double* rerr;  // the tiers' source radius (PatchData::rerr)
  double eps;          // plane classification tolerance
};
constexpr int kBatchPad = 16;

// Pair codes written by classify(): 0 = culled by orientation, 1 + t = rule tier t (0 far field, 1 centroid +
// Hessian, 2..6 m x m Gauss with m = kTierM[t]) with i as source, plus kCodeSwap when j is the source
// (smaller area), kCodeSlow = scalar path (near, straddling or general polygon).
enum : std::int8_t { kCodeCulled = 0, kCodeSlow = 15, kCodeSwap = 16 };

struct BatchKernels {
  const char* name;
  // Pairs (i, j), j in [j0, j1): val[j - j0] = F_ij (from i to j, whichever patch was the source) for tier
  // 0, else 0; err[j - j0] = the error bound on F_ij of the chosen tier (0 for culled and scalar-path pairs);
  // code[j - j0] = the pair code (tier 0 included). Pairs needing more work (tiers 1-6, scalar path) are also
  // listed in rest_code / rest_j (capacity j1 - j0); returns their number. counts[0..1] += pairs culled,
  // tier 0. Reads up to 15 entries past j1 in the SoA (padding).
  int (*classify)(const SoA& s, int i, int j0, int j1, double tol, double* val, double* err, std::int8_t* code,
                  std::int8_t* rest_code, int* rest_j, long long* counts);
  // out[k] = w[k] * F(x_k -> quad t) for the point x_k = (x[k], y[k], z[k]) with the normal of patch sidx[k],
  // t = tidx[k] (outer-rule points with their weights).
  void (*eval_points)(const SoA& s, const double* x, const double* y, const double* z, const double* w,
                      const int* sidx, const int* tidx, int count, double* out);
  // out[k] = F(c_s -> quad t) + Hessian correction (tier 1), s = sidx[k], t = tidx[k].
  void (*eval_centroid)(const SoA& s, const int* sidx, const int* tidx, int count, double* out);
  // F(j, i) = F(i, j) A_i / A_j for i in [i0, i1), j in [j0, j1) (j > i if diag) in a row-major matrix with
  // the given row stride. err[(i - i0) * err_stride + (j - j0)] is the error bound of F_ij. row_i / row_j
  // accumulate the row sums of rows i / j, err_i / err_j their error bounds. An entry outside [0, 1] by at
  // most its bound + 1e-14 is set to 0 or 1 and counted in roundoff; one outside by more is left and counted
  // in outside.
  void (*transpose)(const double* area, double* F, long long stride, int i0, int i1, int j0, int j1, bool diag,
                    const double* err, int err_stride, double* row_i, double* row_j, double* err_i, double* err_j,
                    long long* outside, long long* roundoff);
  // The far links of one receiver cluster in the hierarchy's product (hierarchy_apply.cpp): out[0..59] += the
  // third-order expansion's local record about the receiver's centre ca (o[3 t + r] for the index tuples t of
  // kTuples: g, J, H, C) summed over the links e < count in order of lanes, source record src[e] with visible
  // fraction vis[e]. rec holds kVectorRecord doubles per source: its centre (m), then its vector moments
  // m[3 t + i] = sum A x n_i b^t (scripts/gen_far_field3.py). Centres of a link's two nodes must differ.
  void (*gather_links)(const double* rec, const double* ca, const int* src, const float* vis, long long count,
                       double* out);
  // The same for a flat receiver (axis na) and flat sources: out[0..19] += the scalar local record o[t] (the vector
  // one dotted with na). rec holds kScalarRecord doubles per source: its centre, its axis, then its scalar moments
  // s[t] = sum A x b^t.
  void (*gather_links_flat)(const double* rec, const double* ca, const double* na, const int* src, const float* vis,
                            long long count, double* out);
  // The near-pair contour's inner integral (contour.cpp) at count points of an edge: out[k] = int_0^1
  // ln |w0 + s[k] u - t v| dt, v of length L > 0 (inv_L = 1 / L), in closed form. w0, u, v: 3 doubles each.
  void (*edge_log)(const double* w0, const double* u, const double* v, double L, double inv_L, const double* s,
                   int count, double* out);
  // Lambert's contour sum sum_k theta_k n.c_k / |c_k| of the polygon's m corners (xyz, contiguous) seen from x with
  // normal n (kernel.hpp's signed_contour_sum: signed, no 1/2pi), its edges in the lanes.
  double (*contour_sum)(const double* x, const double* n, const double* poly, int m);
};
// A node's moment records: centre and vector moments (3 per index tuple); centre, axis and scalar moments (1 per
// tuple).
constexpr int kVectorRecord = 63, kScalarRecord = 26;
constexpr int kLocalRecord = 60;  // a receiver's local record: 3 per index tuple (kTuples)
// Symmetric index tuples up to length 3 in the far field's order (scripts/gen_far_field3.py's TUP): (), x y z, then
// the pairs and triples below, with their multiplicities.
constexpr int kTuples = 20;
constexpr int kPairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
constexpr int kTriples[10][3] = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {0, 0, 1}, {0, 0, 2},
                                 {0, 1, 1}, {1, 1, 2}, {0, 2, 2}, {1, 2, 2}, {0, 1, 2}};
constexpr double kPairMult[6] = {1, 1, 1, 2, 2, 2};
constexpr double kTripleMult[10] = {1, 1, 1, 3, 3, 3, 3, 3, 3, 6};

const BatchKernels& batch_kernels();  // the best variant this CPU supports
const BatchKernels& batch_kernels_avx512();
const BatchKernels& batch_kernels_avx2();
const BatchKernels& batch_kernels_generic();

}  // namespace lambert::formfactor::detail
