#pragma once
// Internal to daylight/: small geometry helpers shared by sky.cpp and daylight.cpp.
#include <polyclipping/clipper.hpp>

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

// Every outer boundary of t wound counter-clockwise and every hole clockwise, as Clipper promises.
bool consistent(const ClipperLib::PolyTree& t);

// out = subject (non-zero fill) minus clip (positive fill), consistent. Clipper 6.4's difference can come out
// malformed when many clip paths have nearly collinear edges (udales_shape.obj, a wall patch's hemicube minus 225
// projected polygons: an outer boundary wound as a hole around covered directions, which were then counted as open
// sky, 12 % of that patch's sky, in one order of the polygons and not in another). Checked after every difference;
// redone against the clip paths' union, then half of them at a time (depth: the halving's recursion). clip: each
// polygon a counter-clockwise boundary followed by its clockwise holes.
void difference(ClipperLib::Clipper& c, const ClipperLib::Paths& subject, const ClipperLib::Paths& clip,
                ClipperLib::PolyTree& out, int depth = 0);

}  // namespace lambert::daylight::detail
