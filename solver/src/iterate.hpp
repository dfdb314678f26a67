#pragma once
// Internal: one scalar channel of (I - diag(rho) F) L = Le by the chosen method.
#include <algorithm>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <vector>

#include <Eigen/Core>

#include "lambert/formfactor/operator.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::solver::detail {

struct ChannelResult {
  ChannelReport report;
  bool fl_valid = false;  // FL holds F * L for the returned L
};

// L: on input the start, on output the converged (or best) iterate. FL: F * L when fl_valid.
// report.residual is left for the caller, which recomputes it from the returned L.
// Precondition: Le != 0 (the caller answers L = 0 directly), method != Auto.
ChannelResult iterate(Method method, const formfactor::TransportOperator& F, const Eigen::VectorXd& rho,
                      const Eigen::VectorXd& Le, Eigen::VectorXd& L, Eigen::VectorXd& FL, const Options& options,
                      int channel);

// Products of several channels' solves grouped into one apply_columns: each of `members` threads (a channel's solve)
// hands its product to apply(); the group runs when every member still solving has handed one in (the last to
// arrive runs it, in member order), so a channel's m-th product is always in the group's m-th run. Each column
// comes out bit for bit as from apply() alone (TransportOperator::apply_columns), so the channels' results do not
// depend on the grouping. A member that is done (or failed) calls leave(). An exception from the operator
// reaches every member of that run.
class ProductGroup {
 public:
  ProductGroup(const formfactor::TransportOperator& F, int members);
  void apply(int member, const double* x, double* y);
  void leave();
  const formfactor::TransportOperator& op() const { return F_; }

 private:
  void run();  // with mutex_ held
  const formfactor::TransportOperator& F_;
  std::mutex mutex_;
  std::condition_variable done_;
  int active_, waiting_ = 0;
  long generation_ = 0;
  std::vector<const double*> x_;
  std::vector<double*> y_;
  std::exception_ptr error_;
  Eigen::MatrixXd X_, Y_;
};

// One member's view of the group: apply() goes through ProductGroup::apply, the rest to the operator.
class GroupedOperator final : public formfactor::TransportOperator {
 public:
  GroupedOperator(ProductGroup& group, int member);
  int size() const override;
  void apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const override;
  double row_dot(int i, const Eigen::Ref<const Eigen::VectorXd>& x) const override;
  double diagonal(int i) const override;
  double row_sum(int i) const override;
  bool has_rows() const override;

 private:
  ProductGroup& group_;
  int member_;
};

// Relative residual denominator: ||L||, floored by ||Le|| (the exact L >= Le >= 0 has ||L|| >= ||Le||).
inline double residual_scale(const Eigen::VectorXd& L, double le_norm) { return std::max(L.norm(), le_norm); }

inline constexpr double kDivergenceFactor = 1e4;    // absolute residual above this x its minimum
inline constexpr double kStagnationGain = 1e-3;     // minimum relative improvement over the window
inline constexpr int kStationaryWindow = 50;        // iterations (Jacobi, Gauss-Seidel, BiCGSTAB)
inline constexpr int kGmresWindow = 2;              // restart cycles

}  // namespace lambert::solver::detail
