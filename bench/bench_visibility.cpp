// Exact against ray visibility on closed scenes with occluders (issue 12). Every row of a closed scene sums to 1,
// so max |row sum - 1| measures the visibility error directly (the unoccluded integrals are exact to 1e-8).
//
//   bench_visibility room N M METHOD [RAYS] [THREADS]     room [0,1]^3, N x N quads per wall, block M x M per face
//   bench_visibility obj FILE METHOD [RAYS] [THREADS]     an OBJ (faces as given) closed by an inward box around it
// METHOD: exact | rays | auto. Prints one line: patches, seconds (wall, cpu), row-sum errors, pair counts.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/shapes.hpp"

namespace ff = lambert::formfactor;
namespace mesh = lambert::mesh;
using lambert::Vec3;

namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec) + double(u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_stime.tv_usec);
}

// OBJ faces (v and f lines only), wound as in the file, then a box wound inward, so the scene is closed. A model
// with faces at its lowest z (a ground: udales_shape.obj's ground and building footprints cover its bounding
// rectangle) gets four walls standing on the bounding rectangle's edges and a roof at twice the model's height,
// no floor: every row must sum to 1. Otherwise the box is 10 % larger than the bounding box on every side.
mesh::shapes::Polygons obj_in_box(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    std::fprintf(stderr, "cannot read %s\n", path.c_str());
    std::exit(1);
  }
  std::vector<Vec3> v;
  mesh::shapes::Polygons polys;
  std::string line;
  Eigen::AlignedBox3d box;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    std::string tag;
    ss >> tag;
    if (tag == "v") {
      double x, y, z;
      ss >> x >> y >> z;
      v.emplace_back(x, y, z);
      box.extend(v.back());
    } else if (tag == "f") {
      std::vector<Vec3> poly;
      std::string tok;
      while (ss >> tok) {
        const int k = std::stoi(tok.substr(0, tok.find('/')));
        poly.push_back(v[size_t(k > 0 ? k - 1 : int(v.size()) + k)]);
      }
      polys.push_back(poly);
    }
  }
  const double z0 = box.min().z();
  bool ground = false;
  for (const auto& q : polys) {
    bool low = !q.empty();
    for (const Vec3& p : q) low = low && p.z() == z0;
    ground = ground || low;
  }
  if (ground) {
    const Vec3 lo = box.min(), hi(box.max().x(), box.max().y(), z0 + 2 * (box.max().z() - z0));
    for (auto& q : mesh::shapes::box(lo, hi, 1, true)) {
      bool floor = true;
      for (const Vec3& p : q) floor = floor && p.z() == z0;
      if (!floor) polys.push_back(q);
    }
    return polys;
  }
  const Vec3 c = box.center(), h = 0.55 * box.sizes();
  for (auto& q : mesh::shapes::box(c - h, c + h, 1, true)) polys.push_back(q);
  return polys;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_visibility room N M METHOD [RAYS] [THREADS] | obj FILE METHOD [RAYS] [THREADS]\n");
    return 1;
  }
  const std::string kind = argv[1];
  mesh::shapes::Polygons polys;
  int a = 2;
  if (kind == "room") {
    polys = mesh::shapes::room_with_block(std::atoi(argv[2]), std::atoi(argv[3]));
    a = 4;
  } else {
    polys = obj_in_box(argv[2]);
    a = 3;
  }
  ff::Options o;
  o.visibility_method = ff::parse_visibility_method(argv[a]);
  if (argc > a + 1) o.rays_per_pair = std::atoi(argv[a + 1]);
  if (argc > a + 2) o.threads = std::atoi(argv[a + 2]);
  if (const char* t = std::getenv("LAMBERT_FF_TOL")) o.tolerance = std::atof(t);  // per-entry tolerance (0 = auto)
  const auto g = mesh::PatchGeometry::from_polygons(polys);
  ff::Stats st;
  const double cpu0 = cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();
  const ff::DenseMatrixOperator F = ff::assemble(g, o, &st);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = cpu_seconds() - cpu0;
  // LAMBERT_BENCH_DUMP=FILE: F as raw doubles (rows of N), to compare two builds' entries.
  if (const char* d = std::getenv("LAMBERT_BENCH_DUMP")) {
    std::FILE* fp = std::fopen(d, "wb");
    bool ok = fp != nullptr;
    for (int i = 0; i < g.size() && ok; ++i)
      for (int j = 0; j < g.size() && ok; ++j) {
        const double v = F.matrix()(i, j);
        ok = std::fwrite(&v, sizeof v, 1, fp) == 1;
      }
    if (fp && std::fclose(fp) != 0) ok = false;
    if (!ok) {
      std::fprintf(stderr, "bench_visibility: cannot write LAMBERT_BENCH_DUMP file %s\n", d);
      return 1;
    }
  }
  double mx = 0, sq = 0;
  int worst = 0;
  for (int i = 0; i < g.size(); ++i) {
    const double e = F.row_sum(i) - 1;
    if (std::abs(e) > mx) mx = std::abs(e), worst = i;
    sq += e * e;
  }
  std::printf("patches %d method %s rays %d wall %.2f s cpu %.2f s max|rowsum-1| %.3e (patch %d) rms %.3e "
              "shaft_culled %lld ray_tested %lld exact clear/hidden/integrated %lld/%lld/%lld plane_hidden/tests "
              "%lld/%lld points %lld over_tol %lld t_exact %.2f t_rays %.2f\n",
              g.size(), argv[a], o.rays_per_pair, wall, cpu, mx, worst, std::sqrt(sq / std::max(1, g.size())),
              st.pairs_shaft_culled, st.pairs_ray_tested, st.pairs_exact_clear, st.pairs_exact_hidden,
              st.pairs_exact_integrated, st.pairs_plane_hidden, st.plane_tests, st.exact_points,
              st.pairs_exact_over_tolerance, st.seconds["visibility_exact"], st.seconds["visibility_rays"]);
  return 0;
}
