#pragma once
// Shared helpers for the form-factor tests: polygon builders and independent reference integrals.
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "../formfactor/src/internal.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::fftest {

using Poly = std::vector<Vec3>;

// Axis-aligned rectangle in the plane `axis` = c, spanning [a0,a1] x [b0,b1] in the other two axes
// (cyclic order axis+1, axis+2), with its front facing +axis (front = true) or -axis.
inline Poly rect(int axis, double c, double a0, double a1, double b0, double b1, bool front_positive) {
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  auto P = [&](double a, double b) {
    Vec3 p;
    p[axis] = c;
    p[u] = a;
    p[v] = b;
    return p;
  };
  // (u, v, axis) is right-handed, so counter-clockwise in (u, v) faces +axis.
  Poly q = {P(a0, b0), P(a1, b0), P(a1, b1), P(a0, b1)};
  if (!front_positive) std::swap(q[1], q[3]);
  return q;
}

inline Poly regular_polygon(const Vec3& c, const Vec3& n, double radius, int m, double phase = 0) {
  const Vec3 e1 = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 e2 = n.cross(e1);
  Poly p;
  for (int k = 0; k < m; ++k) {
    const double t = phase + 2 * M_PI * k / m;
    p.push_back(c + radius * (std::cos(t) * e1 + std::sin(t) * e2));
  }
  return p;
}

