// Closed forms by superposition: A_1 F_12 is a signed sum of a corner function over the rectangles' corner
// offsets, the kernel's fourth antiderivative (Howell's catalogue, configurations C-11 / C-14 in general form).
#include "lambert/formfactor/exact.hpp"

#include <cmath>

namespace lambert::formfactor::exact {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

// d^4/(du^2 dv^2) of this is the parallel kernel c^2 / (pi (u^2 + v^2 + c^2)^2) (up to the sign fixed below).
double parallel_corner(double u, double v, double c) {
  const double a = std::sqrt(v * v + c * c), b = std::sqrt(u * u + c * c);
  return (u * a * std::atan(u / a) + v * b * std::atan(v / b) - 0.5 * c * c * std::log(u * u + v * v + c * c)) /
         (2 * kPi);
}

// Fourth antiderivative of the perpendicular kernel y z / (pi (u^2 + y^2 + z^2)^2), as a function of u and
// s^2 = y^2 + z^2; the limits u -> 0 and s -> 0 are taken explicitly (x ln x -> 0).
double perpendicular_corner(double u, double s2) {
  const double u2 = u * u, r2 = u2 + s2;
  double h = 0;
  if (r2 > 0) h += 0.5 * (u2 - s2) * std::log(r2);
  if (s2 > 0 && u != 0) {
    const double s = std::sqrt(s2);
    h += 2 * s * u * std::atan(u / s);
  }
  return -h / (4 * kPi);
}

namespace {

// Superposition over the 16 corner combinations: sum of (-1)^(i+k+j+l) f(a_i - b_k, c_j, d_l).
template <class Corner>
double corner_sum(const double (&a)[2], const double (&b)[2], const double (&c)[2], const double (&d)[2], Corner f) {
  double sum = 0;
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j)
        for (int l = 0; l < 2; ++l) sum += ((i + k + j + l) % 2 == 0 ? 1 : -1) * f(a[i] - b[k], c[j], d[l]);
  return sum;
}

}  // namespace

double parallel_rectangles(double x1, double x2, double y1, double y2, double u1, double u2, double v1, double v2,
                           double c) {
  const double xs[2] = {x1, x2}, us[2] = {u1, u2}, ys[2] = {y1, y2}, vs[2] = {v1, v2};
  const double sum = corner_sum(xs, us, ys, vs, [c](double dx, double y, double v) { return parallel_corner(dx, y - v, c); });
  return sum / ((x2 - x1) * (y2 - y1));
}

double perpendicular_rectangles(double x1, double x2, double z1, double z2, double u1, double u2, double y1,
                                double y2) {
  const double xs[2] = {x1, x2}, us[2] = {u1, u2}, ys[2] = {y1, y2}, zs[2] = {z1, z2};
  const double sum =
      corner_sum(xs, us, ys, zs, [](double dx, double y, double z) { return perpendicular_corner(dx, y * y + z * z); });
  return -sum / ((x2 - x1) * (z2 - z1));
}

double opposed_rectangles(double a, double b, double c) {
  const double X = a / c, Y = b / c, X2 = X * X, Y2 = Y * Y;
  const double s = 0.5 * std::log((1 + X2) * (1 + Y2) / (1 + X2 + Y2)) +
                   X * std::sqrt(1 + Y2) * std::atan(X / std::sqrt(1 + Y2)) +
                   Y * std::sqrt(1 + X2) * std::atan(Y / std::sqrt(1 + X2)) - X * std::atan(X) - Y * std::atan(Y);
  return 2 * s / (kPi * X * Y);
}

double perpendicular_common_edge(double l, double w, double h) {
  const double H = h / l, W = w / l, H2 = H * H, W2 = W * W, R = std::sqrt(H2 + W2);
  const double lg = std::log((1 + W2) * (1 + H2) / (1 + W2 + H2)) +
                    W2 * std::log(W2 * (1 + W2 + H2) / ((1 + W2) * (W2 + H2))) +
                    H2 * std::log(H2 * (1 + H2 + W2) / ((1 + H2) * (H2 + W2)));
  return (W * std::atan(1 / W) + H * std::atan(1 / H) - R * std::atan(1 / R) + 0.25 * lg) / (kPi * W);
}

double coaxial_disks(double r1, double r2, double h) {
  const double R1 = r1 / h, R2 = r2 / h, X = 1 + (1 + R2 * R2) / (R1 * R1);
  return 0.5 * (X - std::sqrt(X * X - 4 * (R2 / R1) * (R2 / R1)));
}

}  // namespace lambert::formfactor::exact
