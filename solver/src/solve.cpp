#include "lambert/solver/solve.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "iterate.hpp"

namespace lambert::solver {

using Eigen::VectorXd;

namespace {

struct MethodName {
  const char* name;
  Method method;
};
constexpr MethodName kMethodNames[] = {
    {"auto", Method::Auto},           {"jacobi", Method::Jacobi}, {"gauss-seidel", Method::GaussSeidel},
    {"gs", Method::GaussSeidel},      {"sor", Method::GaussSeidel}, {"bicgstab", Method::BiCGSTAB},
    {"gmres", Method::GMRES},
};

std::string describe(int patch, int channel) {
  static const char* names[] = {"R", "G", "B"};
  return "patch " + std::to_string(patch) + " channel " + names[channel];
}

void check_field(const ColorField& field, int n, const char* what, bool reflectance) {
  LAMBERT_CHECK(field.rows() == n,
                std::string(what) + ": " + std::to_string(field.rows()) + " rows for " + std::to_string(n) + " patches");
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const double v = field(i, c);
      std::ostringstream msg;
      msg.precision(17);
      if (!std::isfinite(v)) {
        msg << what << " at " << describe(i, c) << " is not finite (" << v << ")";
        throw InputError(msg.str());
      }
      if (reflectance && (v < 0 || v >= 1)) {
        msg << what << " at " << describe(i, c) << " is " << v << ", outside [0, 1)";
        throw InputError(msg.str());
      }
      if (!reflectance && v < 0) {
        msg << what << " at " << describe(i, c) << " is negative (" << v << ")";
        throw InputError(msg.str());
      }
    }
}

void check_options(const Options& o, int n) {
  if (!(o.tolerance > 0 && o.tolerance < 1))
    throw InputError("solver tolerance must be in (0, 1), got " + std::to_string(o.tolerance));
  if (o.max_iterations < 1)
    throw InputError("solver max_iterations must be >= 1, got " + std::to_string(o.max_iterations));
  if (!(o.omega > 0 && o.omega < 2))
    throw InputError("Gauss-Seidel relaxation omega must be in (0, 2), got " + std::to_string(o.omega));
  if (o.restart < 1) throw InputError("GMRES restart must be >= 1, got " + std::to_string(o.restart));
  if (o.initial_guess.size() != 0) {
    if (o.initial_guess.rows() != n)
      throw InputError("initial guess: " + std::to_string(o.initial_guess.rows()) + " rows for " +
                       std::to_string(n) + " patches");
    if (!o.initial_guess.allFinite()) throw InputError("initial guess has non-finite values");
  }
}

}  // namespace

Method choose_method(double rho_max, int patches, int restart) {
  if (rho_max == 0) return Method::Jacobi;
  const double gmres_bytes = (restart + 1.0) * patches * sizeof(double);
  return gmres_bytes > 2.0 * (1u << 30) ? Method::BiCGSTAB : Method::GMRES;
}

Method parse_method(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  for (const auto& m : kMethodNames)
    if (lower == m.name) return m.method;
  std::string valid;
  for (const auto& m : kMethodNames) valid += (valid.empty() ? "" : ", ") + std::string(m.name);
  throw InputError("unknown solver method '" + name + "' (valid: " + valid + ")");
}

std::string to_string(Method method) {
  switch (method) {
    case Method::Auto: return "auto";
    case Method::Jacobi: return "jacobi";
    case Method::GaussSeidel: return "gauss-seidel";
    case Method::BiCGSTAB: return "bicgstab";
    case Method::GMRES: return "gmres";
  }
  return "?";
}

Solver::Solver(std::shared_ptr<const formfactor::TransportOperator> F, std::vector<double> area)
    : F_(std::move(F)), area_(std::move(area)) {
  LAMBERT_CHECK(F_ != nullptr, "solver: no transport operator");
  const int n = F_->size();
  LAMBERT_CHECK(static_cast<int>(area_.size()) == n,
                "solver: " + std::to_string(area_.size()) + " areas for " + std::to_string(n) + " patches");
  for (int i = 0; i < n; ++i)
    LAMBERT_CHECK(area_[i] > 0 && std::isfinite(area_[i]),
                  "solver: area of patch " + std::to_string(i) + " is " + std::to_string(area_[i]) +
                      ", must be positive and finite (the geometry validated it)");
  row_sum_.resize(n);
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 64), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) row_sum_[i] = F_->row_sum(i);
  });
}

