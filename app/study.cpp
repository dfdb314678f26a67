// `lambert study`: accuracy against cost for every knob, on cases with exact answers. One CSV row per run;
// scripts/plot_study.py turns the CSV into the plots and tables of docs/accuracy.md.
//
// Each geometry is assembled once per form-factor setting and then solved for every reflectance, method and
// solver tolerance; every row reports the full cost of its configuration (its assembly + its solve), i.e.
// what a user running that configuration alone would pay.
#include "study.hpp"

#include <fmt/format.h>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/exact.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "lambert/io/atomic_file.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"
#include "lambert/verify/verify.hpp"

namespace lambert::app {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
namespace shapes = mesh::shapes;

// A form-factor setting: a fixed rule, or the adaptive rule at a tolerance.
struct Knob {
  formfactor::Rule rule;
  int order;
  double tolerance;
  bool hierarchical = false;  // the hierarchical operator at `tolerance` (--hierarchy-tolerance)
  std::string label() const {
    if (hierarchical) return fmt::format("hierarchical {:.0e}", tolerance);
    return rule == formfactor::Rule::Adaptive ? fmt::format("adaptive {:.0e}", tolerance)
                                              : formfactor::to_string(rule, order);
  }
};
const Knob kPoint{formfactor::Rule::Point, 1, 0}, kGauss1{formfactor::Rule::Gauss, 1, 0},
    kGauss2{formfactor::Rule::Gauss, 2, 0}, kGauss4{formfactor::Rule::Gauss, 4, 0},
    kAdaptive4{formfactor::Rule::Adaptive, 1, 1e-4}, kAdaptive6{formfactor::Rule::Adaptive, 1, 1e-6},
    kAdaptive8{formfactor::Rule::Adaptive, 1, 1e-8}, kAdaptive10{formfactor::Rule::Adaptive, 1, 1e-10};

struct Row {
  std::string case_name, variant;
  double level = 0, h = 0;
  int patches = 0;
  double rho = 0;
  Knob knob{};
  int rays = 0;
  std::string method = "-";
  double solve_tolerance = 0;
  double t_ff = 0, t_vis = 0, t_solve = 0;
  int iterations = 0, matvecs = 0;
  double residual = 0;
  bool converged = true;
  long long rays_cast = 0;
  double row_sum_dev = 0;
  double max_err = 0, mean_err = 0, rms_err = 0;
  std::string visibility = "rays";  // the visibility path: rays (with `rays` per pair) or exact
};

constexpr const char* kHeader =
    "case,variant,level,h,patches,rho,rule,ff_tolerance,rays,method,solve_tolerance,threads,t_formfactors,"
    "t_visibility,t_solve,t_total,iterations,matvecs,residual,converged,rays_cast,row_sum_dev,max_rel_error,"
    "mean_rel_error,rms_rel_error,visibility";

std::string csv_line(const Row& r, int threads) {
  return fmt::format("{},{},{},{:.6g},{},{},{},{},{},{},{},{},{:.6g},{:.6g},{:.6g},{:.6g},{},{},{:.3e},{},{},{:.3e},"
                     "{:.6e},{:.6e},{:.6e},{}",
                     r.case_name, r.variant, r.level, r.h, r.patches, r.rho, r.knob.label(),
                     r.knob.rule == formfactor::Rule::Adaptive || r.knob.hierarchical ? fmt::format("{:g}", r.knob.tolerance) : "",
                     r.rays, r.method, r.solve_tolerance > 0 ? fmt::format("{:g}", r.solve_tolerance) : "", threads,
                     r.t_ff, r.t_vis, r.t_solve, r.t_ff + r.t_solve, r.iterations, r.matvecs, r.residual,
                     r.converged ? 1 : 0, r.rays_cast, r.row_sum_dev, r.max_err, r.mean_err, r.rms_err, r.visibility);
}

class Study {
 public:
  explicit Study(const StudyOptions& o) : o_(o) {}
  void run();

 private:
  struct Assembly {
    std::shared_ptr<formfactor::DenseMatrixOperator> F;  // dense knobs (null for the hierarchical one)
    std::shared_ptr<const solver::Solver> solver;  // on F (its row sums computed once for every solve)
    formfactor::Stats stats;
    double seconds = 0;  // form factors and the solver's set-up
  };
  Assembly assemble(const mesh::PatchGeometry& g, const Knob& k, int rays,
                    formfactor::VisibilityMethod vis = formfactor::VisibilityMethod::Rays) const;
  void emit(Row r);
  // Solve on an assembled geometry and compare with `exact` (channel 0).
  void solve_row(Row r, const mesh::PatchGeometry& g, const Assembly& a, const ColorField& rho, const ColorField& Le,
                 const Eigen::VectorXd& exact, solver::Method method, double tolerance);
  void sphere_convergence();
  void sphere_form_factors();
  void solver_methods();
  void furnace();
  void visibility();
  void scale();
  void hierarchy();
  void catalogue();

