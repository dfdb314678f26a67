#pragma once
// The a-priori tier choice and the second-order (Hessian) terms, written once for both paths: templates
// instantiated with V = double, B = bool by the scalar path (pair.cpp) and with SIMD vector types by the
// batch kernels (isa/batch.cpp). `cond ? a : b` is a lane-wise select for GCC vector types.
//
// Tiers (rules for the unoccluded F_st, s the source = the smaller patch, t the target):
//   0 far field: centroid-to-centroid kernel plus the Hessian terms on both patches (symmetric in s, t)
//   1 centroid + Hessian: analytic point-to-polygon from the source centroid plus the source's Hessian term
//   2..6 m x m Gauss outer rule over the source (m = kTierM[t]) with the analytic inner integral
// Model: estimate of |F_st error| = C S rp with S = A_t / (pi d^2), r = R_s / d, q = R_t / d, d the distance
// from c_s to the bounding sphere of the target (R_t = circumradius about the centroid; R_s = the larger of the
// source's circumradius and sqrt(6 lambda_max), lambda_max its largest principal second moment per area: a strip's
// rules err like a square's with its length as side, PatchData::rerr), rp = r^p with p the
// rule's order (4 for tiers 0/1, 2m for Gauss), one less for a source that is not centrally symmetric; tier 0
// adds the target's term (q^4 or q^3) and both add r^2 q^2 (the Hessian is taken at one centroid only).
// The constants C are fitted (kTierConstant below). Pairs with d <= 0 or r > kMaxAreaRatio take the
// adaptive contour integral.

