// Adaptive against uniform refinement on a scene file, measured against a fine uniform solve.
// A plain program (not a Google Benchmark one): every run is long and done once.
//
//   bench_adaptive_compare SCENE --reference EDGE [--uniform E1,E2,..] [--adaptive TOL:BUDGET:ROUNDS,..]
//                          [--no-reuse-too]
//
// Reference: mesh::prepare with max_edge = EDGE (a fine uniform mesh), form factors, solve.
// Uniform runs: the same with max_edge = E (time = prepare + form factors + solve).
// Adaptive runs: refine::solve_adaptive from the prepared (unrefined) input with that tolerance, patch
// budget and round limit (time = all rounds). --no-reuse-too repeats each adaptive run without
// reusing form factors between rounds, to measure what reuse saves.
// Error of a run against the reference: reflected radiance R = L - Le (all three channels), sampled at
// each reference patch's centroid from the run's patch that contains it (same input face, point in
// polygon), area-weighted over the reference patches:
//   L2 = sqrt(sum_i A_i |R(c_i) - R_i|^2 / sum_i A_i |R_i|^2),  L1 = sum_i A_i |R(c_i) - R_i|_1 / sum_i A_i |R_i|_1.
// Output: a Markdown table on stdout, per-round details of the adaptive runs after it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/refine/adaptive.hpp"
#include "lambert/solver/solve.hpp"

using namespace lambert;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Run {
  std::string kind, setting;
  mesh::Scene scene;
  ColorField radiance;
  double seconds = 0, ff_seconds = 0;
  std::string rounds;  // adaptive: patches per round
  std::vector<refine::AdaptiveRound> round_info;
};

Run uniform(const mesh::PolygonSoup& soup, double edge) {
  Run r;
  r.kind = "uniform";
  char buf[64];
  std::snprintf(buf, sizeof buf, "max edge %.4g m", edge);
  r.setting = buf;
  const auto t0 = Clock::now();
  mesh::PrepareOptions po;
  po.max_edge = edge;
  r.scene = mesh::prepare_and_build(soup, po);
  const auto t1 = Clock::now();
  const auto F = formfactor::assemble(r.scene.geometry);
  r.ff_seconds = since(t1);
  r.radiance = solver::solve(F, r.scene.geometry.area, r.scene.reflectance_field(), r.scene.emission_field()).radiance;
  r.seconds = since(t0);
  return r;
}

Run adaptive(const mesh::PolygonSoup& soup, double tol, int budget, int rounds, bool reuse) {
  Run r;
  r.kind = reuse ? "adaptive" : "adaptive, no reuse";
  char buf[96];
  std::snprintf(buf, sizeof buf, "tol %.3g, budget %d, rounds %d", tol, budget, rounds);
  r.setting = buf;
  const auto t0 = Clock::now();
  mesh::Report rep;
  const mesh::PolygonSoup prepared = mesh::prepare(soup, mesh::PrepareOptions{}, rep);
  refine::AdaptiveOptions o;
  o.tolerance = tol;
  o.max_patches = budget;
  o.max_rounds = rounds;
  o.reuse = reuse;
  auto res = refine::solve_adaptive(prepared, o);
  r.seconds = since(t0);
  for (const auto& ri : res.rounds) {
    r.ff_seconds += ri.assemble_seconds;
    r.rounds += (r.rounds.empty() ? "" : "→") + std::to_string(ri.patches);
  }
  r.rounds += " (" + res.stop + ")";
  r.round_info = res.rounds;
  r.scene = std::move(res.scene);
  r.radiance = std::move(res.solution.radiance);
  return r;
}