  const StudyOptions& o_;
  std::vector<std::string> lines_;
  Clock::time_point start_ = Clock::now();
};

Study::Assembly Study::assemble(const mesh::PatchGeometry& g, const Knob& k, int rays,
                                formfactor::VisibilityMethod vis) const {
  formfactor::Options ff;
  ff.visibility_method = vis;
  ff.rule = k.rule;
  ff.order = k.order;
  if (k.rule == formfactor::Rule::Adaptive) ff.tolerance = k.tolerance;
  ff.rays_per_pair = rays;
  Assembly a;
  const auto t = Clock::now();
  if (k.hierarchical) {
    formfactor::HierarchyOptions ho;
    ho.tolerance = k.tolerance;
    ho.rays_per_pair = rays;
    formfactor::HierarchyStats hs;
    auto H = std::make_shared<formfactor::HierarchicalOperator>(formfactor::build_hierarchy(g, ho, &hs));
    a.stats.rays_cast = hs.rays_cast;
    a.stats.row_sum_min = hs.row_sum_min;
    a.stats.row_sum_max = hs.row_sum_max;
    a.solver = std::make_shared<const solver::Solver>(H, g.area);
  } else {
    a.F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(g, ff, &a.stats));
    a.solver = std::make_shared<const solver::Solver>(a.F, g.area);
  }
  a.seconds = since(t);
  return a;
}

void Study::emit(Row r) {
  lines_.push_back(csv_line(r, tbb::this_task_arena::max_concurrency()));
  if (!o_.quiet)
    std::fprintf(stderr, "  study %4zu  %-28s %6d patches  %-14s rays %-3d %-12s rho %-5g  err %.2e  %.3f s\n",
                 lines_.size(), (r.case_name + " " + r.variant).c_str(), r.patches, r.knob.label().c_str(), r.rays,
                 r.method.c_str(), r.rho, r.max_err, r.t_ff + r.t_solve);
}

void Study::solve_row(Row r, const mesh::PatchGeometry& g, const Assembly& a, const ColorField& rho,
                      const ColorField& Le, const Eigen::VectorXd& exact, solver::Method method, double tolerance) {
  solver::Options so;
  so.method = method;
  so.tolerance = tolerance;
  so.max_iterations = 200000;  // Jacobi at rho = 0.999 needs ~10^4 sweeps per decade of residual
  const auto t = Clock::now();
  const solver::Solution s = a.solver->solve(rho, Le, so);
  r.t_solve = since(t);
  r.t_ff = a.seconds;
  r.t_vis = a.stats.seconds.count("visibility") ? a.stats.seconds.at("visibility") : 0.0;
  r.rays_cast = a.stats.rays_cast;
  r.row_sum_dev = std::max(std::abs(a.stats.row_sum_min - 1), std::abs(a.stats.row_sum_max - 1));
  r.patches = g.size();
  r.method = solver::to_string(s.method);
  r.solve_tolerance = tolerance;
  r.converged = s.converged;
  for (const auto& c : s.channels) {
    r.iterations = std::max(r.iterations, c.iterations);
    r.matvecs = std::max(r.matvecs, c.matvecs);
    r.residual = std::max(r.residual, c.residual);
  }
  verify::VerifyReport e;
  verify::relative_error(s.radiance.col(0), exact, g.area, e);
  r.max_err = e.max_rel_error;
  r.mean_err = e.mean_rel_error;
  r.rms_err = e.rms_rel_error;
  emit(r);
}

double mean_size(const mesh::PatchGeometry& g) {
  double a = 0;
  for (double x : g.area) a += x;
  return g.size() ? std::sqrt(a / g.size()) : 0.0;
}

