#pragma once
// Internal: one scalar channel of (I - diag(rho) F) L = Le by the chosen method.
#include <algorithm>

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

// Relative residual denominator: ||L||, floored by ||Le|| (the exact L >= Le >= 0 has ||L|| >= ||Le||).
inline double residual_scale(const Eigen::VectorXd& L, double le_norm) { return std::max(L.norm(), le_norm); }

inline constexpr double kDivergenceFactor = 1e4;    // absolute residual above this x its minimum
inline constexpr double kStagnationGain = 1e-3;     // minimum relative improvement over the window
inline constexpr int kStationaryWindow = 50;        // iterations (Jacobi, Gauss-Seidel, BiCGSTAB)
inline constexpr int kGmresWindow = 2;              // restart cycles

}  // namespace lambert::solver::detail
