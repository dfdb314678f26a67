#include "lambert/verify/verify.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>

#include <fmt/format.h>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/shapes.hpp"

namespace lambert::verify {
namespace {

using solver::Options;
using solver::Solution;
using solver::Solver;

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

void require(bool ok, const std::string& what) {
  if (!ok) throw InputError("verify: " + what);
}

// Shared tail of both cases: assemble, solve, compare with `exact`, fill the report.
struct Run {
  mesh::PatchGeometry geometry;
  Solution solution;
  std::vector<double> row_sums;
  double residual_max = 0;  // max_i |Le_i + rho_i (F L)_i - L_i|, channel 0, recomputed from F and L
};

Run assemble_and_solve(mesh::PatchGeometry geometry, const formfactor::Options& ff,
                       const std::function<void(const mesh::PatchGeometry&, ColorField&, ColorField&)>& fields,
                       const Options& so, VerifyReport& r) {
  Run run;
  auto t = Clock::now();
  run.geometry = std::move(geometry);
  r.seconds["mesh"] = since(t);
  r.patches = run.geometry.size();

  t = Clock::now();
  auto F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(run.geometry, ff, &r.ff));
  r.seconds["form_factors"] = since(t);

  t = Clock::now();
  const Solver solver(F, run.geometry.area);
  ColorField rho, Le;
  fields(run.geometry, rho, Le);
  run.solution = solver.solve(rho, Le, so);
  r.seconds["solve"] = since(t);
  run.row_sums = solver.row_sums();
  {
    const Eigen::VectorXd L = run.solution.radiance.col(0);
    Eigen::VectorXd FL(L.size());
    solver.transport().apply(L, FL);
    run.residual_max = (Le.col(0) + rho.col(0).cwiseProduct(FL) - L).cwiseAbs().maxCoeff();
  }
  const auto [lo, hi] = std::minmax_element(run.row_sums.begin(), run.row_sums.end());
  r.row_sum_min = *lo;
  r.row_sum_max = *hi;

  const Solution& s = run.solution;
  r.method = s.method;
  r.converged = s.converged;
  for (const auto& c : s.channels) {
    r.iterations = std::max(r.iterations, c.iterations);
    r.matvecs = std::max(r.matvecs, c.matvecs);
    r.residual = std::max(r.residual, c.residual);
  }
  return run;
}

void compare(const Run& run, const Eigen::VectorXd& exact, VerifyReport& r) {
  relative_error(run.solution.radiance.col(0), exact, run.geometry.area, r);
  // The bound is a prediction; 1e-12 absorbs the round-off of computing the error itself.
  r.within_bound = !(r.error_bound > 0) || r.max_rel_error <= r.error_bound * (1 + 1e-6) + 1e-12;
  r.passed = r.converged && r.max_rel_error <= r.tolerance && r.within_bound;
}

// A-posteriori bound on the relative error of a uniform closed case (exact answer X = E0/(1 - rho)) from
// what the run itself measured, without the exact answer: the row sums s of the assembled F and the
// residual res = Le + rho F L - L of the returned L. The error e = L - X satisfies
// (I - rho F) e = -res - rho (1 - s) X, and ||(I - rho F)^-1||_inf <= 1 / (1 - rho max s), so
// ||e||_inf / X <= (rho max|1 - s| + ||res||_inf / X) / (1 - rho max s).
double uniform_bound(double rho, double smin, double smax, double residual_max, double X) {
  const double dev = std::max(std::abs(1 - smin), std::abs(smax - 1));
  const double denom = 1 - rho * smax;
  return denom > 0 ? (rho * dev + residual_max / X) / denom : INFINITY;
}

std::string table(const VerifyReport& r, const std::string& exact_line, const std::string& basis, const Solution& s) {
  std::string t = fmt::format("lambert verify {}\n", r.name);
  t += fmt::format("  patches      {}\n", r.patches);
  t += fmt::format("  exact        {}\n", exact_line);
  t += fmt::format("  row sums     [1 {:+.2e}, 1 {:+.2e}]", r.row_sum_min - 1, r.row_sum_max - 1);
  if (r.error_bound > 0)
    t += fmt::format(", error bound from row sums and residual {:.2e}{}", r.error_bound,
                     r.within_bound ? "" : " (EXCEEDED: the bound or the solve is wrong)");
  t += "\n";
  t += fmt::format("  solve        {}, {} iterations, {} products F x, residual {:.2e}, {}\n", solver::to_string(r.method),
                   r.iterations, r.matvecs, r.residual, s.channels.empty() ? "" : s.channels[0].stop);
  t += fmt::format("  energy       emitted {:.6g} W, absorbed {:.6g} W, escaped {:.3g} W\n", s.emitted[0], s.absorbed[0],
                   s.escaped[0]);
  t += fmt::format("  time         mesh {:.3f} s, form factors {:.3f} s, solve {:.3f} s, total {:.3f} s\n",
                   r.seconds.at("mesh"), r.seconds.at("form_factors"), r.seconds.at("solve"), r.seconds.at("total"));
  t += fmt::format("  rel. error   max {:.2e} (patch {}), mean {:.2e}, area-weighted RMS {:.2e}\n", r.max_rel_error,
                   r.worst_patch, r.mean_rel_error, r.rms_rel_error);
  t += fmt::format("  tolerance    {:.2e} ({}): {}\n", r.tolerance, basis,
                   r.passed             ? "PASS"
                   : !r.converged       ? "FAIL (solve did not converge)"
                   : !r.within_bound    ? "FAIL (error above its a-posteriori bound)"
                                        : "FAIL (error above tolerance)");
  return t;
}

void check_sphere(const SphereCase& c) {
  require(c.subdivisions >= 0 && c.subdivisions <= 7, "subdivisions must be in [0, 7], got " + std::to_string(c.subdivisions));
  require(c.radius > 0 && std::isfinite(c.radius), "radius must be positive");
  require(c.rho >= 0 && c.rho < 1, "rho must be in [0, 1), got " + std::to_string(c.rho));
  require(c.E0 > 0 && std::isfinite(c.E0), "E0 must be positive");
  require(c.emission == "uniform" || c.emission == "cap" || c.emission == "linear",
          "emission must be uniform, cap or linear, got '" + c.emission + "'");
  require(c.tolerance >= 0, "tolerance must be >= 0");
}

void check_furnace(const FurnaceCase& c) {
  require(c.divisions >= 1 && c.divisions <= 64, "divisions must be in [1, 64], got " + std::to_string(c.divisions));
  require(c.block_divisions >= 1 && c.block_divisions <= 64,
          "block divisions must be in [1, 64], got " + std::to_string(c.block_divisions));
  require(c.rho >= 0 && c.rho < 1, "rho must be in [0, 1), got " + std::to_string(c.rho));
  require(c.E0 > 0 && std::isfinite(c.E0), "E0 must be positive");
  require(c.tolerance >= 0, "tolerance must be >= 0");
  require(c.size > 0 && std::isfinite(c.size), "size must be positive");
  require(c.speck >= 0 && c.speck < 0.1 * c.size, "speck must be in [0, 0.1 size)");
}

}  // namespace

