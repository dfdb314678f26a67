// Iterations, products F x and time per solver method against reflectance, on real form factors:
// the closed room [0,1]^3 with a floating block (mesh::shapes::room_with_block), lit by a ceiling
// panel; and a synthetic reciprocal operator of the same size for comparison.
// Run: bench_solver --benchmark_counters_tabular=true [--benchmark_filter=Room]
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"
#include "../tests/test_solver_util.hpp"

namespace {

using namespace lambert;

struct Problem {
  std::shared_ptr<formfactor::DenseMatrixOperator> F;
  std::vector<double> area;
  ColorField Le;
};

// Room with n x n quads per wall and an (n/2)^2-per-face block: 6 n^2 + 6 (n/2)^2 patches.
const Problem& room(int n) {
  static std::map<int, Problem> cache;
  auto it = cache.find(n);
  if (it == cache.end()) {
    const auto g = mesh::PatchGeometry::from_polygons(mesh::shapes::room_with_block(n, n / 2));
    Problem p;
    p.F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(g));
    p.area = g.area;
    p.Le = ColorField::Zero(g.size(), 3);
    for (int i = 0; i < g.size(); ++i) {
      const Vec3& c = g.centroid[i];
      if (c.z() > 0.999 && std::abs(c.x() - 0.5) < 0.25 && std::abs(c.y() - 0.5) < 0.25) p.Le.row(i).setConstant(1);
    }
    it = cache.emplace(n, std::move(p)).first;
  }
  return it->second;
}

const Problem& synthetic(int n) {
  static std::map<int, Problem> cache;
  auto it = cache.find(n);
  if (it == cache.end()) {
    auto s = solver::testing::make_synthetic(n, 1234, 0.05);
    Problem p{std::make_shared<formfactor::DenseMatrixOperator>(std::move(s.F)), s.area, ColorField::Zero(n, 3)};
    for (int i = 0; i < n; i += 7) p.Le.row(i).setConstant(1.0);
    it = cache.emplace(n, std::move(p)).first;
  }
  return it->second;
}

void run(benchmark::State& state, const Problem& p, solver::Method method) {
  const double rho = state.range(0) / 10000.0;
  const int n = p.F->size();
  const solver::Solver s(p.F, p.area);
  const ColorField R = ColorField::Constant(n, 3, rho);
  solver::Options o;
  o.method = method;
  o.max_iterations = 100000;
  solver::Solution sol;
  for (auto _ : state) sol = s.solve(R, p.Le, o);
  const auto& c = sol.channels.at(0);
  state.counters["patches"] = n;
  state.counters["rho"] = rho;
  state.counters["iterations"] = c.iterations;
  state.counters["products"] = c.matvecs;
  state.counters["converged"] = sol.converged;
  state.counters["residual"] = c.residual;
  state.SetLabel(solver::to_string(sol.method));
}

void rhos(benchmark::internal::Benchmark* b) {
  for (int r : {0, 3000, 5000, 7000, 9000, 9900, 9990}) b->Arg(r);
  b->Unit(benchmark::kMillisecond);
}

#define CASE(NAME, PROBLEM, METHOD)                                                   \
  void NAME##_##METHOD(benchmark::State& st) { run(st, PROBLEM, solver::Method::METHOD); } \
  BENCHMARK(NAME##_##METHOD)->Apply(rhos);
#define ALL(NAME, PROBLEM)         \
  CASE(NAME, PROBLEM, Auto)        \
  CASE(NAME, PROBLEM, Jacobi)      \
  CASE(NAME, PROBLEM, GaussSeidel) \
  CASE(NAME, PROBLEM, BiCGSTAB)    \
  CASE(NAME, PROBLEM, GMRES)

ALL(Room750, room(10))             // 600 + 150 = 750 patches
ALL(Room3000, room(20))            // 2400 + 600 = 3000 patches
ALL(Synthetic3000, synthetic(3000))

}  // namespace

BENCHMARK_MAIN();
