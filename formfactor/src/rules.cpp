// Quadrature rules: Gauss-Legendre, tensor rules on the square, collapsed rules on the triangle.
#include <cmath>
#include <map>
#include <mutex>

#include "internal.hpp"

namespace lambert::formfactor::detail {

void gauss_legendre01(int m, std::vector<double>& x, std::vector<double>& w) {
  x.resize(m);
  w.resize(m);
  // Newton on P_m from the Chebyshev-like initial guess; converges to machine precision in a few steps.
  for (int i = 0; i < m; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (m + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= m; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      if (m == 1) p0 = 1;
      dp = m * (z * p1 - p0) / (z * z - 1);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    // Recompute the derivative at the converged node for the weight.
    double p0 = 1, p1 = z;
    for (int k = 2; k <= m; ++k) {
      const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    dp = m * (z * p1 - p0) / (z * z - 1);
    x[m - 1 - i] = 0.5 * (1 + z);
    w[m - 1 - i] = 1.0 / ((1 - z * z) * dp * dp);  // 2/((1-z^2)P'^2) on [-1,1], halved for [0,1]
  }
}

namespace {
std::mutex rules_mutex;
std::map<int, Rule2D> square_rules, triangle_rules;
}  // namespace

const Rule2D& gauss_square(int m) {
  std::lock_guard lock(rules_mutex);
  auto it = square_rules.find(m);
  if (it != square_rules.end()) return it->second;
  std::vector<double> x, w;
  gauss_legendre01(m, x, w);
  Rule2D r;
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) {
      r.xi.push_back({x[a], x[b]});
      r.w.push_back(w[a] * w[b]);
    }
  return square_rules[m] = r;
}

const Rule2D& gauss_triangle(int m) {
  std::lock_guard lock(rules_mutex);
  auto it = triangle_rules.find(m);
  if (it != triangle_rules.end()) return it->second;
  // Duffy map (s, t) -> (s (1 - t), t) from the square, Jacobian (1 - t). Gauss-Legendre in s; in t the
  // weight (1 - t) is absorbed by an (m+1)-point... kept simple: Gauss-Legendre times the Jacobian, which is
  // exact for polynomials of degree 2m-2 in t (enough: the rules' role is an outer rule of known order).
  std::vector<double> x, w;
  gauss_legendre01(m, x, w);
  Rule2D r;
  double total = 0;
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) {
      const double s = x[a], t = x[b];
      r.xi.push_back({s * (1 - t), t});
      r.w.push_back(w[a] * w[b] * (1 - t));
      total += r.w.back();
    }
  for (double& v : r.w) v /= total;  // exact total is 1/2; normalise to 1
  return triangle_rules[m] = r;
}

}  // namespace lambert::formfactor::detail
