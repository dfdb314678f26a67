// Internal to daylight/: Clipper's difference, checked (clip.hpp).
#include "clip.hpp"

namespace lambert::daylight::detail {

bool consistent(const ClipperLib::PolyTree& t) {
  for (const ClipperLib::PolyNode* n = t.GetFirst(); n; n = n->GetNext()) {
    const double a = ClipperLib::Area(n->Contour);
    if (a != 0 && (a > 0) == n->IsHole()) return false;
  }
  return true;
}

// Tried in turn until the result is consistent: the difference; against the clip paths' union; by halves.
void difference(ClipperLib::Clipper& c, const ClipperLib::Paths& subject, const ClipperLib::Paths& clip,
                ClipperLib::PolyTree& out, int depth) {
  c.Clear();
  c.AddPaths(subject, ClipperLib::ptSubject, true);
  c.AddPaths(clip, ClipperLib::ptClip, true);
  c.Execute(ClipperLib::ctDifference, out, ClipperLib::pftNonZero, ClipperLib::pftPositive);
  if (consistent(out)) return;
  ClipperLib::Paths united;
  c.Clear();
  c.AddPaths(clip, ClipperLib::ptSubject, true);
  c.Execute(ClipperLib::ctUnion, united, ClipperLib::pftPositive, ClipperLib::pftPositive);
  c.Clear();
  c.AddPaths(subject, ClipperLib::ptSubject, true);
  c.AddPaths(united, ClipperLib::ptClip, true);
  c.Execute(ClipperLib::ctDifference, out, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
  if (consistent(out) || clip.size() < 2 || depth >= 16) return;
  // Halves of whole polygons: a hole (clockwise) stays with the boundary before it, or alone it would cover nothing
  // while its boundary covered it.
  size_t half = clip.size() / 2;
  while (half < clip.size() && !ClipperLib::Orientation(clip[half])) ++half;
  if (half == clip.size()) {
    half = clip.size() / 2;
    while (half > 0 && !ClipperLib::Orientation(clip[half])) --half;
  }
  if (half == 0) return;
  const auto mid = clip.begin() + std::ptrdiff_t(half);
  const ClipperLib::Paths first(clip.begin(), mid), second(mid, clip.end());
  difference(c, subject, first, out, depth + 1);
  ClipperLib::Paths rest;
  ClipperLib::PolyTreeToPaths(out, rest);
  difference(c, rest, second, out, depth + 1);
}

}  // namespace lambert::daylight::detail
