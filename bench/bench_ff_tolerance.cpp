// Form-factor tolerance against accuracy and cost, in one run (figures in docs/benchmarks.md, "Default
// tolerance"). For each tolerance T given on the command line (0 = the library default for the scene's
// largest reflectance, formfactor::default_tolerance):
//   sphere K (inward icosphere, 20 * 4^K triangles, convex: no rays), uniform emission E0 = 1 and reflectance
//     rho in {0.9, 0.99, 0.999}: exact discrete answer 1 / (1 - rho) (every row of F sums to 1). Printed: form-factor
//     seconds, max |row sum - 1|, max relative radiance error per rho.
//   cube n (closed unit cube, n x n quads per face), room (32 x 32 per wall, 10 x 10 per block face: 6,744
//     patches), floorplan (examples/floorplan.obj, prepared as `lambert solve` does): form-factor seconds and
//     row sums, at the scene's reflectance (cube and room: none given, 0.9 assumed for "0 = default").
// --row-check also runs formfactor::check_row_sums (64 patches x 4096 rays) on each matrix.
// Usage: bench_ff_tolerance [--scenes sphere4,sphere5,cube64,room,floorplan] [--floorplan PATH] [--row-check] T1 T2 ...
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/check.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/solver/solve.hpp"

namespace {

using namespace lambert;
namespace ff = lambert::formfactor;

struct SceneDef {
  std::string name;
  mesh::PatchGeometry g;
  double rho_max = 0.9;  // used for T = 0
  bool sphere = false;
};

SceneDef make_scene(const std::string& name, const std::string& floorplan) {
  SceneDef s;
  s.name = name;
  if (name.rfind("sphere", 0) == 0) {
    s.g = mesh::PatchGeometry::from_polygons(mesh::shapes::icosphere(std::stoi(name.substr(6)), 1.0, true));
    s.sphere = true;
    s.rho_max = 0.999;
  } else if (name.rfind("cube", 0) == 0) {
    const int n = std::stoi(name.substr(4));
    s.g = mesh::PatchGeometry::from_polygons(mesh::shapes::box(Vec3::Zero(), Vec3::Ones(), n, true));
  } else if (name == "room") {
    s.g = mesh::PatchGeometry::from_polygons(mesh::shapes::room_with_block(32, 10));
  } else if (name == "floorplan") {
    const mesh::PolygonSoup soup = io::read_soup(floorplan);
    const mesh::Scene scene = mesh::prepare_and_build(soup, mesh::PrepareOptions{});
    s.g = scene.geometry;
    s.rho_max = scene.reflectance_field().maxCoeff();
  } else {
    throw std::runtime_error("unknown scene " + name);
  }
  return s;
}

// CPU seconds (user + system, all threads) of this process so far: the load-independent cost.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  std::string scenes = "sphere4,sphere5,cube64,room,floorplan", floorplan = "examples/floorplan.obj";
  std::vector<double> tols;
  bool row_check = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--scenes" && a + 1 < argc) scenes = argv[++a];
    else if (arg == "--floorplan" && a + 1 < argc) floorplan = argv[++a];
    else if (arg == "--row-check") row_check = true;
    else tols.push_back(std::atof(arg.c_str()));
  }
  if (tols.empty()) tols = {1e-8, 0};
  std::printf("scene,patches,tolerance,ff_seconds,ff_cpu_seconds,row_sum_dev_max,row_error_bound_max,err_rho0.9,err_rho0.99,err_rho0.999,"
              "recip_pairs,recip_bound_ratio,recip_worst,recip_residual,entries_roundoff,entries_outside_unit,"
              "pairs_no_visible_sample,pairs_over_tolerance,row_visibility_sigma_max,pairs_by_method\n");
  std::stringstream list(scenes);
  std::string name;
  while (std::getline(list, name, ',')) {
    SceneDef s = make_scene(name, floorplan);
    for (double T : tols) {
      ff::Options o;
      o.tolerance = T;
      o.max_reflectance = s.rho_max;
      ff::Stats st;
      const double cpu0 = cpu_seconds();
      auto F = std::make_shared<ff::DenseMatrixOperator>(ff::assemble(s.g, o, &st));
      const double cpu = cpu_seconds() - cpu0;
      double dev = 0;
      for (int i = 0; i < F->size(); ++i) dev = std::max(dev, std::abs(F->row_sum(i) - 1));
      double err[3] = {NAN, NAN, NAN};
      if (s.sphere) {
        solver::Solver sol(F, s.g.area);
        const double rhos[3] = {0.9, 0.99, 0.999};
        for (int k = 0; k < 3; ++k) {
          solver::Options so;
          so.tolerance = 1e-12;
          const auto r = sol.solve(ColorField::Constant(s.g.size(), 3, rhos[k]), ColorField::Constant(s.g.size(), 3, 1.0), so);
          const double exact = 1 / (1 - rhos[k]);
          err[k] = ((r.radiance.col(0).array() - exact).abs() / exact).maxCoeff();
        }
      }
      std::string methods;
      for (const auto& [m, c] : st.pairs_by_method) methods += m + "=" + std::to_string(c) + " ";
      std::printf("%s,%d,%.3g,%.3f,%.3f,%.3g,%.3g,%.3g,%.3g,%.3g,%lld,%.3g,%s,%.3g,%lld,%lld,%lld,%lld,%.3g,%s\n", s.name.c_str(), s.g.size(), st.tolerance,
                  st.seconds["form_factors"], cpu, dev, st.row_error_bound_max, err[0], err[1], err[2], st.reciprocity_check_pairs, st.reciprocity_bound_ratio,
                  st.reciprocity_worst_method.c_str(), st.reciprocity_residual, st.entries_roundoff,
                  st.entries_outside_unit, st.pairs_no_visible_sample, st.pairs_over_tolerance, st.row_visibility_sigma_max,
                  methods.c_str());
      if (row_check) {
        const ff::RowSumCheck rc = ff::check_row_sums(s.g, *F, &st);
        std::printf("# row-sum check: %d patches, %lld rays, max |difference| %.3g, max ratio %.3g (patch %d: row sum "
                    "%.6f, rays %.6f, allowed %.3g), %s\n",
                    rc.patches_checked, rc.rays, rc.max_difference, rc.max_ratio, rc.worst_patch, rc.worst_row_sum,
                    rc.worst_estimate, rc.worst_allowed, rc.passed ? "passed" : "FAILED");
      }
      std::fflush(stdout);
    }
  }
  return 0;
}
