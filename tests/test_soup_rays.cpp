// mesh::prepare's ray caster (mesh/src/soup_rays.hpp): the BVH and the watertight triangle test, against every
// triangle tested one by one (Moeller-Trumbore in long double, an independent test), and rays aimed exactly at
// the edges and corners of closed surfaces, near the origin and 1e6 m away from it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "../mesh/src/soup_rays.hpp"
#include "soup_util.hpp"

namespace lambert::mesh {
namespace {

using test_util::soup_of;

// Every triangle of the soup (the test soups are triangles), nearest hit with t >= 0 by Moeller-Trumbore in long
// double: (face, t), face -1 when none.
std::pair<int, double> brute_first(const PolygonSoup& s, const Vec3& o, const Vec3& d, int skip) {
  using L = long double;
  int best = -1;
  L best_t = std::numeric_limits<L>::infinity();
  for (int k = 0; k < static_cast<int>(s.faces.size()); ++k) {
    if (k == skip) continue;
    L p[3][3];
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a) p[c][a] = s.positions[s.faces[k].vertices[c]][a];
    const L e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const L e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    const L dd[3] = {d.x(), d.y(), d.z()};
    const L h[3] = {dd[1] * e2[2] - dd[2] * e2[1], dd[2] * e2[0] - dd[0] * e2[2], dd[0] * e2[1] - dd[1] * e2[0]};
    const L det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
    if (det == 0) continue;
    const L sv[3] = {L(o.x()) - p[0][0], L(o.y()) - p[0][1], L(o.z()) - p[0][2]};
    const L u = (sv[0] * h[0] + sv[1] * h[1] + sv[2] * h[2]) / det;
    if (u < 0 || u > 1) continue;
    const L q[3] = {sv[1] * e1[2] - sv[2] * e1[1], sv[2] * e1[0] - sv[0] * e1[2], sv[0] * e1[1] - sv[1] * e1[0]};
    const L v = (dd[0] * q[0] + dd[1] * q[1] + dd[2] * q[2]) / det;
    if (v < 0 || u + v > 1) continue;
    const L t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    if (t >= 0 && t < best_t) best_t = t, best = k;
  }
  return {best, double(best_t)};
}

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  return Vec3(n(rng), n(rng), n(rng)).normalized();
}

// 2,000 random triangles in a 10 m box, 10,000 random rays from inside it: the same first face (or the same
// distance, within 1e-12 relative: two faces at one distance), as every triangle tested in long double. A ray
// grazing a triangle's edge within 1e-9 of its parameter range may go either way in either test; those rays are
// compared by distance only.
TEST(SoupRays, FirstHitMatchesEveryTriangleTestedOneByOne) {
  for (const double shift : {0.0, 1e6}) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 10), small(-0.7, 0.7);
    std::vector<Vec3> pos;
    std::vector<std::vector<int>> faces;
    for (int k = 0; k < 2000; ++k) {
      const Vec3 c(u(rng), u(rng), u(rng));
      for (int j = 0; j < 3; ++j) pos.push_back(Vec3(shift, -shift, shift) + c + Vec3(small(rng), small(rng), small(rng)));
      faces.push_back({3 * k, 3 * k + 1, 3 * k + 2});
    }
    const PolygonSoup s = soup_of(pos, faces);
    const detail::SoupRays rays(s, std::vector<char>(s.faces.size(), 1));
    int compared = 0, misses = 0;
    for (int r = 0; r < 10000; ++r) {
      const Vec3 o = Vec3(shift, -shift, shift) + Vec3(u(rng), u(rng), u(rng));
      const Vec3 d = random_unit(rng);
      const int skip = r % 7 == 0 ? static_cast<int>(r % 2000) : -1;
      const auto h = rays.first(o, d, [skip](int f) { return f == skip; });
      const auto [face, t] = brute_first(s, o, d, skip);
      ++compared;
      if (face < 0) {
        EXPECT_EQ(h.face, -1) << "shift " << shift << " ray " << r << ": hits face " << h.face << " at t " << h.t
                              << ", the brute force finds none";
        ++misses;
        continue;
      }
      ASSERT_GE(h.face, 0) << "shift " << shift << " ray " << r << ": no hit; brute force: face " << face << " at " << t;
      EXPECT_NEAR(h.t, t, 1e-12 * std::max(1.0, t) + 1e-10 * (shift > 0))
          << "shift " << shift << " ray " << r << ": face " << h.face << " vs " << face;
      if (h.face != face) {
        EXPECT_NEAR(h.t, t, 1e-10) << "shift " << shift << " ray " << r << ": face " << h.face << " vs " << face;
      }
      EXPECT_EQ(h.front, d.dot(rays.normal(h.face)) < 0) << "ray " << r;
    }
    EXPECT_GT(misses, 100) << "the rays should also escape";
    EXPECT_LT(misses, compared - 1000) << "the rays should mostly hit";
  }
}

