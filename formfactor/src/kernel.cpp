// Point-to-polygon form factor by Lambert's contour formula.
#include <algorithm>
#include <cmath>

#include "batch.hpp"
#include "internal.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor {
namespace detail {

void clip_front(std::span<const Vec3> poly, const Vec3& n, double offset, double eps, std::vector<Vec3>& out) {
  out.clear();
  const size_t m = poly.size();
  if (m == 0) return;
  auto dist = [&](const Vec3& p) { return n.dot(p) - offset; };
  // eps is a distance in the polygon's plane from the line where it meets the clipping plane: a corner that close to
  // the line is on it. Its height over the clipping plane is that times the sine of the angle between the planes,
  // so a polygon nearly parallel to the plane keeps only corners nearly in it. (With the height tested against eps
  // itself, two patches of one wall 6e-7 rad apart in a model rounded to single precision kept a corner 1e-9 behind
  // the other's plane, and with it a triangle of the polygon 1 mm wide and 0.5 m long behind that plane: its
  // negative cosines gave F = -2.9e-9 against an error estimate of 7.7e-10, and the solve was refused.)
  if (eps > 0 && m >= 3) {
    const Vec3 np = mesh::newell_normal(poly);
    const double a = np.norm(), ln = n.norm();
    if (a > 0 && ln > 0) eps *= std::min(1.0, np.cross(n).norm() / (a * ln));
  }
  double sp = dist(poly[m - 1]);
  for (size_t k = 0; k < m; ++k) {
    const Vec3& prev = poly[(k + m - 1) % m];
    const Vec3& cur = poly[k];
    const double sc = dist(cur);
    const bool in_p = sp >= -eps, in_c = sc >= -eps;
    // A crossing is only created between a strictly-inside and a strictly-outside corner: corners within eps
    // of the plane are kept, so a polygon touching the plane is not cut into slivers.
    if (in_c) {
      if (!in_p && sc > eps) out.push_back(prev + (cur - prev) * (sp / (sp - sc)));
      out.push_back(cur);
    } else if (in_p && sp > eps) {
      out.push_back(prev + (cur - prev) * (sp / (sp - sc)));
    }
    sp = sc;
  }
  if (out.size() < 3) out.clear();
}

double signed_contour_sum(const Vec3& x, const Vec3& n, std::span<const Vec3> poly) {
  // Per edge: a = corner - x, c = a x (edge vector) (= a x b: the edge vector is exact, so far points keep their
  // relative accuracy), the angle atan2(|c|, a . b) with b = next corner - x; |c| = 0 (x on the edge's line or a
  // zero-length edge) adds nothing. The edges in SIMD lanes (batch.hpp).
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "corners read as contiguous xyz");
  if (poly.empty()) return 0;
  return batch_kernels().contour_sum(x.data(), n.data(), poly.data()->data(), int(poly.size()));
}

double contour_sum(const Vec3& x, const Vec3& n, std::span<const Vec3> poly) {
  return std::abs(signed_contour_sum(x, n, poly)) / (2 * kPi);
}

std::array<double, 2> plane_range(std::span<const Vec3> poly, const Vec3& n, double offset) {
  double lo = INFINITY, hi = -INFINITY;
  for (const Vec3& p : poly) {
    const double s = n.dot(p) - offset;
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  return {lo, hi};
}

}  // namespace detail

double point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> polygon) {
  if (polygon.size() < 3 || !x.allFinite() || !n.allFinite()) return 0;
  const Vec3 N = mesh::newell_normal(polygon);
  const double len = N.norm();
  if (!(len > 0) || !std::isfinite(len)) return 0;
  // One-sided: x must be strictly in front of the polygon's plane.
  if (!((x - polygon[0]).dot(N) > 0)) return 0;
  const double nn = n.norm();
  if (!(nn > 0)) return 0;
  const Vec3 u = n / nn;
  const auto [lo, hi] = detail::plane_range(polygon, u, u.dot(x));
  if (!(hi > 0)) return 0;  // entirely behind or in x's tangent plane
  if (lo >= 0) return detail::contour_sum(x, u, polygon);
  thread_local std::vector<Vec3> clipped;
  detail::clip_front(polygon, u, u.dot(x), 0.0, clipped);
  if (clipped.size() < 3) return 0;
  return detail::contour_sum(x, u, clipped);
}

}  // namespace lambert::formfactor