// Is x (on or near the plane of polygon P, normal n) inside P? Crossing test in the projection that
// drops n's largest coordinate; points within eps of an edge count as inside.
bool inside(const Vec3& x, std::span<const Vec3> P, const Vec3& n, double eps) {
  int drop = 0;
  n.cwiseAbs().maxCoeff(&drop);
  const int a = (drop + 1) % 3, b = (drop + 2) % 3;
  bool in = false;
  const size_t m = P.size();
  for (size_t i = 0, j = m - 1; i < m; j = i++) {
    const double xi = P[i][a], yi = P[i][b], xj = P[j][a], yj = P[j][b];
    // Distance to the edge (in projection): on the boundary counts as inside.
    const double ex = xj - xi, ey = yj - yi, len2 = ex * ex + ey * ey;
    const double t = len2 > 0 ? std::clamp(((x[a] - xi) * ex + (x[b] - yi) * ey) / len2, 0.0, 1.0) : 0.0;
    const double dx = x[a] - (xi + t * ex), dy = x[b] - (yi + t * ey);
    if (dx * dx + dy * dy <= eps * eps) return true;
    if ((yi > x[b]) != (yj > x[b]) && x[a] < (xj - xi) * (x[b] - yi) / (yj - yi) + xi) in = !in;
  }
  return in;
}

bool g_per_face = false;  // --per-face: print each input face's share of the squared error

struct Error {
  double l2 = 0, l1 = 0;
  long missed = 0;  // reference centroids no patch of the run contains (nearest centroid used)
};

