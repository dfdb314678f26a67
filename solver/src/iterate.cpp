// The four iterations on one channel. All see F only through TransportOperator.
#include "iterate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/IterativeLinearSolvers>  // IdentityPreconditioner
#include <unsupported/Eigen/IterativeSolvers>  // GMRES

namespace lambert::solver::detail {
class SystemMatrix;
}
namespace Eigen::internal {
template <>
struct traits<lambert::solver::detail::SystemMatrix> : public traits<Eigen::SparseMatrix<double>> {};
}  // namespace Eigen::internal

namespace lambert::solver::detail {
namespace {

using Eigen::VectorXd;
using formfactor::TransportOperator;

enum class Verdict { Continue, Diverged, Stagnated };

// History, progress callback, best iterate, divergence and stagnation, shared by all methods.
class Monitor {
 public:
  Monitor(const Options& options, int channel, int window, ChannelReport& report)
      : options_(options), channel_(channel), window_(window), report_(report) {}

  // Records the relative (and absolute) residual of the iterate after `iteration`.
  Verdict record(int iteration, double rel, double abs) {
    report_.history.push_back(rel);
    if (options_.progress) options_.progress(channel_, iteration, rel);
    if (!std::isfinite(rel) || !std::isfinite(abs)) return Verdict::Diverged;
    improved_ = rel < best_rel_;
    best_rel_ = std::min(best_rel_, rel);
    best_.push_back(best_rel_);
    min_abs_ = std::min(min_abs_, abs);
    if (abs > kDivergenceFactor * min_abs_) return Verdict::Diverged;
    const size_t n = best_.size();
    if (n > size_t(window_) && best_[n - 1] >= (1 - kStagnationGain) * best_[n - 1 - window_]) return Verdict::Stagnated;
    return Verdict::Continue;
  }
  bool improved() const { return improved_; }  // the last record() set a new best
  // After a restart from the true residual: a recurrence residual may have run below it, which
  // must not count as growth.
  void rebase(double abs) { min_abs_ = abs; }

