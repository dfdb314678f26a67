// Proof that occluders in one separating plane hide one region from another (separation.hpp).
#include "separation.hpp"

#include <polyclipping/clipper.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace lambert::formfactor::detail {

struct SeparationScratch {
  std::vector<double> da, db;
  std::vector<std::pair<int, int>> order;  // (plane id, patch)
  std::vector<int> group;
  std::vector<Eigen::Vector2d> pts, hull, poly, tmp, rel;
  std::vector<char> held;
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

// Whether q lies inside the polygon or within tol of its boundary (crossing number; tol in its units).
bool inside_or_near(const std::vector<V2>& poly, const V2& q, double tol) {
  bool in = false;
  const size_t m = poly.size();
  for (size_t k = 0, l = m - 1; k < m; l = k++) {
    const V2 &a = poly[l], &b = poly[k];
    const V2 e = b - a;
    const double len2 = e.squaredNorm();
    const double t = len2 > 0 ? std::clamp((q - a).dot(e) / len2, 0.0, 1.0) : 0.0;
    if ((a + t * e - q).squaredNorm() <= tol * tol) return true;
    if ((a.y() > q.y()) != (b.y() > q.y()) && q.x() < a.x() + (q.y() - a.y()) / (b.y() - a.y()) * e.x()) in = !in;
  }
  return in;
}

// Whether the convex polygon (either orientation) holds every point of `pts` (within tol of its edges); false
// if the polygon is not convex.
bool convex_holds(const std::vector<V2>& poly, const std::vector<V2>& pts, double tol) {
  const size_t m = poly.size();
  double sign = 0;
  for (size_t k = 0; k < m; ++k) {
    const double c = cross(poly[k], poly[(k + 1) % m], poly[(k + 2) % m]);
    if (c == 0) continue;
    if (sign == 0) sign = c > 0 ? 1 : -1;
    else if ((c > 0 ? 1 : -1) != sign) return false;
  }
  if (sign == 0) return false;
  for (size_t k = 0; k < m; ++k) {
    const V2 &a = poly[k], &b = poly[(k + 1) % m];
    const double len = (b - a).norm();
    for (const V2& q : pts)
      if (sign * cross(a, b, q) < -tol * len) return false;
  }
  return true;
}

}  // namespace

bool lies_in_plane_facing(const mesh::PatchGeometry& g, int p, const Vec3& n, double o, double eps) {
  if (!(g.normal[size_t(p)].dot(n) > 0)) return false;
  for (const Vec3& v : g.polygon(p))
    if (std::abs(n.dot(v) - o) > eps) return false;
  return true;
}

std::vector<int> occluder_planes(const mesh::PatchGeometry& g, std::span<const int> occluders, double scale) {
  return mesh::plane_ids(g, occluders, scale);
}

