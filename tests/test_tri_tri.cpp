// mesh::prepare's triangle contact (mesh/src/tri_tri.hpp: exact sides, double-precision points) against CGAL's
// exact constructions (Epeck, rounded once at the end), an independent computation: random pairs in general position,
// and the contacts of architecture (walls standing on slabs, corners on faces, edges along edges), rotated at random
// and moved 1e6 m from the origin.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/intersections.h>
#include <Eigen/Geometry>

#include "../mesh/src/tri_tri.hpp"

namespace lambert::mesh {
namespace {

using detail::TriangleContact;
using KE = CGAL::Exact_predicates_exact_constructions_kernel;
using Tri = std::array<Vec3, 3>;

KE::Triangle_3 exact(const Tri& t) {
  auto p = [](const Vec3& v) { return KE::Point_3(v.x(), v.y(), v.z()); };
  return {p(t[0]), p(t[1]), p(t[2])};
}
Vec3 vec(const KE::Point_3& p) { return {CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())}; }

std::string show(const Tri& t) {
  char b[256];
  std::snprintf(b, sizeof b, "(%.17g %.17g %.17g) (%.17g %.17g %.17g) (%.17g %.17g %.17g)", t[0].x(), t[0].y(),
                t[0].z(), t[1].x(), t[1].y(), t[1].z(), t[2].x(), t[2].y(), t[2].z());
  return b;
}

// The reference: Epeck's intersection of two triangles that are not coplanar, as none, a point or a segment.
TriangleContact reference(const Tri& t, const Tri& u) {
  TriangleContact r;
  const auto x = CGAL::intersection(exact(t), exact(u));
  if (!x) return r;
  if (const auto* s = boost::get<KE::Segment_3>(&*x)) {
    r.kind = TriangleContact::kSegment, r.a = vec(s->source()), r.b = vec(s->target());
  } else if (const auto* p = boost::get<KE::Point_3>(&*x)) {
    r.kind = TriangleContact::kPoint, r.a = r.b = vec(*p);
  } else {
    r.kind = TriangleContact::kNeedsExact;
  }
  return r;
}

// Tolerance: the double-precision points are within a few roundings of the coordinates (|x| up to `reach`) of the
// exact ones; 1e-12 of the triangles' size (1) covers the planes' angle (at least 1e-4 rad here, see tri_tri.hpp).
// Where the exact answer is a point, or a segment shorter than the tolerance, rounding may make it a point, a
// segment within the tolerance of it, or nothing (a gap of that size): all three are accepted.
// Returns true if the double-precision path answered (false: it handed the pair to the exact constructions, as it
// must for coplanar triangles; the caller then takes Epeck's answer, the same by construction).
bool expect_same(const Tri& t, const Tri& u, double reach, int trial) {
  const TriangleContact want = reference(t, u), got = detail::intersect_triangles(t, u);
  const double tol = 1e-12 + 64 * 0x1p-52 * reach;
  const std::string where = "trial " + std::to_string(trial) + ": t = " + show(t) + ", u = " + show(u);
  if (want.kind == TriangleContact::kNeedsExact) {
    EXPECT_EQ(got.kind, TriangleContact::kNeedsExact) << where;
  }
  if (got.kind == TriangleContact::kNeedsExact) return false;
  const bool tiny = want.kind != TriangleContact::kNone && (want.a - want.b).norm() <= tol;
  if (tiny) {
    if (got.kind == TriangleContact::kNone) return true;
    EXPECT_LE((got.a - want.a).norm(), 2 * tol) << where;
    EXPECT_LE((got.b - want.a).norm(), 2 * tol) << where;
    return true;
  }
  EXPECT_EQ(int(got.kind), int(want.kind)) << where << " (0 none, 1 point, 2 segment)";
  if (want.kind == TriangleContact::kNone || got.kind != want.kind) return true;
  // Either order.
  const double same = std::max((got.a - want.a).norm(), (got.b - want.b).norm());
  const double swapped = std::max((got.a - want.b).norm(), (got.b - want.a).norm());
  EXPECT_LE(std::min(same, swapped), tol) << where << ": got (" << got.a.transpose() << ") (" << got.b.transpose()
                                          << "), exact (" << want.a.transpose() << ") (" << want.b.transpose() << ")";
  return true;
}

Tri moved(const Tri& t, const Eigen::Matrix3d& R, const Vec3& offset) {
  return {R * t[0] + offset, R * t[1] + offset, R * t[2] + offset};
}

TEST(TriangleContact, RandomPairsMatchExactConstructions) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> c(-1, 1);
  int segments = 0, nones = 0, exact = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const Tri t{Vec3(c(rng), c(rng), c(rng)), Vec3(c(rng), c(rng), c(rng)), Vec3(c(rng), c(rng), c(rng))};
    const Tri u{Vec3(c(rng), c(rng), c(rng)), Vec3(c(rng), c(rng), c(rng)), Vec3(c(rng), c(rng), c(rng))};
    exact += !expect_same(t, u, 1, trial);
    const auto k = detail::intersect_triangles(t, u).kind;
    segments += k == TriangleContact::kSegment;
    nones += k == TriangleContact::kNone;
  }
  // Both outcomes must be exercised for the comparison to mean something, and general positions rarely need the
  // exact constructions (an edge or plane within 1e-4 rad of the other's plane).
  EXPECT_GT(segments, 400);
  EXPECT_GT(nones, 400);
  EXPECT_LT(exact, 40);
}

