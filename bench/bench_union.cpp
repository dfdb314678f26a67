// The 2D Boolean step of exact visibility (issue 12): the union of K occluder quads projected onto a target's
// plane, intersected with the target square, as done at every outer point of a partially hidden pair.
// Clipper (integer coordinates, 2^29 units per half-size, what formfactor/src/exact_visibility.cpp uses) against
// CGAL's Boolean set operations with the exact-predicates-exact-constructions kernel.
//   build/bench/bench_union [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_set_2.h>
#include <polyclipping/clipper.hpp>

#include <array>
#include <cmath>
#include <random>
#include <vector>

namespace {

using Quad = std::array<std::array<double, 2>, 4>;

// K random convex quads (slightly rotated, overlapping), in [-1.5, 1.5]^2 around the target [-1, 1]^2.
std::vector<Quad> quads(int K, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> c(-1.2, 1.2), h(0.2, 0.8), a(-0.3, 0.3);
  std::vector<Quad> out;
  for (int k = 0; k < K; ++k) {
    const double x = c(rng), y = c(rng), w = h(rng), e = h(rng), t = a(rng), ct = std::cos(t), st = std::sin(t);
    Quad q;
    const double px[4] = {-w, w, w, -w}, py[4] = {-e, -e, e, e};
    for (int i = 0; i < 4; ++i) q[i] = {x + ct * px[i] - st * py[i], y + st * px[i] + ct * py[i]};
    out.push_back(q);
  }
  return out;
}

void ClipperUnion(benchmark::State& state) {
  const auto qs = quads(int(state.range(0)), 1);
  const double S = 536870912.0 / 1.5;
  ClipperLib::Clipper c;
  ClipperLib::Paths subj, res;
  ClipperLib::Path target = {{-ClipperLib::cInt(S), -ClipperLib::cInt(S)}, {ClipperLib::cInt(S), -ClipperLib::cInt(S)},
                             {ClipperLib::cInt(S), ClipperLib::cInt(S)}, {-ClipperLib::cInt(S), ClipperLib::cInt(S)}};
  double area = 0;
  for (auto _ : state) {
    subj.clear();
    for (const Quad& q : qs) {
      ClipperLib::Path p;
      for (const auto& v : q) p.push_back({ClipperLib::cInt(std::llround(v[0] * S)), ClipperLib::cInt(std::llround(v[1] * S))});
      subj.push_back(p);
    }
    c.Clear();
    c.AddPaths(subj, ClipperLib::ptSubject, true);
    c.AddPath(target, ClipperLib::ptClip, true);
    c.Execute(ClipperLib::ctIntersection, res, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
    area = 0;
    for (const auto& p : res) area += ClipperLib::Area(p);
    benchmark::DoNotOptimize(area);
  }
  state.counters["area"] = area / (S * S);
}

void CgalUnion(benchmark::State& state) {
  using K = CGAL::Exact_predicates_exact_constructions_kernel;
  using Polygon = CGAL::Polygon_2<K>;
  const auto qs = quads(int(state.range(0)), 1);
  Polygon target;
  for (auto [x, y] : std::array<std::array<double, 2>, 4>{{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}}) target.push_back({x, y});
  double area = 0;
  for (auto _ : state) {
    CGAL::Polygon_set_2<K> set;
    for (const Quad& q : qs) {
      Polygon p;
      for (const auto& v : q) p.push_back({v[0], v[1]});
      set.join(p);
    }
    set.intersection(target);
    std::vector<CGAL::Polygon_with_holes_2<K>> res;
    set.polygons_with_holes(std::back_inserter(res));
    area = 0;
    for (const auto& p : res) {
      area += CGAL::to_double(p.outer_boundary().area());
      for (auto h = p.holes_begin(); h != p.holes_end(); ++h) area += CGAL::to_double(h->area());
    }
    benchmark::DoNotOptimize(area);
  }
  state.counters["area"] = area;
}

}  // namespace

BENCHMARK(ClipperUnion)->Arg(2)->Arg(6)->Arg(20);
BENCHMARK(CgalUnion)->Arg(2)->Arg(6)->Arg(20);
BENCHMARK_MAIN();
