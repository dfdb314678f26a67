#pragma once
// Dense N x N form-factor matrix as a TransportOperator. Stored in double: 8 N^2 bytes
// (24,576 patches = 4.8 GB); float would halve that but its 6e-8 rounding, amplified by
// rho/(1-rho) near rho = 1, would break the 1e-6 accuracy we promise on closed scenes.
#include <cstddef>

#include <Eigen/Core>

#include "lambert/formfactor/operator.hpp"

namespace lambert::formfactor {

class DenseMatrixOperator final : public TransportOperator {
 public:
  // Row-major: apply() and Gauss-Seidel's row_dot() both stream contiguous rows.
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  DenseMatrixOperator() = default;
  explicit DenseMatrixOperator(Matrix F) : F_(std::move(F)) {}

  int size() const override { return static_cast<int>(F_.rows()); }
  void apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const override;
  double row_dot(int i, const Eigen::Ref<const Eigen::VectorXd>& x) const override;
  double diagonal(int i) const override { return F_(i, i); }
  double row_sum(int i) const override;

  const Matrix& matrix() const { return F_; }  // F(i, j): from patch i to patch j
  Matrix& matrix() { return F_; }

  // Bytes a dense matrix of n patches needs; used to refuse oversized requests before allocating.
  static std::size_t bytes_for(std::size_t n) { return n * n * sizeof(double); }

 private:
  Matrix F_;
};

}  // namespace lambert::formfactor
