// SIMD pair kernels. This file is compiled three times (AVX-512, AVX2+FMA, baseline) with
// LAMBERT_ISA_SUFFIX naming the variant; GCC vector extensions of 8 doubles lower to each ISA.
#include <cmath>
#include <cstring>

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
inline vd vsqrt(vd x) {
  vd r;
  for (int k = 0; k < W; ++k) r[k] = __builtin_sqrt(x[k]);
  return r;
}
inline vd vabs(vd x) {
  vd r;
  for (int k = 0; k < W; ++k) r[k] = __builtin_fabs(x[k]);
  return r;
}
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

// atan2(z, w) for z >= 0, in [0, pi]. Cephes-style rational approximation of atan on [0, 0.66] after the
// reduction atan(a) = pi/4 + atan((a - 1)/(a + 1)); ~1 ulp.
inline vd atan2_pos(vd z, vd w) {
  const vd aw = vabs(w);
  const vd mx = vmax(z, aw), mn = vmin(z, aw);
  const vl big = mn > 0.66 * mx;
  const vd num = sel(big, mn - mx, mn);
  vd den = sel(big, mn + mx, mx);
  den = sel(den > 0, den, splat(1.0));
  const vd t = num / den, t2 = t * t;
  const vd p = (((-8.750608600031904122785e-1 * t2 - 1.615753718733365076637e1) * t2 - 7.500855792314704667340e1) * t2 -
                1.228866684490136173410e2) * t2 - 6.485021904942025371773e1;
  const vd q = ((((t2 + 2.485846490142306297962e1) * t2 + 1.650270098316988542046e2) * t2 + 4.328810604912902668951e2) *
                    t2 + 4.853903996359136964868e2) * t2 + 1.945506571482613964425e2;
  const vd at = t + t * (t2 * p / q);
  const vd phi = sel(big, (kPi / 4) + (at + 3.061616997868382943065e-17), at);
  vd th = sel(z > aw, (kPi / 2) - phi, phi);
  return sel(w < 0, kPi - th, th);
}

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
    // Second-order correction (1/2) tr(M_s Hess K) A_t, as detail::hessian_correction.
    const vd cjx = gather(s.cx, T), cjy = gather(s.cy, T), cjz = gather(s.cz, T);
    const vd njx = gather(s.nx, T), njy = gather(s.ny, T), njz = gather(s.nz, T);
    const vd ux = cix - cjx, uy = ciy - cjy, uz = ciz - cjz;
    const vd uu = ux * ux + uy * uy + uz * uz;
    const vd A = -(nix * ux + niy * uy + niz * uz), nu = njx * ux + njy * uy + njz * uz;
    const vd mxx = gather(s.M[0], S), myy = gather(s.M[1], S), mzz = gather(s.M[2], S);
    const vd mxy = gather(s.M[3], S), mxz = gather(s.M[4], S), myz = gather(s.M[5], S);
    const vd Mux = mxx * ux + mxy * uy + mxz * uz, Muy = mxy * ux + myy * uy + myz * uz,
             Muz = mxz * ux + myz * uy + mzz * uz;
    const vd i3 = splat(1.0) / (uu * uu * uu);
    const vd tr = (-8 * (njx * Mux + njy * Muy + njz * Muz) - 4 * nu * (mxx + myy + mzz) +
                   24 * nu * (ux * Mux + uy * Muy + uz * Muz) / uu) * i3;
    F += (0.5 / kPi) * gather(s.area, T) * A * tr;
    for (int k = 0; k < W && b + k < count; ++k) out[b + k] = F[k];
  }
}

// Second-order corrections of the kernel at the centroids, u = c_s - c_t (as detail::far_field and
// hessian_correction in pair.cpp).
struct Moments {
  vd xx, yy, zz, xy, xz, yz;
  vd mul_dot(vd ax, vd ay, vd az, vd bx, vd by, vd bz) const {  // a . M b
    return ax * (xx * bx + xy * by + xz * bz) + ay * (xy * bx + yy * by + yz * bz) + az * (xz * bx + yz * by + zz * bz);
  }
  vd trace() const { return xx + yy + zz; }
};

