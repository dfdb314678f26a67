#include "lambert/formfactor/dense.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace lambert::formfactor {

void DenseMatrixOperator::apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const Eigen::Index n = F_.rows();
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, n, 256), [&](const tbb::blocked_range<Eigen::Index>& r) {
    const Eigen::Index b = r.begin(), m = r.end() - r.begin();
    y.segment(b, m).noalias() = F_.middleRows(b, m) * x;
  });
}

double DenseMatrixOperator::row_dot(int i, const Eigen::Ref<const Eigen::VectorXd>& x) const {
  return F_.row(i).dot(x);
}

double DenseMatrixOperator::row_sum(int i) const { return F_.row(i).sum(); }

}  // namespace lambert::formfactor
