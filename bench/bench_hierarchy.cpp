// Hierarchical against dense operator: build time, solve time, memory and radiance error.
//   cube N     closed unit cube, N x N quads per face (inward), rho = 0.5 (--rho R), the top face (+z) emits Le = 1
//              (--rho 0.01: nearly the direct light alone, where the far links from the emitter err)
//   obj PATH   an OBJ scene (materials from its MTL), e.g. ../shared/models/udales_shape.obj, closed by a
//              large emitting sky box (Le = 1, rho = 0) around it when --sky is given
// Usage: bench_hierarchy [--dense] [--two-pass] [--no-portals] [--tolerance T] [--threads K] [--rho R] cube N |
//        obj PATH [--sky]
// With --dense and LAMBERT_HIERARCHY_ERRORS=FILE: per patch index, centroid, L_h and L_d (channel 0) into FILE (where the
// hierarchy's error sits). With --dense and LAMBERT_PROBE_ROW=i: row i of both operators (the hierarchy's per patch
// pair, for_each_in_row) summed over emitting and other sources, and the 12 sources it has most below dense;
// LAMBERT_PROBE_J=j puts source j first, and LAMBERT_PROBE_EXACT=1 adds the first two's exact visible form factor
// (visible_polygon_to_polygon against every other patch: seconds on udales), a reference for both ray estimates.
// --two-pass: brightness for the refinement from a first solve at 10x the tolerance (an experiment; the CLI
// uses the a-priori bound Le + rho max Le / (1 - rho_max)).
// The dense reference (--dense) is assembled at the default tolerance and solved to 1e-10; the error is
// max_i |L_h - L_d| / max L_d, with the mean (its sign) and rms over the patches. Peak memory: VmHWM of the process after each phase (the dense run, if any,
// last, so the hierarchical figure is not inflated by it).
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/scene.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"

using namespace lambert;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

long vm_hwm_kb() {
  std::ifstream f("/proc/self/status");
  std::string k;
  while (f >> k)
    if (k == "VmHWM:") {
      long v;
      f >> v;
      return v;
    }
  return -1;
}

struct Problem {
  mesh::PatchGeometry g;
  ColorField rho, Le;
};

Problem cube(int n, double rho) {
  Problem p;
  p.g = mesh::PatchGeometry::from_polygons(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), n, true));
  const int N = p.g.size();
  p.rho = ColorField::Constant(N, 3, rho);
  p.Le = ColorField::Zero(N, 3);
  for (int i = 0; i < N; ++i)
    if (p.g.centroid[i].z() > 1 - 1e-9) p.Le.row(i).setConstant(1.0);
  return p;
}