 private:
  const Options& options_;
  int channel_, window_;
  ChannelReport& report_;
  std::vector<double> best_;  // running minimum of the relative residual
  double best_rel_ = std::numeric_limits<double>::infinity();
  double min_abs_ = std::numeric_limits<double>::infinity();
  bool improved_ = false;
};

const char* verdict_name(Verdict v) { return v == Verdict::Diverged ? "divergence" : "stagnation"; }

// Counts products with F.
struct Product {
  const TransportOperator& F;
  int count = 0;
  void operator()(const VectorXd& x, VectorXd& y) {
    F.apply(x, y);
    ++count;
  }
};

ChannelResult jacobi(Product& F, const VectorXd& rho, const VectorXd& Le, VectorXd& L, VectorXd& FL,
                     const Options& o, int channel) {
  ChannelResult out;
  Monitor monitor(o, channel, kStationaryWindow, out.report);
  const double le_norm = Le.norm();
  VectorXd next(L.size()), best = L;
  for (int k = 0;; ++k) {
    F(L, FL);
    next = Le + rho.cwiseProduct(FL);
    // next - L is exactly the residual of L: this sweep both measures L_k and produces L_{k+1}.
    const double abs = (next - L).norm(), rel = abs / residual_scale(L, le_norm);
    const Verdict v = monitor.record(k, rel, abs);
    out.report.iterations = k;
    if (rel <= o.tolerance) {
      out.report.stop = "converged";
      out.fl_valid = true;  // FL = F L_k, the returned iterate
      return out;
    }
    if (monitor.improved()) best = L;
    if (v != Verdict::Continue) {
      out.report.stop = verdict_name(v);
      break;
    }
    if (k == o.max_iterations) {
      out.report.stop = "max_iterations";
      break;
    }
    L.swap(next);
  }
  L = best;
  return out;
}

ChannelResult gauss_seidel(Product& F, const VectorXd& rho, const VectorXd& Le, VectorXd& L, VectorXd& FL,
                           const Options& o, int channel) {
  ChannelResult out;
  Monitor monitor(o, channel, kStationaryWindow, out.report);
  const TransportOperator& op = F.F;
  const int n = op.size();
  const double le_norm = Le.norm();
  VectorXd diag_factor(n);  // 1 - rho_i F_ii: row i solved for L_i
  for (int i = 0; i < n; ++i) diag_factor[i] = 1.0 - rho[i] * op.diagonal(i);

  // Starting residual (one product) for the history and the divergence baseline.
  F(L, FL);
  {
    const double abs = (Le + rho.cwiseProduct(FL) - L).norm();
    const double rel = abs / residual_scale(L, le_norm);
    monitor.record(0, rel, abs);
    if (rel <= o.tolerance) {
      out.report.stop = "converged";
      out.fl_valid = true;
      return out;
    }
  }
  VectorXd best = L;
  for (int k = 1;; ++k) {
    double sumsq = 0;
    for (int i = 0; i < n; ++i) {
      // Residual of row i at the moment of its update (rows < i already new).
      const double r = Le[i] + rho[i] * op.row_dot(i, L) - L[i];
      sumsq += r * r;
      L[i] += o.omega * r / diag_factor[i];
    }
    const double abs = std::sqrt(sumsq), rel = abs / residual_scale(L, le_norm);
    const Verdict v = monitor.record(k, rel, abs);
    out.report.iterations = k;
    if (rel <= o.tolerance) {
      // The running residual is a proxy: confirm with the true one before stopping.
      F(L, FL);
      const double true_rel = (Le + rho.cwiseProduct(FL) - L).norm() / residual_scale(L, le_norm);
      if (true_rel <= o.tolerance) {
        out.report.stop = "converged";
        out.fl_valid = true;
        return out;
      }
    }
    if (monitor.improved()) best = L;
    if (v != Verdict::Continue) {
      out.report.stop = verdict_name(v);
      break;
    }
    if (k >= o.max_iterations) {
      out.report.stop = "max_iterations";
      break;
    }
  }
  L = best;
  return out;
}

// BiCGSTAB (van der Vorst 1992) on A = I - diag(rho) F, restarted from the true residual when
// its recurrence claims convergence falsely or the shadow residual breaks down.
ChannelResult bicgstab(Product& F, const VectorXd& rho, const VectorXd& Le, VectorXd& x, VectorXd& FL,
                       const Options& o, int channel) {
  ChannelResult out;
  Monitor monitor(o, channel, kStationaryWindow, out.report);
  const int n = static_cast<int>(x.size());
  const double le_norm = Le.norm();
  VectorXd tmp(n);
  auto A = [&](const VectorXd& in, VectorXd& result) {  // result = in - rho .* (F in)
    F(in, tmp);
    result = in - rho.cwiseProduct(tmp);
  };
  auto true_residual = [&](VectorXd& r) {  // r = Le - A x, leaves F x in FL
    F(x, FL);
    r = Le - x + rho.cwiseProduct(FL);
  };

  VectorXd r(n), r_hat(n), p = VectorXd::Zero(n), v = VectorXd::Zero(n), s(n), t(n), best = x;
  true_residual(r);
  double rel = r.norm() / residual_scale(x, le_norm);
  monitor.record(0, rel, r.norm());
  if (rel <= o.tolerance) {
    out.report.stop = "converged";
    out.fl_valid = true;
    return out;
  }
  r_hat = r;
  double r0_dot_old = 1, alpha = 1, omega = 1;
  const double eps = std::numeric_limits<double>::epsilon();
  auto restart = [&] {
    r_hat = r;
    p.setZero();
    v.setZero();
    r0_dot_old = alpha = omega = 1;
  };
  for (int k = 1;; ++k) {
    double r0_dot = r_hat.dot(r);
    if (std::abs(r0_dot) < eps * eps * r_hat.squaredNorm() * r.squaredNorm() || omega == 0) {
      restart();  // r_hat nearly orthogonal to r: the Lanczos recurrence would break down
      r0_dot = r.squaredNorm();
    }
    p = r + (r0_dot / r0_dot_old) * (alpha / omega) * (p - omega * v);
    A(p, v);
    const double rv = r_hat.dot(v);
    alpha = rv != 0 ? r0_dot / rv : 0;
    s = r - alpha * v;
    A(s, t);
    const double tt = t.squaredNorm();
    omega = tt > 0 ? t.dot(s) / tt : 0;
    x += alpha * p + omega * s;
    r = s - omega * t;
    r0_dot_old = r0_dot;

    const double abs = r.norm();
    rel = abs / residual_scale(x, le_norm);
    const Verdict verdict = monitor.record(k, rel, abs);
    out.report.iterations = k;
    if (rel <= o.tolerance) {
      true_residual(r);  // the recurrence drifts from the true residual: check before stopping
      if (r.norm() / residual_scale(x, le_norm) <= o.tolerance) {
        out.report.stop = "converged";
        out.fl_valid = true;
        return out;
      }
      monitor.rebase(r.norm());
      restart();
    }
    if (monitor.improved()) best = x;
    if (verdict != Verdict::Continue) {
      out.report.stop = verdict_name(verdict);
      break;
    }
    if (k >= o.max_iterations) {
      out.report.stop = "max_iterations";
      break;
    }
  }
  x = best;
  return out;
}

}  // namespace

// Matrix-free A = I - diag(rho) F for Eigen's iterative solvers (Eigen's "matrix-free solvers" pattern).
class SystemMatrix : public Eigen::EigenBase<SystemMatrix> {
 public:
  using Scalar = double;
  using RealScalar = double;
  using StorageIndex = int;
  enum { ColsAtCompileTime = Eigen::Dynamic, MaxColsAtCompileTime = Eigen::Dynamic, IsRowMajor = false };

