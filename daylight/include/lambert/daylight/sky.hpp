#pragma once
// Skies as emitters at infinity, and the exact directional moments of a polygon that occludes them.
// Units: radiance in W m^-2 sr^-1 (or cd m^-2: the sky is linear, lambert only scales it), irradiance in W m^-2
// (or lux), solid angle in sr. The sky is grey (the same value in R, G and B). Derivations: docs/physics.md §9.
#include <span>
#include <string>

#include "lambert/mesh/types.hpp"

namespace lambert::daylight {

// Sky radiance for a direction omega (unit) above the horizon, gamma its altitude (sin gamma = up . omega):
//   uniform       L(omega) = L
//   cie-overcast  L(omega) = Lz (1 + 2 sin gamma) / 3          (CIE standard overcast sky, Moon & Spencer)
// Below the horizon the external ground, a Lambertian plane of reflectance rho_g lit by the unobstructed sky:
//   L_ground = rho_g E_h / pi,  E_h = unobstructed horizontal irradiance of the sky = pi L (uniform),
//   (7/9) pi Lz (overcast).
// Both are linear in omega above the horizon: L(omega) = a + b (up . omega), a constant below. That is what makes
// the sky term of a polygon a sum of contour integrals (Moments below).
struct Sky {
  enum class Kind { Uniform, CieOvercast };
  Kind kind = Kind::CieOvercast;
  double radiance = 1;            // L (uniform) or Lz (overcast, zenith), > 0
  double ground_reflectance = 0.2;  // rho_g in [0, 1]
  Vec3 up = Vec3::UnitY();        // unit zenith direction

  double a() const { return kind == Kind::Uniform ? radiance : radiance / 3; }      // constant term above
  double b() const { return kind == Kind::Uniform ? 0.0 : 2 * radiance / 3; }       // sin(gamma) coefficient
  double horizontal_irradiance() const;                                            // E_h
  double ground_radiance() const { return ground_reflectance * horizontal_irradiance() / 3.14159265358979323846; }
  double radiance_at(const Vec3& omega) const;  // sky above, ground below (omega unit)
  std::string name() const;                     // "uniform" | "cie-overcast"
};

// Parses "uniform[:L]" or "cie-overcast[:Lz]" (the value > 0 and finite; default_radiance when absent).
// Throws InputError naming the accepted forms ("cie-clear" is not implemented and says so).
Sky parse_sky(const std::string& text, double default_radiance);

// Parses "x", "y", "z", "+x", "-y", ... into a unit vector; throws InputError otherwise.
Vec3 parse_axis(const std::string& text);

// What a polygon covers of the directions a point sees, split at the horizon, as the integrals the sky needs:
//   cos_above    = integral of (n . omega) domega over the directions of P above the horizon through x (sr)
//   cos_up_above = integral of (up . omega)(n . omega) domega over the same directions (sr)
//   cos_below    = integral of (n . omega) domega over the directions of P below the horizon (sr)
// Only directions in x's front hemisphere (n . omega > 0) count. Two-sided: a polygon seen from behind
// covers the sky as well (coverage is geometry, not light). Exact (contour integrals: Arvo 1995), no
// quadrature. The polygon is planar, >= 3 corners; x not in its plane (else all 0); n, up unit.
struct Moments {
  double cos_above = 0, cos_up_above = 0, cos_below = 0;
  Moments& operator+=(const Moments& o) {
    cos_above += o.cos_above;
    cos_up_above += o.cos_up_above;
    cos_below += o.cos_below;
    return *this;
  }
};
Moments polygon_moments(const Vec3& x, const Vec3& n, const Vec3& up, std::span<const Vec3> polygon);

// The same integrals over the whole front hemisphere (nothing occluding), in closed form:
// cos_above = pi (1 + cos beta) / 2, cos_up_above = (2/3)((pi - beta) cos beta + sin beta),
// cos_below = pi (1 - cos beta) / 2, beta the angle between n and up.
Moments hemisphere_moments(const Vec3& n, const Vec3& up);

// Irradiance a region with moments m receives from the sky and ground (a m.cos_above + b m.cos_up_above +
// L_ground m.cos_below).
double irradiance(const Sky& sky, const Moments& m);

}  // namespace lambert::daylight
