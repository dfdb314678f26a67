#pragma once
// Internal to daylight/: small geometry helpers shared by sky.cpp and daylight.cpp.
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::daylight::detail {

// Sutherland-Hodgman: the part of `poly` (corners relative to an apex) with d . a >= 0; `out` is cleared, and
// left empty when fewer than three corners remain.
inline void clip_halfspace(const std::vector<Vec3>& poly, const Vec3& d, std::vector<Vec3>& out) {
  out.clear();
  const size_t m = poly.size();
  if (m == 0) return;
  double sp = d.dot(poly[m - 1]);
  for (size_t k = 0; k < m; ++k) {
    const Vec3& prev = poly[(k + m - 1) % m];
    const Vec3& cur = poly[k];
    const double sc = d.dot(cur);
    if (sc >= 0) {
      if (sp < 0) out.push_back(prev + (cur - prev) * (sp / (sp - sc)));
      out.push_back(cur);
    } else if (sp > 0) {
      out.push_back(prev + (cur - prev) * (sp / (sp - sc)));
    }
    sp = sc;
  }
  if (out.size() < 3) out.clear();
}

}  // namespace lambert::daylight::detail
