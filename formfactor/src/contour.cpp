// Double line integral for near pairs: A_i F_ij = (1/2pi) sum_ab (u_a . v_b) int_0^1 int_0^1 ln r dt ds.
// The inner integral over edge b is elementary (batch.hpp's edge_log, a panel's 15 nodes per call); the outer one over
// edge a is adaptive Gauss-Kronrod (7/15),
// split where edge a passes closest to edge b (the integrand's derivative is log-singular where edges touch).
#include <algorithm>
#include <cmath>
#include <queue>

#include "batch.hpp"
#include "internal.hpp"

namespace lambert::formfactor::detail {
namespace {

struct Interval {
  double a, b, value, error;
  int piece;
  bool operator<(const Interval& o) const { return error < o.error; }
};

// One Gauss-Kronrod 7/15 panel; error estimate |K15 - G7|, the error of the lower-order rule, which
// over-estimates the error of K15 (deliberately: QUADPACK's sharper heuristic let a 3e-7 error through on
// nearly touching parallel rectangles at tolerance 1e-8). f(tau, n, out) evaluates n <= 15 nodes at once.
template <class F>
Interval gk15(const F& f, double a, double b, int piece, long long& evals) {
  const double c = 0.5 * (a + b), h = 0.5 * (b - a);
  double tau[15], fv[15];
  for (int i = 0; i < 7; ++i) tau[i] = c - h * kXgk[i], tau[7 + i] = c + h * kXgk[i];
  tau[14] = c;
  f(tau, 15, fv);
  const double fc = fv[14];
  double k = fc * kWgk[7], g = fc * kWg[3];
  for (int i = 0; i < 7; ++i) {
    const double f1 = fv[i], f2 = fv[7 + i];
    k += kWgk[i] * (f1 + f2);
    if (i % 2 == 1) g += kWg[i / 2] * (f1 + f2);
  }
  evals += 15;
  return {a, b, k * h, std::abs(k - g) * h, piece};
}

// Parameter on segment a (origin A, direction u) of the point closest to segment b (origin B, direction v).
double closest_s(const Vec3& A, const Vec3& u, const Vec3& B, const Vec3& v) {
  const Vec3 r = A - B;
  const double a = u.dot(u), e = v.dot(v), f = v.dot(r), c = u.dot(r), b = u.dot(v);
  const double den = a * e - b * b;
  double s = den > 1e-14 * a * e ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1) {
    t = 1;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
  return s;
}

}  // namespace

ContourResult contour_pair(std::span<const Vec3> Pi, std::span<const Vec3> Pj, double abs_tol) {
  ContourResult res;
  const size_t mi = Pi.size(), mj = Pj.size();
  if (mi < 3 || mj < 3) return res;
  // Scale to unit edge lengths: ln r then stays O(1) and the closed-contour identity sum (u.v) = 0 removes the
  // reference length exactly.
  double ell = 0;
  for (size_t k = 0; k < mi; ++k) ell = std::max(ell, (Pi[(k + 1) % mi] - Pi[k]).norm());
  for (size_t k = 0; k < mj; ++k) ell = std::max(ell, (Pj[(k + 1) % mj] - Pj[k]).norm());
  if (!(ell > 0)) return res;
  const double inv = 1.0 / ell;
  const Vec3 o = Pi[0];
  std::vector<Vec3> A(mi), U(mi), B(mj), V(mj);
  for (size_t k = 0; k < mi; ++k) {
    A[k] = (Pi[k] - o) * inv;
    U[k] = (Pi[(k + 1) % mi] - Pi[k]) * inv;
  }
  for (size_t k = 0; k < mj; ++k) {
    B[k] = (Pj[k] - o) * inv;
    V[k] = (Pj[(k + 1) % mj] - Pj[k]) * inv;
  }
  double weight_sum = 0;
  for (size_t a = 0; a < mi; ++a)
    for (size_t b = 0; b < mj; ++b) {
      const double uv = U[a].dot(V[b]);
      if (std::abs(uv) > 1e-14 * U[a].norm() * V[b].norm()) weight_sum += std::abs(uv);
    }
  if (!(weight_sum > 0)) return res;
  const double tol_scaled = abs_tol * inv * inv * 2 * kPi;  // on sum_ab (u.v) J_ab
  const double tol_ab = tol_scaled / weight_sum;
  constexpr int kMaxIntervals = 4000;
  double total = 0, total_err = 0;
  const BatchKernels& K = batch_kernels();
  std::vector<double> cuts;
  for (size_t a = 0; a < mi; ++a) {
    const double La2 = U[a].squaredNorm();
    if (!(La2 > 0)) continue;
    for (size_t b = 0; b < mj; ++b) {
      const double uv = U[a].dot(V[b]);
      const double Lb2 = V[b].squaredNorm();
      if (!(Lb2 > 0) || !(std::abs(uv) > 1e-14 * std::sqrt(La2 * Lb2))) continue;
      const double Lb = std::sqrt(Lb2), inv_Lb = 1.0 / Lb;
      const Vec3 w0 = A[a] - B[b];
      // Breakpoints where edge a passes within a quarter of its length of segment b (closest approach, and
      // the feet of b's endpoints): the integrand's derivative is log-singular where the edges touch.
      cuts.assign({0.0, 1.0});
      auto add_cut = [&](double s) {
        if (s > 1e-12 && s < 1 - 1e-12) cuts.push_back(s);
      };
      const double near2 = 0.0625 * La2;
      const double sc = closest_s(A[a], U[a], B[b], V[b]);
      const Vec3 pc = A[a] + sc * U[a] - B[b];
      if ((pc - std::clamp(pc.dot(V[b]) / Lb2, 0.0, 1.0) * V[b]).squaredNorm() < near2) add_cut(sc);
      for (const Vec3& q : {B[b], Vec3(B[b] + V[b])}) {
        const double s = (q - A[a]).dot(U[a]) / La2;
        if ((A[a] + s * U[a] - q).squaredNorm() < near2) add_cut(s);
      }
      std::sort(cuts.begin(), cuts.end());
      cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double x, double y) { return y - x < 1e-12; }), cuts.end());
      // Each piece between cuts is integrated in tau with s = c0 + L phi(tau), phi(tau) = 10 tau^3 - 15 tau^4
      // + 6 tau^5: phi' vanishes to second order at both ends, which turns the (s - c) log(s - c) behaviour
      // at touching points into a much smoother tau^5 log(tau), so few subdivisions are needed.
      auto h = [&](int piece, const double* tau, int n, double* out) {
        const double c0 = cuts[piece], L = cuts[piece + 1] - cuts[piece];
        double sv[15], jac[15];
        for (int k = 0; k < n; ++k) {
          const double t = tau[k], t2 = t * t, u = 1 - t;
          const double phi = t2 * t * (10 - 15 * t + 6 * t2), dphi = 30 * t2 * u * u;
          sv[k] = c0 + L * phi;
          jac[k] = dphi > 0 ? L * dphi : 0.0;
        }
        K.edge_log(w0.data(), U[a].data(), V[b].data(), Lb, inv_Lb, sv, n, out);
        for (int k = 0; k < n; ++k) out[k] = jac[k] > 0 ? out[k] * jac[k] : 0.0;
      };
      std::priority_queue<Interval> heap;
      double val = 0, err = 0, mag = 0;
      for (size_t k = 0; k + 1 < cuts.size(); ++k) {
        const int piece = int(k);
        const Interval iv =
            gk15([&](const double* tau, int n, double* out) { h(piece, tau, n, out); }, 0.0, 1.0, piece, res.evaluations);
        val += iv.value;
        err += iv.error;
        mag += std::abs(iv.value);
        heap.push(iv);
      }
      // Below ~1e-14 of |J| the Kronrod/Gauss difference is rounding, not truncation: stop there.
      const double goal = std::max(tol_ab, 1e-14 * mag);
      for (int iter = int(heap.size()); err > goal && iter < kMaxIntervals; ++iter) {
        const Interval top = heap.top();
        heap.pop();
        const double mid = 0.5 * (top.a + top.b);
        if (!(mid > top.a && mid < top.b)) {  // cannot split further in double precision
          heap.push({top.a, top.b, top.value, 0.0, top.piece});
          err -= top.error;
          res.error += top.error * std::abs(uv);
          continue;
        }
        auto f = [&](const double* tau, int n, double* out) { h(top.piece, tau, n, out); };
        const Interval l = gk15(f, top.a, mid, top.piece, res.evaluations);
        const Interval r = gk15(f, mid, top.b, top.piece, res.evaluations);
        val += l.value + r.value - top.value;
        err += l.error + r.error - top.error;
        heap.push(l);
        heap.push(r);
      }
      // Re-sum to avoid drift from the incremental updates.
      val = 0;
      err = 0;
      while (!heap.empty()) {
        val += heap.top().value;
        err += heap.top().error;
        heap.pop();
      }
      total += uv * val;
      total_err += std::abs(uv) * err;
    }
  }
  const double scale = ell * ell / (2 * kPi);
  res.AF = total * scale;
  res.error = (total_err + res.error) * scale;
  return res;
}

}  // namespace lambert::formfactor::detail
