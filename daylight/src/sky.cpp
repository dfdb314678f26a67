// Sky models and the exact directional moments of polygons (docs/physics.md §9).
#include "lambert/daylight/sky.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

#include "clip.hpp"

namespace lambert::daylight {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Signed integrals over the cone of the polygon (corners a_k relative to the apex), oriented so that the solid
// angle of a counter-clockwise (seen from the apex) polygon is positive:
//   Omega = sum of fan triangles (van Oosterom & Strackee),
//   int (e . w) dw = (1/2) sum_k theta_k (e . nu_k),
//   int (e . w)(f . w) dw = (1/3) [ (e . f) Omega + sum_k (e . nu_k) f . ((p_k+1 - p_k) x nu_k) ],
// nu_k the unit normal of the plane through the apex and edge k (a_k x a_k+1 normalised), theta_k the edge's
// angle, p_k = a_k / |a_k|. Returns the cosine (e = n) and up-cosine (e = up, f = n) moments, sign-corrected.
void cone_moments(const std::vector<Vec3>& a, const Vec3& n, const Vec3& up, double& cos_n, double& cos_up_n) {
  cos_n = cos_up_n = 0;
  const size_t m = a.size();
  if (m < 3) return;
  thread_local std::vector<Vec3> p;
  p.resize(m);
  for (size_t k = 0; k < m; ++k) {
    const double len = a[k].norm();
    if (!(len > 0)) return;  // the apex is a corner: zero-measure contribution
    p[k] = a[k] / len;
  }
  double omega = 0;
  for (size_t k = 1; k + 1 < m; ++k) {
    const Vec3 &A = p[0], &B = p[k], &C = p[k + 1];
    const double num = A.dot(B.cross(C));
    const double den = 1 + A.dot(B) + B.dot(C) + C.dot(A);
    omega += 2 * std::atan2(num, den);
  }
  double first = 0, second = 0;
  for (size_t k = 0; k < m; ++k) {
    const Vec3& P = p[k];
    const Vec3& Q = p[(k + 1) % m];
    const Vec3 c = a[k].cross(a[(k + 1) % m]);
    const double cn = c.norm();
    if (!(cn > 0)) continue;  // an edge through the apex's line: no area
    const Vec3 nu = c / cn;
    const double theta = std::atan2(cn, a[k].dot(a[(k + 1) % m]));
    first += theta * n.dot(nu);
    second += up.dot(nu) * n.dot((Q - P).cross(nu));
  }
  first *= 0.5;
  second = (up.dot(n) * omega + second) / 3;
  const double s = omega > 0 ? 1.0 : omega < 0 ? -1.0 : 0.0;
  cos_n = s * first;
  cos_up_n = s * second;
}

}  // namespace

double Sky::horizontal_irradiance() const {
  return kind == Kind::Uniform ? kPi * radiance : 7.0 / 9.0 * kPi * radiance;
}

double Sky::radiance_at(const Vec3& omega) const {
  const double s = up.dot(omega);
  return s > 0 ? a() + b() * s : ground_radiance();
}

std::string Sky::name() const { return kind == Kind::Uniform ? "uniform" : "cie-overcast"; }

Sky parse_sky(const std::string& text, double default_radiance) {
  const auto colon = text.find(':');
  const std::string kind = text.substr(0, colon);
  Sky sky;
  if (kind == "uniform") {
    sky.kind = Sky::Kind::Uniform;
  } else if (kind == "cie-overcast") {
    sky.kind = Sky::Kind::CieOvercast;
  } else if (kind == "cie-clear") {
    throw InputError("--sky " + text + ": the CIE clear sky is not implemented yet; expected uniform[:L] or "
                     "cie-overcast[:Lz]");
  } else {
    throw InputError("--sky " + text + ": unknown sky; expected uniform[:L] or cie-overcast[:Lz] (L, Lz the sky's "
                     "(zenith) radiance, W m^-2 sr^-1, or luminance in cd m^-2 with --units photometric)");
  }
  sky.radiance = default_radiance;
  if (colon != std::string::npos) {
    const std::string v = text.substr(colon + 1);
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(x) || !(x > 0))
      throw InputError("--sky " + text + ": '" + v + "' is not a finite number > 0 (the sky's " +
                       (kind == "uniform" ? "radiance L" : "zenith radiance Lz") + ")");
    sky.radiance = x;
  }
  return sky;
}

Vec3 parse_axis(const std::string& text) {
  std::string t = text;
  double sign = 1;
  if (!t.empty() && (t[0] == '+' || t[0] == '-')) {
    sign = t[0] == '-' ? -1 : 1;
    t = t.substr(1);
  }
  if (t == "x" || t == "X") return sign * Vec3::UnitX();
  if (t == "y" || t == "Y") return sign * Vec3::UnitY();
  if (t == "z" || t == "Z") return sign * Vec3::UnitZ();
  throw InputError("--up " + text + ": expected one of x, y, z, -x, -y, -z");
}

Moments polygon_moments(const Vec3& x, const Vec3& n, const Vec3& up, std::span<const Vec3> polygon) {
  Moments out;
  if (polygon.size() < 3) return out;
  thread_local std::vector<Vec3> rel, front, part;
  rel.resize(polygon.size());
  for (size_t k = 0; k < polygon.size(); ++k) rel[k] = polygon[k] - x;
  detail::clip_halfspace(rel, n, front);  // x's front hemisphere only
  if (front.size() < 3) return out;
  double c = 0, cu = 0;
  detail::clip_halfspace(front, up, part);
  cone_moments(part, n, up, c, cu);
  out.cos_above = c;
  out.cos_up_above = cu;
  detail::clip_halfspace(front, -up, part);
  cone_moments(part, n, up, c, cu);
  out.cos_below = c;
  return out;
}

Moments hemisphere_moments(const Vec3& n, const Vec3& up) {
  const double cb = std::clamp(n.dot(up), -1.0, 1.0);
  const double beta = std::acos(cb), sb = std::sin(beta);
  Moments m;
  m.cos_above = kPi * (1 + cb) / 2;
  m.cos_up_above = 2.0 / 3.0 * ((kPi - beta) * cb + sb);
  m.cos_below = kPi * (1 - cb) / 2;
  return m;
}

double irradiance(const Sky& sky, const Moments& m) {
  return sky.a() * m.cos_above + sky.b() * m.cos_up_above + sky.ground_radiance() * m.cos_below;
}

}  // namespace lambert::daylight
