// Triangle-triangle contact with exact side decisions and double-precision points (see tri_tri.hpp).
#include "tri_tri.hpp"

#include <algorithm>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

namespace lambert::mesh::detail {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;

K::Point_3 point(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

// Smallest sine of the planes' angle for which double-precision points are trusted: a corner's distance from the
// other plane is then at least 1e-4 of its distance along it, so rounding moves a point by at most ~1e-12 of the
// triangles' size. Closer planes go to the exact constructions (kNeedsExact).
constexpr double kMinSine = 1e-4;

// The part of triangle t on the other triangle's plane (unnormalised normal m): its corners whose exact side is 0,
// and the crossings of its edges whose corners lie strictly on opposite sides (s: exact sides, d: distances times
// |m|, double precision). Returns the number of points, 1 or 2 (the sides are neither all equal nor all 0), or -1
// if an edge crosses the plane at less than 1e-4 rad: there the crossing's position along the edge rests on the
// distances' last bits (an edge lying in the plane, rotated and rounded), and only exact constructions place it.
int on_plane(const std::array<Vec3, 3>& t, const int s[3], const double d[3], const Vec3& m, Vec3 out[2]) {
  int n = 0;
  for (int k = 0; k < 3; ++k)
    if (s[k] == 0) out[n++] = t[k];
  for (int k = 0; k < 3 && n < 2; ++k) {
    const int l = (k + 1) % 3;
    if (s[k] * s[l] >= 0) continue;
    // Opposite sides: |d_k| + |d_l| is |m| |edge| sin(angle) up to rounding.
    const Vec3 e = t[l] - t[k];
    const double spread = std::abs(d[k]) + std::abs(d[l]);
    if (!(spread >= kMinSine * m.norm() * e.norm())) return -1;
    // The rounded distances still have opposite signs (their errors are ~1e-12 of the spread); w stays in [0, 1].
    const double w = std::clamp(d[k] / (d[k] - d[l]), 0.0, 1.0);
    out[n++] = t[k] + w * e;
  }
  return n;
}

}  // namespace

TriangleContact intersect_triangles(const std::array<Vec3, 3>& t, const std::array<Vec3, 3>& u) {
  TriangleContact r;
  const K::Point_3 T[3] = {point(t[0]), point(t[1]), point(t[2])}, U[3] = {point(u[0]), point(u[1]), point(u[2])};
  int su[3], st[3];
  for (int k = 0; k < 3; ++k) su[k] = int(CGAL::orientation(T[0], T[1], T[2], U[k]));
  if ((su[0] > 0 && su[1] > 0 && su[2] > 0) || (su[0] < 0 && su[1] < 0 && su[2] < 0)) return r;
  if (su[0] == 0 && su[1] == 0 && su[2] == 0) {
    r.kind = TriangleContact::kNeedsExact;
    return r;
  }
  for (int k = 0; k < 3; ++k) st[k] = int(CGAL::orientation(U[0], U[1], U[2], T[k]));
  if ((st[0] > 0 && st[1] > 0 && st[2] > 0) || (st[0] < 0 && st[1] < 0 && st[2] < 0)) return r;
  const Vec3 nt = (t[1] - t[0]).cross(t[2] - t[0]), nu = (u[1] - u[0]).cross(u[2] - u[0]);
  const Vec3 line = nt.cross(nu);
  if (!(line.norm() >= kMinSine * nt.norm() * nu.norm())) {
    r.kind = TriangleContact::kNeedsExact;
    return r;
  }
  double dt[3], du[3];
  for (int k = 0; k < 3; ++k) dt[k] = nu.dot(t[k] - u[0]), du[k] = nt.dot(u[k] - t[0]);
  // Each triangle's piece of the common line; their overlap along it.
  Vec3 pt[2], pu[2];
  const int mt = on_plane(t, st, dt, nu, pt), mu = on_plane(u, su, du, nt, pu);
  if (mt < 0 || mu < 0) {
    r.kind = TriangleContact::kNeedsExact;
    return r;
  }
  auto ends = [&](const Vec3* p, int m, Vec3& lo, Vec3& hi) {
    lo = hi = p[0];
    if (m == 2 && line.dot(p[1]) < line.dot(p[0])) lo = p[1];
    if (m == 2 && line.dot(p[1]) > line.dot(p[0])) hi = p[1];
  };
  Vec3 tlo, thi, ulo, uhi;
  ends(pt, mt, tlo, thi);
  ends(pu, mu, ulo, uhi);
  const Vec3& lo = line.dot(tlo) >= line.dot(ulo) ? tlo : ulo;
  const Vec3& hi = line.dot(thi) <= line.dot(uhi) ? thi : uhi;
  if (line.dot(lo) > line.dot(hi)) return r;
  r.a = lo;
  r.b = hi;
  r.kind = lo == hi ? TriangleContact::kPoint : TriangleContact::kSegment;
  return r;
}

}  // namespace lambert::mesh::detail