  SystemMatrix(Product& F, const VectorXd& rho) : F_(F), rho_(rho), tmp_(rho.size()) {}
  Eigen::Index rows() const { return rho_.size(); }
  Eigen::Index cols() const { return rho_.size(); }

  template <typename Rhs>
  Eigen::Product<SystemMatrix, Rhs, Eigen::AliasFreeProduct> operator*(const Eigen::MatrixBase<Rhs>& x) const {
    return Eigen::Product<SystemMatrix, Rhs, Eigen::AliasFreeProduct>(*this, x.derived());
  }
  // dst += alpha * A x
  template <typename Dest>
  void add_product(Dest& dst, const VectorXd& x, double alpha) const {
    if ((x.array() == 0).all()) return;  // Eigen forms A * 0 for a zero start: skip the product
    F_(x, tmp_);
    dst += alpha * (x - rho_.cwiseProduct(tmp_));
  }

 private:
  Product& F_;
  const VectorXd& rho_;
  mutable VectorXd tmp_;
};

}  // namespace lambert::solver::detail

namespace Eigen::internal {
template <typename Rhs>
struct generic_product_impl<lambert::solver::detail::SystemMatrix, Rhs, SparseShape, DenseShape, GemvProduct>
    : generic_product_impl_base<lambert::solver::detail::SystemMatrix, Rhs,
                                generic_product_impl<lambert::solver::detail::SystemMatrix, Rhs>> {
  template <typename Dest>
  static void scaleAndAddTo(Dest& dst, const lambert::solver::detail::SystemMatrix& lhs, const Rhs& rhs,
                            const double& alpha) {
    const Eigen::VectorXd x = rhs;
    lhs.add_product(dst, x, alpha);
  }
};
}  // namespace Eigen::internal

namespace lambert::solver::detail {
namespace {

// Restarted GMRES from Eigen, run one restart cycle per call so that every cycle starts from the
// true residual, which is monitored like the other methods. Each cycle solves A d = r from d = 0.
ChannelResult gmres(Product& F, const VectorXd& rho, const VectorXd& Le, VectorXd& x, VectorXd& FL,
                    const Options& o, int channel) {
  ChannelResult out;
  Monitor monitor(o, channel, kGmresWindow, out.report);
  const double le_norm = Le.norm();
  SystemMatrix A(F, rho);
  Eigen::GMRES<SystemMatrix, Eigen::IdentityPreconditioner> solver;
  solver.set_restart(o.restart);
  solver.compute(A);
  VectorXd r(x.size()), d(x.size()), best = x;
  for (int cycle = 0;; ++cycle) {
    F(x, FL);
    r = Le - x + rho.cwiseProduct(FL);
    const double abs = r.norm(), scale = residual_scale(x, le_norm), rel = abs / scale;
    const Verdict verdict = monitor.record(out.report.iterations, rel, abs);
    if (rel <= o.tolerance) {
      out.report.stop = "converged";
      out.fl_valid = true;
      return out;
    }
    if (monitor.improved()) best = x;
    if (verdict != Verdict::Continue) {
      out.report.stop = verdict_name(verdict);
      break;
    }
    if (out.report.iterations >= o.max_iterations) {
      out.report.stop = "max_iterations";
      break;
    }
    // Eigen's tolerance is relative to this cycle's starting residual. ||x|| usually grows
    // towards ||L||, so aiming at tol * ||x|| is conservative; the true residual decides.
    solver.setTolerance(std::min(0.5, 0.5 * o.tolerance * scale / abs));
    solver.setMaxIterations(std::min(o.restart, o.max_iterations - out.report.iterations));
    d.setZero();
    d = solver.solveWithGuess(r, d);
    out.report.iterations += static_cast<int>(std::max<Eigen::Index>(solver.iterations(), 1));
    x += d;
  }
  x = best;
  return out;
}

}  // namespace

ChannelResult iterate(Method method, const TransportOperator& F, const VectorXd& rho, const VectorXd& Le,
                      VectorXd& L, VectorXd& FL, const Options& options, int channel) {
  Product product{F};
  ChannelResult out;
  switch (method) {
    case Method::Jacobi: out = jacobi(product, rho, Le, L, FL, options, channel); break;
    case Method::GaussSeidel: out = gauss_seidel(product, rho, Le, L, FL, options, channel); break;
    case Method::BiCGSTAB: out = bicgstab(product, rho, Le, L, FL, options, channel); break;
    case Method::GMRES: out = gmres(product, rho, Le, L, FL, options, channel); break;
    case Method::Auto: throw std::logic_error("solver::detail::iterate: Auto must be resolved by the caller");
  }
  out.report.matvecs = product.count;
  return out;
}

}  // namespace lambert::solver::detail