// Sphere with varying emission and reflectance against the continuum answer: the convergence order in h.
void Study::sphere_convergence() {
  const int kmax = o_.quick ? 3 : 5;
  const std::vector<Knob> knobs =
      o_.quick ? std::vector<Knob>{kPoint, kGauss1, kAdaptive8} : std::vector<Knob>{kPoint, kGauss1, kGauss2, kAdaptive4, kAdaptive8};
  for (int K = 0; K <= kmax; ++K) {
    verify::SphereCase c;
    c.subdivisions = K;
    c.emission = "linear";
    c.rho = 0.9;
    const mesh::PatchGeometry g = verify::sphere_geometry(c);
    ColorField rho, Le;
    verify::sphere_fields(c, g, rho, Le);
    const Eigen::VectorXd exact = verify::sphere_exact(c, g);
    for (const Knob& k : knobs) {
      const Assembly a = assemble(g, k, 16);
      Row r{.case_name = "sphere_linear", .variant = fmt::format("K={}", K), .level = double(K), .h = mean_size(g),
            .rho = c.rho, .knob = k};
      solve_row(r, g, a, rho, Le, exact, solver::Method::GMRES, 1e-10);
    }
  }
}

// Uniform sphere: the discrete answer is exact, so the error is the form factors' (row sums) alone.
void Study::sphere_form_factors() {
  const std::vector<int> levels = o_.quick ? std::vector<int>{1, 2, 3} : std::vector<int>{1, 2, 3, 4};
  const std::vector<Knob> knobs = o_.quick ? std::vector<Knob>{kPoint, kGauss1, kAdaptive8}
                                           : std::vector<Knob>{kPoint, kGauss1, kGauss2, kGauss4, kAdaptive4,
                                                               kAdaptive6, kAdaptive8, kAdaptive10};
  for (int K : levels) {
    verify::SphereCase c;
    c.subdivisions = K;
    const mesh::PatchGeometry g = verify::sphere_geometry(c);
    for (const Knob& k : knobs) {
      const Assembly a = assemble(g, k, 16);
      for (double rho : {0.9, 0.99, 0.999}) {
        c.rho = rho;
        ColorField R, Le;
        verify::sphere_fields(c, g, R, Le);
        const Eigen::VectorXd exact = verify::sphere_exact(c, g);
        Row r{.case_name = "sphere_uniform", .variant = fmt::format("K={}", K), .level = double(K),
              .h = mean_size(g), .rho = rho, .knob = k};
        solve_row(r, g, a, R, Le, exact, solver::Method::GMRES, 1e-12);
      }
    }
  }
}

// Iterations and error against rho, method and solver tolerance, on one assembled room: the furnace room
// and block lit by its ceiling only (on the sphere every method converges in a few steps, its kernel being
// of rank one). Errors are against the same discrete problem solved to 1e-13: the solver's error alone.
void Study::solver_methods() {
  verify::FurnaceCase c;
  c.divisions = o_.quick ? 4 : 8;
  c.block_divisions = c.divisions / 2;
  const mesh::PatchGeometry g = verify::furnace_geometry(c);
  const Assembly a = assemble(g, kAdaptive8, 16);
  const std::vector<double> rhos = o_.quick ? std::vector<double>{0.5, 0.9, 0.99} : std::vector<double>{0.5, 0.9, 0.99, 0.999};
  const std::vector<double> tols = o_.quick ? std::vector<double>{1e-4, 1e-8} : std::vector<double>{1e-4, 1e-6, 1e-8, 1e-10};
  for (double rho : rhos) {
    const ColorField R = ColorField::Constant(g.size(), 3, rho);
    ColorField Le = ColorField::Zero(g.size(), 3);
    for (int i = 0; i < g.size(); ++i)
      if (g.centroid[i].z() > 0.999 && g.normal[i].z() < -0.5) Le.row(i).setConstant(1.0);  // the ceiling
    // Reference: the discrete solution to 1e-13 (GMRES), so that the rows show the solver's error alone.
    solver::Options ref;
    ref.method = solver::Method::GMRES;
    ref.tolerance = 1e-13;
    const Eigen::VectorXd exact = a.solver->solve(R, Le, ref).radiance.col(0);
    for (solver::Method m : {solver::Method::Jacobi, solver::Method::GaussSeidel, solver::Method::BiCGSTAB,
                             solver::Method::GMRES})
      for (double tol : tols) {
        Row r{.case_name = "solver", .variant = fmt::format("room n={}", c.divisions), .level = double(c.divisions),
              .h = mean_size(g), .rho = rho, .knob = kAdaptive8, .rays = 16};
        solve_row(r, g, a, R, Le, exact, m, tol);
      }
  }
}