mesh::PatchGeometry sphere_geometry(const SphereCase& c) {
  check_sphere(c);
  return mesh::PatchGeometry::from_polygons(mesh::shapes::icosphere(c.subdivisions, c.radius, true));
}

void sphere_fields(const SphereCase& c, const mesh::PatchGeometry& g, ColorField& rho, ColorField& Le) {
  const double R = c.radius;
  const int n = g.size();
  rho.resize(n, 3);
  Le.resize(n, 3);
  for (int i = 0; i < n; ++i) {
    const Vec3& x = g.centroid[i];
    double le = c.E0, rh = c.rho;
    if (c.emission == "cap") le = x.z() > 0.5 * R ? c.E0 : 0.0;
    if (c.emission == "linear") {
      le = c.E0 * (1 + x.z() / R) / 2;
      rh = c.rho * (0.75 + 0.25 * x.x() / R);
    }
    rho.row(i).setConstant(rh);
    Le.row(i).setConstant(le);
  }
}

Eigen::VectorXd sphere_exact(const SphereCase& c, const mesh::PatchGeometry& g, std::string* basis) {
  const int n = g.size();
  Eigen::VectorXd exact(n);
  if (c.emission == "uniform") {
    exact.setConstant(c.E0 / (1 - c.rho));
    if (basis) *basis = fmt::format("L = E0/(1-rho) = {:.10g} (closed polyhedron: exact discrete answer)", exact[0]);
    return exact;
  }
  ColorField rho, Le;
  sphere_fields(c, g, rho, Le);
  double area = 0, Ebar = 0, rhobar = 0;
  for (int i = 0; i < n; ++i) {
    area += g.area[i];
    Ebar += g.area[i] * Le(i, 0);
    rhobar += g.area[i] * rho(i, 0);
  }
  Ebar /= area;
  rhobar /= area;
  for (int i = 0; i < n; ++i) exact[i] = Le(i, 0) + rho(i, 0) * Ebar / (1 - rhobar);
  // Mean edge length of the icosphere relative to R: the icosahedron's edge is 1.0515 R, halved per level.
  const double h = 1.0514622242382672 / std::pow(2.0, c.subdivisions);
  if (basis)
    *basis = fmt::format("L = Le + rho Ebar/(1-rhobar), Ebar = {:.6g}, rhobar = {:.6g} (continuum limit, O(h), h = {:.3g} R)",
                         Ebar, rhobar, h);
  return exact;
}

