// Exact visibility (issue 12): occluders clipped out of the contour integral, against closed forms and
// independent references.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/mesh/shapes.hpp"
#include "test_formfactor_util.hpp"

namespace lambert {
namespace {

using fftest::Poly;
using fftest::rect;
namespace ff = formfactor;
namespace shapes = mesh::shapes;

// Differential element at the origin facing +z to the rectangle [x0,x1] x [y0,y1] in the plane z = c (facing
// -z): superposition of the catalogue's corner formula (Howell B-3), independent of the contour code.
double corner(double a, double b, double c) {  // element below the corner (0,0), rectangle [0,a] x [0,b]
  const double A = a / c, B = b / c, sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
  return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * M_PI);
}
double signed_corner(double a, double b, double c) {
  const double s = (a < 0 ? -1 : 1) * (b < 0 ? -1 : 1);
  return s * corner(std::abs(a), std::abs(b), c);
}
double point_to_rect(double px, double py, double x0, double x1, double y0, double y1, double c) {
  return signed_corner(x1 - px, y1 - py, c) - signed_corner(x0 - px, y1 - py, c) - signed_corner(x1 - px, y0 - py, c) +
         signed_corner(x0 - px, y0 - py, c);
}

// A point below a rectangle, with a strip of occluders (narrow rectangles, some overlapping, some at different
// heights) between them: the hidden part of the target is the union of the strips' shadows, rectangles whose
// union is known in closed form; the visible factor is the target's minus the union's (superposed corners).
TEST(ExactVisibility, PointBehindAStripOfOccludersMatchesClosedForm) {
  const double c = 2.0;
  const Poly target = rect(2, c, -1, 1.5, -0.5, 1, false);  // faces -z, towards the point
  const Vec3 x(0.1, 0.2, 0), n(0, 0, 1);
  // Occluder k at height h_k spans [a, b] in x and all of y: shadow x in px + (a - px) c/h ... (central projection).
  struct Strip { double a, b, h; };
  const std::vector<Strip> strips = {{-0.6, -0.4, 1.0}, {-0.1, 0.05, 0.5}, {0.0, 0.2, 1.5}, {0.5, 0.6, 0.8}};
  std::vector<std::vector<Vec3>> occ;
  std::vector<std::pair<double, double>> shadows;
  for (const Strip& s : strips) {
    occ.push_back(rect(2, s.h, s.a, s.b, -10, 10, true));
    const double k = c / s.h;
    shadows.emplace_back(x.x() + (s.a - x.x()) * k, x.x() + (s.b - x.x()) * k);
  }
  // Union of the shadow intervals, clipped to the target's x range [-1, 1.5].
  std::sort(shadows.begin(), shadows.end());
  std::vector<std::pair<double, double>> uni;
  for (auto [a, b] : shadows) {
    a = std::max(a, -1.0), b = std::min(b, 1.5);
    if (a >= b) continue;
    if (!uni.empty() && a <= uni.back().second) uni.back().second = std::max(uni.back().second, b);
    else uni.emplace_back(a, b);
  }
  double expected = point_to_rect(x.x(), x.y(), -1, 1.5, -0.5, 1, c);
  for (auto [a, b] : uni) expected -= point_to_rect(x.x(), x.y(), a, b, -0.5, 1, c);
  const double got = ff::visible_point_to_polygon(x, n, target, occ);
  // Tolerance: the union is snapped to 2^-29 of the target's half-size (2.3e-9 m here); with |dF/d(edge
  // position)| <= 0.2 per metre and 8 shadow edges, F moves by at most ~4e-9 (measured 2e-10).
  EXPECT_NEAR(got, expected, 4e-9) << "unoccluded " << point_to_rect(x.x(), x.y(), -1, 1.5, -0.5, 1, c)
                                    << ", shadows " << uni.size();
  EXPECT_GT(got, 0.1 * expected);  // the case is not trivially hidden or clear
  EXPECT_LT(got, 0.9 * point_to_rect(x.x(), x.y(), -1, 1.5, -0.5, 1, c));
}

// Parallel unit squares at distance 1 (s at z = 0 facing up, t at z = 1 facing down) with a parallel square
// occluder at z = 1/2 covering x <= 1/2 over the whole shaft: the segment from p to q is blocked iff
// (p_x + q_x)/2 <= 1/2, so from p the visible part of t is the rectangle x in [1 - p_x, 1]: its point factor is
// the closed form above, and the area integral over p is smooth (no penumbra kink inside s), done with 24 x 24
// Gauss points: an independent reference for F_st with the hidden part removed analytically.
TEST(ExactVisibility, SquarePartlyHiddenByParallelSquareMatchesAreaFormulation) {
  const Poly s = rect(2, 0, 0, 1, 0, 1, true), t = rect(2, 1, 0, 1, 0, 1, false);
  const std::vector<std::vector<Vec3>> occ = {rect(2, 0.5, -1, 0.5, -1, 2, true)};
  std::vector<double> gx, gw;
  fftest::gauss01(24, gx, gw);
  double ref = 0;
  for (size_t a = 0; a < gx.size(); ++a)
    for (size_t b = 0; b < gx.size(); ++b) ref += gw[a] * gw[b] * point_to_rect(gx[a], gx[b], 1 - gx[a], 1, 0, 1, 1);
  const ff::PairResult r = ff::visible_polygon_to_polygon(s, t, occ, 1e-9);
  // Tolerance: the requested 1e-9 on the hidden part plus the unoccluded integral's 1e-9; the reference's 24-point
  // Gauss rule on an analytic integrand is exact to ~1e-13.
  EXPECT_NEAR(r.F, ref, 3e-9) << "unoccluded " << ff::polygon_to_polygon(s, t, 1e-9).F;
  EXPECT_NEAR(r.F, 0.1998248957 - ref, 0.2) << "sanity: the occluder hides about half";
  // Reciprocity of the visible values (same patch areas).
  EXPECT_NEAR(r.F_reverse, r.F, 1e-15);
}

}  // namespace
}  // namespace lambert
