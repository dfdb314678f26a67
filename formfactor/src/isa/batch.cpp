// SIMD pair kernels. This file is compiled three times (AVX-512, AVX2+FMA, baseline) with
// LAMBERT_ISA_SUFFIX naming the variant; GCC vector extensions of 8 doubles lower to each ISA.
#include <cmath>
#include <cstring>

#include "../atan_reduced.hpp"
#include "../batch.hpp"

#ifndef LAMBERT_ISA_SUFFIX
#error "define LAMBERT_ISA_SUFFIX"
#endif
#define LAMBERT_CAT2(a, b) a##b
#define LAMBERT_CAT(a, b) LAMBERT_CAT2(a, b)

namespace lambert::formfactor::detail {
namespace {

constexpr int W = 8;
typedef double vd __attribute__((vector_size(8 * W)));
typedef long long vl __attribute__((vector_size(8 * W)));

constexpr double kPi = 3.14159265358979323846;

inline vd splat(double x) { return vd{} + x; }
inline vd load(const double* p) {
  vd v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline vd gather(const double* a, const int* idx) {
  vd v;
  for (int k = 0; k < W; ++k) v[k] = a[idx[k]];
  return v;
}
template <class V>
constexpr int lanes_of() {
  return int(sizeof(V) / sizeof(double));
}
template <class V>
inline V sqrt_v(V x) {
  V r;
  for (int k = 0; k < lanes_of<V>(); ++k) r[k] = __builtin_sqrt(x[k]);
  return r;
}
template <class V>
inline V abs_v(V x) {
  V r;
  for (int k = 0; k < lanes_of<V>(); ++k) r[k] = __builtin_fabs(x[k]);
  return r;
}
inline vd vsqrt(vd x) { return sqrt_v(x); }
inline vd vabs(vd x) { return abs_v(x); }
inline vd sel(vl m, vd a, vd b) { return m ? a : b; }
inline bool any(vl m) {
  long long a[W];
  std::memcpy(a, &m, sizeof m);
  long long r = 0;
  for (int k = 0; k < W; ++k) r |= a[k];
  return r != 0;
}
inline vd vmax(vd a, vd b) { return a > b ? a : b; }
inline vd vmin(vd a, vd b) { return a < b ? a : b; }

// atan2(z, w) for z >= 0, in [0, pi] (atan_reduced.hpp; ~1 ulp), any width.
template <class V>
inline V atan2_pos_v(V z, V w) {
  const V aw = abs_v(w);
  const V mx = z > aw ? z : aw, mn = z > aw ? aw : z;
  const auto big = mn > kAtanSplit * mx;
  const V num = big ? mn - mx : mn;
  V den = big ? mn + mx : mx;
  den = den > 0 ? den : V{} + 1.0;
  const V at = atan_reduced(num / den);
  const V phi = big ? (kPi / 4) + (at + kPio4Tail) : at;
  const V th = z > aw ? (kPi / 2) - phi : phi;
  return w < 0 ? kPi - th : th;
}
inline vd atan2_pos(vd z, vd w) { return atan2_pos_v(z, w); }

struct Quad {
  vd x[4], y[4], z[4];
};
inline Quad gather_quad(const SoA& s, const int* t) {
  Quad q;
  for (int c = 0; c < 4; ++c) {
    q.x[c] = gather(s.qx[c], t);
    q.y[c] = gather(s.qy[c], t);
    q.z[c] = gather(s.qz[c], t);
  }
  return q;
}

// Lambert's contour formula for 8 (point, normal, quad) lanes; the quads are entirely in front of the points.
inline vd point_quad(vd px, vd py, vd pz, vd nx, vd ny, vd nz, const Quad& q) {
  vd sum = splat(0);
  vd ax = q.x[0] - px, ay = q.y[0] - py, az = q.z[0] - pz;
  for (int k = 0; k < 4; ++k) {
    const int k1 = (k + 1) & 3;
    const vd ex = q.x[k1] - q.x[k], ey = q.y[k1] - q.y[k], ez = q.z[k1] - q.z[k];
    const vd bx = ax + ex, by = ay + ey, bz = az + ez;
    // c = a x e (= a x b, exactly representable edge vector keeps far points accurate)
    const vd cx = ay * ez - az * ey, cy = az * ex - ax * ez, cz = ax * ey - ay * ex;
    const vd cc = cx * cx + cy * cy + cz * cz;
    const vd zc = vsqrt(cc);
    const vd w = ax * bx + ay * by + az * bz;
    const vd nc = nx * cx + ny * cy + nz * cz;
    const vl ok = zc > 0;
    const vd inv = splat(1.0) / sel(ok, zc, splat(1.0));
    sum += sel(ok, atan2_pos(zc, w) * (nc * inv), splat(0));
    ax = bx;
    ay = by;
    az = bz;
  }
  return vabs(sum) * (1 / (2 * kPi));
}

void eval_points(const SoA& s, const double* x, const double* y, const double* z, const double* w, const int* sidx,
                 const int* tidx, int count, double* out) {
  for (int b = 0; b < count; b += W) {
    int S[W], T[W], L[W];
    for (int k = 0; k < W; ++k) {
      L[k] = b + k < count ? b + k : count - 1;  // pad the last batch by repeating a lane
      S[k] = sidx[L[k]];
      T[k] = tidx[L[k]];
    }
    const Quad q = gather_quad(s, T);
    const vd F = point_quad(gather(x, L), gather(y, L), gather(z, L), gather(s.nx, S), gather(s.ny, S),
                            gather(s.nz, S), q) *
                 gather(w, L);
    for (int k = 0; k < W && b + k < count; ++k) out[b + k] = F[k];
  }
}

void eval_centroid(const SoA& s, const int* sidx, const int* tidx, int count, double* out) {
  for (int b = 0; b < count; b += W) {
    int S[W], T[W];
    for (int k = 0; k < W; ++k) {
      const int l = b + k < count ? b + k : count - 1;  // pad the last batch by repeating a lane
      S[k] = sidx[l];
      T[k] = tidx[l];
    }
    const Quad q = gather_quad(s, T);
    const vd cix = gather(s.cx, S), ciy = gather(s.cy, S), ciz = gather(s.cz, S);
    const vd nix = gather(s.nx, S), niy = gather(s.ny, S), niz = gather(s.nz, S);
    vd F = point_quad(cix, ciy, ciz, nix, niy, niz, q);
    // Second-order correction (1/2) tr(M_s Hess K) A_t (tiers.hpp, shared with the scalar path).
    const Moments<vd> Ms{gather(s.M[0], S), gather(s.M[1], S), gather(s.M[2], S),
                         gather(s.M[3], S), gather(s.M[4], S), gather(s.M[5], S)};
    F += centroid_hessian_correction(cix - gather(s.cx, T), ciy - gather(s.cy, T), ciz - gather(s.cz, T), nix, niy, niz,
                                     gather(s.nx, T), gather(s.ny, T), gather(s.nz, T), Ms, gather(s.area, T));
    for (int k = 0; k < W && b + k < count; ++k) out[b + k] = F[k];
  }
}

int classify(const SoA& soa, int i, int j0, int j1, double tol, double* val, double* err, std::int8_t* code,
             std::int8_t* rest_code, int* rest_j, long long* counts) {
  const SoA s = soa;  // a local copy: stores through val cannot alias its pointers, so they stay in registers
  int nrest = 0;
  vl c_culled = vl{}, c_t0 = vl{};
  const vd eps = splat(s.eps);
  const double nix = s.nx[i], niy = s.ny[i], niz = s.nz[i], oi = s.off[i];
  double qix[4], qiy[4], qiz[4];
  for (int c = 0; c < 4; ++c) {
    qix[c] = s.qx[c][i];
    qiy[c] = s.qy[c][i];
    qiz[c] = s.qz[c][i];
  }
  const double cix = s.cx[i], ciy = s.cy[i], ciz = s.cz[i], Ai = s.area[i], ri = s.radius[i], rei = s.rerr[i];
  const double fi = s.fast[i], symi = s.sym[i];
  const Moments<vd> MI{splat(s.M[0][i]), splat(s.M[1][i]), splat(s.M[2][i]),
                       splat(s.M[3][i]), splat(s.M[4][i]), splat(s.M[5][i])};
  for (int j = j0; j < j1; j += W) {
    const int n = j1 - j < W ? j1 - j : W;
    auto store = [&](double* dst, vd v) {
      if (n < W) {
        for (int k = 0; k < n; ++k) dst[j - j0 + k] = v[k];
      } else {
        std::memcpy(dst + (j - j0), &v, sizeof v);
      }
    };
    // Corners of j against i's plane, corners of i against j's plane.
    vd smin = splat(INFINITY), smax = splat(-INFINITY), tmin = smin, tmax = smax;
    const vd njx = load(s.nx + j), njy = load(s.ny + j), njz = load(s.nz + j), oj = load(s.off + j);
    for (int c = 0; c < 4; ++c) {
      const vd sc = nix * load(s.qx[c] + j) + niy * load(s.qy[c] + j) + niz * load(s.qz[c] + j) - oi;
      smin = vmin(smin, sc);
      smax = vmax(smax, sc);
      const vd tc = njx * qix[c] + njy * qiy[c] + njz * qiz[c] - oj;
      tmin = vmin(tmin, tc);
      tmax = vmax(tmax, tc);
    }
    vl valid = vl{} - 1;
    for (int k = n; k < W; ++k) valid[k] = 0;
    const vl fast = load(s.fast + j) * fi > 0.5;
    const vl culled = fast & ((smax <= eps) | (tmax <= eps));  // polygons off the fast path are re-tested
    if (!any(valid & ~culled)) {  // a whole batch back to back or coplanar (common: same wall)
      for (int k = 0; k < n; ++k) {
        val[j - j0 + k] = 0;
        err[j - j0 + k] = 0;
        code[j - j0 + k] = kCodeCulled;
      }
      c_culled -= valid;
      continue;
    }
    const vl straddle = (smin < -eps) | (tmin < -eps);
    const vd Aj = load(s.area + j), rj = load(s.radius + j), rej = load(s.rerr + j);
    const vl swap = Aj < splat(Ai * kSmallerBy);  // the error model integrates from the smaller patch (source_is_j)
    // The source's error radius (PatchData::rerr), the target's circumradius (its bounding sphere).
    const vd rs = sel(swap, rej, splat(rei)), rt = sel(swap, splat(ri), rj), At = sel(swap, splat(Ai), Aj);
    const vd symj = load(s.sym + j);
    const vl ssym = sel(swap, symj, splat(symi)) > 0.5, tsym = sel(swap, splat(symi), symj) > 0.5;
    const vd cjx = load(s.cx + j), cjy = load(s.cy + j), cjz = load(s.cz + j);
    // u = c_i - c_j
    const vd ux = cix - cjx, uy = ciy - cjy, uz = ciz - cjz;
    const vd D = vsqrt(ux * ux + uy * uy + uz * uz);
    const TierInput<vd> in = tier_input(D, rs, rt, At);  // tiers.hpp, shared with pair_scalar
    const vl live = (vl)tier_eligible(D, rt, in) & ~(culled | straddle) & fast & valid;
    const vd e0 = tier0_error(in, ssym, tsym);
    const vl t0 = live & (e0 <= tol);
    vd tier = splat(0), est = e0;
    if (any(live & ~t0)) {  // only then the costlier rules' estimates
      vd e[kTiers];
      tier_errors(in, ssym, e);
      tier = splat(7);
      for (int t = kTiers - 1; t >= 1; --t) {
        tier = sel(e[t] <= tol, splat(t), tier);
        est = sel(e[t] <= tol, e[t], est);
      }
      tier = sel(e0 <= tol, splat(0), tier);
      est = sel(e0 <= tol, e0, est);
    }
    const vl slow = (~fast) | straddle | ~live | (tier > 6.5);
    const vd cd = sel(~fast, splat(kCodeSlow),
                      sel(culled, splat(kCodeCulled),
                          sel(slow, splat(kCodeSlow), tier + 1 + sel(swap, splat(kCodeSwap), splat(0)))));
    vd out = splat(0);
    if (any(t0)) {
      // Tier 0, the far-field expansion, is symmetric in (i, j): evaluated directly as F_ij with i as the
      // "source" (tiers.hpp, as far_field in pair.cpp).
      const Moments<vd> MJ{load(s.M[0] + j), load(s.M[1] + j), load(s.M[2] + j),
                           load(s.M[3] + j), load(s.M[4] + j), load(s.M[5] + j)};
      const vd uxs = sel(t0, ux, splat(1.0));  // keep culled or coincident lanes finite
      out = sel(t0, far_field_value(uxs, uy, uz, splat(nix), splat(niy), splat(niz), njx, njy, njz, MI, MJ, Aj),
                splat(0));
    }
    store(val, out);
    // Error bound on F_ij: the estimate bounds F_st; F_ij = F_ji A_j / A_i when j is the source.
    const vd e_ij = sel(slow | culled, splat(0), sel(swap, est * Aj / Ai, est));
    store(err, e_ij);
    for (int k = 0; k < n; ++k) code[j - j0 + k] = static_cast<std::int8_t>(t0[k] ? 1 + (swap[k] ? kCodeSwap : 0) : cd[k]);
    c_culled -= culled & valid & (cd < 0.5);  // masks are -1 where true
    c_t0 -= t0 & valid;
    const vl rest = valid & (cd > 0.5) & ~t0;
    if (any(rest))
      for (int k = 0; k < n; ++k)
        if (rest[k]) {
          rest_code[nrest] = static_cast<std::int8_t>(cd[k]);
          rest_j[nrest++] = j + k;
        }
  }
  long long a = 0, b = 0;
  for (int k = 0; k < W; ++k) {
    a += c_culled[k];
    b += c_t0[k];
  }
  counts[0] += a;
  counts[1] += b;
  return nrest;
}

// The reciprocal direction of an I x J block: F(j, i) = F(i, j) A_i / A_j, with row sums, the rows' error
// bounds and the entries outside [0, 1].
void transpose(const double* area, double* F, long long stride, int i0, int i1, int j0, int j1, bool diag,
               const double* err, int err_stride, double* row_i, double* row_j, double* err_i, double* err_j,
               long long* outside, long long* roundoff) {
  long long out_total = 0, round_total = 0;
  // An entry outside [0, 1] by no more than its error bound (+ 1e-14, rounding) is set to 0 or 1 and counted.
  auto fix = [&](double& f, double e) {
    const double excess = f < 0 ? -f : f - 1;
    if (!(excess > 0)) return;
    if (excess <= e + 1e-14) {
      f = f < 0 ? 0.0 : 1.0;
      ++round_total;
    } else {
      ++out_total;
    }
  };
  for (int i = i0; i < i1; ++i) {
    const int js = diag ? i + 1 : j0;
    if (js >= j1) continue;
    double* Fi = F + (long long)i * stride;
    const double* Ei = err + (long long)(i - i0) * err_stride;
    const double Ai = area[i];
    double rowi = 0, erri = 0;
    int j = js;
    vd acc = splat(0), eacc = splat(0);
    for (; j + W <= j1; j += W) {
      vd fij = load(Fi + j);
      const vd Aj = load(area + j), eij = load(Ei + (j - j0));
      const vd ratio = Ai / Aj;
      vd fji = fij * ratio;
      if (any((fij < 0) | (fij > 1) | (fji < 0) | (fji > 1))) {
        for (int k = 0; k < W; ++k) {
          double a = fij[k], b = fji[k];
          fix(a, eij[k]);
          fix(b, eij[k] * ratio[k]);
          fij[k] = a;
          fji[k] = b;
        }
        std::memcpy(Fi + j, &fij, sizeof fij);
      }
      for (int k = 0; k < W; ++k) F[(long long)(j + k) * stride + i] = fji[k];
      vd rj = load(row_j + (j - j0)) + fji;
      std::memcpy(row_j + (j - j0), &rj, sizeof rj);
      vd ej = load(err_j + (j - j0)) + eij * ratio;
      std::memcpy(err_j + (j - j0), &ej, sizeof ej);
      acc += fij;
      eacc += eij;
    }
    for (int k = 0; k < W; ++k) {
      rowi += acc[k];
      erri += eacc[k];
    }
    for (; j < j1; ++j) {
      const double Aj = area[j], ratio = Ai / Aj, eij = Ei[j - j0];
      double fij = Fi[j], fji = fij * ratio;
      fix(fij, eij);
      fix(fji, eij * ratio);
      Fi[j] = fij;
      F[(long long)j * stride + i] = fji;
      row_j[j - j0] += fji;
      err_j[j - j0] += eij * ratio;
      rowi += fij;
      erri += eij;
    }
    row_i[i - i0] += rowi;
    err_i[i - i0] += erri;
  }
  *outside += out_total;
  *roundoff += round_total;
}

// Lanes per step: as many doubles as one register holds (8 links at a time would spill the accumulators of
// AVX2's 16 registers).
#if defined(__AVX512F__)
constexpr int kGatherLanes = 8;
#elif defined(__AVX2__)
constexpr int kGatherLanes = 4;
#else
constexpr int kGatherLanes = 2;
#endif
typedef double vg __attribute__((vector_size(8 * kGatherLanes)));

#include "far_field3.inc"

// Far links of one receiver, kGatherLanes links per step (one per lane): the third-order Taylor expansion of
// sum_j K(u + b_j - a) A_j x_j n_j in b and a, K(u) = -u u^T / (pi |u|^4), u = c_B - c_A, from the source's moments
// (far_field3.inc, written by scripts/gen_far_field3.py), times the link's visible fraction. Padding lanes read
// the first link's source with visible fraction 0. Flat: the scalar kernel of a flat receiver and flat sources.
template <bool Flat>
void gather(const double* rec, const double* ca, const double* na, const int* src, const float* vis, long long count,
            double* out) {
  constexpr int L = kGatherLanes, kOut = Flat ? kTuples : kLocalRecord;
  constexpr int kStride = Flat ? kScalarRecord : kVectorRecord;  // the centre, then what the kernel reads
  vg acc[kOut];
  for (vg& a : acc) a = vg{};
  vg n[3];
  if constexpr (Flat)
    for (int i = 0; i < 3; ++i) n[i] = vg{} + na[i];
  for (long long e0 = 0; e0 < count; e0 += L) {
    const long long m = count - e0 < L ? count - e0 : L;
    const double* r[L];
    vg vv;
    for (int k = 0; k < L; ++k) {
      r[k] = rec + std::ptrdiff_t(src[e0 + (k < m ? k : 0)]) * kStride;
      vv[k] = k < m ? double(vis[e0 + k]) : 0.0;
    }
    vg f[kStride];
    for (int c = 0; c < kStride; ++c)
      for (int k = 0; k < L; ++k) f[c][k] = r[k][c];
    const vg u[3] = {f[0] - ca[0], f[1] - ca[1], f[2] - ca[2]};
    const vg is = 1.0 / (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    vg ph[4];  // the derivatives of 1 / (pi s^2) at s = |u|^2
    ph[0] = (1 / kPi) * is * is;
    ph[1] = -2.0 * ph[0] * is;
    ph[2] = -3.0 * ph[1] * is;
    ph[3] = -4.0 * ph[2] * is;
    vg o[kOut];
    if constexpr (Flat)
      far_flat3(u, ph, n, f + 3, f + 6, o);
    else
      far_vector3(u, ph, f + 3, o);
    for (int c = 0; c < kOut; ++c) acc[c] += vv * o[c];
  }
  for (int c = 0; c < kOut; ++c) {
    double s = 0;
    for (int k = 0; k < L; ++k) s += acc[c][k];
    out[c] += s;
  }
}

void gather_links(const double* rec, const double* ca, const int* src, const float* vis, long long count,
                  double* out) {
  gather<false>(rec, ca, nullptr, src, vis, count, out);
}

void gather_links_flat(const double* rec, const double* ca, const double* na, const int* src, const float* vis,
                       long long count, double* out) {
  gather<true>(rec, ca, na, src, vis, count, out);
}

// The contour kernels below run kGatherLanes wide (8 on AVX-512, 4 on AVX2, 2 on the baseline), on the same grounds
// as gather_links: 8 lanes of doubles on AVX2 spilled their registers to the stack (udales' assembly with
// LAMBERT_ISA=avx2 was slower than the scalar code they replaced: 4.9 against 4.2 s).
// ln x for positive normal x, not subnormal (Cephes log: x = m 2^e with m in [sqrt(1/2), sqrt(2)), ln m = z - z^2/2 +
// z^3 P(z) / Q(z) for z = m - 1, ln 2 split in two so that e ln 2 adds no rounding; ~1 ulp).
template <class V>
inline V log_v(V x) {
  using L = decltype(x < x);  // long long lanes of the same width
  L bits;
  std::memcpy(&bits, &x, sizeof x);
  L e = ((bits >> 52) & 0x7ff) - 1022;  // x = m 2^e, m in [0.5, 1)
  bits = (bits & 0x000fffffffffffffLL) | 0x3fe0000000000000LL;
  V m;
  std::memcpy(&m, &bits, sizeof m);
  const L small = m < 0.70710678118654752440;
  e = small ? e - 1 : e;
  const V z = small ? m + m - 1.0 : m - 1.0;
  V ef;
  for (int k = 0; k < lanes_of<V>(); ++k) ef[k] = double(e[k]);  // small integers: exact either way
  const V P = ((((1.01875663804580931796e-4 * z + 4.97494994976747001425e-1) * z + 4.70579119878881725854e0) * z +
                1.44989225341610930846e1) * z + 1.79368678507819816313e1) * z + 7.70838733755885391666e0;
  const V Q = ((((z + 1.12873587189167450590e1) * z + 4.52279145837532221105e1) * z + 8.29875266912776603211e1) * z +
               7.11544750618563894466e1) * z + 2.31251620126765340583e1;
  const V z2 = z * z;
  V y = z * (z2 * P / Q);
  y = y - ef * 2.121944400546905827679e-4;
  y = y - 0.5 * z2;
  return (z + y) + ef * 0.693359375;
}

// int_0^1 ln |w - t v| dt for w = w0 + s u: with the distance d from w to the line of v and sigma the signed position
// along it, the antiderivative of ln(sigma^2 + d^2) is G = sigma ln(sigma^2 + d^2) - 2 sigma + 2 d atan(sigma / d).
void edge_log(const double* w0, const double* u, const double* v, double L, double inv_L, const double* s, int count,
              double* out) {
  constexpr int N = kGatherLanes;
  for (int b = 0; b < count; b += N) {
    const int m = count - b < N ? count - b : N;
    vg sv = vg{};
    for (int k = 0; k < m; ++k) sv[k] = s[b + k];
    const vg wx = w0[0] + sv * u[0], wy = w0[1] + sv * u[1], wz = w0[2] + sv * u[2];
    const vg wv = (wx * v[0] + wy * v[1] + wz * v[2]) * inv_L;
    const vg cx = wy * v[2] - wz * v[1], cy = wz * v[0] - wx * v[2], cz = wx * v[1] - wy * v[0];
    const vg d2 = (cx * cx + cy * cy + cz * cz) * (inv_L * inv_L);
    const vg d = sqrt_v(d2);
    auto G = [&](vg sg) {
      const vg r2 = sg * sg + d2;
      vg g = -2 * sg;
      g += sg != 0 ? sg * log_v(r2 > 0 ? r2 : vg{} + 1.0) : vg{};
      const vg at = atan2_pos_v(abs_v(sg), d);
      g += d > 0 ? 2 * d * (sg < 0 ? -at : at) : vg{};
      return g;
    };
    const vg r = (G(L - wv) - G(-wv)) * (0.5 * inv_L);
    for (int k = 0; k < m; ++k) out[b + k] = r[k];
  }
}

// The edges of one polygon in the lanes: each edge's term as signed_contour_sum forms it (a = corner - x, e = the
// edge vector, c = a x e, the angle atan2(|c|, a . (next corner - x))), summed lane by lane, then across the lanes in
// order (for m <= kGatherLanes corners the scalar loop's order).
double contour_sum(const double* x, const double* n, const double* poly, int m) {
  constexpr int N = kGatherLanes;
  vg sum = vg{};
  for (int b = 0; b < m; b += N) {
    vg ax{}, ay{}, az{}, ex{}, ey{}, ez{}, bx{}, by{}, bz{};
    for (int k = 0; k < N && b + k < m; ++k) {
      const double* p = poly + 3 * (b + k);
      const double* q = poly + 3 * (b + k + 1 == m ? 0 : b + k + 1);
      ax[k] = p[0] - x[0], ay[k] = p[1] - x[1], az[k] = p[2] - x[2];
      ex[k] = q[0] - p[0], ey[k] = q[1] - p[1], ez[k] = q[2] - p[2];
      bx[k] = q[0] - x[0], by[k] = q[1] - x[1], bz[k] = q[2] - x[2];
    }
    const vg cx = ay * ez - az * ey, cy = az * ex - ax * ez, cz = ax * ey - ay * ex;
    const vg zc = sqrt_v(cx * cx + cy * cy + cz * cz);
    const vg w = ax * bx + ay * by + az * bz;
    const vg nc = n[0] * cx + n[1] * cy + n[2] * cz;
    const auto ok = zc > 0;
    sum += ok ? atan2_pos_v(zc, w) * (nc / (ok ? zc : vg{} + 1.0)) : vg{};
  }
  double s = 0;
  for (int k = 0; k < N; ++k) s += sum[k];
  return s;
}

}  // namespace

const BatchKernels& LAMBERT_CAT(batch_kernels_, LAMBERT_ISA_SUFFIX)() {
  static const BatchKernels k{LAMBERT_ISA_NAME, &classify,     &eval_points, &eval_centroid,
                              &transpose,       &gather_links, &gather_links_flat, &edge_log,
                              &contour_sum};
  return k;
}

}  // namespace lambert::formfactor::detail
