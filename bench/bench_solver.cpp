// Iterations, products F x and time per solver method against reflectance.
// Operators: a synthetic reciprocal closed operator ("synthetic", see tests/test_solver_util.hpp) and,
// when formfactor::assemble is available, the white-furnace room with a block (real form factors).
// Run: bench_solver --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "lambert/solver/solve.hpp"
#include "../tests/test_solver_util.hpp"

namespace {

using namespace lambert;

struct Problem {
  std::shared_ptr<formfactor::DenseMatrixOperator> F;
  std::vector<double> area;
};

const Problem& synthetic(int n) {
  static std::map<int, Problem> cache;
  auto it = cache.find(n);
  if (it == cache.end()) {
    auto s = solver::testing::make_synthetic(n, 1234, 0.05);
    it = cache.emplace(n, Problem{std::make_shared<formfactor::DenseMatrixOperator>(std::move(s.F)), s.area}).first;
  }
  return it->second;
}

void run(benchmark::State& state, const Problem& p, solver::Method method) {
  const double rho = state.range(0) / 10000.0;
  const int n = p.F->size();
  const solver::Solver s(p.F, p.area);
  ColorField R = ColorField::Constant(n, 3, rho), Le = ColorField::Zero(n, 3);
  for (int i = 0; i < n; i += 7) Le.row(i).setConstant(1.0);  // scattered emitters
  solver::Options o;
  o.method = method;
  o.max_iterations = 100000;
  solver::Solution sol;
  for (auto _ : state) sol = s.solve(R, Le, o);
  const auto& c = sol.channels.at(0);
  state.counters["rho"] = rho;
  state.counters["iterations"] = c.iterations;
  state.counters["products"] = c.matvecs;
  state.counters["converged"] = sol.converged;
  state.counters["residual"] = c.residual;
  state.SetLabel(solver::to_string(sol.method));
}

void rhos(benchmark::internal::Benchmark* b) {
  for (int r : {0, 3000, 5000, 7000, 9000, 9500, 9900, 9990}) b->Arg(r);
  b->Unit(benchmark::kMillisecond);
}

#define SYNTH(NAME, METHOD)                                                                         \
  void Synthetic2000_##NAME(benchmark::State& st) { run(st, synthetic(2000), solver::Method::METHOD); } \
  BENCHMARK(Synthetic2000_##NAME)->Apply(rhos);
SYNTH(auto, Auto)
SYNTH(jacobi, Jacobi)
SYNTH(gauss_seidel, GaussSeidel)
SYNTH(bicgstab, BiCGSTAB)
SYNTH(gmres, GMRES)

}  // namespace

BENCHMARK_MAIN();