mesh::PatchGeometry furnace_geometry(const FurnaceCase& c) {
  check_furnace(c);
  mesh::shapes::Polygons p = mesh::shapes::room_with_block(c.divisions, c.block_divisions);
  if (c.speck > 0) {
    const double e = c.speck / c.size;
    for (auto& q : mesh::shapes::box(Vec3::Constant(0.2), Vec3::Constant(0.2 + e), 1, false)) p.push_back(std::move(q));
  }
  for (auto& poly : p)
    for (Vec3& v : poly) v *= c.size;
  return mesh::PatchGeometry::from_polygons(p);
}

void relative_error(const Eigen::VectorXd& L, const Eigen::VectorXd& exact, const std::vector<double>& area,
                    VerifyReport& r) {
  double sum = 0, sq = 0, total_area = 0;
  r.max_rel_error = 0;
  r.worst_patch = -1;
  for (Eigen::Index i = 0; i < exact.size(); ++i) {
    const double diff = std::abs(L[i] - exact[i]);
    const double e = exact[i] > 0 ? diff / exact[i] : (diff == 0 ? 0.0 : INFINITY);
    sum += e;
    sq += area[size_t(i)] * e * e;
    total_area += area[size_t(i)];
    if (r.worst_patch < 0 || e > r.max_rel_error) {
      r.max_rel_error = e;
      r.worst_patch = int(i);
    }
  }
  r.mean_rel_error = exact.size() ? sum / double(exact.size()) : 0;
  r.rms_rel_error = total_area > 0 ? std::sqrt(sq / total_area) : 0;
}

VerifyReport verify_sphere(const SphereCase& c) {
  const auto start = Clock::now();
  VerifyReport r;
  r.name = fmt::format("sphere K={} {} rho={}", c.subdivisions, c.emission, c.rho);
  auto fields = [&](const mesh::PatchGeometry& g, ColorField& rho, ColorField& Le) { sphere_fields(c, g, rho, Le); };
  formfactor::Options ff = c.ff;
  if (ff.max_reflectance < 0) ff.max_reflectance = c.rho;  // the largest reflectance of every emission pattern
  Run run = assemble_and_solve(sphere_geometry(c), ff, fields, c.solve, r);
  std::string exact_line, basis;
  const Eigen::VectorXd exact = sphere_exact(c, run.geometry, &exact_line);
  if (c.emission == "uniform") {
    r.error_bound = uniform_bound(c.rho, r.row_sum_min, r.row_sum_max, run.residual_max, exact[0]);
    r.tolerance = c.tolerance > 0 ? c.tolerance : 1e-6;
    basis = c.tolerance > 0 ? "given" : "exact discrete answer: form-factor and solver error only";
  } else {
    const double h = 1.0514622242382672 / std::pow(2.0, c.subdivisions);
    r.tolerance = c.tolerance > 0 ? c.tolerance : 0.2 * h;
    basis = c.tolerance > 0 ? "given" : "0.2 h/R: >= 3x the measured O(h) discretisation error";
  }
  compare(run, exact, r);
  r.seconds["total"] = since(start);
  r.table = table(r, exact_line, basis, run.solution);
  return r;
}

VerifyReport verify_furnace(const FurnaceCase& c) {
  const auto start = Clock::now();

  VerifyReport r;
  r.name = fmt::format("furnace n={} block m={} rho={}", c.divisions, c.block_divisions, c.rho);
  auto fields = [&](const mesh::PatchGeometry& g, ColorField& rho, ColorField& Le) {
    rho = ColorField::Constant(g.size(), 3, c.rho);
    Le = ColorField::Constant(g.size(), 3, c.E0);
  };
  formfactor::Options ff = c.ff;
  if (ff.max_reflectance < 0) ff.max_reflectance = c.rho;
  Run run = assemble_and_solve(furnace_geometry(c), ff, fields, c.solve, r);
  const Eigen::VectorXd exact = Eigen::VectorXd::Constant(run.geometry.size(), c.E0 / (1 - c.rho));
  r.error_bound = uniform_bound(c.rho, r.row_sum_min, r.row_sum_max, run.residual_max, exact[0]);
  r.tolerance = c.tolerance > 0 ? c.tolerance : 5e-3;
  compare(run, exact, r);
  r.seconds["total"] = since(start);
  const std::string basis =
      c.tolerance > 0 ? "given" : "what 256-ray visibility achieves up to rho = 0.99, fixed (docs/benchmarks.md)";
  r.table = table(r, fmt::format("L = E0/(1-rho) = {:.10g} everywhere (closed enclosure)", exact[0]), basis,
                  run.solution);
  return r;
}

}  // namespace lambert::verify