// White furnace with an occluder: rays per pair against error, for three reflectances.
void Study::furnace() {
  const std::vector<int> divisions = o_.quick ? std::vector<int>{4} : std::vector<int>{4, 8, 12};
  const std::vector<int> rays = o_.quick ? std::vector<int>{4, 16} : std::vector<int>{1, 4, 16, 64, 256};
  auto one = [&](verify::FurnaceCase c, const Knob& k, int R) {
    const mesh::PatchGeometry g = verify::furnace_geometry(c);
    const Assembly a = assemble(g, k, R);
    for (double rho : {0.5, 0.9, 0.99}) {
      const ColorField Rf = ColorField::Constant(g.size(), 3, rho), Le = ColorField::Constant(g.size(), 3, 1.0);
      const Eigen::VectorXd exact = Eigen::VectorXd::Constant(g.size(), 1 / (1 - rho));
      Row r{.case_name = "furnace", .variant = fmt::format("n={}", c.divisions), .level = double(c.divisions),
            .h = mean_size(g), .rho = rho, .knob = k, .rays = R};
      solve_row(r, g, a, Rf, Le, exact, solver::Method::GMRES, 1e-12);
    }
  };
  for (int n : divisions)
    for (int R : rays) {
      verify::FurnaceCase c;
      c.divisions = n;
      c.block_divisions = std::max(1, n / 2);
      one(c, kAdaptive8, R);
    }
  if (!o_.quick)
    for (const Knob& k : {kPoint, kGauss1, kGauss2, kAdaptive4}) {
      verify::FurnaceCase c;
      c.divisions = 8;
      c.block_divisions = 4;
      one(c, k, 16);
    }
}

// The hierarchical operator against the dense one on cases with exact answers: its tolerance against the
// error and the time, so that docs/accuracy.md shows where --operator auto should switch. Cases: the uniformly
// emitting closed sphere (exact discrete answer E0 / (1 - rho), any deviation is operator error) and the white
// furnace (room with a block: occlusion).
void Study::hierarchy() {
  const Knob kH2{formfactor::Rule::Adaptive, 1, 1e-2, true}, kH3{formfactor::Rule::Adaptive, 1, 1e-3, true},
      kH4{formfactor::Rule::Adaptive, 1, 1e-4, true};
  const std::vector<Knob> knobs = o_.quick ? std::vector<Knob>{kH2, kH3, kAdaptive8} : std::vector<Knob>{kH2, kH3, kH4, kAdaptive8};
  const std::vector<int> levels = o_.quick ? std::vector<int>{3} : std::vector<int>{3, 4};
  for (int K : levels) {
    verify::SphereCase c;
    c.subdivisions = K;
    const mesh::PatchGeometry g = verify::sphere_geometry(c);
    for (const Knob& k : knobs) {
      const Assembly a = assemble(g, k, 16);
      for (double rho : {0.5, 0.9}) {
        c.rho = rho;
        ColorField R, Le;
        verify::sphere_fields(c, g, R, Le);
        const Eigen::VectorXd exact = verify::sphere_exact(c, g);
        Row r{.case_name = "hier_sphere", .variant = fmt::format("K={}", K), .level = double(K), .h = mean_size(g),
              .rho = rho, .knob = k, .rays = 16};
        solve_row(r, g, a, R, Le, exact, solver::Method::GMRES, 1e-12);
      }
    }
  }
  const std::vector<int> divisions = o_.quick ? std::vector<int>{8} : std::vector<int>{8, 16};
  for (int n : divisions) {
    verify::FurnaceCase c;
    c.divisions = n;
    c.block_divisions = n / 2;
    const mesh::PatchGeometry g = verify::furnace_geometry(c);
    for (const Knob& k : knobs) {
      const Assembly a = assemble(g, k, 16);
      for (double rho : {0.5, 0.9}) {
        const ColorField Rf = ColorField::Constant(g.size(), 3, rho), Le = ColorField::Constant(g.size(), 3, 1.0);
        const Eigen::VectorXd exact = Eigen::VectorXd::Constant(g.size(), 1 / (1 - rho));
        Row r{.case_name = "hier_furnace", .variant = fmt::format("n={}", n), .level = double(n), .h = mean_size(g),
              .rho = rho, .knob = k, .rays = 16};
        solve_row(r, g, a, Rf, Le, exact, solver::Method::GMRES, 1e-12);
      }
    }
  }
}

