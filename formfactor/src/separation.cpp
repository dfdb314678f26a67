// Proof that occluders in one separating plane hide one region from another (separation.hpp).
#include "separation.hpp"

#include <polyclipping/clipper.hpp>

#include <algorithm>
#include <cmath>

namespace lambert::formfactor::detail {

struct SeparationScratch {
  std::vector<double> da, db;
  std::vector<char> used;
  std::vector<int> group;
  std::vector<Eigen::Vector2d> pts, hull, poly, tmp;
  ClipperLib::Clipper clipper;
  ClipperLib::Paths occ, result;
  ClipperLib::Path hull_path;
};

void SeparationScratchDeleter::operator()(SeparationScratch* s) const { delete s; }
SeparationScratchPtr make_separation_scratch() { return SeparationScratchPtr(new SeparationScratch); }

namespace {

using V2 = Eigen::Vector2d;

double cross(const V2& o, const V2& a, const V2& b) { return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x(); }

// Andrew's monotone chain: counter-clockwise hull without collinear points (sorts `p`).
void convex_hull(std::vector<V2>& p, std::vector<V2>& h) {
  std::sort(p.begin(), p.end(), [](const V2& a, const V2& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  h.assign(2 * p.size(), V2::Zero());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  h.resize(k > 1 ? k - 1 : k);
}

// Sutherland-Hodgman against the square |x|, |y| <= r (keeps the snapped coordinates in Clipper's fast range).
void clip_square(std::vector<V2>& poly, double r, std::vector<V2>& tmp) {
  for (int axis = 0; axis < 2; ++axis)
    for (double sign : {1.0, -1.0}) {
      tmp.clear();
      const size_t m = poly.size();
      for (size_t k = 0; k < m; ++k) {
        const V2& p = poly[(k + m - 1) % m];
        const V2& c = poly[k];
        const double sp = r - sign * p[axis], sc = r - sign * c[axis];  // >= 0 inside
        if (sc >= 0) {
          if (sp < 0) tmp.push_back(p + (c - p) * (sp / (sp - sc)));
          tmp.push_back(c);
        } else if (sp >= 0) {
          if (sp > 0) tmp.push_back(p + (c - p) * (sp / (sp - sc)));
        }
      }
      poly.swap(tmp);
      if (poly.size() < 3) {
        poly.clear();
        return;
      }
    }
}

}  // namespace

bool hidden_by_plane(std::span<const Vec3> a, std::span<const Vec3> b, const mesh::PatchGeometry& g,
                     std::span<const int> candidates, double eps, SeparationScratch& S) {
  if (a.empty() || b.empty() || candidates.empty()) return false;
  S.used.assign(candidates.size(), 0);
  S.da.resize(a.size());
  S.db.resize(b.size());
  for (size_t c = 0; c < candidates.size(); ++c) {
    if (S.used[c]) continue;
    const int p = candidates[c];
    const Vec3 n = g.normal[size_t(p)];
    const double o = n.dot(g.centroid[size_t(p)]);
    // A on the side n.x <= o, B on n.x >= o (or the mirror), each within eps of touching the plane.
    double amin = INFINITY, amax = -INFINITY, bmin = INFINITY, bmax = -INFINITY;
    for (size_t k = 0; k < a.size(); ++k) {
      S.da[k] = n.dot(a[k]) - o;
      amin = std::min(amin, S.da[k]);
      amax = std::max(amax, S.da[k]);
    }
    for (size_t k = 0; k < b.size(); ++k) {
      S.db[k] = n.dot(b[k]) - o;
      bmin = std::min(bmin, S.db[k]);
      bmax = std::max(bmax, S.db[k]);
    }
    const bool ab = amax <= eps && bmin >= -eps, ba = bmax <= eps && amin >= -eps;
    if (!ab && !ba) continue;
    // The plane's occluders: every candidate lying in it (both sides of a two-sided face, the tiles of a wall).
    S.group.clear();
    double occluder_area = 0;
    for (size_t q = c; q < candidates.size(); ++q) {
      if (S.used[q]) continue;
      const int id = candidates[q];
      if (std::abs(g.normal[size_t(id)].dot(n)) < 1 - 1e-9) continue;
      bool in_plane = true;
      for (const Vec3& v : g.polygon(id)) in_plane = in_plane && std::abs(n.dot(v) - o) <= eps;
      if (!in_plane) continue;
      S.used[q] = 1;
      S.group.push_back(id);
      occluder_area += g.area[size_t(id)];
    }
    // The crossings of the segments between the given points. A segment with both ends in the plane runs
    // along it: not decided here.
    const Vec3 e1 = n.unitOrthogonal(), e2 = n.cross(e1);
    const Vec3 origin = g.centroid[size_t(p)] - n * (n.dot(g.centroid[size_t(p)]) - o);
    S.pts.clear();
    bool along = false;
    for (size_t i = 0; i < a.size() && !along; ++i)
      for (size_t j = 0; j < b.size(); ++j) {
        const double di = S.da[i], dj = S.db[j];
        if (std::abs(di) <= eps && std::abs(dj) <= eps) {
          along = true;
          break;
        }
        const double t = std::clamp(di / (di - dj), 0.0, 1.0);
        const Vec3 x = a[i] + t * (b[j] - a[i]) - origin;
        S.pts.emplace_back(e1.dot(x), e2.dot(x));
      }
    if (along) continue;
    convex_hull(S.pts, S.hull);
    double hull_area = 0;
    for (size_t k = 0; k < S.hull.size(); ++k) hull_area += cross(V2::Zero(), S.hull[k], S.hull[(k + 1) % S.hull.size()]);
    hull_area *= 0.5;
    if (S.hull.size() < 3) continue;  // a degenerate bundle (a and b single points): not decided here
    if (occluder_area < hull_area * (1 - 1e-9)) continue;  // cannot cover it
    // Integer frame centred on the hull, 2^29 units across its half-size.
    V2 lo = S.hull[0], hi = S.hull[0];
    for (const V2& v : S.hull) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    const V2 mid = 0.5 * (lo + hi);
    const double half = 0.5 * (hi - lo).maxCoeff();
    if (!(half > 0)) continue;
    const double scale = double(1 << 29) / half;
    auto snap = [&](const V2& v) {
      return ClipperLib::IntPoint(ClipperLib::cInt(std::llround((v.x() - mid.x()) * scale)),
                                  ClipperLib::cInt(std::llround((v.y() - mid.y()) * scale)));
    };
    S.hull_path.clear();
    for (const V2& v : S.hull) S.hull_path.push_back(snap(v));
    S.occ.clear();
    for (int id : S.group) {
      S.poly.clear();
      for (const Vec3& v : g.polygon(id)) S.poly.emplace_back(e1.dot(v - origin) - mid.x(), e2.dot(v - origin) - mid.y());
      clip_square(S.poly, 1.5 * half, S.tmp);  // what lies beyond cannot cover the hull
      if (S.poly.empty()) continue;
      ClipperLib::Path path;
      path.reserve(S.poly.size());
      for (const V2& v : S.poly) path.push_back(snap(v + mid));
      if (!ClipperLib::Orientation(path)) ClipperLib::ReversePath(path);
      S.occ.push_back(std::move(path));
    }
    if (S.occ.empty()) continue;
    S.clipper.Clear();
    S.clipper.AddPath(S.hull_path, ClipperLib::ptSubject, true);
    S.clipper.AddPaths(S.occ, ClipperLib::ptClip, true);
    S.result.clear();
    S.clipper.Execute(ClipperLib::ctDifference, S.result, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
    // Uncovered: anything left but the snapping's slivers (mean width 2 |area| / perimeter <= 2 units).
    bool covered = true;
    for (const ClipperLib::Path& r : S.result) {
      double per = 0;
      for (size_t k = 0; k < r.size(); ++k) {
        const ClipperLib::IntPoint &u = r[k], &v = r[(k + 1) % r.size()];
        per += std::hypot(double(v.X - u.X), double(v.Y - u.Y));
      }
      if (2 * std::abs(ClipperLib::Area(r)) > 2.0 * per + 4.0) covered = false;
    }
    if (covered) return true;
  }
  return false;
}

}  // namespace lambert::formfactor::detail