int classify(const SoA& soa, int i, int j0, int j1, double tol, double* val, std::int8_t* rest_code, int* rest_j,
             long long* counts) {
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
  const double cix = s.cx[i], ciy = s.cy[i], ciz = s.cz[i], Ai = s.area[i], ri = s.rho[i];
  const double fi = s.fast[i], symi = s.sym[i];
  const double Mi[6] = {s.M[0][i], s.M[1][i], s.M[2][i], s.M[3][i], s.M[4][i], s.M[5][i]};
  for (int j = j0; j < j1; j += W) {
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
    const int n = j1 - j < W ? j1 - j : W;
    vl valid = vl{} - 1;
    for (int k = n; k < W; ++k) valid[k] = 0;
    const vl fast = load(s.fast + j) * fi > 0.5;
    const vl culled = fast & ((smax <= eps) | (tmax <= eps));  // polygons off the fast path are re-tested
    if (!any(valid & ~culled)) {  // a whole batch back to back or coplanar (common: same wall)
      for (int k = 0; k < n; ++k) val[j - j0 + k] = 0;
      c_culled -= valid;
      continue;
    }
    const vl straddle = (smin < -eps) | (tmin < -eps);
    const vd Aj = load(s.area + j), rj = load(s.rho + j);
    const vl swap = Aj < Ai;  // the error model integrates from the smaller patch
    const vd rs = sel(swap, rj, splat(ri)), rt = sel(swap, splat(ri), rj), At = sel(swap, splat(Ai), Aj);
    const vd symj = load(s.sym + j);
    const vl ssym = sel(swap, symj, splat(symi)) > 0.5, tsym = sel(swap, splat(symi), symj) > 0.5;
    const vd cjx = load(s.cx + j), cjy = load(s.cy + j), cjz = load(s.cz + j);
    // u = c_i - c_j
    const vd ux = cix - cjx, uy = ciy - cjy, uz = ciz - cjz;
    const vd uu = ux * ux + uy * uy + uz * uz;
    const vd d = vsqrt(uu) - rt;
    const vd dd = sel(d > 0, d, splat(1.0));
    const vd inv_dd = splat(1.0) / dd;
    const vd r = rs * inv_dd, q = rt * inv_dd, S = At * inv_dd * inv_dd * (1 / kPi);
    const vl near = (d <= 0) | (r > kMaxAreaRatio);
    const vd r2 = r * r, r3 = r2 * r, r4 = r2 * r2, q2 = q * q;
    auto C = [&](int m) { return sel(ssym, splat(kTierConstant[m][1]), splat(kTierConstant[m][0])); };
    const vd rp = sel(ssym, r4, r3);
    const vd e0 = C(0) * S * (rp + sel(tsym, q2 * q2, q2 * q) + r2 * q2);
    const vl live = ~(culled | straddle | near) & fast & valid;
    const vl t0 = live & (e0 <= tol);
    vd tier = splat(0);
    if (any(live & ~t0)) {  // only then the costlier rules' estimates (exponents 2m, or 2m - 1)
      const vd r8 = r4 * r4;
      const vd e1 = C(1) * S * (rp + r2 * q2);
      const vd e2 = C(2) * S * rp;
      const vd e3 = C(3) * S * rp * r2;
      const vd e4 = C(4) * S * rp * r4;
      const vd e5 = C(5) * S * rp * r8;
      const vd e6 = C(6) * S * rp * r8 * r4;
      tier = sel(e6 <= tol, splat(6), splat(7));
      tier = sel(e5 <= tol, splat(5), tier);
      tier = sel(e4 <= tol, splat(4), tier);
      tier = sel(e3 <= tol, splat(3), tier);
      tier = sel(e2 <= tol, splat(2), tier);
      tier = sel(e1 <= tol, splat(1), tier);
      tier = sel(e0 <= tol, splat(0), tier);
    }
    const vl slow = (~fast) | straddle | near | (tier > 6.5);
    const vd cd = sel(~fast, splat(kCodeSlow),
                      sel(culled, splat(kCodeCulled),
                          sel(slow, splat(kCodeSlow), tier + 1 + sel(swap, splat(kCodeSwap), splat(0)))));
    vd out = splat(0);
    if (any(t0)) {
      // Tier 0, the far-field expansion, is symmetric in (i, j): evaluated directly as F_ij with i as the
      // "source", A = n_i.(c_j - c_i), nu = n_j.u (as detail::far_field).
      const Moments MJ{load(s.M[0] + j), load(s.M[1] + j), load(s.M[2] + j),
                       load(s.M[3] + j), load(s.M[4] + j), load(s.M[5] + j)};
      const Moments MI{splat(Mi[0]), splat(Mi[1]), splat(Mi[2]), splat(Mi[3]), splat(Mi[4]), splat(Mi[5])};
      const vd inv = splat(1.0) / sel(uu > 0, uu, splat(1.0));
      const vd i3 = inv * inv * inv;
      const vd A = -(nix * ux + niy * uy + niz * uz), nu = njx * ux + njy * uy + njz * uz;
      const vd src = (-8 * MI.mul_dot(njx, njy, njz, ux, uy, uz) - 4 * nu * MI.trace() +
                      24 * nu * MI.mul_dot(ux, uy, uz, ux, uy, uz) * inv) * i3;  // tr(M_i Hess_x g)
      const vd tgt = (8 * MJ.mul_dot(splat(nix), splat(niy), splat(niz), ux, uy, uz) - 4 * A * MJ.trace() +
                      24 * A * MJ.mul_dot(ux, uy, uz, ux, uy, uz) * inv) * i3;   // tr(M_j Hess_y g)
      out = sel(t0, (Aj * (1 / kPi)) * (A * nu * inv * inv + 0.5 * A * src + 0.5 * nu * tgt), splat(0));
    }
    if (n < W) {
      for (int k = 0; k < n; ++k) val[j - j0 + k] = out[k];
    } else {
      std::memcpy(val + (j - j0), &out, sizeof out);
    }
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

// The reciprocal direction of an I x J block: F(j, i) = F(i, j) A_i / A_j, with row sums and checks.
void transpose(const double* area, double* F, long long stride, int i0, int i1, int j0, int j1, bool diag,
               double* row_i, double* row_j, long long* outside, double* recip) {
  long long out_total = 0;
  double rmax = *recip;
  for (int i = i0; i < i1; ++i) {
    const int js = diag ? i + 1 : j0;
    if (js >= j1) continue;
    const double* Fi = F + (long long)i * stride;
    const double Ai = area[i];
    double rowi = 0;
    int j = js;
    vd acc = splat(0), rm = splat(rmax);
    vl oc = vl{};
    for (; j + W <= j1; j += W) {
      const vd fij = load(Fi + j), Aj = load(area + j);
      const vd fji = fij * Ai / Aj;
      for (int k = 0; k < W; ++k) F[(long long)(j + k) * stride + i] = fji[k];
      vd rj = load(row_j + (j - j0)) + fji;
      std::memcpy(row_j + (j - j0), &rj, sizeof rj);
      acc += fij;
      oc -= (fij < 0) | (fij > 1) | (fji < 0) | (fji > 1);
      const vd ai = Ai * fij, aj = Aj * fji, mx = vmax(vabs(ai), vabs(aj));
      rm = vmax(rm, sel(mx > 0, vabs(ai - aj) / sel(mx > 0, mx, splat(1.0)), splat(0)));
    }
    for (int k = 0; k < W; ++k) {
      rowi += acc[k];
      out_total += oc[k];
      rmax = rm[k] > rmax ? rm[k] : rmax;
    }
    for (; j < j1; ++j) {
      const double fij = Fi[j], Aj = area[j], fji = fij * Ai / Aj;
      F[(long long)j * stride + i] = fji;
      row_j[j - j0] += fji;
      rowi += fij;
      out_total += (fij < 0 || fij > 1) + (fji < 0 || fji > 1);
      const double ai = Ai * fij, aj = Aj * fji, mx = __builtin_fmax(__builtin_fabs(ai), __builtin_fabs(aj));
      if (mx > 0) rmax = __builtin_fmax(rmax, __builtin_fabs(ai - aj) / mx);
    }
    row_i[i - i0] += rowi;
  }
  *outside += out_total;
  *recip = rmax;
}


}  // namespace

const BatchKernels& LAMBERT_CAT(batch_kernels_, LAMBERT_ISA_SUFFIX)() {
  static const BatchKernels k{LAMBERT_ISA_NAME, &classify, &eval_points, &eval_centroid, &transpose};
  return k;
}

}  // namespace lambert::formfactor::detail