// Visibility axis: exact visibility (at three tolerances) against rays (1..256 per pair) on the white furnace
// at rho = 0.99 and on the room with a floating block at rho = 0.9 (uniform emission: exact answer E0/(1-rho)).
void Study::visibility() {
  const std::vector<int> rays = o_.quick ? std::vector<int>{4, 16} : std::vector<int>{1, 4, 16, 64, 256};
  const std::vector<Knob> exact = o_.quick ? std::vector<Knob>{kAdaptive6}
                                           : std::vector<Knob>{kAdaptive6, Knob{formfactor::Rule::Adaptive, 1, 1e-7},
                                                               kAdaptive8};
  struct Scene {
    const char* name;
    int n, m;
    double rho;
  };
  const std::vector<Scene> scenes = o_.quick ? std::vector<Scene>{{"furnace", 3, 1, 0.99}, {"room_block", 4, 2, 0.9}}
                                             : std::vector<Scene>{{"furnace", 6, 3, 0.99}, {"room_block", 8, 4, 0.9}};
  for (const Scene& sc : scenes) {
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(mesh::shapes::room_with_block(sc.n, sc.m));
    const ColorField Rf = ColorField::Constant(g.size(), 3, sc.rho), Le = ColorField::Constant(g.size(), 3, 1.0);
    const Eigen::VectorXd exact_L = Eigen::VectorXd::Constant(g.size(), 1 / (1 - sc.rho));
    auto one = [&](const Knob& k, int R, formfactor::VisibilityMethod vm) {
      const Assembly a = assemble(g, k, R, vm);
      Row r{.case_name = "visibility", .variant = fmt::format("{} n={}", sc.name, sc.n), .level = double(sc.n),
            .h = mean_size(g), .rho = sc.rho, .knob = k, .rays = vm == formfactor::VisibilityMethod::Exact ? 0 : R};
      r.visibility = formfactor::to_string(vm);
      solve_row(r, g, a, Rf, Le, exact_L, solver::Method::GMRES, 1e-12);
    };
    for (int R : rays) one(kAdaptive8, R, formfactor::VisibilityMethod::Rays);
    for (const Knob& k : exact) one(k, 16, formfactor::VisibilityMethod::Exact);
  }
}

// One closed scene spanning 1 mm to 1 km: a 1000 m furnace room with a 1 mm speck floating inside.
void Study::scale() {
  const std::vector<Knob> knobs =
      o_.quick ? std::vector<Knob>{kPoint, kAdaptive8} : std::vector<Knob>{kPoint, kGauss1, kGauss2, kAdaptive4, kAdaptive8};
  verify::FurnaceCase c;
  c.divisions = 4;
  c.block_divisions = 2;
  c.size = 1e3;
  c.speck = 1e-3;
  const mesh::PatchGeometry g = verify::furnace_geometry(c);
  for (const Knob& k : knobs) {
    const Assembly a = assemble(g, k, 16);
    for (double rho : {0.9, 0.99, 0.999}) {
      const ColorField Rf = ColorField::Constant(g.size(), 3, rho), Le = ColorField::Constant(g.size(), 3, 1.0);
      const Eigen::VectorXd exact = Eigen::VectorXd::Constant(g.size(), 1 / (1 - rho));
      Row r{.case_name = "scale", .variant = "1mm-1km", .level = 1, .h = mean_size(g), .rho = rho, .knob = k,
            .rays = 16};
      solve_row(r, g, a, Rf, Le, exact, solver::Method::GMRES, 1e-12);
    }
  }
}