Error error_vs(const Run& run, const Run& ref) {
  const auto& g = run.scene.geometry;
  std::vector<std::vector<int>> by_face;
  for (int p = 0; p < run.scene.patches(); ++p) {
    const int f = run.scene.face_id[p];
    if (f >= static_cast<int>(by_face.size())) by_face.resize(f + 1);
    by_face[f].push_back(p);
  }
  const ColorField R = run.radiance - run.scene.emission_field();
  const ColorField Rref = ref.radiance - ref.scene.emission_field();
  const auto& gr = ref.scene.geometry;
  double e2 = 0, n2 = 0, e1 = 0, n1 = 0;
  std::vector<double> face_e2(ref.scene.input_faces + 1, 0.0), face_n2(ref.scene.input_faces + 1, 0.0);
  Error err;
  for (int i = 0; i < ref.scene.patches(); ++i) {
    const Vec3& c = gr.centroid[i];
    const int f = ref.scene.face_id[i];
    int found = -1;
    double best = std::numeric_limits<double>::infinity();
    int nearest = -1;
    if (f < static_cast<int>(by_face.size()))
      for (int p : by_face[f]) {
        const double eps = 1e-9 * std::sqrt(g.area[p]) + 1e-12;
        if (std::abs(g.normal[p].dot(c - g.centroid[p])) < 1e-3 * std::sqrt(g.area[p]) &&
            inside(c, g.polygon(p), g.normal[p], eps)) {
          found = p;
          break;
        }
        const double d = (g.centroid[p] - c).squaredNorm();
        if (d < best) best = d, nearest = p;
      }
    if (found < 0) {
      ++err.missed;
      found = nearest;
    }
    if (found < 0) {
      std::fprintf(stderr, "reference patch %d (input face %d) has no counterpart\n", i, f);
      std::exit(1);
    }
    const double A = gr.area[i];
    const Eigen::RowVector3d d = R.row(found) - Rref.row(i);
    e2 += A * d.squaredNorm();
    if (f >= 0 && f < static_cast<int>(face_e2.size())) {
      face_e2[f] += A * d.squaredNorm();
      face_n2[f] += A * Rref.row(i).squaredNorm();
    }
    n2 += A * Rref.row(i).squaredNorm();
    e1 += A * d.cwiseAbs().sum();
    n1 += A * Rref.row(i).cwiseAbs().sum();
  }
  err.l2 = std::sqrt(e2 / n2);
  if (g_per_face) {
    std::fprintf(stderr, "%s %s: per input face: share of squared error, relative L2 on the face\n", run.kind.c_str(),
                 run.setting.c_str());
    for (size_t f = 0; f < face_e2.size(); ++f)
      if (face_n2[f] > 0)
        std::fprintf(stderr, "  face %zu: %.3f  %.4f\n", f, face_e2[f] / e2, std::sqrt(face_e2[f] / face_n2[f]));
  }
  err.l1 = e1 / n1;
  return err;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, sep);)
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr,
                 "usage: %s SCENE --reference EDGE [--uniform E1,E2,..] [--adaptive TOL:BUDGET:ROUNDS,..] "
                 "[--no-reuse-too]\n",
                 argv[0]);
    return 2;
  }
  const std::string path = argv[1];
  double ref_edge = 0;
  std::vector<double> edges;
  struct Cfg {
    double tol;
    int budget, rounds;
  };
  std::vector<Cfg> cfgs;
  bool no_reuse_too = false;
  for (int k = 2; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--reference" && k + 1 < argc) {
      ref_edge = std::atof(argv[++k]);
    } else if (a == "--uniform" && k + 1 < argc) {
      for (const auto& e : split(argv[++k], ',')) edges.push_back(std::atof(e.c_str()));
    } else if (a == "--adaptive" && k + 1 < argc) {
      for (const auto& c : split(argv[++k], ',')) {
        const auto p = split(c, ':');
        if (p.size() != 3) {
          std::fprintf(stderr, "--adaptive wants TOL:BUDGET:ROUNDS, got %s\n", c.c_str());
          return 2;
        }
        cfgs.push_back({std::atof(p[0].c_str()), std::atoi(p[1].c_str()), std::atoi(p[2].c_str())});
      }
    } else if (a == "--per-face") {
      g_per_face = true;
    } else if (a == "--no-reuse-too") {
      no_reuse_too = true;
    } else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  if (!(ref_edge > 0)) {
    std::fprintf(stderr, "--reference EDGE (> 0) is required\n");
    return 2;
  }
  try {
    const mesh::PolygonSoup soup = io::read_soup(path);
    std::fprintf(stderr, "reference: max edge %g m ...\n", ref_edge);
    const Run ref = uniform(soup, ref_edge);
    std::printf("scene %s; reference: uniform, max edge %g m, %d patches, %.1f s (form factors %.1f s)\n\n",
                path.c_str(), ref_edge, ref.scene.patches(), ref.seconds, ref.ff_seconds);
    std::vector<Run> runs;
    for (double e : edges) {
      std::fprintf(stderr, "uniform %g ...\n", e);
      runs.push_back(uniform(soup, e));
    }
    for (const Cfg& c : cfgs) {
      std::fprintf(stderr, "adaptive %g %d %d ...\n", c.tol, c.budget, c.rounds);
      runs.push_back(adaptive(soup, c.tol, c.budget, c.rounds, true));
      if (no_reuse_too) runs.push_back(adaptive(soup, c.tol, c.budget, c.rounds, false));
    }
    std::printf("| run | setting | patches | time (s) | of it form factors (s) | L2 error | L1 error | rounds |\n");
    std::printf("|---|---|---|---|---|---|---|---|\n");
    for (const Run& r : runs) {
      const Error e = error_vs(r, ref);
      std::printf("| %s | %s | %d | %.3f | %.3f | %.4f | %.4f | %s |\n", r.kind.c_str(), r.setting.c_str(),
                  r.scene.patches(), r.seconds, r.ff_seconds, e.l2, e.l1, r.rounds.c_str());
      if (e.missed > 0) std::fprintf(stderr, "  (%ld reference centroids outside every patch: nearest used)\n", e.missed);
    }
    std::printf("\nAdaptive rounds: patches, form-factor pairs reused, seconds (form factors / solve / indicators)\n\n");
    for (const Run& r : runs) {
      if (r.round_info.empty()) continue;
      std::printf("- %s, %s:", r.kind.c_str(), r.setting.c_str());
      for (const auto& ri : r.round_info)
        std::printf(" [%d, %.0f%% reused, %.3f / %.3f / %.3f]", ri.patches,
                    ri.pairs_total ? 100.0 * double(ri.pairs_reused) / double(ri.pairs_total) : 0.0,
                    ri.assemble_seconds, ri.solve_seconds, ri.indicator_seconds);
      std::printf("\n");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