int hidden_by_plane(std::span<const Vec3> a, std::span<const Vec3> b, const mesh::PatchGeometry& g,
                    std::span<const int> plane_of, std::span<const int> candidates, double eps,
                    SeparationScratch& S, const TouchingCheck& touching_ok) {
  if (a.empty() || b.empty() || candidates.empty()) return -1;
  // Candidates grouped by plane (sorted by plane id, then patch: deterministic).
  S.order.clear();
  for (int c : candidates)
    if (plane_of[size_t(c)] >= 0) S.order.emplace_back(plane_of[size_t(c)], c);
  std::sort(S.order.begin(), S.order.end());
  S.da.resize(a.size());
  S.db.resize(b.size());
  for (size_t r0 = 0, r1 = 0; r0 < S.order.size(); r0 = r1) {
    r1 = r0;
    while (r1 < S.order.size() && S.order[r1].first == S.order[r0].first) ++r1;
    const int p = S.order[r0].second;
    const Vec3 n = g.normal[size_t(p)];
    const double o = n.dot(g.centroid[size_t(p)]);
    // A strictly on the side n.x < o, B strictly on n.x > o (or the mirror). A point in the plane would cross it
    // where it starts: on its own patch, or on a coplanar one that does not block it (the back of a two-sided
    // face), so a region touching the plane needs the caller's word (touching_ok).
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
    bool ab = amax < -eps && bmin > eps, ba = bmax < -eps && amin > eps;
    // One region touching the plane (the other strictly off it), if the caller vouches for its patches there.
    bool touching = false;
    if (!ab && !ba && touching_ok) {
      ab = (amax <= eps && bmin > eps) || (amax < -eps && bmin >= -eps);
      ba = (bmax <= eps && amin > eps) || (bmax < -eps && amin >= -eps);
      touching = ab || ba;
    }
    // Accepted proof: for a touching region, its patches lying in the plane must not face the other region.
    auto accept = [&] { return !touching || touching_ok(ab ? n : Vec3(-n), ab ? o : -o); };
    if (!ab && !ba) continue;
    // The plane's occluders among the candidates (both sides of a two-sided face, the tiles of a wall); those
    // outside the shaft cannot cover the crossings, which lie inside it.
    S.group.clear();
    double occluder_area = 0;
    for (size_t q = r0; q < r1; ++q) {
      S.group.push_back(S.order[q].second);
      occluder_area += g.area[size_t(S.order[q].second)];
    }
    // The plane's 2D frame, centred on one of its occluders (coordinates stay small far from the origin).
    const Vec3 e1 = n.unitOrthogonal(), e2 = n.cross(e1);
    const Vec3 origin = g.centroid[size_t(p)] - n * (n.dot(g.centroid[size_t(p)]) - o);
    // A necessary condition first (most separating planes fail it): the segment between the two regions'
    // centroids crosses the plane inside one of its occluders (that crossing is one of those to be covered).
    {
      Vec3 ca = Vec3::Zero(), cb = Vec3::Zero();
      double dca = 0, dcb = 0;
      for (size_t k = 0; k < a.size(); ++k) ca += a[k] - origin, dca += S.da[k];
      for (size_t k = 0; k < b.size(); ++k) cb += b[k] - origin, dcb += S.db[k];
      ca /= double(a.size()), cb /= double(b.size()), dca /= double(a.size()), dcb /= double(b.size());
      const Vec3 x = ca + (dca / (dca - dcb)) * (cb - ca);
      const V2 q(e1.dot(x), e2.dot(x));
      const double tol = 1e-9 * ((cb - ca).norm() + 1e-300);
      bool held = false;
      for (size_t k = 0; k < S.group.size() && !held; ++k) {
        S.poly.clear();
        for (const Vec3& v : g.polygon(S.group[k])) S.poly.emplace_back(e1.dot(v - origin), e2.dot(v - origin));
        held = inside_or_near(S.poly, q, tol);
      }
      if (!held) continue;
    }
    // The crossings of the segments between the given points (each has one end strictly off the plane).
    S.pts.clear();
    for (size_t i = 0; i < a.size(); ++i)
      for (size_t j = 0; j < b.size(); ++j) {
        const double di = S.da[i], dj = S.db[j];  // opposite signs, at least one beyond eps
        const Vec3 x = a[i] + std::clamp(di / (di - dj), 0.0, 1.0) * (b[j] - a[i]) - origin;
        S.pts.emplace_back(e1.dot(x), e2.dot(x));
      }
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
    // Quick answers before the Boolean operation: one convex occluder holding the whole hull covers it; a hull
    // corner that no occluder holds is uncovered. Both within 1e-9 of the hull's size (the snap's order).
    const double tol = 1e-9 * half;
    S.rel.clear();
    for (const V2& v : S.hull) S.rel.push_back(v - mid);
    S.held.assign(S.rel.size(), 0);
    bool one_holds = false;
    for (int id : S.group) {
      S.poly.clear();
      for (const Vec3& v : g.polygon(id)) S.poly.emplace_back(e1.dot(v - origin) - mid.x(), e2.dot(v - origin) - mid.y());
      if (convex_holds(S.poly, S.rel, tol)) {
        one_holds = true;
        break;
      }
      for (size_t k = 0; k < S.rel.size(); ++k)
        if (!S.held[k]) S.held[k] = inside_or_near(S.poly, S.rel[k], tol);
    }
    if (one_holds && accept()) return S.order[r0].first;
    if (one_holds) continue;
    if (std::find(S.held.begin(), S.held.end(), 0) != S.held.end()) continue;
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
    if (covered && accept()) return S.order[r0].first;
  }
  return -1;
}

}  // namespace lambert::formfactor::detail
