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

void eval_points(const SoA& s, const int* pidx, const int* sidx, const int* tidx, int count, double* out) {
  for (int b = 0; b < count; b += W) {
    int P[W], S[W], T[W];
    for (int k = 0; k < W; ++k) {
      const int l = b + k < count ? b + k : count - 1;  // pad the last batch by repeating a lane
      P[k] = pidx[l];
      S[k] = sidx[l];
      T[k] = tidx[l];
    }
    const Quad q = gather_quad(s, T);
    const vd F = point_quad(gather(s.px, P), gather(s.py, P), gather(s.pz, P), gather(s.nx, S), gather(s.ny, S),
                            gather(s.nz, S), q) *
                 gather(s.pw, P);
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

int classify(const SoA& s, int i, int j0, int j1, double tol, double* val, std::int8_t* rest_code, int* rest_j,
             long long* counts) {
  int nrest = 0;
  vl c_culled = vl{}, c_t0 = vl{}, c_t1 = vl{};
  const vd eps = splat(s.eps);
  const double nix = s.nx[i], niy = s.ny[i], niz = s.nz[i], oi = s.off[i];
  double qix[4], qiy[4], qiz[4];
  for (int c = 0; c < 4; ++c) {
    qix[c] = s.qx[c][i];
    qiy[c] = s.qy[c][i];
    qiz[c] = s.qz[c][i];
  }
  const double cix = s.cx[i], ciy = s.cy[i], ciz = s.cz[i], Ai = s.area[i], ri = s.rho[i], inv_Ai = 1.0 / Ai;
  const double fi = s.fast[i], symi = s.sym[i];
  const double Mi[6] = {s.M[0][i], s.M[1][i], s.M[2][i], s.M[3][i], s.M[4][i], s.M[5][i]};
  for (int j = j0; j < j1; j += W) {
    // Corners of j against i's plane, corners of i against j's plane.
    vd smin = splat(INFINITY), smax = splat(-INFINITY), tmin = smin, tmax = smax;
    const vd njx = load(s.nx + j), njy = load(s.ny + j), njz = load(s.nz + j), oj = load(s.off + j);
    Quad qj;
    for (int c = 0; c < 4; ++c) {
      qj.x[c] = load(s.qx[c] + j);
      qj.y[c] = load(s.qy[c] + j);
      qj.z[c] = load(s.qz[c] + j);
      const vd sc = nix * qj.x[c] + niy * qj.y[c] + niz * qj.z[c] - oi;
      smin = vmin(smin, sc);
      smax = vmax(smax, sc);
      const vd tc = njx * qix[c] + njy * qiy[c] + njz * qiz[c] - oj;
      tmin = vmin(tmin, tc);
      tmax = vmax(tmax, tc);
    }
    const vl culled = (smax <= eps) | (tmax <= eps);
    const vl straddle = (smin < -eps) | (tmin < -eps);
    const vd Aj = load(s.area + j), rj = load(s.rho + j);
    const vl swap = Aj < Ai;  // integrate from the smaller patch
    const vd rs = sel(swap, rj, splat(ri)), rt = sel(swap, splat(ri), rj), At = sel(swap, splat(Ai), Aj);
    const vd symj = load(s.sym + j);
    const vl ssym = sel(swap, symj, splat(symi)) > 0.5, tsym = sel(swap, splat(symi), symj) > 0.5;
    const vd cjx = load(s.cx + j), cjy = load(s.cy + j), cjz = load(s.cz + j);
    const vd dx = cjx - cix, dy = cjy - ciy, dz = cjz - ciz;
    const vd D = vsqrt(dx * dx + dy * dy + dz * dz);
    const vd d = D - rt;
    const vd dd = sel(d > 0, d, splat(1.0));
    const vd inv_dd = splat(1.0) / dd;
    const vd r = rs * inv_dd, q = rt * inv_dd, S = At * inv_dd * inv_dd * (1 / kPi);
    const vl near = (d <= 0) | (r > kMaxAreaRatio);
    const vd r2 = r * r, r3 = r2 * r, r4 = r2 * r2, q2 = q * q;
    auto C = [&](int m) { return sel(ssym, splat(kTierConstant[m][1]), splat(kTierConstant[m][0])); };
    const vd e0 = C(0) * S * (sel(ssym, r4, r3) + sel(tsym, q2 * q2, q2 * q) + r2 * q2);
    const vd e1 = C(1) * S * (sel(ssym, r4, r3) + r2 * q2);
    const vd e2 = C(2) * S * sel(ssym, r4, r3);
    const vd e3 = C(3) * S * sel(ssym, r4 * r2, r4 * r);
    const vd e4 = C(4) * S * sel(ssym, r4 * r4, r4 * r3);
    const vd tier = sel(e0 <= tol, splat(0),
                        sel(e1 <= tol, splat(1),
                            sel(e2 <= tol, splat(2), sel(e3 <= tol, splat(3), sel(e4 <= tol, splat(4), splat(5))))));
    const vl fast = load(s.fast + j) * fi > 0.5;
    const vl slow = (~fast) | straddle | near | (tier > 4.5);
    const vd cd = sel(~fast, splat(kCodeSlow),
                      sel(culled, splat(kCodeCulled),
                          sel(slow, splat(kCodeSlow), tier + 1 + sel(swap, splat(kCodeSwap), splat(0)))));
    // Tiers 0 and 1 are evaluated here, on contiguous target data; roles per lane (s = source, t = target).
    const vl live = ~(culled | slow);
    const vl t0 = live & (tier < 0.5), t1 = live & (tier > 0.5) & (tier < 1.5);
    vd out = splat(0);
    bool any0 = false, any1 = false;
    for (int k = 0; k < W; ++k) {
      any0 |= t0[k] != 0;
      any1 |= t1[k] != 0;
    }
    if (any0 || any1) {
      // u = c_s - c_t, A = n_s.(c_t - c_s), nu = n_t.u
      const vd ux = sel(swap, dx, -dx), uy = sel(swap, dy, -dy), uz = sel(swap, dz, -dz);
      const vd nsx = sel(swap, njx, splat(nix)), nsy = sel(swap, njy, splat(niy)), nsz = sel(swap, njz, splat(niz));
      const vd ntx = sel(swap, splat(nix), njx), nty = sel(swap, splat(niy), njy), ntz = sel(swap, splat(niz), njz);
      const Moments Mj{load(s.M[0] + j), load(s.M[1] + j), load(s.M[2] + j),
                       load(s.M[3] + j), load(s.M[4] + j), load(s.M[5] + j)};
      const Moments MI{splat(Mi[0]), splat(Mi[1]), splat(Mi[2]), splat(Mi[3]), splat(Mi[4]), splat(Mi[5])};
      const Moments Ms{sel(swap, Mj.xx, MI.xx), sel(swap, Mj.yy, MI.yy), sel(swap, Mj.zz, MI.zz),
                       sel(swap, Mj.xy, MI.xy), sel(swap, Mj.xz, MI.xz), sel(swap, Mj.yz, MI.yz)};
      const Moments Mt{sel(swap, MI.xx, Mj.xx), sel(swap, MI.yy, Mj.yy), sel(swap, MI.zz, Mj.zz),
                       sel(swap, MI.xy, Mj.xy), sel(swap, MI.xz, Mj.xz), sel(swap, MI.yz, Mj.yz)};
      const vd uu = ux * ux + uy * uy + uz * uz;
      const vd inv = splat(1.0) / sel(uu > 0, uu, splat(1.0));
      const vd i3 = inv * inv * inv;
      const vd A = -(nsx * ux + nsy * uy + nsz * uz), nu = ntx * ux + nty * uy + ntz * uz;
      const vd uMsu = Ms.mul_dot(ux, uy, uz, ux, uy, uz), ntMsu = Ms.mul_dot(ntx, nty, ntz, ux, uy, uz);
      const vd src = (-8 * ntMsu - 4 * nu * Ms.trace() + 24 * nu * uMsu * inv) * i3;  // tr(M_s Hess_x g)
      vd F = splat(0);
      if (any0) {
        const vd uMtu = Mt.mul_dot(ux, uy, uz, ux, uy, uz), nsMtu = Mt.mul_dot(nsx, nsy, nsz, ux, uy, uz);
        const vd tgt = (8 * nsMtu - 4 * A * Mt.trace() + 24 * A * uMtu * inv) * i3;
        F = (At * (1 / kPi)) * (A * nu * inv * inv + 0.5 * A * src + 0.5 * nu * tgt);
      }
      if (any1) {
        // Analytic point-to-quad from the source centroid, plus the source Hessian correction.
        Quad qt;
        for (int c = 0; c < 4; ++c) {
          qt.x[c] = sel(swap, splat(qix[c]), qj.x[c]);
          qt.y[c] = sel(swap, splat(qiy[c]), qj.y[c]);
          qt.z[c] = sel(swap, splat(qiz[c]), qj.z[c]);
        }
        const vd csx = sel(swap, cjx, splat(cix)), csy = sel(swap, cjy, splat(ciy)), csz = sel(swap, cjz, splat(ciz));
        const vd F1 = point_quad(csx, csy, csz, nsx, nsy, nsz, qt) + (0.5 / kPi) * At * A * src;
        F = sel(t1, F1, F);
      }
      // Stored as F_ij: a swapped lane computed F_ji, and A_i F_ij = A_j F_ji.
      out = sel(t0 | t1, sel(swap, F * (Aj * inv_Ai), F), splat(0));
    }
    const int n = j1 - j < W ? j1 - j : W;
    vl valid;
    for (int k = 0; k < W; ++k) valid[k] = k < n ? -1 : 0;
    c_culled -= culled & valid & (cd < 0.5);  // masks are -1 where true
    c_t0 -= t0 & valid;
    c_t1 -= t1 & valid;
    for (int k = 0; k < n; ++k) val[j - j0 + k] = out[k];
    const vl rest = valid & (cd > 0.5) & ~(t0 | t1);
    bool any_rest = false;
    for (int k = 0; k < W; ++k) any_rest |= rest[k] != 0;
    if (any_rest)
      for (int k = 0; k < n; ++k)
        if (rest[k]) {
          rest_code[nrest] = static_cast<std::int8_t>(cd[k]);
          rest_j[nrest++] = j + k;
        }
  }
  long long a = 0, b = 0, c = 0;
  for (int k = 0; k < W; ++k) {
    a += c_culled[k];
    b += c_t0[k];
    c += c_t1[k];
  }
  counts[0] += a;
  counts[1] += b;
  counts[2] += c;
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
  static const BatchKernels k{LAMBERT_ISA_NAME, &classify, &eval_points, &transpose};
  return k;
}

}  // namespace lambert::formfactor::detail
