#pragma once
// TransportOperator: all the solver knows about form factors. F is N x N, dimensionless;
// F(i, j) is the fraction of energy leaving patch i (Lambertian) that arrives at patch j, so
// sum_j F(i, j) = 1 for a closed enclosure and A_i F_ij = A_j F_ji (reciprocity).
// Implementations: the dense matrix (dense.hpp) and the hierarchical operator (hierarchy.hpp).
#include <Eigen/Core>

namespace lambert::formfactor {

class TransportOperator {
 public:
  virtual ~TransportOperator() = default;
  virtual int size() const = 0;
  // y = F x. x and y have size() entries and must not alias.
  virtual void apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const = 0;
  // sum_j F(i, j) x_j: one row, for Gauss-Seidel sweeps.
  virtual double row_dot(int i, const Eigen::Ref<const Eigen::VectorXd>& x) const = 0;
  // F(i, i): 0 for planar patches, kept for generality (curved or clustered elements).
  virtual double diagonal(int i) const = 0;
  // sum_j F(i, j): 1 in a closed scene; the deficit is what escapes.
  virtual double row_sum(int i) const = 0;
  // Whether rows are stored (row_dot is then cheap). A hierarchical operator has no rows: Gauss-Seidel, which
  // sweeps rows, cannot use it (the solver refuses, and its automatic choice never picks it).
  virtual bool has_rows() const { return true; }
};

}  // namespace lambert::formfactor