namespace lambert::formfactor::detail {

constexpr int kTiers = 7;
constexpr int kTierM[kTiers] = {0, 1, 2, 3, 4, 6, 8};  // Gauss points per direction for tiers 2..6

// A-priori error model constants: 4 x the worst ratio |error| / (S r^p) seen on 40,000 random pairs of
// triangles, parallelograms and convex quads (target 1-3x the source, r = R_s/d from 0.004 to 0.6, grazing
// angles included); index [tier][source centrally symmetric]. For 6x6 and 8x8 Gauss, whose errors mostly sat
// at rounding level, 7x and 70x the worst measurable ratio.
constexpr double kTierConstant[kTiers][2] = {{0.8, 1.3}, {0.6, 2.5}, {0.4, 0.5},   {0.07, 0.09},
                                             {0.008, 0.012}, {1e-4, 1e-4}, {1e-6, 1e-6}};
// The source is the smaller patch, j only if smaller than i by more than 1e-6 of i's area: areas equal but for
// rounding (a regular grid's, a floor's and a ceiling's matching patches) keep i. Which one rounded smaller changed
// with where the model sat (examples/room.obj moved by 1e6 m swapped the pair's source, so its ray samples, and an
// entry moved by 1.4e-3; 1e-9 was not enough for a file written with 10 decimals there, 1e-10 m on a 0.23 m patch).
// Either patch is as good a source then. The SIMD tier choice (isa/batch.cpp) writes the same comparison.
constexpr double kSmallerBy = 1 - 1e-6;
inline bool source_is_j(double Ai, double Aj) { return Aj < Ai * kSmallerBy; }
constexpr double kMaxAreaRatio = 0.5;  // R_s / d above this: always the scalar path (contour)
constexpr double kTierPi = 3.14159265358979323846;

template <class V>
struct TierInput {
  V S, r, q;  // S = A_t / (pi d^2), r = R_s / d, q = R_t / d
};
// D = |c_s - c_t|; the model's distance is d = D - R_t. Callers test tier_eligible() before using the result.
template <class V>
inline TierInput<V> tier_input(V D, V radius_s, V radius_t, V area_t) {
  const V d = D - radius_t;
  const V inv = (V{} + 1.0) / d;
  return {area_t * inv * inv * (1 / kTierPi), radius_s * inv, radius_t * inv};
}
// d > 0 and r <= kMaxAreaRatio (as a bool or a lane mask).
template <class V>
inline auto tier_eligible(V D, V radius_t, const TierInput<V>& in) {
  return (D - radius_t > 0) & (in.r <= kMaxAreaRatio);
}

// Estimates of tier 0 and of tiers 1..6 (the latter only needed when tier 0 does not fit).
template <class V, class B>
inline V tier0_error(const TierInput<V>& in, B ssym, B tsym) {
  const V r = in.r, q = in.q, r2 = r * r, q2 = q * q;
  const V rp = ssym ? r2 * r2 : r2 * r;
  const V C = ssym ? V{} + kTierConstant[0][1] : V{} + kTierConstant[0][0];
  return C * in.S * (rp + (tsym ? q2 * q2 : q2 * q) + r2 * q2);
}
template <class V, class B>
inline void tier_errors(const TierInput<V>& in, B ssym, V (&e)[kTiers]) {
  const V r = in.r, q = in.q, r2 = r * r, r4 = r2 * r2, r8 = r4 * r4, q2 = q * q;
  const V rp = ssym ? r4 : r2 * r;
  auto C = [&](int t) { return ssym ? V{} + kTierConstant[t][1] : V{} + kTierConstant[t][0]; };
  e[1] = C(1) * in.S * (rp + r2 * q2);
  e[2] = C(2) * in.S * rp;
  e[3] = C(3) * in.S * rp * r2;
  e[4] = C(4) * in.S * rp * r4;
  e[5] = C(5) * in.S * rp * r8;
  e[6] = C(6) * in.S * rp * r8 * r4;
}

// Symmetric 3x3 second-moment tensor / area (xx yy zz xy xz yz) of a patch about its centroid.
template <class V>
struct Moments {
  V xx, yy, zz, xy, xz, yz;
  V mul_dot(V ax, V ay, V az, V bx, V by, V bz) const {  // a . M b
    return ax * (xx * bx + xy * by + xz * bz) + ay * (xy * bx + yy * by + yz * bz) + az * (xz * bx + yz * by + zz * bz);
  }
  V trace() const { return xx + yy + zz; }
};

// With u = c_s - c_t and the kernel K(x, y) = (n_s.(y - x)) (n_t.(x - y)) / (pi |x - y|^4):
// tr(M_s Hess_x K) and tr(M_t Hess_y K) at the centroids, times pi |u|^6 (first-order terms vanish at
// centroids, the mixed term too). A = n_s.(c_t - c_s), nu = n_t.u.
template <class V>
inline V hessian_source(V ux, V uy, V uz, V njx, V njy, V njz, V nu, V inv_uu, const Moments<V>& Ms) {
  return -8 * Ms.mul_dot(njx, njy, njz, ux, uy, uz) - 4 * nu * Ms.trace() + 24 * nu * Ms.mul_dot(ux, uy, uz, ux, uy, uz) * inv_uu;
}
template <class V>
inline V hessian_target(V ux, V uy, V uz, V nix, V niy, V niz, V A, V inv_uu, const Moments<V>& Mt) {
  return 8 * Mt.mul_dot(nix, niy, niz, ux, uy, uz) - 4 * A * Mt.trace() + 24 * A * Mt.mul_dot(ux, uy, uz, ux, uy, uz) * inv_uu;
}

// Tier 0: F_st ~ A_t K(c_s, c_t) + (1/2) tr(M_s Hess_x K) A_t + (1/2) tr(M_t Hess_y K) A_t.
template <class V>
inline V far_field_value(V ux, V uy, V uz, V nix, V niy, V niz, V njx, V njy, V njz, const Moments<V>& Ms,
                         const Moments<V>& Mt, V At) {
  const V uu = ux * ux + uy * uy + uz * uz;
  const V inv = (V{} + 1.0) / uu, i3 = inv * inv * inv;
  const V A = -(nix * ux + niy * uy + niz * uz), nu = njx * ux + njy * uy + njz * uz;
  const V src = hessian_source(ux, uy, uz, njx, njy, njz, nu, inv, Ms) * i3;
  const V tgt = hessian_target(ux, uy, uz, nix, niy, niz, A, inv, Mt) * i3;
  return (At * (1 / kTierPi)) * (A * nu * inv * inv + 0.5 * A * src + 0.5 * nu * tgt);
}
// Tier 1's correction to the analytic centroid value: (1/2) tr(M_s Hess_x K) A_t.
template <class V>
inline V centroid_hessian_correction(V ux, V uy, V uz, V nix, V niy, V niz, V njx, V njy, V njz, const Moments<V>& Ms,
                                     V At) {
  const V uu = ux * ux + uy * uy + uz * uz;
  const V inv = (V{} + 1.0) / uu, i3 = inv * inv * inv;
  const V A = -(nix * ux + niy * uy + niz * uz), nu = njx * ux + njy * uy + njz * uz;
  return (0.5 / kTierPi) * At * A * hessian_source(ux, uy, uz, njx, njy, njz, nu, inv, Ms) * i3;
}

}  // namespace lambert::formfactor::detail