Solution Solver::solve(const ColorField& rho, const ColorField& Le, const Options& options) const {
  const auto start = std::chrono::steady_clock::now();
  const int n = size();
  check_field(rho, n, "reflectance", true);
  check_field(Le, n, "emission", false);
  check_options(options, n);

  Solution sol;
  sol.radiance = ColorField::Zero(n, 3);
  sol.irradiance = ColorField::Zero(n, 3);
  const double rho_max = n > 0 ? rho.maxCoeff() : 0;
  sol.method = options.method == Method::Auto ? choose_method(rho_max, n, options.restart) : options.method;
  if (sol.method == Method::GaussSeidel && !F_->has_rows())
    throw InputError("gauss-seidel sweeps rows of F, which this transport operator does not store (the hierarchical "
                     "operator); use --method auto, gmres, bicgstab or jacobi, or --operator dense");

  // ||diag(rho) F||_inf = max_i rho_i sum_j F_ij bounds the Neumann series' contraction factor.
  double contraction = 0;
  int worst = -1;
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (rho(i, c) * row_sum_[i] > contraction) contraction = rho(i, c) * row_sum_[i], worst = i;
  if (contraction >= 1) {
    std::ostringstream msg;
    msg << "patch " << worst << ": reflectance " << rho.row(worst).maxCoeff() << " times form-factor row sum "
        << row_sum_[worst] << " is >= 1, so the Neumann series (Jacobi, Gauss-Seidel) may not converge and the "
        << "solution may be unphysical (row sums above 1 are form-factor error)";
    sol.warnings.push_back(msg.str());
  }

  // Channels equal in rho and Le to an earlier one reuse its result; grey scenes solve one.
  const bool grey = rho.col(0) == rho.col(1) && rho.col(0) == rho.col(2) && Le.col(0) == Le.col(1) &&
                    Le.col(0) == Le.col(2) &&
                    (options.initial_guess.size() == 0 ||
                     (options.initial_guess.col(0) == options.initial_guess.col(1) &&
                      options.initial_guess.col(0) == options.initial_guess.col(2)));
  const int channels = grey ? 1 : 3;
  const double pi = std::numbers::pi;
  sol.converged = true;
  long negative = 0;
  double most_negative = 0, largest = 0;
  for (int c = 0; c < channels; ++c) {
    int same = -1;
    for (int e = 0; e < c && same < 0; ++e)
      if (rho.col(e) == rho.col(c) && Le.col(e) == Le.col(c) &&
          (options.initial_guess.size() == 0 || options.initial_guess.col(e) == options.initial_guess.col(c)))
        same = e;
    if (same >= 0) {
      sol.radiance.col(c) = sol.radiance.col(same);
      sol.irradiance.col(c) = sol.irradiance.col(same);
      sol.channels.push_back(sol.channels[same]);
      continue;
    }
    // The system is linear: solve for Le / s with s the power of two nearest below max Le (exact scaling,
    // no rounding), then scale back. Emission of 1e-170 or 1e160 W m^-2 sr^-1 would otherwise underflow or
    // overflow in the squared norms of the residuals (residual NaN, "divergence").
    const double emax = Le.col(c).maxCoeff();
    const double scale = emax > 0 ? std::ldexp(1.0, std::ilogb(emax)) : 1.0;
    const VectorXd r = rho.col(c), e = Le.col(c) / scale;
    VectorXd L = options.initial_guess.size() ? VectorXd(options.initial_guess.col(c) / scale) : e;
    VectorXd FL(n);
    ChannelReport report;
    if (e.isZero(0)) {
      // (I - diag(rho) F) is invertible for rho < 1 and row sums <= 1: zero emission, zero radiance.
      L.setZero();
      FL.setZero();
      report.stop = "converged";
      report.history.push_back(0);
    } else {
      detail::ChannelResult res = detail::iterate(sol.method, *F_, r, e, L, FL, options, c);
      if (!res.fl_valid) {
        F_->apply(L, FL);
        ++res.report.matvecs;
      }
      report = std::move(res.report);
      const VectorXd resid = e + r.cwiseProduct(FL) - L;
      report.residual = resid.norm() / detail::residual_scale(L, e.norm());
      report.residual_max = resid.cwiseAbs().maxCoeff() / std::max(L.cwiseAbs().maxCoeff(), e.cwiseAbs().maxCoeff());
      L *= scale;
      FL *= scale;
    }
    sol.converged = sol.converged && report.stop == "converged";
    negative += (L.array() < 0).count();
    most_negative = std::min(most_negative, L.minCoeff());
    largest = std::max(largest, L.maxCoeff());
    sol.radiance.col(c) = L;
    sol.irradiance.col(c) = pi * FL;
    sol.channels.push_back(std::move(report));
  }
  if (grey) {
    sol.radiance.col(1) = sol.radiance.col(2) = sol.radiance.col(0);
    sol.irradiance.col(1) = sol.irradiance.col(2) = sol.irradiance.col(0);
  }
  // Radiance is never negative in exact arithmetic. Values below zero by less than the solve's tolerance
  // times the largest radiance are what stopping at that tolerance leaves; larger ones mean inaccurate form
  // factors or a solve that went wrong. Both are reported, left as computed (no clamping).
  if (negative > 0) {
    std::ostringstream msg;
    msg << negative << " negative radiance values, the most negative " << most_negative;
    if (-most_negative <= options.tolerance * largest)
      msg << ": within the solve's tolerance (" << options.tolerance << ") of the largest radiance " << largest
          << ", i.e. iterative round-off where (almost) no light arrives; left as computed";
    else
      msg << " (largest radiance " << largest << "): the form factors or the solve are inaccurate";
    sol.warnings.push_back(msg.str());
  }

  // Energy balance per channel (W).
  for (int i = 0; i < n; ++i) {
    const double a = area_[i];
    for (int c = 0; c < 3; ++c) {
      sol.emitted[c] += pi * a * Le(i, c);
      sol.absorbed[c] += a * (1 - rho(i, c)) * sol.irradiance(i, c);
      sol.escaped[c] += pi * a * sol.radiance(i, c) * (1 - row_sum_[i]);
    }
  }
  for (int c = 0; c < 3; ++c)
    if (sol.emitted[c] > 0)
      sol.energy_residual = std::max(
          sol.energy_residual, std::abs(sol.emitted[c] - sol.absorbed[c] - sol.escaped[c]) / sol.emitted[c]);
  sol.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return sol;
}

Solution solve(const formfactor::TransportOperator& F, const std::vector<double>& area, const ColorField& reflectance,
               const ColorField& emission, const Options& options) {
  // Non-owning: F outlives this call.
  std::shared_ptr<const formfactor::TransportOperator> view(&F, [](const formfactor::TransportOperator*) {});
  return Solver(std::move(view), area).solve(reflectance, emission, options);
}

}  // namespace lambert::solver