// Gauss-Legendre nodes/weights on [0, 1] (Golub-Welsch free: Newton on Legendre polynomials).
inline void gauss01(int m, std::vector<double>& x, std::vector<double>& w) {
  x.resize(m);
  w.resize(m);
  for (int i = 0; i < m; ++i) {
    double z = std::cos(M_PI * (i + 0.75) / (m + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= m; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = m * (z * p1 - p0) / (z * z - 1);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = 0.5 * (1 + z);
    w[i] = 1.0 / ((1 - z * z) * dp * dp);
  }
}

// Reference F_ij for a triangle source: the outer integral of the analytic point_to_polygon over the
// triangle (a, b, c), in collapsed coordinates with geometric grading towards the edge (a, b) (where a
// neighbour may touch) and towards the corner c: `layers` graded layers of `m`-point Gauss-Legendre rules in
// each direction. Independent of the library's outer rules and of its contour method.
inline double graded_triangle_source(const Vec3& a, const Vec3& b, const Vec3& c, const Poly& target,
                                     int layers = 24, int m = 12, double ratio = 0.2) {
  const Vec3 n = (b - a).cross(c - a).normalized();
  const double area = 0.5 * (b - a).cross(c - a).norm();
  std::vector<double> gx, gw;
  gauss01(m, gx, gw);
  // Graded partition of [0, 1]: [0, r^L], [r^L, r^(L-1)], ..., [r, 1] and mirrored for the other end.
  std::vector<double> cuts = {0.0};
  for (int k = layers; k >= 1; --k) cuts.push_back(0.5 * std::pow(ratio, k));
  const size_t half = cuts.size();
  for (size_t k = half; k-- > 1;) cuts.push_back(1 - cuts[k]);
  cuts.push_back(1.0);
  // Point = a + s (b - a) + t (c - a)... as (1 - t) [ (1 - s) a + s b ] + t c, Jacobian (1 - t) * 2 * area.
  double sum = 0;
  for (size_t i = 0; i + 1 < cuts.size(); ++i)
    for (size_t j = 0; j + 1 < cuts.size(); ++j)
      for (int p = 0; p < m; ++p)
        for (int q = 0; q < m; ++q) {
          const double s = cuts[i] + (cuts[i + 1] - cuts[i]) * gx[p];
          const double t = cuts[j] + (cuts[j + 1] - cuts[j]) * gx[q];
          const double w = gw[p] * (cuts[i + 1] - cuts[i]) * gw[q] * (cuts[j + 1] - cuts[j]) * (1 - t) * 2;
          const Vec3 x = (1 - t) * ((1 - s) * a + s * b) + t * c;
          sum += w * formfactor::point_to_polygon(x, n, target);
        }
  (void)area;
  return sum;  // the weights integrate to 1 over the triangle: this is the area average
}

// The area average over the polygon `source` (unit normal n) of the visible point-to-polygon factor to `target` past
// `occluders`: the midpoint rule on each triangle of its triangulation, taken as a quad with a collapsed side (a
// convex quad source as itself), in the bilinear parameters on k cells a side, the first and last of them each cut into 12
// halving cells towards the edge, so that a steep strip along an edge (a wall's foot standing on it) is resolved down
// to 1/2^12 of a cell. Independent of the library's outer rules; its error at kinks (shadow edges) falls like 1/k^2
// only on average: judge it against 2k.
inline double graded_midpoint_visible(const Poly& source, const Vec3& n, const Poly& target, const std::vector<Poly>& occluders,
                                      int k) {
  std::vector<std::array<double, 2>> cells;  // [start, width] on [0, 1]
  const double h = 1.0 / k;
  for (int a = 1; a + 1 < k; ++a) cells.push_back({a * h, h});
  for (int m = 1; m <= 12; ++m) {  // [h/2, h], [h/4, h/2], ..., [h/2^12, h/2^11], and the same at the other end
    const double w = h / std::ldexp(1.0, m);
    cells.push_back({w, w});
    cells.push_back({1 - 2 * w, w});
  }
  const double w12 = h / std::ldexp(1.0, 12);
  cells.push_back({0, w12});
  cells.push_back({1 - w12, w12});
  std::vector<std::array<Vec3, 4>> quads;
  bool convex_quad = source.size() == 4;
  for (size_t c = 0; c < 4 && convex_quad; ++c)
    convex_quad = (source[(c + 1) % 4] - source[c]).cross(source[(c + 2) % 4] - source[(c + 1) % 4]).dot(n) > 0;
  if (convex_quad) quads.push_back({source[0], source[1], source[2], source[3]});
  else
    for (const auto& T : mesh::triangulate_polygon(source, n))
      quads.push_back({source[size_t(T[0])], source[size_t(T[1])], source[size_t(T[2])], source[size_t(T[2])]});
  double sum = 0, area = 0;
  for (const auto& P : quads)
    for (const auto& [sa, wa] : cells)
      for (const auto& [sb, wb] : cells) {
        const double u = sa + 0.5 * wa, v = sb + 0.5 * wb;
        const Vec3 x = (1 - u) * (1 - v) * P[0] + u * (1 - v) * P[1] + u * v * P[2] + (1 - u) * v * P[3];
        const Vec3 du = (1 - v) * (P[1] - P[0]) + v * (P[2] - P[3]), dv = (1 - u) * (P[3] - P[0]) + u * (P[2] - P[1]);
        const double J = std::abs(du.cross(dv).dot(n)) * wa * wb;
        sum += J * formfactor::visible_point_to_polygon(x, n, target, occluders);
        area += J;
      }
  return sum / area;
}

// The shortest edge's opposite corner of triangle t (the apex of a needle) and whether t is a needle as
// exact_hidden_pair takes one: shortest edge under a third of the longest.
inline int needle_apex(const Poly& t, bool* needle = nullptr) {
  int apex = 0;
  double shortest = INFINITY, longest = 0;
  for (int k = 0; k < 3; ++k) {
    const double l = (t[size_t((k + 1) % 3)] - t[size_t((k + 2) % 3)]).norm();
    if (l < shortest) shortest = l, apex = k;
    longest = std::max(longest, l);
  }
  if (needle) *needle = 3 * shortest < longest;
  return apex;
}

// Reference F from a needle triangle `source` to `target` past `occluders` (plain polygons): the triangle cut into
// `strips` strips from the apex opposite its shortest edge (the first a triangle, the others trapezoids), each
// integrated by visible_polygon_to_polygon at `tol` and weighted by its share of the area. Independent of
// exact_hidden_pair's own strips (other counts, other elements, unmerged occluders); 20, 50 and 200 strips agreed
// to 1e-11 on storey.stl's floor sliver, whose whole-triangle value the midpoint rule could not decide.
inline double strips_from_apex_visible(const Poly& source, const Poly& target, const std::vector<Poly>& occluders,
                                       int strips = 20, double tol = 1e-11) {
  const int apex = needle_apex(source);
  const Vec3 &a = source[size_t(apex)], &b = source[size_t((apex + 1) % 3)], &c = source[size_t((apex + 2) % 3)];
  double ref = 0;
  for (int k = 0; k < strips; ++k) {
    const double u0 = double(k) / strips, u1 = double(k + 1) / strips;
    const Poly piece = k == 0 ? Poly{a, a + u1 * (b - a), a + u1 * (c - a)}
                              : Poly{a + u0 * (b - a), a + u1 * (b - a), a + u1 * (c - a), a + u0 * (c - a)};
    ref += formfactor::visible_polygon_to_polygon(piece, target, occluders, tol).F * (u1 * u1 - u0 * u0);
  }
  return ref;
}

// Reference F from a convex quad `source` to `target` past `occluders` (plain polygons): the quad cut into n x n
// bilinear pieces, each integrated by visible_polygon_to_polygon at `tol` and weighted by its share of the area.
// Independent of the assembly's elements and merged occluders; n = 2, 4, 8 agreed to 3e-13 on storey.obj's
// cabinet front to the ceiling behind a lamp.
inline double grid_visible_quad(const Poly& source, const Poly& target, const std::vector<Poly>& occluders, int n = 4,
                                double tol = 1e-11) {
  auto at = [&](double u, double v) {
    return ((1 - u) * (1 - v)) * source[0] + (u * (1 - v)) * source[1] + (u * v) * source[2] +
           ((1 - u) * v) * source[3];
  };
  const double area = mesh::newell_normal(source).norm() / 2;
  double ref = 0;
  for (int a = 0; a < n; ++a)
    for (int c = 0; c < n; ++c) {
      const double u0 = double(a) / n, u1 = double(a + 1) / n, v0 = double(c) / n, v1 = double(c + 1) / n;
      const Poly piece = {at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1)};
      const double share = mesh::newell_normal(piece).norm() / 2 / area;
      ref += formfactor::visible_polygon_to_polygon(piece, target, occluders, tol).F * share;
    }
  return ref;
}

// Reference F from any planar `source` (unit normal n) to `target` past `occluders`: a triangle in `strips` strips
// from its apex (strips_from_apex_visible), a convex quad in `grid` x `grid` pieces (grid_visible_quad), any other
// polygon by its triangles in strips, weighted by their areas. What bench_exact_scan, bench_exact_entries and the
// tests take as an independent reference.
inline double pieces_visible(const Poly& source, const Vec3& n, const Poly& target, const std::vector<Poly>& occluders,
                             int strips = 50, int grid = 4) {
  if (source.size() == 3) return strips_from_apex_visible(source, target, occluders, strips);
  bool convex_quad = source.size() == 4;
  for (size_t c = 0; c < 4 && convex_quad; ++c)
    convex_quad = (source[(c + 1) % 4] - source[c]).cross(source[(c + 2) % 4] - source[(c + 1) % 4]).dot(n) > 0;
  if (convex_quad) return grid_visible_quad(source, target, occluders, grid);
  const double area = mesh::newell_normal(source).norm() / 2;
  double ref = 0;
  for (const auto& t : mesh::triangulate_polygon(source, n)) {
    const Poly tri = {source[size_t(t[0])], source[size_t(t[1])], source[size_t(t[2])]};
    ref += strips_from_apex_visible(tri, target, occluders, strips) * (mesh::newell_normal(tri).norm() / 2 / area);
  }
  return ref;
}

// Adaptive Gauss-Kronrod (7-point Gauss inside the 15-point Kronrod rule) of f on [a, b]: an interval is bisected
// until the two rules agree within its share of tol (or at depth 30).
template <class F>
double gauss_kronrod(const F& f, double a, double b, double tol, int depth = 0) {
  using formfactor::detail::kWg, formfactor::detail::kWgk, formfactor::detail::kXgk;  // the contour integral's table
  const double c = 0.5 * (a + b), h = 0.5 * (b - a), fc = f(c);
  double K = kWgk[7] * fc, G = kWg[3] * fc;
  for (int k = 0; k < 7; ++k) {
    const double f1 = f(c - h * kXgk[k]), f2 = f(c + h * kXgk[k]);
    K += kWgk[k] * (f1 + f2);
    if (k % 2 == 1) G += kWg[k / 2] * (f1 + f2);
  }
  K *= h, G *= h;
  if (std::abs(K - G) <= tol || depth >= 30) return K;
  return gauss_kronrod(f, a, c, 0.5 * tol, depth + 1) + gauss_kronrod(f, c, b, 0.5 * tol, depth + 1);
}

// Reference A_s F(s -> target past occluders) for a convex quad `source` (unit normal n): nested adaptive
// Gauss-Kronrod over its bilinear parameters, each point by visible_point_to_polygon. It shares no outer rule,
// element split or critical line with the exact path (its bisections follow the integrand wherever its kinks are).
inline double nested_gauss_kronrod_visible(const Poly& source, const Vec3& n, const Poly& target,
                                           const std::vector<Poly>& occluders, double tol) {
  const Poly& v = source;
  auto f = [&](double u, double w) {
    const Vec3 x = (1 - u) * (1 - w) * v[0] + u * (1 - w) * v[1] + u * w * v[2] + (1 - u) * w * v[3];
    const Vec3 ds = (1 - w) * (v[1] - v[0]) + w * (v[2] - v[3]), dt = (1 - u) * (v[3] - v[0]) + u * (v[2] - v[1]);
    return std::abs(ds.cross(dt).dot(n)) * formfactor::visible_point_to_polygon(x, n, target, occluders);
  };
  return gauss_kronrod([&](double w) { return gauss_kronrod([&](double u) { return f(u, w); }, 0, 1, tol); }, 0, 1,
                       tol);
}

}  // namespace lambert::fftest