// Catalogue view factors between two surfaces, each meshed at a level; F_12 aggregated over patches.
void Study::catalogue() {
  struct Config {
    std::string name, variant;
    double exact;
    std::function<shapes::Polygons(int)> first, second;  // meshed at level k
  };
  const Vec3 X(1, 0, 0), Y(0, 1, 0), Z(0, 0, 1);
  std::vector<Config> configs;
  // C-11: unit squares facing each other at distance 1.
  configs.push_back({"opposed_squares", "a=b=c=1", formfactor::exact::opposed_rectangles(1, 1, 1),
                     [=](int k) { return shapes::grid(Vec3::Zero(), X, Y, k, k); },
                     [=](int k) { return shapes::grid(Vec3(0, 0, 1), Y, X, k, k); }});
  // C-14: perpendicular unit squares sharing an edge (touching: the kernel is singular along it).
  configs.push_back({"common_edge", "l=w=h=1", formfactor::exact::perpendicular_common_edge(1, 1, 1),
                     [=](int k) { return shapes::grid(Vec3::Zero(), X, Y, k, k); },    // z = 0, facing +z
                     [=](int k) { return shapes::grid(Vec3::Zero(), Z, X, k, k); }});  // y = 0, facing +y
  // Nearly touching: the same squares pulled apart along both planes by a gap g (relative to the size).
  for (double gap : {1e-2, 1e-4, 1e-6})
    configs.push_back({"near_touching", fmt::format("gap={:g}", gap),
                       formfactor::exact::perpendicular_rectangles(0, 1, gap, 1 + gap, 0, 1, gap, 1 + gap),
                       [=](int k) { return shapes::grid(Vec3(0, 0, gap), Z, X, k, k); },   // y = 0, facing +y
                       [=](int k) { return shapes::grid(Vec3(0, gap, 0), X, Y, k, k); }});  // z = 0, facing +z
  // Slivers: opposed squares cut into k strips of two triangles each (aspect ratio ~k).
  auto slivers = [](const Vec3& o, const Vec3& u, const Vec3& v, int k) {
    shapes::Polygons p;
    for (const auto& q : shapes::grid(o, u, v, k, 1)) {
      p.push_back({q[0], q[1], q[2]});
      p.push_back({q[0], q[2], q[3]});
    }
    return p;
  };
  configs.push_back({"sliver", "strips", formfactor::exact::opposed_rectangles(1, 1, 1),
                     [=](int k) { return slivers(Vec3::Zero(), X, Y, k); },
                     [=](int k) { return slivers(Vec3(0, 0, 1), Y, X, k); }});
  const std::vector<Knob> knobs = o_.quick ? std::vector<Knob>{kPoint, kGauss1, kGauss2, kAdaptive8}
                                           : std::vector<Knob>{kPoint, kGauss1, kGauss2, kGauss4, kAdaptive4,
                                                               kAdaptive6, kAdaptive8};
  for (const Config& cfg : configs) {
    std::vector<int> levels = o_.quick ? std::vector<int>{1, 2, 4, 8} : std::vector<int>{1, 2, 4, 8, 16};
    if (cfg.name == "sliver") levels = o_.quick ? std::vector<int>{4, 16, 64} : std::vector<int>{4, 16, 64, 256};
    for (int k : levels) {
      shapes::Polygons p = cfg.first(k);
      const int n1 = int(p.size());
      for (auto& q : cfg.second(k)) p.push_back(std::move(q));
      const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(p);
      double A1 = 0;
      for (int i = 0; i < n1; ++i) A1 += g.area[i];
      for (const Knob& kn : knobs) {
        const Assembly a = assemble(g, kn, 16);
        const auto& F = a.F->matrix();
        double AF = 0;
        for (int i = 0; i < n1; ++i)
          for (int j = n1; j < g.size(); ++j) AF += g.area[i] * F(i, j);
        const double err = std::abs(AF / A1 - cfg.exact) / cfg.exact;
        Row r{.case_name = cfg.name, .variant = cfg.variant, .level = double(k), .h = mean_size(g), .knob = kn};
        r.patches = g.size();
        r.t_ff = a.seconds;
        r.t_vis = 0;
        r.row_sum_dev = 0;
        r.max_err = r.mean_err = r.rms_err = err;
        emit(r);
      }
    }
  }
}

void Study::run() {
  // Fail before minutes of work if the output directory cannot be made or written.
  std::error_code ec;
  std::filesystem::create_directories(o_.out, ec);
  if (ec || !std::filesystem::is_directory(o_.out))
    throw InputError("study: cannot create the output directory '" + o_.out + "'" + (ec ? ": " + ec.message() : ""));
  const std::string path = (std::filesystem::path(o_.out) / "study.csv").string();
  io::write_file_atomically(path + ".probe", [](std::ostream&) {});
  std::filesystem::remove(path + ".probe", ec);
  if (!o_.quiet)
    std::fprintf(stderr, "lambert study (%s): writing %s/study.csv\n", o_.quick ? "quick" : "full", o_.out.c_str());
  catalogue();
  sphere_convergence();
  sphere_form_factors();
  solver_methods();
  furnace();
  visibility();
  scale();
  hierarchy();
  io::write_file_atomically(path, [&](std::ostream& out) {
    out << kHeader << '\n';
    for (const auto& l : lines_) out << l << '\n';
  });
  if (!o_.quiet)
    std::fprintf(stderr, "lambert study: %zu runs in %.1f s -> %s\n  plots and tables: python3 scripts/plot_study.py %s\n",
                 lines_.size(), since(start_), path.c_str(), path.c_str());
}

}  // namespace

int run_study(const StudyOptions& o) {
  Study(o).run();
  return 0;
}

}  // namespace lambert::app
