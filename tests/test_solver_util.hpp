#pragma once
// Synthetic transport operators for solver tests: reciprocal (A_i F_ij = A_j F_ji) with chosen row
// sums, built by symmetric Sinkhorn scaling of a positive symmetric kernel; and an exact direct solve.
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "lambert/formfactor/dense.hpp"
#include "lambert/mesh/types.hpp"

namespace lambert::solver::testing {

using Matrix = formfactor::DenseMatrixOperator::Matrix;

struct Synthetic {
  std::vector<double> area;  // m^2
  Matrix F;
};

// n patches with areas log-uniform in [area_lo, area_hi]; kernel K_ij = exp(-(t_i - t_j)^2 / width^2)
// for random t in [0,1] (small width: slow mixing, a spread spectrum like a real room), zero diagonal
// unless keep_diagonal. Row sums are row_sum_lo..row_sum_hi (1, 1 for a closed scene).
inline Synthetic make_synthetic(int n, unsigned seed, double width = 0.1, double row_sum_lo = 1,
                                double row_sum_hi = 1, double area_lo = 0.5, double area_hi = 2,
                                bool keep_diagonal = false) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Synthetic s;
  std::vector<double> t(n), target(n);
  for (int i = 0; i < n; ++i) {
    s.area.push_back(area_lo * std::pow(area_hi / area_lo, u(gen)));
    t[i] = u(gen);
    target[i] = s.area[i] * (row_sum_lo + (row_sum_hi - row_sum_lo) * u(gen));
  }
  Eigen::MatrixXd K(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      K(i, j) = (i == j && !keep_diagonal) ? 0.0 : std::exp(-(t[i] - t[j]) * (t[i] - t[j]) / (width * width)) + 1e-3;
  // Symmetric Sinkhorn: find d with d_i (K d)_i = target_i, then S = D K D is symmetric with row sums target.
  Eigen::VectorXd d = Eigen::VectorXd::Ones(n), tv = Eigen::Map<Eigen::VectorXd>(target.data(), n);
  for (int it = 0; it < 20000; ++it) {
    const Eigen::VectorXd Kd = K * d;
    const Eigen::VectorXd next = (d.array() * tv.array() / Kd.array()).sqrt();
    const double change = ((next - d).array().abs() / d.array()).maxCoeff();
    d = next;
    if (change < 1e-15) break;
  }
  s.F = Matrix(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) s.F(i, j) = d[i] * K(i, j) * d[j] / s.area[i];
  return s;
}

// Exact discrete answer of (I - diag(rho) F) L = Le by LU, independent of the iterative code.
inline Eigen::VectorXd direct_solve(const Matrix& F, const Eigen::VectorXd& rho, const Eigen::VectorXd& Le) {
  const Eigen::Index n = F.rows();
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n) - rho.asDiagonal() * Eigen::MatrixXd(F);
  return A.partialPivLu().solve(Le);
}

inline ColorField grey(const Eigen::VectorXd& v) {
  ColorField c(v.size(), 3);
  c.col(0) = c.col(1) = c.col(2) = v;
  return c;
}
inline ColorField constant(int n, double value) { return ColorField::Constant(n, 3, value); }

}  // namespace lambert::solver::testing