// Architecture: a slab triangle and triangles standing on it, touching it at a corner, lying along its edges,
// crossing it; each configuration rotated at random and moved 1e6 m away (the exact predicates then decide on the
// rounded corners, as Epeck does).
TEST(TriangleContact, ContactsOfWallsAndSlabsMatchExactConstructions) {
  const Tri slab{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const std::array<Tri, 10> others{{
      {Vec3(0.2, 0.2, 0), Vec3(0.6, 0.2, 0), Vec3(0.4, 0.2, 0.5)},     // wall standing inside the slab
      {Vec3(-0.5, 0.3, 0), Vec3(1.5, 0.3, 0), Vec3(0.5, 0.3, 0.5)},    // wall standing across the slab's edges
      {Vec3(0.3, 0.3, 0), Vec3(0.2, 0.1, 0.4), Vec3(0.5, 0.2, 0.6)},   // corner on the slab
      {Vec3(0.3, 0.3, -0.2), Vec3(0.2, 0.1, 0.4), Vec3(0.5, 0.2, 0.6)},  // crossing it
      {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0, 0.7)},              // standing on the slab's edge (shared edge)
      {Vec3(0.5, 0.5, 0), Vec3(1, 0, 0), Vec3(0.8, 0.2, 0.7)},         // along part of the hypotenuse
      {Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(1.5, 0, 0.7)},               // touching the slab at its corner only
      {Vec3(0.2, 0.2, 0.3), Vec3(0.6, 0.2, 0.3), Vec3(0.4, 0.2, 0.9)},  // above it
      {Vec3(0.2, -0.3, 0), Vec3(0.6, -0.3, 0), Vec3(0.4, -0.6, 0)},    // in its plane, outside it (coplanar)
      {Vec3(0.2, -0.3, 0), Vec3(0.6, -0.3, 0), Vec3(0.4, -0.3, 0.5)},  // standing on its plane, outside it
  }};
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g;
  int trial = 0;
  for (const double shift : {0.0, 1e6})
    for (int r = 0; r < 60; ++r) {
      const Eigen::Matrix3d R =
          r == 0 ? Eigen::Matrix3d::Identity()
                 : Eigen::Quaterniond(Eigen::Vector4d(g(rng), g(rng), g(rng), g(rng)).normalized()).toRotationMatrix();
      const Vec3 offset(shift, 0.7 * shift, -0.3 * shift);
      for (size_t k = 0; k < others.size(); ++k) {
        const Tri &a = moved(slab, R, offset), &b = moved(others[k], R, offset);
        const bool fast = expect_same(a, b, 1 + shift, trial) & expect_same(b, a, 1 + shift, trial);
        // Axis-aligned (as most models are), every contact but the coplanar one is answered in double precision:
        // the corners on the slab's plane are exactly on it, and no edge crosses it at a grazing angle.
        if (r == 0) {
          EXPECT_EQ(fast, k != 8) << "configuration " << k << ", shift " << shift;
        }
        ++trial;
      }
    }
  // Unrotated, at the origin: the wall inside the slab meets it along its whole foot, exactly.
  const TriangleContact foot = detail::intersect_triangles(slab, others[0]);
  ASSERT_EQ(foot.kind, TriangleContact::kSegment);
  EXPECT_EQ(std::min(foot.a.x(), foot.b.x()), 0.2);
  EXPECT_EQ(std::max(foot.a.x(), foot.b.x()), 0.6);
}

// Planes closer than 1e-4 rad, and coplanar triangles, are left to the exact constructions.
TEST(TriangleContact, NearlyParallelPlanesAreLeftToExactConstructions) {
  const Tri slab{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const Tri flat{Vec3(0.1, 0.1, 0), Vec3(0.6, 0.1, 0), Vec3(0.1, 0.6, 0)};
  const Tri tilted{Vec3(0.1, 0.1, -1e-6), Vec3(0.6, 0.1, 1e-6), Vec3(0.1, 0.6, -1e-6)};
  EXPECT_EQ(detail::intersect_triangles(slab, flat).kind, TriangleContact::kNeedsExact);
  EXPECT_EQ(detail::intersect_triangles(slab, tilted).kind, TriangleContact::kNeedsExact);
}

}  // namespace
}  // namespace lambert::mesh
