// The entries of a form-factor file (`lambert formfactors ... --visibility exact -o F.csv`) against independent
// references, entry by entry (issue 12: the per-entry tolerance). bench_exact_scan re-runs the method on sampled pairs
// with its own occluder lists; this checks what the assembly wrote, with the lists its shafts gave (the floor plan's
// entries were off by up to 1.7e-7 where the scan's re-runs were right).
//
//   bench_exact_entries MODEL F.csv [N] [SEED] [MIN_F]
//   (with LAMBERT_ENTRIES_PATCHES="s,t;s,t": only the references' unoccluded, visible and hidden F of those patch pairs,
//   from patch s; the file is not read)
//   (with LAMBERT_ENTRIES_AGAINST=G.csv, another run's output of the same model: only the entries where the two differ
//   by more than 1e-8 are drawn, and G's value is shown beside F's: which run is right)
//
// MODEL as `lambert formfactors` read it (same preparation), F.csv its output. Of the entries F_ij >= MIN_F (default
// 1e-6) between input faces that are one patch each and that a patch near them may occlude (a box test), N (default
// 200) drawn with SEED (default 1) are compared with a reference that shares nothing with the assembly's outer rule
// or merged occluders: the source cut into pieces (a triangle in 50 strips from the apex opposite its shortest edge,
// a convex quad in 4 x 4 bilinear pieces, other polygons by their triangles in strips), every piece by
// visible_polygon_to_polygon at 1e-11 with every patch near the pair as a plain occluder. The assembly promises 1e-8
// on the unoccluded integral and 1e-8 on the hidden part (the latter for the smaller patch's direction, scaled by the
// area ratio in the other): entries off by more than 2e-8 are listed. Parallel over entries (TBB).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../tests/test_formfactor_util.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"

