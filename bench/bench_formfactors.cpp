// Form-factor assembly benchmarks (figures in docs/benchmarks.md):
//  * closed unit cube, n x n quads per face (n = 16, 32, 64): wall time, peak memory, and the largest error
//    over EVERY entry against the closed forms for aligned rectangles (no rays may be cast: convex scene);
//  * unit room with a floating block [0.35, 0.65]^3 (32 x 32 per wall, 10 x 10 per block face, 6,744
//    patches): wall time and row-sum error (ideal 1: the room is closed) against rays per pair.
// Run: build/bench/bench_formfactors [--benchmark_filter=Cube/64]
#include <benchmark/benchmark.h>
#include <tbb/parallel_for.h>

#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/exact.hpp"
#include "lambert/mesh/shapes.hpp"

namespace {

using namespace lambert;
namespace ff = lambert::formfactor;

// CPU seconds (user + system, all threads) of this process so far.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Peak resident set size of this process since the last reset, in MB (Linux: VmHWM, reset via clear_refs).
void reset_peak() { std::ofstream("/proc/self/clear_refs") << "5"; }
double peak_mb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

// Exact form factors between the grid quads of the closed unit cube, from tables of the closed-form corner
// functions (exact::parallel_corner / perpendicular_corner) at grid offsets: 16 look-ups per entry.
class CubeExact {
 public:
  CubeExact(const mesh::PatchGeometry& g, int n) : n_(n), h_(1.0 / n) {
    for (int p = 0; p < g.size(); ++p) {
      Cell c{};
      const Vec3& nn = g.normal[p];
      for (int k = 1; k < 3; ++k)
        if (std::abs(nn[k]) > std::abs(nn[c.axis])) c.axis = k;
      c.pos = int(std::lround(g.centroid[p][c.axis]));
      for (int k = 0; k < 3; ++k) {
        double lo = 1e300;
        for (const Vec3& v : g.polygon(p)) lo = std::min(lo, v[k]);
        c.lo[k] = int(std::lround(lo * n));
      }
      cells_.push_back(c);
    }
    const int w = 2 * n + 1;
    par_.resize(size_t(w) * w);
    for (int du = -n; du <= n; ++du)
      for (int dv = -n; dv <= n; ++dv) par_[size_t(du + n) * w + (dv + n)] = ff::exact::parallel_corner(du * h_, dv * h_, 1.0);
    perp_.resize(size_t(w) * (n + 1) * (n + 1));
    for (int du = -n; du <= n; ++du)
      for (int y = 0; y <= n; ++y)
        for (int z = 0; z <= n; ++z)
          perp_[(size_t(du + n) * (n + 1) + y) * (n + 1) + z] =
              ff::exact::perpendicular_corner(du * h_, (double(y) * y + double(z) * z) * h_ * h_);
  }

  double operator()(int p, int q) const {
    const Cell &A = cells_[p], &B = cells_[q];
    const int n = n_, w = 2 * n + 1;
    double sum = 0;
    if (A.axis == B.axis) {
      if (A.pos == B.pos) return 0;
      const int u = (A.axis + 1) % 3, v = (A.axis + 2) % 3;
      for (int i = 0; i < 2; ++i)
        for (int k = 0; k < 2; ++k)
          for (int j = 0; j < 2; ++j)
            for (int l = 0; l < 2; ++l) {
              const int du = (A.lo[u] + i) - (B.lo[u] + k), dv = (A.lo[v] + j) - (B.lo[v] + l);
              sum += ((i + k + j + l) % 2 ? -1 : 1) * par_[size_t(du + n) * w + (dv + n)];
            }
      return sum / (h_ * h_);
    }
    // A in plane axis a, B in plane axis b; e runs along their common edge line. z: A's distance from B's
    // plane, y: B's distance from A's plane, in grid units.
    const int a = A.axis, b = B.axis, e = 3 - a - b;
    const int z0 = B.pos == 0 ? A.lo[b] : n - A.lo[b] - 1, y0 = A.pos == 0 ? B.lo[a] : n - B.lo[a] - 1;
    for (int i = 0; i < 2; ++i)
      for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 2; ++j)
          for (int l = 0; l < 2; ++l) {
            const int du = (A.lo[e] + i) - (B.lo[e] + k);
            sum += ((i + k + j + l) % 2 ? -1 : 1) * perp_[(size_t(du + n) * (n + 1) + (y0 + j)) * (n + 1) + (z0 + l)];
          }
    return -sum / (h_ * h_);
  }