// A closed box of 12 triangles and a fan of 64 triangles around one corner: rays from inside aimed exactly at every
// corner and at points of every edge must hit (a ray through a shared edge hits one of its two triangles), also
// 1e6 m from the origin where coordinates carry 1e-10 m of rounding. A test of non-watertight kind (barycentrics
// each compared with 0 separately, in double) lets a share of them through.
TEST(SoupRays, RaysThroughSharedEdgesAndCornersDoNotLeak) {
  for (const double shift : {0.0, 1e6, -3.3e5}) {
    const Vec3 off(shift, 0.37 * shift, -0.61 * shift);
    std::vector<Vec3> pos;
    std::vector<std::vector<int>> faces;
    // Box [0, 2] x [0, 3] x [0, 1.7], its faces split into two triangles each (diagonals both ways).
    const Vec3 lo(0, 0, 0), hi(2, 3, 1.7);
    for (int i = 0; i < 8; ++i) pos.push_back(off + Vec3(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z()));
    const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
      faces.push_back({q[0], q[1], q[2]});
      faces.push_back({q[0], q[2], q[3]});
    }
    const PolygonSoup s = soup_of(pos, faces);
    const detail::SoupRays rays(s, std::vector<char>(s.faces.size(), 1));
    std::vector<Vec3> targets;
    for (int i = 0; i < 8; ++i) targets.push_back(pos[i]);
    for (const auto& f : faces)
      for (int c = 0; c < 3; ++c)
        for (const double w : {0.5, 0.25, 1.0 / 3.0, 0.123456789})
          targets.push_back((1 - w) * pos[f[c]] + w * pos[f[(c + 1) % 3]]);
    const std::vector<Vec3> origins = {off + Vec3(1, 1.5, 0.85), off + Vec3(0.3, 0.2, 0.1), off + Vec3(1.9, 2.95, 1.6),
                                       off + Vec3(1e-3, 1.5, 0.85)};
    int leaks = 0, tested = 0;
    for (const Vec3& o : origins)
      for (const Vec3& p : targets) {
        const Vec3 d = (p - o).normalized();
        if (!((p - o).norm() > 1e-6)) continue;
        ++tested;
        const auto h = rays.first(o, d, [](int) { return false; });
        if (h.face < 0) {
          ++leaks;
          ADD_FAILURE() << "shift " << shift << ": the ray from (" << (o - off).transpose() << ") towards ("
                        << (p - off).transpose() << ") leaves the closed box";
        } else {
          EXPECT_NEAR(h.t, (p - o).norm(), 1e-12 + 1e-14 * std::abs(shift))  // round-off of the coordinates
              << "shift " << shift << ": target (" << (p - off).transpose() << ")";
        }
      }
    EXPECT_EQ(leaks, 0) << "of " << tested;
  }
}

}  // namespace
}  // namespace lambert::mesh