namespace mesh = lambert::mesh;
namespace fftest = lambert::fftest;
using lambert::Vec3;
using Poly = std::vector<Vec3>;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_exact_entries MODEL F.csv [N] [SEED] [MIN_F]\n");
    return 2;
  }
  const int n_draw = argc > 3 ? std::atoi(argv[3]) : 200;
  const unsigned seed = argc > 4 ? unsigned(std::atoi(argv[4])) : 1u;
  const double min_f = argc > 5 ? std::atof(argv[5]) : 1e-6;
  const auto t0 = std::chrono::steady_clock::now();
  const mesh::Scene scene = mesh::prepare_and_build(lambert::io::read_soup(argv[1]), {}, {});
  const mesh::PatchGeometry& g = scene.geometry;
  // Input faces that are one patch.
  std::vector<int> patch_of(size_t(scene.input_faces), -1);
  for (int p = 0; p < g.size(); ++p) {
    const int f = scene.face_id[size_t(p)];
    if (f >= 0 && f < scene.input_faces) patch_of[size_t(f)] = patch_of[size_t(f)] == -1 ? p : -2;
  }
  std::vector<Eigen::AlignedBox3d> box(size_t(g.size()));
  for (int p = 0; p < g.size(); ++p)
    for (const Vec3& v : g.polygon(p)) box[size_t(p)].extend(v);
  auto near_of = [&](int i, int j) {
    Eigen::AlignedBox3d b = box[size_t(i)];
    b.extend(box[size_t(j)]);
    std::vector<int> near;
    for (int q = 0; q < g.size(); ++q)
      if (q != i && q != j && box[size_t(q)].intersects(b)) near.push_back(q);
    return near;
  };
  // LAMBERT_ENTRIES_PATCHES="s,t;s,t;...": the hidden part H = F_st(unoccluded) - F_st(visible) of these patch pairs
  // (patch indices, from the source s), by the same references, then exit.
  if (const char* pairs = std::getenv("LAMBERT_ENTRIES_PATCHES")) {
    std::istringstream ps(pairs);
    std::string item;
    while (std::getline(ps, item, ';')) {
      int s = -1, t = -1;
      if (std::sscanf(item.c_str(), "%d,%d", &s, &t) != 2 || s < 0 || t < 0 || s >= g.size() || t >= g.size()) continue;
      const Poly Ps(g.polygon(s).begin(), g.polygon(s).end()), Pt(g.polygon(t).begin(), g.polygon(t).end());
      std::vector<Poly> occ;
      for (int q : near_of(s, t)) occ.emplace_back(g.polygon(q).begin(), g.polygon(q).end());
      const double vis = fftest::pieces_visible(Ps, g.normal[s], Pt, occ), all = fftest::pieces_visible(Ps, g.normal[s], Pt, {});
      std::printf("patches %d -> %d: F unoccluded %.10e, visible %.10e, hidden %.10e (%zu occluders near); A_s H %.10e\n",
                  s, t, all, vis, all - vis, occ.size(), g.area[s] * (all - vis));
    }
    return 0;
  }
  struct Entry {
    int fi, fj, i, j;
    double F, ref = 0, G = 0;  // G: the other run's value (LAMBERT_ENTRIES_AGAINST)
  };
  // i,j,F lines of a form-factor file (the header and anything else skipped), by (i, j).
  auto read_csv = [&](const char* path, std::map<std::pair<int, int>, double>& out) {
    std::ifstream in(path);
    if (!in) {
      std::fprintf(stderr, "bench_exact_entries: cannot read %s\n", path);
      std::exit(2);
    }
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream ss(line);
      int fi = -1, fj = -1;
      double F = 0;
      char c1 = 0, c2 = 0;
      if (!(ss >> fi >> c1 >> fj >> c2 >> F) || c1 != ',' || c2 != ',') continue;
      out[{fi, fj}] = F;
    }
  };
  std::map<std::pair<int, int>, double> file, other;
  read_csv(argv[2], file);
  const char* against = std::getenv("LAMBERT_ENTRIES_AGAINST");
  if (against) read_csv(against, other);
  std::vector<Entry> entries;
  auto consider = [&](int fi, int fj, double F, double G) {
    if (fi < 0 || fj < 0 || fi >= scene.input_faces || fj >= scene.input_faces || std::max(F, G) < min_f) return;
    if (against && !(std::abs(F - G) > 1e-8)) return;
    const int i = patch_of[size_t(fi)], j = patch_of[size_t(fj)];
    if (i < 0 || j < 0) return;
    entries.push_back({fi, fj, i, j, F, 0, G});
  };
  for (const auto& [k, F] : file) {
    const auto it = other.find(k);
    consider(k.first, k.second, F, it == other.end() ? 0.0 : it->second);
  }
  if (against)  // entries only the other run wrote
    for (const auto& [k, G] : other)
      if (!file.count(k)) consider(k.first, k.second, 0.0, G);
  std::mt19937 rng(seed);
  std::shuffle(entries.begin(), entries.end(), rng);
  // The first n_draw of the shuffled entries that a patch near them may occlude (the box test only for those read).
  size_t kept = 0;
  for (size_t k = 0; k < entries.size() && int(kept) < n_draw; ++k)
    if (!near_of(entries[k].i, entries[k].j).empty()) entries[kept++] = entries[k];
  entries.resize(kept);
  tbb::parallel_for(size_t(0), entries.size(), [&](size_t k) {
    Entry& e = entries[k];
    const Poly Pi(g.polygon(e.i).begin(), g.polygon(e.i).end()), Pj(g.polygon(e.j).begin(), g.polygon(e.j).end());
    std::vector<Poly> occ;
    for (int q : near_of(e.i, e.j)) occ.emplace_back(g.polygon(q).begin(), g.polygon(q).end());
    e.ref = fftest::pieces_visible(Pi, g.normal[e.i], Pj, occ);
  });
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return std::abs(a.F - a.ref) > std::abs(b.F - b.ref); });
  int over1 = 0, over2 = 0;
  for (const Entry& e : entries) {
    const double d = e.F - e.ref;
    over1 += std::abs(d) > 1e-8;
    over2 += std::abs(d) > 2e-8;
    if (std::abs(d) > 2e-8 || (against && std::abs(e.G - e.ref) > 2e-8)) {
      char other_diff[64] = "";
      if (against) std::snprintf(other_diff, sizeof other_diff, ", the other run's %.2e", e.G - e.ref);
      std::printf("faces %d -> %d (patches %d, %d): F %.9e, reference %.9e, difference %.2e%s\n", e.fi, e.fj, e.i, e.j,
                  e.F, e.ref, d, other_diff);
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int other1 = 0;
  double other_worst = 0;
  for (const Entry& e : entries)
    if (against) other1 += std::abs(e.G - e.ref) > 1e-8, other_worst = std::max(other_worst, std::abs(e.G - e.ref));
  if (against)
    std::printf("%s: of the same entries %d off by > 1e-8, largest |difference| %.2e\n", against, other1, other_worst);
  std::printf("%s: %zu entries compared (F >= %.0e, faces of one patch each, occluders near%s): %d off by > 1e-8, "
              "%d by > 2e-8; largest |difference| %.2e (faces %d -> %d); %.1f s\n",
              argv[2], entries.size(), min_f, against ? ", differing from the other run by > 1e-8" : "", over1, over2,
              entries.empty() ? 0.0 : std::abs(entries[0].F - entries[0].ref), entries.empty() ? -1 : entries[0].fi,
              entries.empty() ? -1 : entries[0].fj, seconds);
  return 0;
}