 private:
  struct Cell {
    int axis = 0, pos = 0, lo[3] = {0, 0, 0};
  };
  int n_;
  double h_;
  std::vector<Cell> cells_;
  std::vector<double> par_, perp_;
};

// The table look-up against the direct closed forms, on a small cube (guards the benchmark's reference).
void check_exact_tables() {
  const int n = 3;
  const auto g = mesh::PatchGeometry::from_polygons(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), n, true));
  const CubeExact ex(g, n);
  const auto F = ff::assemble(g).matrix();
  for (int p = 0; p < g.size(); ++p)
    for (int q = 0; q < g.size(); ++q)
      if (p != q && std::abs(F(p, q) - ex(p, q)) > 1e-8)
        throw std::runtime_error("benchmark reference disagrees at " + std::to_string(p) + "," + std::to_string(q));
}

void Cube(benchmark::State& state) {
  static bool checked = (check_exact_tables(), true);
  (void)checked;
  const int n = int(state.range(0));
  const auto g = mesh::PatchGeometry::from_polygons(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), n, true));
  ff::Stats st;
  ff::DenseMatrixOperator F;
  reset_peak();
  const double cpu0 = cpu_seconds();
  for (auto _ : state) F = ff::assemble(g, {}, &st);
  const double cpu = cpu_seconds() - cpu0;
  const double peak = peak_mb();
  // Every entry against the closed forms (outside the timed loop), in parallel over rows.
  const CubeExact ex(g, n);
  const auto& M = F.matrix();
  const int N = g.size();
  std::vector<double> worst(N, 0.0);
  tbb::parallel_for(0, N, [&](int i) {
    double w = 0;
    for (int j = 0; j < N; ++j) w = std::max(w, std::abs(M(i, j) - (i == j ? 0.0 : ex(i, j))));
    worst[i] = w;
  });
  double max_err = 0, row_err = 0;
  for (int i = 0; i < N; ++i) {
    max_err = std::max(max_err, worst[i]);
    row_err = std::max(row_err, std::abs(F.row_sum(i) - 1));
  }
  state.counters["patches"] = N;
  state.counters["max_abs_err"] = max_err;
  state.counters["row_sum_err"] = row_err;
  state.counters["rays"] = double(st.rays_cast);
  state.counters["peak_MB"] = peak;
  state.counters["matrix_MB"] = double(st.bytes) / (1 << 20);
  state.counters["ff_s"] = st.seconds["form_factors"];
  state.counters["cpu_s"] = cpu;  // all threads: the wall time on an otherwise idle machine is ~ cpu_s / cores
  if (st.rays_cast != 0) state.SkipWithError("rays cast for a convex scene");
}

void RoomWithBlock(benchmark::State& state) {
  const int rays = int(state.range(0));
  const auto g = mesh::PatchGeometry::from_polygons(mesh::shapes::room_with_block(32, 10));
  ff::Options o;
  o.rays_per_pair = rays;
  ff::Stats st;
  ff::DenseMatrixOperator F;
  reset_peak();
  const double cpu0 = cpu_seconds();
  for (auto _ : state) F = ff::assemble(g, o, &st);
  const double cpu = cpu_seconds() - cpu0;
  const double peak = peak_mb();
  double max_err = 0, sq = 0;
  for (int i = 0; i < g.size(); ++i) {
    const double e = F.row_sum(i) - 1;
    max_err = std::max(max_err, std::abs(e));
    sq += e * e;
  }
  state.counters["patches"] = g.size();
  state.counters["row_sum_max_err"] = max_err;
  state.counters["row_sum_rms_err"] = std::sqrt(sq / g.size());
  state.counters["rays"] = double(st.rays_cast);
  state.counters["pairs_ray_tested"] = double(st.pairs_ray_tested);
  state.counters["pairs_shaft_culled"] = double(st.pairs_shaft_culled);
  state.counters["peak_MB"] = peak;
  state.counters["cpu_s"] = cpu;
}

}  // namespace

BENCHMARK(Cube)->Arg(16)->Arg(32)->Arg(64)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(RoomWithBlock)->Arg(4)->Arg(16)->Arg(64)->Arg(256)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_MAIN();