Problem obj(const std::string& path, bool sky) {
  mesh::PolygonSoup soup = io::read_soup(path);
  if (sky) {
    // A box 3x the scene's extent around it, inward, emitting: a uniform sky (and ground beyond the model).
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    for (const auto& v : soup.positions) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
    const Vec3 c = 0.5 * (lo + hi), h = 1.5 * (hi - lo).cwiseMax(Vec3::Constant((hi - lo).maxCoeff() * 0.5));
    mesh::Material m;
    m.name = "sky";
    m.reflectance = RGB::Zero();
    m.emission = RGB::Ones();
    const int mat = int(soup.materials.size());
    soup.materials.push_back(m);
    for (const auto& q : mesh::shapes::box(c - h, c + h, 4, true)) {
      mesh::SoupFace face;
      face.material = mat;
      for (const Vec3& v : q) {
        face.vertices.push_back(int(soup.positions.size()));
        soup.positions.push_back(v);
        soup.position_lines.push_back(0);
      }
      soup.faces.push_back(face);
    }
  }
  mesh::Scene s = mesh::prepare_and_build(soup, {});
  Problem p;
  p.g = s.geometry;
  p.rho = s.reflectance_field();
  p.Le = s.emission_field();
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  bool dense = false, sky = false, two_pass = false, portals = true;
  double tol = 1e-3, entry_tol = 0, cube_rho = 0.5;
  int threads = 0;
  std::string kind, arg;
  for (int k = 1; k < argc; ++k) {
    if (!std::strcmp(argv[k], "--dense")) dense = true;
    else if (!std::strcmp(argv[k], "--sky")) sky = true;
    else if (!std::strcmp(argv[k], "--two-pass")) two_pass = true;
    else if (!std::strcmp(argv[k], "--no-portals")) portals = false;
    else if (!std::strcmp(argv[k], "--tolerance") && k + 1 < argc) tol = std::atof(argv[++k]);
    else if (!std::strcmp(argv[k], "--threads") && k + 1 < argc) threads = std::atoi(argv[++k]);
    else if (!std::strcmp(argv[k], "--entry-tolerance") && k + 1 < argc) entry_tol = std::atof(argv[++k]);
    else if (!std::strcmp(argv[k], "--rho") && k + 1 < argc) cube_rho = std::atof(argv[++k]);
    else if (kind.empty()) kind = argv[k];
    else arg = argv[k];
  }
  if (kind.empty() || arg.empty()) {
    std::fprintf(stderr, "usage: bench_hierarchy [--dense] [--no-portals] [--tolerance T] [--entry-tolerance E] [--threads K] [--rho R] cube N | obj PATH "
                 "[--sky]\n");
    return 1;
  }
  std::optional<tbb::global_control> gc;
  if (threads > 0) gc.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
  const Problem p = kind == "cube" ? cube(std::atoi(arg.c_str()), cube_rho) : obj(arg, sky);
  const int N = p.g.size();
  const double rho_max = p.rho.maxCoeff();
  std::printf("patches %d, rho_max %.3g, tolerance %.1e, baseline VmHWM %.0f MB\n", N, rho_max, tol, vm_hwm_kb() / 1024.0);

  solver::Options so;
  so.tolerance = 1e-10;
  auto t0 = Clock::now();
  formfactor::HierarchyOptions ho;
  ho.tolerance = tol;
  ho.max_reflectance = rho_max;
  ho.entry_tolerance = entry_tol;
  ho.portals = portals;
  formfactor::HierarchyStats hs;
  if (two_pass) {
    // Brightness from a first solve at 10x the tolerance: links from what turned out dark are accepted coarser.
    formfactor::HierarchyOptions h1 = ho;
    h1.tolerance = std::min(0.1, 10 * tol);
    formfactor::HierarchyStats s1;
    const formfactor::HierarchicalOperator H1 = formfactor::build_hierarchy(p.g, h1, &s1);
    solver::Options o1;
    o1.tolerance = 1e-6;
    const solver::Solution L1 = solver::solve(H1, p.g.area, p.rho, p.Le, o1);
    const double lmax = L1.radiance.maxCoeff();
    ho.brightness.resize(N);
    for (int i = 0; i < N; ++i)
      ho.brightness[i] = L1.radiance.row(i).maxCoeff() + 10 * s1.radiance_error_max * lmax;
    std::printf("pass 1: %.2f s, %lld cluster links, %lld patch pairs\n", since(t0), s1.far_links, s1.leaf_links);
  }
  auto H = std::make_shared<formfactor::HierarchicalOperator>(formfactor::build_hierarchy(p.g, ho, &hs));
  const double t_build = since(t0);
  t0 = Clock::now();
  const solver::Solution sh = solver::solve(*H, p.g.area, p.rho, p.Le, so);
  const double t_solve = since(t0);
  std::printf("hierarchical: build %.2f s (tree %.2f, links %.2f), solve %.2f s (%d matvecs), total %.2f s, VmHWM %.0f MB, "
              "operator %.0f MB\n",
              t_build, hs.seconds_tree, hs.seconds_links, t_solve, sh.channels[0].matvecs, t_build + t_solve,
              vm_hwm_kb() / 1024.0, hs.bytes / 1048576.0);
  std::printf("  nodes %d, levels %d, far links %lld, leaf links %lld (dense pairs %lld, %.2f%%), culled %lld, "
              "shaft-clear %lld, ray-tested %lld, rays %lld\n",
              hs.nodes, hs.levels, hs.far_links, hs.leaf_links, hs.dense_pairs_equivalent,
              100.0 * double(hs.far_links + hs.leaf_links) / double(std::max(1LL, hs.dense_pairs_equivalent)),
              hs.pairs_culled, hs.links_shaft_clear, hs.links_ray_tested, hs.rays_cast);
  std::printf("  cluster links blocked %lld; patch pairs: ray-tested %lld, shaft-clear %lld\n", hs.links_blocked,
              hs.pairs_ray_tested, hs.pairs_shaft_clear);
  std::printf("  admitted row error %.2e (F), %.2e (radiance, relative), row sums [%.6f, %.6f]\n", hs.row_error_max,
              hs.radiance_error_max, hs.row_sum_min, hs.row_sum_max);
  if (dense) {
    t0 = Clock::now();
    formfactor::Options fo;
    fo.max_reflectance = rho_max;
    auto F = std::make_shared<formfactor::DenseMatrixOperator>(formfactor::assemble(p.g, fo));
    const double t_ff = since(t0);
    t0 = Clock::now();
    const solver::Solution sd = solver::solve(*F, p.g.area, p.rho, p.Le, so);
    const double t_ds = since(t0);
    double worst = 0, lmax = sd.radiance.maxCoeff();
    int at = 0;
    for (int i = 0; i < N; ++i)
      for (int c = 0; c < 3; ++c)
        if (std::abs(sh.radiance(i, c) - sd.radiance(i, c)) > worst) worst = std::abs(sh.radiance(i, c) - sd.radiance(i, c)), at = i;
    if (const char* dump = std::getenv("LAMBERT_HIERARCHY_ERRORS")) {  // per patch: centroid, L_h, L_d (channel 0)
      std::FILE* f = std::fopen(dump, "w");
      for (int i = 0; f && i < N; ++i)
        std::fprintf(f, "%d,%.9g,%.9g,%.9g,%.17g,%.17g\n", i, p.g.centroid[i].x(), p.g.centroid[i].y(),
                     p.g.centroid[i].z(), sh.radiance(i, 0), sd.radiance(i, 0));
      if (f) std::fclose(f);
    }
    const char* pr = std::getenv("LAMBERT_PROBE_ROW");
    if (pr && std::atoi(pr) >= 0 && std::atoi(pr) < N) {  // where a row's light goes missing (see the header)
      const int i = std::atoi(pr);
      std::vector<double> fh(size_t(N), 0.0);
      H->for_each_in_row(i, [&](int j, double f) { fh[size_t(j)] += f; });
      double sd_sky = 0, sh_sky = 0, sd_city = 0, sh_city = 0, Ld = 0, Lh = 0;  // emitters ("sky") and the rest
      std::vector<std::pair<double, int>> diffs;
      for (int j = 0; j < N; ++j) {
        const double fd = F->matrix()(i, j);
        const bool skyp = p.Le(j, 0) > 0;
        (skyp ? sd_sky : sd_city) += fd;
        (skyp ? sh_sky : sh_city) += fh[size_t(j)];
        Ld += fd * sd.radiance(j, 0);
        Lh += fh[size_t(j)] * sd.radiance(j, 0);
        diffs.push_back({fh[size_t(j)] - fd, j});
      }
      std::printf("row %d: F to emitters dense %.6e hierarchical %.6e; to the rest dense %.6e hierarchical %.6e; "
                  "sum F L_d dense %.6e hierarchical %.6e\n", i, sd_sky, sh_sky, sd_city, sh_city, Ld, Lh);
      std::sort(diffs.begin(), diffs.end());
      for (int k = 0; k < std::min(12, N); ++k) {
        const char* pj = std::getenv("LAMBERT_PROBE_J");
        const int j = pj && k == 0 && std::atoi(pj) >= 0 && std::atoi(pj) < N ? std::atoi(pj) : diffs[size_t(k)].second;
        std::printf("  source %d (%s, centroid %.1f %.1f %.1f): dense %.4e hierarchical %.4e\n", j,
                    p.Le(j, 0) > 0 ? "emitter" : "other", p.g.centroid[j].x(), p.g.centroid[j].y(),
                    p.g.centroid[j].z(), F->matrix()(i, j), fh[size_t(j)]);
        if (k < 2 && std::getenv("LAMBERT_PROBE_EXACT")) {
          std::vector<std::vector<Vec3>> occ;
          for (int q = 0; q < N; ++q)
            if (q != i && q != j) occ.emplace_back(p.g.polygon(q).begin(), p.g.polygon(q).end());
          const auto vis = formfactor::visible_polygon_to_polygon(p.g.polygon(i), p.g.polygon(j), occ, 1e-7);
          const auto unoccluded = formfactor::polygon_to_polygon(p.g.polygon(i), p.g.polygon(j), 1e-10);
          std::printf("    exact visible F %.4e (unoccluded %.4e, estimate %.1e)\n", vis.F, unoccluded.F, vis.error_estimate);
        }
      }
    }
    std::printf("dense: assemble %.2f s, solve %.2f s, total %.2f s, VmHWM %.0f MB\n", t_ff, t_ds, t_ff + t_ds,
                vm_hwm_kb() / 1024.0);
    std::printf("max |L_h - L_d| / max L_d = %.2e (patch %d), speed-up %.1fx\n", worst / lmax, at,
                (t_ff + t_ds) / (t_build + t_solve));
    // The errors' spread and sign over the patches (channel 0): blocked links only remove light, so a mean below 0
    // and few patches above dense tell a one-signed loss from noise.
    double sum = 0, sum2 = 0;
    int above = 0, below = 0;
    for (int i = 0; i < N; ++i) {
      const double d = (sh.radiance(i, 0) - sd.radiance(i, 0)) / lmax;
      sum += d;
      sum2 += d * d;
      above += d > 1e-5;
      below += d < -1e-5;
    }
    std::printf("(L_h - L_d) / max L_d over patches: mean %+.2e, rms %.2e; %d above +1e-5, %d below -1e-5\n", sum / N,
                std::sqrt(sum2 / N), above, below);
  }
  return 0;
}
