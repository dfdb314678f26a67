// Exact partial visibility: occluders clipped to the cone from a point through the target, projected onto the
// target's plane, united with Clipper (integer coordinates), and the union's contour integral subtracted.
#include "exact_visibility.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Partition_traits_2.h>
#include <CGAL/convex_hull_3.h>
#include <CGAL/partition_2.h>

#include <polyclipping/clipper.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <queue>

#include "lambert/formfactor/kernel.hpp"

namespace lambert::formfactor::detail {

struct ExactScratch {
  std::vector<std::vector<Vec3>> surv;  // clipped occluders (first `count` used)
  std::vector<bool> surv_convex;
  std::vector<Vec3> a, b;               // clipping ping-pong
  std::vector<std::array<double, 4>> planes;  // m.x, m.y, m.z, c: keep m.q - c >= 0
  ClipperLib::Clipper clipper;
  ClipperLib::Paths subject, result;
  ClipperLib::Path clip_path;
  std::vector<Vec3> lifted, cs, ct, pts, pts2;
  std::vector<Occluder> kept;           // classify: candidates given their unit normal
  std::vector<const Occluder*> kept_ref;  // classify: the candidates that can block anything
  std::vector<std::array<double, 4>> hull;
  std::vector<std::array<double, 2>> uv, hull2;  // projected corners and their convex hull (one convex solid)
  std::vector<std::array<ClipperLib::cInt, 4>> boxes;  // per projected occluder: x_min, y_min, x_max, y_max
  std::vector<std::uint8_t> inside;                    // per projected occluder: inside another one (left out)
  ClipperLib::Paths convex;                            // the projections with repeated corners removed
  std::vector<std::array<double, 2>> removed;          // per edge: parameter intervals inside other projections
  std::vector<std::uint8_t> gone;                      // per occluder of a pair: in another's umbra (left out)
  std::vector<int> surv_solid;                         // per clipped occluder: its convex solid, or -1
  std::vector<int> outside;                            // solids x is outside of (their back faces left out)
  std::vector<std::array<double, 2>> target2, shadow2, tmp2;  // one solid's 2D shadow clipped to the target
  // The target's frame for hidden_point_to_polygon, kept for the next call with the same target (corners and normal
  // compared exactly): the points of a pair all see one target. target2: its corners in (u, v), counter-clockwise.
  std::vector<Vec3> frame_of;
  Vec3 frame_nt = Vec3::Zero(), frame_u = Vec3::Zero(), frame_v = Vec3::Zero(), frame_tc = Vec3::Zero();
  double frame_twice_area = 0;
};

void ExactScratchDeleter::operator()(ExactScratch* s) const { delete s; }
ExactScratchPtr make_exact_scratch() { return ExactScratchPtr(new ExactScratch()); }

namespace {

// Keeps the part of `in` with m.q - c >= 0 (Sutherland-Hodgman) into `out`. A polygon entirely on one side
// is copied or dropped without arithmetic on its corners.
void clip_keep(const std::vector<Vec3>& in, const Vec3& m, double c, std::vector<Vec3>& out) {
  out.clear();
  const size_t k = in.size();
  if (k < 3) return;
  bool all_in = true, all_out = true;
  for (const Vec3& q : in) {
    const double d = m.dot(q) - c;
    all_in = all_in && d >= 0;
    all_out = all_out && d <= 0;
  }
  if (all_in) {
    out = in;
    return;
  }
  if (all_out) return;
  // Where an edge crosses the plane, computed from its lexicographically smaller end: the same point to the bit
  // whichever way a polygon runs along the edge (the convex pieces of one region share their diagonals; clipped
  // separately they must still meet exactly, or the union keeps a sliver between them).
  auto crossing = [](const Vec3& a, double da, const Vec3& b, double db) {
    const bool swap = std::lexicographical_compare(b.data(), b.data() + 3, a.data(), a.data() + 3);
    return swap ? Vec3(b + (a - b) * (db / (db - da))) : Vec3(a + (b - a) * (da / (da - db)));
  };
  double dp = m.dot(in[k - 1]) - c;
  for (size_t i = 0; i < k; ++i) {
    const Vec3& prev = in[(i + k - 1) % k];
    const Vec3& cur = in[i];
    const double dc = m.dot(cur) - c;
    if (dc >= 0) {
      if (dp < 0) out.push_back(crossing(prev, dp, cur, dc));
      out.push_back(cur);
    } else if (dp > 0) {
      out.push_back(crossing(prev, dp, cur, dc));
    }
    dp = dc;
  }
  if (out.size() < 3) out.clear();
}

Vec3 average(std::span<const Vec3> poly) {
  Vec3 c = Vec3::Zero();
  for (const Vec3& v : poly) c += v;
  return c / double(poly.size());
}

// True if the ray from x through every corner of `target` meets the convex planar polygon q (closed), at a
// parameter in (0, 1]: then q hides the whole target from x (central projection preserves convexity).
bool covers(const Vec3& x, std::span<const Vec3> target, const std::vector<Vec3>& q) {
  const Vec3 nq = mesh::newell_normal(q);
  const double len = nq.norm();
  if (!(len > 0)) return false;
  const Vec3 u = nq / len;
  const double oq = u.dot(q[0] - x);
  for (const Vec3& tk : target) {
    const Vec3 d = tk - x;
    const double den = u.dot(d);
    if (den == 0) return false;
    const double lam = oq / den;
    if (!(lam > 0 && lam <= 1)) return false;
    const Vec3 p = x + lam * d;
    const size_t m = q.size();
    for (size_t k = 0; k < m; ++k) {
      const Vec3 e = q[(k + 1) % m] - q[k];
      if (e.cross(p - q[k]).dot(u) < -1e-12 * e.squaredNorm()) return false;
    }
  }
  return true;
}

// True if every corner of `a` lies on the inner (left) side of every edge of the counter-clockwise path `b`, or on
// it: then `a` lies in b's kernel, inside b. Exact in 64-bit integers: coordinates are within Clipper's loRange
// (|c| < 2^30), so differences are below 2^31, products below 2^62 and their difference below 2^63.
bool in_kernel(const ClipperLib::Path& a, const ClipperLib::Path& b) {
  const size_t m = b.size();
  for (size_t e = 0; e < m; ++e) {
    const ClipperLib::IntPoint &p = b[e], &q = b[(e + 1) % m];
    const long long dx = q.X - p.X, dy = q.Y - p.Y;
    for (const ClipperLib::IntPoint& c : a)
      if (dx * (c.Y - p.Y) - dy * (c.X - p.X) < 0) return false;
  }
  return true;
}

__extension__ typedef __int128 Int128;

// The projection `in` (counter-clockwise) without repeated corners, into `out`. False unless it is strictly convex
// and simple: every turn to the left or straight, at least one to the left, and the edges' x-components change sign
// exactly twice around it (a polygon winding twice has all its turns to the left too).
bool strictly_convex(const ClipperLib::Path& in, ClipperLib::Path& out) {
  out.clear();
  for (const ClipperLib::IntPoint& q : in)
    if (out.empty() || q.X != out.back().X || q.Y != out.back().Y) out.push_back(q);
  while (out.size() > 1 && out.back().X == out[0].X && out.back().Y == out[0].Y) out.pop_back();
  const size_t m = out.size();
  if (m < 3) return false;
  bool left = false;
  int changes = 0, last = 0;
  for (size_t k = 0; k < m; ++k) {
    const ClipperLib::IntPoint &a = out[k], &b = out[(k + 1) % m], &c = out[(k + 2) % m];
    const long long turn = (b.X - a.X) * (c.Y - b.Y) - (b.Y - a.Y) * (c.X - b.X);  // < 2^63, as in in_kernel
    if (turn < 0) return false;
    left = left || turn > 0;
    const int sx = b.X > a.X ? 1 : b.X < a.X ? -1 : 0;
    if (sx != 0) {
      if (last != 0 && sx != last) ++changes;
      last = sx;
    }
  }
  // The cyclic change from the last nonzero sign back to the first.
  int first = 0;
  for (size_t k = 0; k < m && first == 0; ++k) first = out[(k + 1) % m].X > out[k].X ? 1 : out[(k + 1) % m].X < out[k].X ? -1 : 0;
  if (first != 0 && last != 0 && first != last) ++changes;
  return left && changes == 2;
}

// Andrew's monotone chain over pts, sorted (x, then y): the convex hull counter-clockwise, collinear corners dropped,
// into hull[0, h) with hull[h - 1] == hull[0]; returns h (below 4: fewer than 3 corners, no area). turn(o, a, b) is
// the cross product (a - o) x (b - o).
template <class P, class Turn>
size_t monotone_chain(const std::vector<P>& pts, std::vector<P>& hull, const Turn& turn) {
  const size_t m = pts.size();
  hull.resize(2 * m + 1);
  size_t h = 0;
  for (size_t k = 0; k < m; ++k) {
    while (h >= 2 && turn(hull[h - 2], hull[h - 1], pts[k]) <= 0) --h;
    hull[h++] = pts[k];
  }
  for (size_t k = m - 1, lower = h + 1; m > 0 && k-- > 0;) {
    while (h >= lower && turn(hull[h - 2], hull[h - 1], pts[k]) <= 0) --h;
    hull[h++] = pts[k];
  }
  return h;
}

// The convex hull of the integer points `in` (counter-clockwise, collinear corners dropped) into `out`; false if they
// are collinear. Coordinates within Clipper's loRange (2^30): cross products below 2^63.
bool integer_hull(const ClipperLib::Path& in, ClipperLib::Path& out) {
  ClipperLib::Path pts(in);
  std::sort(pts.begin(), pts.end(), [](const ClipperLib::IntPoint& a, const ClipperLib::IntPoint& b) {
    return a.X < b.X || (a.X == b.X && a.Y < b.Y);
  });
  const size_t h = monotone_chain(pts, out, [](const ClipperLib::IntPoint& o, const ClipperLib::IntPoint& a,
                                                const ClipperLib::IntPoint& b) {
    return (a.X - o.X) * (b.Y - o.Y) - (a.Y - o.Y) * (b.X - o.X);
  });
  if (h < 4) return false;
  out.resize(h - 1);
  return true;
}

// Intersects the convex counter-clockwise polygon `x` with the convex counter-clockwise polygon `c` (in place); below.
void intersect_convex(std::vector<std::array<double, 2>>& x, const std::vector<std::array<double, 2>>& c,
                      std::vector<std::array<double, 2>>& tmp);

constexpr double kSnap = 536870912.0;  // 2^29 units per half-extent of the target: Clipper's 64-bit fast range
// The inside test and the edges' union compare every projection with every other: above this many, Clipper's sweep
// (n log n) does the union alone.
constexpr size_t kMaxPairwise = 64;  // also the width of convex_union_contour's bit sets

// The contour sum (as signed_contour_sum) of the boundary of the union of the strictly convex counter-clockwise
// integer polygons P[0, count), lifted to 3D by lift(X, Y). The boundary is the union of the polygons' edges without
// their parts inside another polygon; an edge lying along another polygon's edge is left out where that polygon is
// on its other side (both sides covered) and kept once, by the lower index, where it is on the same side. Every
// such decision is exact (64-bit cross products, 128-bit comparisons of their ratios); only the parameters where
// the kept pieces start and end are rounded (to double), which moves F by ~1e-16 of an edge's contribution.
template <class Lift>
double convex_union_contour(const ClipperLib::Paths& P, size_t count, const std::vector<std::array<ClipperLib::cInt, 4>>& box,
                            const Vec3& x, const Vec3& n, const Lift& lift, std::vector<std::array<double, 2>>& removed) {
  double total = 0;
  // Per projection, the others whose boxes meet its box (count <= kMaxPairwise: one bit each); its edges are
  // tested against those only.
  static_assert(kMaxPairwise <= 64);
  std::array<std::uint64_t, kMaxPairwise> near{};
  for (size_t i = 0; i < count; ++i)
    for (size_t j = i + 1; j < count; ++j) {
      const auto &a = box[i], &b = box[j];
      if (a[2] < b[0] || a[0] > b[2] || a[3] < b[1] || a[1] > b[3]) continue;
      near[i] |= std::uint64_t(1) << j;
      near[j] |= std::uint64_t(1) << i;
    }
  for (size_t i = 0; i < count; ++i) {
    const ClipperLib::Path& A = P[i];
    const size_t m = A.size();
    for (size_t e = 0; e < m; ++e) {
      const ClipperLib::IntPoint &p = A[e], &q = A[(e + 1) % m];
      const long long dx = q.X - p.X, dy = q.Y - p.Y;
      const ClipperLib::cInt x0 = std::min(p.X, q.X), x1 = std::max(p.X, q.X), y0 = std::min(p.Y, q.Y),
                             y1 = std::max(p.Y, q.Y);
      removed.clear();
      for (std::uint64_t bits = near[i]; bits != 0; bits &= bits - 1) {
        const size_t j = size_t(__builtin_ctzll(bits));
        const auto& b = box[j];
        if (x1 < b[0] || x0 > b[2] || y1 < b[1] || y0 > b[3]) continue;
        // Cyrus-Beck: p + t d inside B where cross(f, p + t d - w0) >= 0 for every edge f = w1 - w0 of B.
        const ClipperLib::Path& B = P[j];
        long long lo_n = 0, lo_d = 1, hi_n = 1, hi_d = 1;  // t in [lo_n / lo_d, hi_n / hi_d], denominators > 0
        int along = 0;  // e lies on the line of an edge of B: +1 same direction, -1 opposite
        bool empty = false;
        for (size_t f = 0; f < B.size() && !empty; ++f) {
          const ClipperLib::IntPoint &w0 = B[f], &w1 = B[(f + 1) % B.size()];
          const long long fx = w1.X - w0.X, fy = w1.Y - w0.Y;
          const long long a = fx * (p.Y - w0.Y) - fy * (p.X - w0.X), c = fx * dy - fy * dx;
          if (a < 0 && c < -a) {  // both ends outside this edge of B (a + c < 0, without overflow)
            empty = true;
            break;
          }
          if (c > 0) {  // t >= -a / c
            if (Int128(-a) * lo_d > Int128(lo_n) * c) lo_n = -a, lo_d = c;
          } else if (c < 0) {  // t <= a / -c
            if (Int128(a) * hi_d < Int128(hi_n) * -c) hi_n = a, hi_d = -c;
          } else if (a < 0) {
            empty = true;
          } else if (a == 0) {
            along = fx * dx + fy * dy > 0 ? 1 : -1;
          }
        }
        if (empty || Int128(lo_n) * hi_d >= Int128(hi_n) * lo_d) continue;  // nothing, or a single point
        if (along > 0 && i < j) continue;  // the same side: the lower index keeps its copy
        if (lo_n <= 0 && hi_n >= hi_d) {  // all of e is inside B (or along it, covered on both sides): nothing left
          removed.assign(1, {0.0, 1.0});
          break;
        }
        removed.push_back({double(lo_n) / double(lo_d), double(hi_n) / double(hi_d)});
      }
      // The pieces of [0, 1] outside every removed interval.
      std::sort(removed.begin(), removed.end());
      double t = 0;
      auto piece = [&](double t0, double t1) {
        if (!(t1 > t0)) return;
        const Vec3 a = lift(double(p.X) + t0 * double(dx), double(p.Y) + t0 * double(dy)) - x;
        const Vec3 b = lift(double(p.X) + t1 * double(dx), double(p.Y) + t1 * double(dy)) - x;
        const Vec3 c = a.cross(b - a);
        const double cn = c.norm();
        if (cn > 0) total += atan2_pos(cn, a.dot(b)) * (n.dot(c) / cn);
      };
      for (const auto& r : removed) {
        piece(t, std::min(r[0], 1.0));
        t = std::max(t, r[1]);
        if (t >= 1) break;
      }
      piece(t, 1.0);
    }
  }
  return total;
}

// The convex hull of the projected corners S.uv (sorted here) into S.hull2, counter-clockwise, collinear corners
// dropped, S.hull2[h - 1] == S.hull2[0]; returns h (below 4: no area).
size_t uv_hull(ExactScratch& S) {
  std::sort(S.uv.begin(), S.uv.end());
  return monotone_chain(S.uv, S.hull2, [](const std::array<double, 2>& o, const std::array<double, 2>& a,
                                          const std::array<double, 2>& b) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  });
}

// The convex hull of the corners of the clipped occluders S.surv[k], k < count with pick(k), projected from x onto
// the target's plane (height hx of x above it, t0 = nt . target[0]; frame tc, u, v), lifted back to that plane, into
// out (counter-clockwise in (u, v), collinear corners dropped). False if it has no area (fewer than 3 distinct
// corners).
template <class Pick>
bool projected_hull(const Vec3& x, const Vec3& nt, double t0, double hx, const Vec3& tc, const Vec3& u, const Vec3& v,
                    size_t count, const Pick& pick, ExactScratch& S, std::vector<Vec3>& out) {
  S.uv.clear();
  for (size_t k = 0; k < count; ++k)
    if (pick(k))
      for (const Vec3& q : S.surv[k]) {
        const double hq = nt.dot(q) - t0;  // as for the union: a corner on the plane through x moves far outside
        const Vec3 y = x + (q - x) * (hx / std::max(hx - hq, 1e-12 * hx));
        S.uv.push_back({u.dot(y - tc), v.dot(y - tc)});
      }
  const size_t h = uv_hull(S);
  if (h < 4) return false;  // the last corner repeats the first
  out.clear();
  for (size_t k = 0; k + 1 < h; ++k) out.push_back(tc + S.hull2[k][0] * u + S.hull2[k][1] * v);
  return true;
}

// S.surv[0, count) with the clipped faces of each convex solid (S.surv_solid) replaced by their projected hull (one
// convex polygon in the target's plane, its own projection from x); hulls without area dropped. Returns the new count.
size_t hull_per_solid(const Vec3& x, const Vec3& nt, double t0, double hx, const Vec3& tc, const Vec3& u, const Vec3& v,
                      size_t count, ExactScratch& S) {
  constexpr int kTaken = -2;  // a face already in an earlier face's hull
  size_t w = 0;
  for (size_t i = 0; i < count; ++i) {
    const int sol = S.surv_solid[i];
    if (sol == kTaken) continue;
    int faces = 0;
    if (sol >= 0)
      for (size_t j = i; j < count; ++j) faces += S.surv_solid[j] == sol;
    if (faces < 2) {  // not a solid's, or its only face: kept as it is
      if (w != i) std::swap(S.surv[w], S.surv[i]), S.surv_convex[w] = S.surv_convex[i];
      ++w;
      continue;
    }
    const bool area = projected_hull(x, nt, t0, hx, tc, u, v, count,
                                     [&](size_t k) { return k >= i && S.surv_solid[k] == sol; }, S, S.lifted);
    for (size_t j = i + 1; j < count; ++j)
      if (S.surv_solid[j] == sol) S.surv_solid[j] = kTaken;
    if (!area) continue;
    std::swap(S.surv[w], S.lifted);
    S.surv_convex[w] = true;
    ++w;
  }
  return w;
}

}  // namespace

bool convex_hides(std::span<const Vec3> a, std::span<const Vec3> b, std::span<const Vec3> q, const Vec3& unit,
                  double offset, double eps) {
  const size_t m = q.size();
  if (m < 3 || !(unit.squaredNorm() > 0)) return false;
  // Every corner of a strictly on one side of q's plane and every corner of b strictly on the other.
  constexpr size_t kMax = 16;
  if (a.empty() || b.empty()) return false;
  if (a.size() > kMax || b.size() > kMax || m > kMax) {  // many corners (a merged wall): without the tables
    for (const Vec3& pa : a)
      for (const Vec3& pb : b) {
        const double ea = unit.dot(pa) - offset, eb = unit.dot(pb) - offset;
        if (!((ea > eps && eb < -eps) || (ea < -eps && eb > eps))) return false;
        const Vec3 p = pa + (pb - pa) * (ea / (ea - eb));
        for (size_t k = 0; k < m; ++k)
          if ((q[k + 1 < m ? k + 1 : 0] - q[k]).cross(p - q[k]).dot(unit) < 0) return false;
      }
    return true;
  }
  double da[kMax], db[kMax];
  for (size_t i = 0; i < a.size(); ++i) da[i] = unit.dot(a[i]) - offset;
  for (size_t i = 0; i < b.size(); ++i) db[i] = unit.dot(b[i]) - offset;
  const double sa = da[0] > eps ? 1 : da[0] < -eps ? -1 : 0;
  if (sa == 0) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!(sa * da[i] > eps)) return false;
  for (size_t i = 0; i < b.size(); ++i)
    if (!(sa * db[i] < -eps)) return false;
  // Crossings inside q: (q[k+1] - q[k]) x (p - q[k]) . unit = (unit x (q[k+1] - q[k])) . (p - q[k]) >= 0 per edge.
  Vec3 w[kMax];
  double c[kMax];
  for (size_t k = 0; k < m; ++k) {
    w[k] = unit.cross(q[k + 1 < m ? k + 1 : 0] - q[k]);
    c[k] = w[k].dot(q[k]);
  }
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j) {
      const Vec3 p = a[i] + (b[j] - a[i]) * (da[i] / (da[i] - db[j]));
      for (size_t k = 0; k < m; ++k)
        if (w[k].dot(p) < c[k]) return false;
    }
  return true;
}

double hidden_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> target, const Vec3& nt,
                               bool target_convex, std::span<const Occluder> occluders, ExactScratch& S, int* kind) {
  int unused_kind = 0;
  int& K = kind ? *kind : unused_kind;
  K = 0;
  const size_t mt = target.size();
  if (mt < 3 || occluders.empty()) return 0;
  const double hx = nt.dot(x - target[0]);
  if (!(hx > 0)) return 0;
  const double t0 = nt.dot(target[0]);
  // Frame of the target's plane: u along the first usable edge, v = nt x u; the target's corners in it.
  if (!(S.frame_nt == nt && S.frame_of.size() == mt && std::equal(target.begin(), target.end(), S.frame_of.begin()))) {
    S.frame_of.assign(target.begin(), target.end());
    S.frame_nt = nt;
    S.frame_tc = average(target);
    Vec3 u = Vec3::Zero();
    for (size_t k = 0; k < mt && !(u.squaredNorm() > 0); ++k) u = target[(k + 1) % mt] - target[k];
    S.frame_u = u.normalized();
    S.frame_v = nt.cross(S.frame_u);
    double twice_area = 0;
    S.target2.clear();
    for (const Vec3& p : target) S.target2.push_back({S.frame_u.dot(p - S.frame_tc), S.frame_v.dot(p - S.frame_tc)});
    for (size_t k = 0; k < mt; ++k) {
      const auto &a = S.target2[k], &b = S.target2[(k + 1) % mt];
      twice_area += a[0] * b[1] - a[1] * b[0];
    }
    if (twice_area < 0) std::reverse(S.target2.begin(), S.target2.end());
    S.frame_twice_area = std::abs(twice_area);
  }
  const Vec3 tc = S.frame_tc, u = S.frame_u, v = S.frame_v;
  // Every occluder a face of one closed convex solid C (convex_solids), the target convex: see below. If x is
  // outside C (in front of one of the faces), a segment from x that meets C enters it through a face facing x: the
  // faces with x on their inner side are left out.
  bool one_solid = target_convex && occluders[0].solid >= 0, cull = false;
  for (const Occluder& o : occluders) one_solid = one_solid && o.solid == occluders[0].solid;
  if (one_solid)
    for (const Occluder& o : occluders) cull = cull || (o.cull && o.inner.dot(x) < o.inner_offset);
  // One convex solid C whose faces' corners all lie strictly between the target's plane and x's height (not within
  // 1e-3 of x's height, where their projections would run far out): a segment from x to the target meets C exactly
  // where its end lies in the projection of C from x, the convex hull of the projected corners (a central projection
  // keeps convex sets convex away from the plane through x parallel to the target). That hull is clipped to the
  // target in its plane's frame: no clipping of faces in 3D (room with a block: the hidden part costs ~40 % less).
  // The faces x sees from behind are left out as below; their corners are points of C all the same.
  if (one_solid) {
    S.uv.clear();
    bool between = true;
    for (const Occluder& o : occluders) {
      if (cull && o.cull && o.inner.dot(x) >= o.inner_offset) continue;
      for (const Vec3& q : o.poly) {
        const double hq = nt.dot(q) - t0;
        if (!(hq > 1e-8 * hx && hq < (1 - 1e-3) * hx)) {
          between = false;
          break;
        }
        const Vec3 y = x + (q - x) * (hx / (hx - hq));
        S.uv.push_back({u.dot(y - tc), v.dot(y - tc)});
      }
      if (!between) break;
    }
    if (between && !S.uv.empty()) {
      const size_t h = uv_hull(S);
      if (h < 4) return 0;
      S.shadow2.assign(S.hull2.begin(), S.hull2.begin() + std::ptrdiff_t(h - 1));
      // The target in the frame (S.target2), counter-clockwise whatever its winding.
      intersect_convex(S.shadow2, S.target2, S.tmp2);
      if (S.shadow2.size() < 3) return 0;
      double twice_shadow = 0;
      S.lifted.clear();
      for (size_t k = 0; k < S.shadow2.size(); ++k) {
        const auto &a = S.shadow2[k], &b = S.shadow2[k + 1 < S.shadow2.size() ? k + 1 : 0];
        twice_shadow += a[0] * b[1] - a[1] * b[0];
        S.lifted.push_back(tc + a[0] * u + a[1] * v);
      }
      twice_shadow = std::abs(twice_shadow);
      const double twice_area = S.frame_twice_area;
      K = twice_shadow <= 1e-9 * twice_area ? 0 : twice_shadow >= (1 - 1e-9) * twice_area ? 1 : 2;
      return std::abs(signed_contour_sum(x, n, S.lifted)) / (2 * kPi);
    }
  }
  K = -1;
  // The cone from x through the target (its edges if convex, else its bounding rectangle in the frame).
  S.planes.clear();
  auto add_side = [&](const Vec3& a, const Vec3& b) {
    Vec3 m = (a - x).cross(b - x);
    if (!(m.squaredNorm() > 0)) return;
    if (m.dot(tc - x) < 0) m = -m;
    S.planes.push_back({m.x(), m.y(), m.z(), m.dot(x)});
  };
  double R = 0;
  if (target_convex) {
    for (size_t k = 0; k < mt; ++k) add_side(target[k], target[(k + 1) % mt]);
    for (const Vec3& p : target) R = std::max({R, std::abs(u.dot(p - tc)), std::abs(v.dot(p - tc))});
  } else {
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (const Vec3& p : target) {
      const double a = u.dot(p - tc), b = v.dot(p - tc);
      lo[0] = std::min(lo[0], a), hi[0] = std::max(hi[0], a), lo[1] = std::min(lo[1], b), hi[1] = std::max(hi[1], b);
    }
    const double pad = 1e-6 * std::max(hi[0] - lo[0], hi[1] - lo[1]);
    lo[0] -= pad, lo[1] -= pad, hi[0] += pad, hi[1] += pad;
    const Vec3 B[4] = {tc + lo[0] * u + lo[1] * v, tc + hi[0] * u + lo[1] * v, tc + hi[0] * u + hi[1] * v,
                       tc + lo[0] * u + hi[1] * v};
    for (int k = 0; k < 4; ++k) add_side(B[k], B[(k + 1) % 4]);
    R = std::max({-lo[0], hi[0], -lo[1], hi[1]});
  }
  R *= 1 + 1e-6;
  S.planes.push_back({nt.x(), nt.y(), nt.z(), t0});                               // not behind the target
  const double top = t0 + hx * (1 - 1e-12);
  S.planes.push_back({-nt.x(), -nt.y(), -nt.z(), -top});                          // between x and the target
  S.planes.push_back({n.x(), n.y(), n.z(), n.dot(x)});                             // in front of x
  // Several solids (a street of buildings, furniture): per solid, the faces x sees from behind are left out where x
  // is outside it (in front of one of its faces), as for one solid below.
  S.outside.clear();
  if (!one_solid)
    for (const Occluder& o : occluders)
      if (o.solid >= 0 && o.cull && o.inner.dot(x) < o.inner_offset &&
          std::find(S.outside.begin(), S.outside.end(), o.solid) == S.outside.end())
        S.outside.push_back(o.solid);
  // Occluders clipped to the cone.
  size_t count = 0;
  bool grouped = false;  // two clipped faces of one solid
  // One polygon clipped to the cone, appended to S.surv[0, count) if anything is left.
  auto clip_in = [&](std::span<const Vec3> poly, bool convex, int solid) {
    S.a.assign(poly.begin(), poly.end());
    for (const auto& pl : S.planes) {
      // Most planes keep the whole polygon (or none of it): decided before clip_keep copies anything.
      const Vec3 m(pl[0], pl[1], pl[2]);
      bool all_in = true, all_out = true;
      for (const Vec3& q : S.a) {
        const double d = m.dot(q) - pl[3];
        all_in = all_in && d >= 0;
        all_out = all_out && d <= 0;
      }
      if (all_in) continue;
      if (all_out) {
        S.a.clear();
        break;
      }
      clip_keep(S.a, m, pl[3], S.b);
      std::swap(S.a, S.b);
      if (S.a.empty()) break;
    }
    if (S.a.size() < 3) return;
    // A face of a solid clipped down to a sliver on the target's plane (every corner within 1e-8 of x's height of it)
    // hides at most that sliver (a solid's face lying flat just above the target is its bottom, seen from behind and
    // hidden by the faces above it), but its corners would widen the solid's hull below: left out. A solid lying
    // behind the target and sharing the target's edges (the target one of its faces) reaches in front of the plane
    // only by the merge's snapping of its corners (~1e-9 of its size); its slivers along two edges of the target made
    // a hull over half of it (floorplan.obj, faces 2997 -> 3049: F 87 % low).
    if (solid >= 0) {
      double rise = 0;
      for (const Vec3& q : S.a) rise = std::max(rise, nt.dot(q) - t0);
      if (rise <= 1e-8 * hx) return;
    }
    if (S.surv.size() <= count) S.surv.emplace_back(), S.surv_convex.push_back(false), S.surv_solid.push_back(-1);
    std::swap(S.surv[count], S.a);
    S.surv_convex[count] = convex;
    S.surv_solid[count] = one_solid ? -1 : solid;
    for (size_t k = 0; k < count && !grouped && solid >= 0; ++k) grouped = S.surv_solid[k] == solid;
    ++count;
  };
  for (const Occluder& o : occluders) {
    if (cull && o.cull && o.inner.dot(x) >= o.inner_offset) continue;
    if (!one_solid && o.solid >= 0 && o.cull && o.inner.dot(x) >= o.inner_offset &&
        std::find(S.outside.begin(), S.outside.end(), o.solid) != S.outside.end())
      continue;
    if (!o.convex && !o.parts.empty())
      for (const std::vector<Vec3>& part : o.parts) clip_in(part, true, o.solid);
    else
      clip_in(o.poly, o.convex, o.solid);
  }
  if (count == 0) return 0;
  // The clipped faces of one convex solid C become one convex polygon: a segment from x to the target that meets C
  // crosses its surface inside the cone (a convex cone: the target's, or its bounding rectangle's), so the union of
  // the faces' projections is the projection of C within the cone, the convex hull of their projected corners (as for
  // one solid below). The hull is lifted to the target's plane, where it is its own projection. Fewer, convex
  // projections for the union (a street of buildings: one per building instead of one per face).
  if (grouped) count = hull_per_solid(x, nt, t0, hx, tc, u, v, count, S);
  if (count == 1 && target_convex) return contour_sum(x, n, S.surv[0]);
  for (size_t k = 0; k < count; ++k)
    if (S.surv_convex[k] && covers(x, target, S.surv[k])) return contour_sum(x, n, target);
  // One convex solid C: a segment from x to the target that meets C crosses its surface at a face, inside the cone,
  // so the union of the faces' projections is the projection of C within the cone, a convex region: the convex hull
  // of the clipped faces' projected corners (each of them a point of C in the cone; the hull lies in the target).
  // No Boolean operation, no snapping.
  if (one_solid) {
    if (!projected_hull(x, nt, t0, hx, tc, u, v, count, [](size_t) { return true; }, S, S.lifted)) return 0;
    return std::abs(signed_contour_sum(x, n, S.lifted)) / (2 * kPi);
  }
  // Union of the projections on the target's plane (integer coordinates, kSnap per R), intersected with the
  // target when the cone was only its bounding rectangle.
  const double scale = kSnap / R, inv = R / kSnap;
  const double lim = double(ClipperLib::loRange);
  auto snap = [&](double a) { return ClipperLib::cInt(std::llround(std::clamp(a * scale, -lim, lim))); };
  S.subject.resize(count);
  for (size_t k = 0; k < count; ++k) {
    ClipperLib::Path& path = S.subject[k];
    path.clear();
    for (const Vec3& q : S.surv[k]) {
      // A corner on the clipping plane through x (kept by the clip's rounding) projects to infinity: it is moved
      // to 1e12 x's height instead, far outside the target (0 * inf was NaN for x 3.5e-10 from the target's plane).
      const double hq = nt.dot(q) - t0;
      const Vec3 y = x + (q - x) * (hx / std::max(hx - hq, 1e-12 * hx));
      path.push_back({snap(u.dot(y - tc)), snap(v.dot(y - tc))});
    }
    if (!ClipperLib::Orientation(path)) ClipperLib::ReversePath(path);
  }
  // A projection lying inside another one adds nothing to the union: left out (on the floor plan 44 % of the
  // projections are, mostly furniture seen through a wall's or a table's larger face). Exact in the snapped integer
  // coordinates: every corner of P_i on the inner side of every edge of P_j (counter-clockwise) puts P_i inside the
  // kernel of P_j (the intersection of its edges' inner half-planes), a convex set inside P_j. Identical projections:
  // the later one is kept.
  if (count > 1 && count <= kMaxPairwise) {
    S.boxes.resize(count);
    S.inside.assign(count, 0);
    for (size_t k = 0; k < count; ++k) {
      auto& b = S.boxes[k];
      b = {S.subject[k][0].X, S.subject[k][0].Y, S.subject[k][0].X, S.subject[k][0].Y};
      for (const ClipperLib::IntPoint& q : S.subject[k])
        b = {std::min(b[0], q.X), std::min(b[1], q.Y), std::max(b[2], q.X), std::max(b[3], q.Y)};
    }
    size_t kept = count;
    for (size_t i = 0; i < count; ++i) {
      const auto& bi = S.boxes[i];
      for (size_t j = 0; j < count; ++j) {
        const auto& bj = S.boxes[j];
        if (j == i || S.inside[j] || bi[0] < bj[0] || bi[1] < bj[1] || bi[2] > bj[2] || bi[3] > bj[3]) continue;
        if (in_kernel(S.subject[i], S.subject[j])) {
          S.inside[i] = 1;
          --kept;
          break;
        }
      }
    }
    if (kept < count) {
      size_t w = 0;
      for (size_t k = 0; k < count; ++k) {
        if (S.inside[k]) continue;
        if (w != k) {
          std::swap(S.subject[w], S.subject[k]);
          std::swap(S.surv[w], S.surv[k]);
          S.surv_convex[w] = S.surv_convex[k];
          S.boxes[w] = S.boxes[k];
        }
        ++w;
      }
      count = w;
      // One projection left, inside the (convex) target: its contour, as for a single occluder above.
      if (w == 1 && target_convex) return contour_sum(x, n, S.surv[0]);
    }
  }
  // Convex occluders in front of a convex target: the union's contour from the projections' edges directly (no
  // Boolean operation; on the floor plan's exact path Clipper and its allocations were two thirds of the time).
  if (target_convex && count > 1 && count <= kMaxPairwise) {
    bool convex = true;
    if (S.convex.size() < count) S.convex.resize(count);
    // A convex occluder's projection that snapping left with a right turn (a sliver seen edge-on, a corner almost on
    // an edge's line) is replaced by the hull of its snapped corners, within one unit of it (as close as snapping
    // already is), or left out if they are collinear (no area). Its box stays its box.
    size_t kept = 0;
    for (size_t k = 0; k < count && convex; ++k) {
      convex = S.surv_convex[k];
      if (!convex) break;
      if (!strictly_convex(S.subject[k], S.convex[kept]) && !integer_hull(S.subject[k], S.convex[kept])) continue;
      S.boxes[kept++] = S.boxes[k];
    }
    if (convex) {
      if (kept == 0) return 0;
      auto lift = [&](double X, double Y) -> Vec3 { return tc + (X * inv) * u + (Y * inv) * v; };
      return std::abs(convex_union_contour(S.convex, kept, S.boxes, x, n, lift, S.removed)) / (2 * kPi);
    }
  }
  S.clipper.Clear();
  for (size_t k = 0; k < count; ++k) S.clipper.AddPath(S.subject[k], ClipperLib::ptSubject, true);
  if (target_convex) {
    S.clipper.Execute(ClipperLib::ctUnion, S.result, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
  } else {
    S.clip_path.clear();
    for (const Vec3& p : target) S.clip_path.push_back({snap(u.dot(p - tc)), snap(v.dot(p - tc))});
    if (!ClipperLib::Orientation(S.clip_path)) ClipperLib::ReversePath(S.clip_path);
    S.clipper.AddPath(S.clip_path, ClipperLib::ptClip, true);
    S.clipper.Execute(ClipperLib::ctIntersection, S.result, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
  }
  // Outer paths are counter-clockwise in (u, v), holes clockwise: their signed contour sums add up.
  double total = 0;
  for (const ClipperLib::Path& path : S.result) {
    if (path.size() < 3) continue;
    S.lifted.clear();
    for (const auto& ip : path) S.lifted.push_back(tc + (double(ip.X) * inv) * u + (double(ip.Y) * inv) * v);
    total += signed_contour_sum(x, n, S.lifted);
  }
  return std::abs(total) / (2 * kPi);
}

double visible_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> target,
                                std::span<const Occluder> occluders) {
  const double full = point_to_polygon(x, n, target);
  if (!(full > 0) || occluders.empty()) return full;
  thread_local ExactScratchPtr S = make_exact_scratch();
  const Vec3 nn = n.normalized();
  const Vec3 nt = mesh::newell_normal(target).normalized();
  // The part of the target in front of x (as point_to_polygon sees it).
  std::vector<Vec3> front;
  clip_front(target, nn, nn.dot(x), 0.0, front);
  if (front.size() < 3) return 0;
  // Convexity of the clipped target: every turn has the normal's sign.
  bool convex = true;
  for (size_t k = 0; k < front.size() && convex; ++k) {
    const Vec3 e0 = front[(k + 1) % front.size()] - front[k], e1 = front[(k + 2) % front.size()] - front[(k + 1) % front.size()];
    convex = e0.cross(e1).dot(nt) >= 0;
  }
  const double h = hidden_point_to_polygon(x, nn, front, nt, convex, occluders, *S);
  return std::max(0.0, full - h);
}

namespace {

// Elements of the adaptive outer rule: bilinear quads (corners v0..v3; a triangle enters as three quads). Each
// carries its own embedded rule (Genz & Malik 1980, degree 7 with a degree-5 rule on the same 17 points, as in
// adaptive cubature codes such as HCubature): the value is the degree-7 rule, the error estimate the two rules'
// difference, and the fourth differences along s and t pick the direction of a bisection. Bisection (not quartering)
// lets elements become thin along a straight penumbra kink, so a kink parallel to a source edge (the common case
// in architecture) costs O(log 1/tol) elements instead of O(1/h).
struct Elem {
  std::array<Vec3, 4> v;
  double Q = 0;    // the element's degree-7 rule applied to F_hidden
  double E = 0;    // |degree-7 - degree-5|
  int dir = -1;    // bisection across s (0) or t (1) by the larger fourth difference; -1: no preference
  bool has_Q = false;
  int kind = -1;  // what its samples saw: 0 nothing hidden, 1 the whole target hidden, 2 partly (or mixed)
  bool hidden = false;  // the target is hidden from all of it (proven: hidden_from_all_of or one convex occluder)
  double hidden_bound = 0;  // then: bound on F(x -> what the proof left uncovered), per unit area
  double failed_area = INFINITY;  // area of the last element of its line whose proof failed (retried at 1/4 of it)
};
int combine(int a, int b) { return a < 0 ? b : b < 0 ? a : a == b ? a : 2; }
struct Leaf {
  Elem e;
  std::array<Elem, 3> kids;  // the halves of its bisection, or the 2-3 pieces of a split along a critical line
  int nkids = 2;
  bool lazy = false;         // split along a line above kLineForcedArea: no rule evaluated yet (value unknown)
  int occ_begin = 0, occ_count = 0;    // the element's occluders (in the pair's pool)
  int line_begin = 0, line_count = 0;  // the critical lines crossing it (in the pair's line pool)
  double value = 0, err = 0;  // the element's rule and its error estimate (or bound)
  bool operator<(const Leaf& o) const { return err < o.err; }
};

// Forced refinement of shadow-reachable elements whose samples see no shadow, down to this fraction of the
// source's area.
constexpr double kForcedArea = 1.0 / 64;
// Elements a critical line crosses are split on down to this fraction of the source whatever their rules say (see
// push); below it, the rules decide. With no floor a pair with 600 lines could not finish its arrangement within the
// point cap (storey.stl: error bound 0.09); at 1/256 the row sums are unchanged on the rooms and storey.stl.
constexpr double kLineForcedArea = 1.0 / 256;
// Pairs with at least this many occluders try to prove elements hidden by several occluders together
// (hidden_from_all_of).
constexpr int kMinFusionOccluders = 4;


Vec3 bilinear(const std::array<Vec3, 4>& v, double s, double t) {
  return (1 - s) * (1 - t) * v[0] + s * (1 - t) * v[1] + s * t * v[2] + (1 - s) * t * v[3];
}

// The candidates that meet the convex hull of cs and ct (through an edge of one and a corner of the other,
// every corner on one side; an occluder with every corner beyond one of its planes, or behind either patch's
// plane, meets no segment between the two), appended to `kept`. Returns kClear if none does, kHidden if one
// convex occluder is crossed strictly inside by every segment between corners of cs and ct (the crossings of
// all segments form the convex hull of those corner crossings: the pair is hidden), else kIntegrated. Without
// hull_cull only the patches' planes and the occluders' own planes cull (no hull is built): for an element whose
// parent's occluders are the faces of one convex solid, which its samples project as one hull whatever faces it
// keeps, and which hardly ever leaves an element's hull (room with a block: 0.2 % of such elements came out clear).
int classify(std::span<const Vec3> cs, std::span<const Vec3> ct, const Vec3& ns, const Vec3& nt, double os,
             double ot, std::span<const Occluder> candidates, double eps, ExactScratch& S,
             std::vector<Occluder>& kept, bool hull_cull) {
  S.pts.assign(cs.begin(), cs.end());
  S.pts.insert(S.pts.end(), ct.begin(), ct.end());
  S.hull.clear();
  // The planes through an edge of P and a corner of Q with every point of P and Q on one side. `pts`: those points,
  // Q's first (P's corners off the edge lie on one side of such a plane, Q's may lie on both: the test stops sooner).
  auto hull_planes = [&](std::span<const Vec3> P, std::span<const Vec3> Q, const std::vector<Vec3>& pts) {
    for (size_t k = 0; k < P.size(); ++k) {
      const Vec3 &a = P[k], &b = P[(k + 1) % P.size()];
      for (const Vec3& c : Q) {
        const Vec3 m = (b - a).cross(c - a);
        const double len = m.norm();
        if (!(len > 0)) continue;
        // Unnormalised: the side tests compare with eps * len, and stop at the first point on each side (most
        // candidate planes cut the hull).
        const double e = eps * len;
        bool above = false, below = false;
        for (const Vec3& p : pts) {
          const double d = m.dot(p - a);
          above = above || d > e;
          below = below || d < -e;
          if (above && below) break;
        }
        if (above && below) continue;
        const Vec3 u = m / len;
        if (!above) S.hull.push_back({u.x(), u.y(), u.z(), u.dot(a)});
        else S.hull.push_back({-u.x(), -u.y(), -u.z(), -u.dot(a)});
      }
    }
  };
  // The candidates that can block anything at all: in front of both planes, their own plane between some corners.
  // Referred to, not copied (a candidate without its unit normal yet is copied into S.kept to get one; reserved:
  // the references stay valid).
  S.kept.clear();
  S.kept.reserve(candidates.size());
  S.kept_ref.clear();
  for (const Occluder& candidate : candidates) {
    bool behind_s = true, behind_t = true;
    for (const Vec3& q : candidate.poly) {
      behind_s = behind_s && ns.dot(q) - os <= eps;
      behind_t = behind_t && nt.dot(q) - ot <= eps;
    }
    if (behind_s || behind_t) continue;
    // The occluder's own plane with every corner of cs and ct on one side (within eps): the segments meet that plane
    // at most at their ends, so it blocks nothing. A wall that a target or source patch touches at a corner or an
    // edge (a floor patch against the wall) meets their hull only there; kept, it made every element of the pair
    // "reachable" and its clipped sliver, a rounding residue, spent the pair's point budget.
    const Occluder* op = &candidate;
    if (!candidate.has_unit) {
      Occluder& o = S.kept.emplace_back(candidate);
      const Vec3 nq = mesh::newell_normal(o.poly);
      const double len = nq.norm();
      o.has_unit = true;
      o.unit = len > 0 ? Vec3(nq / len) : Vec3::Zero();
      o.unit_offset = o.unit.dot(o.poly[0]);
      op = &o;
    }
    const Occluder& o = *op;
    if (o.unit.squaredNorm() > 0) {
      double lo = INFINITY, hi = -INFINITY;
      for (const Vec3& p : S.pts) {
        const double d = o.unit.dot(p) - o.unit_offset;
        lo = std::min(lo, d), hi = std::max(hi, d);
      }
      if (hi <= eps || lo >= -eps) continue;
    }
    S.kept_ref.push_back(op);
  }
  if (S.kept_ref.empty()) return ExactPairResult::kClear;
  // Hidden by one of them, tested before any hull is built (most pairs a convex occluder hides end here): an
  // occluder that every segment crosses meets the hull, so the hull's culling below would have kept it too.
  for (const Occluder* o : S.kept_ref)
    if (o->convex && convex_hides(cs, ct, o->poly, o->unit, o->unit_offset, eps)) {
      kept.push_back(*o);  // the hiding occluder alone is enough from anywhere in cs
      return ExactPairResult::kHidden;
    }
  if (hull_cull) {
    S.pts2.assign(ct.begin(), ct.end());
    S.pts2.insert(S.pts2.end(), cs.begin(), cs.end());
    hull_planes(cs, ct, S.pts2);
    hull_planes(ct, cs, S.pts);
  }
  const size_t first = kept.size();
  for (const Occluder* o : S.kept_ref) {
    bool outside = false;
    for (const auto& h : S.hull) {
      const Vec3 m(h[0], h[1], h[2]);
      bool all = true;
      for (const Vec3& q : o->poly)
        if (!(m.dot(q) - h[3] > eps)) {
          all = false;
          break;
        }
      if (all) {
        outside = true;
        break;
      }
    }
    if (!outside) kept.push_back(*o);
  }
  if (kept.size() == first) return ExactPairResult::kClear;
  return ExactPairResult::kIntegrated;
}

// Occluders that another one hides from every point of the source are left out of the pair's list (a leg behind a
// table's top, furniture behind a wall's face), with their critical lines. A lies in the umbra of a convex planar B, as
// seen from the convex hull E of `corners`, when every segment from a corner of E to a corner of A crosses B strictly
// inside: for convex B, the points x whose segment from a corner c meets B form a convex set (c + t (b - c), b in B,
// t >= 1), so the corners of A in all of them put A in all of them; and for such an x the points of E's plane whose
// segment to x meets B form a convex set that holds every corner of E, hence all of E. From every point p of E each
// point of A then lies behind a point of B on the same ray, inside the cone from p through the target and in front of
// the target, so A's projection lies inside B's: the union of the projections, and the critical lines of its boundary,
// are the same without A. Faces of one convex solid are not tested against each other (its silhouette's lines need
// them). An occluder is tested only against occluders still listed, so every one left out lies in the projection of
// one kept. Keeps the others in their order; returns how many.
constexpr size_t kMaxUmbraOccluders = 128;  // the test is quadratic in the occluders
size_t drop_hidden_occluders(std::span<const Vec3> corners, std::vector<Occluder>& occ, double eps,
                             std::vector<std::uint8_t>& gone) {
  const size_t n = occ.size();
  if (n < 2 || n > kMaxUmbraOccluders) return n;
  gone.assign(n, 0);
  size_t dropped = 0;
  for (size_t a = 0; a < n; ++a) {
    const Occluder& A = occ[a];
    for (size_t b = 0; b < n && !gone[a]; ++b) {
      const Occluder& B = occ[b];
      if (b == a || gone[b] || !B.convex || !B.has_unit || !(B.unit.squaredNorm() > 0)) continue;
      if (A.solid >= 0 && A.solid == B.solid) continue;
      const Vec3& nb = B.unit;
      const double ob = B.unit_offset;
      // B's plane strictly between the corners and A (a plane test first: most pairs stop here).
      double side = 0;
      bool ok = true;
      for (const Vec3& c : corners) {
        const double d = nb.dot(c) - ob;
        if (!(std::abs(d) > eps) || (side != 0 && (d > 0) != (side > 0))) {
          ok = false;
          break;
        }
        side = d;
      }
      for (size_t k = 0; ok && k < A.poly.size(); ++k) {
        const double d = nb.dot(A.poly[k]) - ob;
        ok = std::abs(d) > eps && (d > 0) != (side > 0);
      }
      // Every segment from a corner to a corner of A crosses B at least eps inside each of its edges.
      const size_t m = B.poly.size();
      for (size_t i = 0; ok && i < corners.size(); ++i) {
        const Vec3& c = corners[i];
        const double dc = nb.dot(c) - ob;
        for (size_t k = 0; ok && k < A.poly.size(); ++k) {
          const double da = nb.dot(A.poly[k]) - ob;
          const Vec3 x = c + (A.poly[k] - c) * (dc / (dc - da));
          for (size_t q = 0; q < m && ok; ++q) {
            const Vec3 e = B.poly[(q + 1) % m] - B.poly[q];
            ok = e.cross(x - B.poly[q]).dot(nb) > eps * e.norm();
          }
        }
      }
      if (ok) {
        gone[a] = 1;
        ++dropped;
      }
    }
  }
  if (dropped == 0) return n;
  size_t w = 0;
  for (size_t k = 0; k < n; ++k)
    if (!gone[k]) {
      if (w != k) occ[w] = occ[k];
      ++w;
    }
  occ.resize(w);
  return w;
}

// A critical line of the pair on the source's plane (discontinuity meshing, Heckbert 1992): from a point x on it
// a vertex of one polygon (the target or an occluder) lines up with an edge of another, so the hidden part of
// the target changes its combinatorial structure there; F_hidden(x) is smooth between such lines, except on the
// curves where three edges line up (EEE events, left to the adaptive rule).
struct Critical {
  Vec3 p, d, u;  // the point of the line nearest the source's centre, its unit direction, the in-plane unit normal
  double t0 = -INFINITY, t1 = INFINITY;  // the part of the line p + t d that is critical (an infinite end: a ray)
  bool target = false;  // an occluder's vertex or edge against the target's (else: two occluders')
};

// The critical line of the plane through c and the segment [q0, q1] (normal m, unnormalised): the x on the source's
// plane (ns.y = os, centre g) for which c and a point of the segment line up. Returns false if the planes are
// parallel or c lies on the segment's line (two faces of one solid sharing an edge: no event there). The line is
// built from the two planes (not from projected points, which go to infinity as the segment nears the plane through
// c parallel to the source), so it is well-conditioned wherever it passes.
bool critical_line(const Vec3& c, const Vec3& q0, const Vec3& q1, const Vec3& ns, double os, const Vec3& g, bool target,
                   Critical& out) {
  const Vec3 m = (q0 - c).cross(q1 - c);
  const double ml = m.norm();
  if (!(ml > 1e-7 * (q0 - c).norm() * (q1 - c).norm())) return false;
  const Vec3 mh = m / ml;
  Vec3 u = mh - mh.dot(ns) * ns;
  const double ul = u.norm();
  if (!(ul > 1e-9)) return false;
  u /= ul;
  out.u = u;
  out.d = ns.cross(u);
  out.p = g - u * (mh.dot(g - c) / mh.dot(u));
  out.p -= ns * (ns.dot(out.p) - os);
  out.t0 = -INFINITY, out.t1 = INFINITY;
  out.target = target;
  return std::isfinite(out.p.x()) && std::isfinite(out.p.y()) && std::isfinite(out.p.z());
}

// True if every corner of `within` lies strictly on one side of the plane through c with normal m: then the line
// where that plane meets the source's plane passes outside the convex hull of `within`, so it crosses no element
// there (an element's points lie on one side of it, and crosses() needs them on both). On the source's plane the
// line's signed distance of a point x is m . (x - c) times a positive factor.
bool one_side(const Vec3& c, const Vec3& m, std::span<const Vec3> within) {
  bool pos = true, neg = true;
  for (const Vec3& x : within) {
    const double d = m.dot(x - c);
    pos = pos && d > 0;
    neg = neg && d < 0;
  }
  return pos || neg;
}

// The central projection of the segment [q0, q1] from c onto the source's plane: its critical line, restricted to the
// image of the segment where that is finite. Appended to `out` unless it degenerates, or unless it cannot cross the
// convex hull of `within` (empty: no such test).
void project_critical(const Vec3& c, const Vec3& q0, const Vec3& q1, const Vec3& ns, double os, const Vec3& g,
                      bool target, double eps, std::vector<Critical>& out, std::span<const Vec3> within = {}) {
  const double hc = os - ns.dot(c);
  if (!(std::abs(hc) > eps)) return;  // c on the plane: handled by the caller
  if (!within.empty() && one_side(c, (q0 - c).cross(q1 - c), within)) return;
  Critical L;
  if (!critical_line(c, q0, q1, ns, os, g, target, L)) return;
  const double d0 = ns.dot(q0 - c), d1 = ns.dot(q1 - c);
  if (d0 * d1 > 0) {  // the image is the segment between the two corners' images
    const double a = L.d.dot(c + (hc / d0) * (q0 - c) - L.p), b = L.d.dot(c + (hc / d1) * (q1 - c) - L.p);
    L.t0 = std::min(a, b), L.t1 = std::max(a, b);
    if (!(L.t1 - L.t0 > eps)) return;
    if (!std::isfinite(L.t0)) L.t0 = -INFINITY;
    if (!std::isfinite(L.t1)) L.t1 = INFINITY;
  }  // else the segment crosses the plane through c parallel to the source: the image is the whole line
  out.push_back(L);
}

// The distinct corners of an element (a triangle enters as a quad with a repeated corner). Corners within 1e-12 of
// the element's size of the previous one are the same corner: a split through a corner leaves such near-copies.
int corners_of(const std::array<Vec3, 4>& v, std::array<Vec3, 4>& c) {
  double size = 0;
  for (int k = 1; k < 4; ++k) size = std::max(size, (v[k] - v[0]).lpNorm<Eigen::Infinity>());
  const double tol = 1e-12 * size;
  auto same = [&](const Vec3& a, const Vec3& b) { return (a - b).lpNorm<Eigen::Infinity>() <= tol; };
  int n = 0;
  for (int k = 0; k < 4; ++k)
    if (n == 0 || !same(v[k], c[n - 1])) c[n++] = v[k];
  while (n > 1 && same(c[n - 1], c[0])) --n;
  return n;
}

// Cyrus-Beck: clips the line a + t d, t in [t0, t1], to the convex polygon p[0 .. n) of the plane with normal ns,
// grown by `grow` on every side. False if nothing is left.
bool clip_to_polygon(const std::array<Vec3, 4>& p, int n, const Vec3& ns, const Vec3& a, const Vec3& d, double grow,
                     double& t0, double& t1) {
  double turn = 0;
  for (int k = 1; k + 1 < n; ++k) turn += (p[k] - p[0]).cross(p[k + 1] - p[0]).dot(ns);
  const double o = turn >= 0 ? 1 : -1;
  for (int k = 0; k < n; ++k) {
    Vec3 nk = o * ns.cross(p[(k + 1) % n] - p[k]);  // points into the polygon
    const double len = nk.norm();
    if (!(len > 0)) continue;
    nk /= len;
    const double num = nk.dot(a - p[k]) + grow, den = nk.dot(d);  // inside: num + t den >= 0
    if (den == 0) {
      if (num < 0) return false;
      continue;
    }
    const double t = -num / den;
    if (den > 0) t0 = std::max(t0, t);
    else t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  return true;
}

// True if the segment [a, b] (in the source's plane) meets the convex element v or passes within eps of it.
bool touches(const std::array<Vec3, 4>& v, const Vec3& a, const Vec3& b, const Vec3& ns, double eps) {
  std::array<Vec3, 4> p;
  const int n = corners_of(v, p);
  double t0 = 0, t1 = 1;
  return n >= 3 && clip_to_polygon(p, n, ns, a, b - a, eps, t0, t1);
}

// True if the critical line c passes through the interior of the convex element v, leaving more than eps and 1e-6 of
// the element's width on both sides. `side` receives the distance of the element's centre from the line.
bool crosses(const Critical& c, const std::array<Vec3, 4>& v, const Vec3& ns, double eps, double* side) {
  std::array<Vec3, 4> p;
  const int n = corners_of(v, p);
  if (n < 3) return false;
  double lo = INFINITY, hi = -INFINITY;
  Vec3 centre = Vec3::Zero();
  for (int k = 0; k < n; ++k) {
    const double s = c.u.dot(p[k] - c.p);
    lo = std::min(lo, s), hi = std::max(hi, s);
    centre += p[k];
  }
  // A line within 1e-6 of the element's width from its side is left to the element's rule: the sliver it would cut
  // off holds at most that share of the element, and such slivers (a line through a corner the source shares with
  // the target's plane) put samples within 1e-10 of the target's plane.
  const double keep = std::max(eps, 1e-6 * (hi - lo));
  if (!(lo < -keep && hi > keep)) return false;
  *side = std::abs(c.u.dot(centre / double(n) - c.p));
  if (c.t0 == -INFINITY && c.t1 == INFINITY) return true;
  // The part of the critical segment inside the element.
  double t0 = c.t0, t1 = c.t1;
  return clip_to_polygon(p, n, ns, c.p, c.d, 0.0, t0, t1) && t1 - t0 > eps;
}

// Splits the convex element v along the line of c into 2 or 3 elements (triangles as quads with a repeated last
// corner, a pentagon as a quad and a triangle), same orientation, written to kids; returns their number, or 0 if
// the line does not cut the element into two proper pieces (the caller bisects instead). A corner within 1e-12 of
// the element's width from the line lies on it: it goes to both pieces and no crossing is made next to it (a line
// through a corner within rounding once made crossings on both of its edges and lost the element's area).
int split_along(const std::array<Vec3, 4>& v, const Critical& c, std::array<Elem, 3>& kids) {
  std::array<Vec3, 4> p;
  const int n = corners_of(v, p);
  if (n < 3) return 0;
  std::array<double, 4> sd;
  double lo = INFINITY, hi = -INFINITY;
  for (int k = 0; k < n; ++k) sd[k] = c.u.dot(p[k] - c.p), lo = std::min(lo, sd[k]), hi = std::max(hi, sd[k]);
  const double tol = 1e-12 * (hi - lo);
  for (int k = 0; k < n; ++k)
    if (std::abs(sd[k]) <= tol) sd[k] = 0;
  std::array<Vec3, 6> side[2];
  int cnt[2] = {0, 0};
  for (int k = 0; k < n; ++k) {
    const Vec3 &a = p[k], &b = p[(k + 1) % n];
    const double sa = sd[k], sb = sd[(k + 1) % n];
    if (sa >= 0 && cnt[0] < 6) side[0][cnt[0]++] = a;
    if (sa <= 0 && cnt[1] < 6) side[1][cnt[1]++] = a;
    if ((sa > 0 && sb < 0) || (sa < 0 && sb > 0)) {
      const Vec3 x = a + (b - a) * (sa / (sa - sb));
      if (cnt[0] < 6) side[0][cnt[0]++] = x;
      if (cnt[1] < 6) side[1][cnt[1]++] = x;
    }
  }
  if (cnt[0] < 3 || cnt[0] > 5 || cnt[1] < 3 || cnt[1] > 5) return 0;
  int out = 0;
  for (int h = 0; h < 2; ++h) {
    const auto& q = side[h];
    if (cnt[h] == 3) kids[out++].v = {q[0], q[1], q[2], q[2]};
    else if (cnt[h] == 4) kids[out++].v = {q[0], q[1], q[2], q[3]};
    else kids[out++].v = {q[0], q[1], q[2], q[3]}, kids[out++].v = {q[3], q[4], q[0], q[0]};
  }
  for (int k = 0; k < out; ++k) kids[k].has_Q = false;
  return out;
}

// True if every turn of the polygon is counter-clockwise (or straight) about n: convex, oriented by n.
bool convex_polygon(std::span<const Vec3> poly, const Vec3& n) {
  const size_t m = poly.size();
  for (size_t k = 0; k < m; ++k)
    if ((poly[(k + 1) % m] - poly[k]).cross(poly[(k + 2) % m] - poly[(k + 1) % m]).dot(n) < 0) return false;
  return true;
}

// The part [lo, hi] (parameters of q0 + mu (q1 - q0), mu in [0, 1]) of the segment whose line through c meets the
// convex polygon t (counter-clockwise about nt): the segment inside the double cone from c through t, whose two
// nappes are the intersections of the half-spaces through c and t's edges (inner, or all outer). Conservative:
// the hull of the two nappes' intervals. False if no part of the segment is inside.
bool sight_through(const Vec3& c, const Vec3& q0, const Vec3& q1, std::span<const Vec3> t, double& lo, double& hi) {
  const size_t m = t.size();
  Vec3 centre = Vec3::Zero();
  for (const Vec3& q : t) centre += q;
  centre /= double(m);
  double lo_in = 0, hi_in = 1, lo_out = 0, hi_out = 1;  // the forward and backward nappes
  // Scale-free slack: a corner on a cone face (within rounding) counts as inside.
  const double slack = 1e-12;
  for (size_t k = 0; k < m; ++k) {
    // Inner normal of the plane through c and the edge t_k t_k+1: towards the target's interior.
    const Vec3 a = t[k] - c, b = t[(k + 1) % m] - c;
    Vec3 h = a.cross(b);
    const double hl = h.norm();
    if (!(hl > 0)) return lo = 0, hi = 1, true;  // c on the target's plane: no cone, keep the whole edge
    h /= hl;
    if (h.dot(centre - c) < 0) h = -h;  // the target's side positive
    const double f0 = h.dot(q0 - c), f1 = h.dot(q1 - c);
    const double tol = slack * ((q0 - c).norm() + (q1 - c).norm());
    // f(mu) = f0 + mu (f1 - f0) >= -tol (forward nappe), <= tol (backward nappe).
    auto cut = [&](double g0, double g1, double& l, double& u) {
      if (g0 >= -tol && g1 >= -tol) return;
      if (g0 < -tol && g1 < -tol) {
        l = 1, u = 0;
        return;
      }
      const double mu = (-tol - g0) / (g1 - g0);
      if (g0 < -tol) l = std::max(l, mu);
      else u = std::min(u, mu);
    };
    cut(f0, f1, lo_in, hi_in);
    cut(-f0, -f1, lo_out, hi_out);
  }
  const bool in = lo_in <= hi_in, out = lo_out <= hi_out;
  if (!in && !out) return false;
  lo = std::min(in ? lo_in : 1.0, out ? lo_out : 1.0);
  hi = std::max(in ? hi_in : 0.0, out ? hi_out : 0.0);
  return true;
}

// Critical lines are generated only for pairs with at most this many occluders and lines (those between two
// occluders for at most kMaxInterOccluders: they grow as the square); beyond, the adaptive rule resolves the kinks,
// its elements that see shadow and light checked against their halves (push). storey.stl: pairs at the point cap 557
// (no lines) -> 181 (lines up to 24 occluders) -> 82 (64). With 16 units instead of 6, a floor plan pair went from 170
// lines to more than 4,096, hence none. Now that lines are kept only where they can cross the source, 16 units would
// give a corner of udales 12 % fewer points and storey.obj 8 %, but the pairs with 7-16 units then lose the check of
// their mixed elements against their halves, and one of them (floorplan.obj, faces 595 -> 141, 22 occluders) holds a
// kink no line catches (where three edges line up): estimate 2.6e-9, error 4.8e-6. Kept at 6.
constexpr int kMaxLineOccluders = 64;
constexpr size_t kMaxLines = 4096;
constexpr int kMaxInterOccluders = 6;

// The critical lines of the pair (cs -> ct, clipped in front of each other) from its occluders (classify's list for
// the whole source), appended to `lines`. False (and no lines) above kMaxLineOccluders occluders or kMaxLines lines.
// With only_crossing, the lines that cannot cross the source (every corner of cs on one side: 95 % of them in the
// room with a block) are left out. The cap still counts them, as without the test: a pair with more candidates than
// kMaxLines is computed again in full.
bool critical_lines_of(std::span<const Vec3> cs, std::span<const Vec3> ct, const Vec3& ns, double os, const Vec3& nt,
                       double ot, std::span<const Occluder> pool, double eps, ExactScratch& S, std::vector<Critical>& lines,
                       bool only_crossing = false, bool* with_inter = nullptr) {
  if (with_inter) *with_inter = false;
  const int root_count = int(pool.size());
  if (root_count > kMaxLineOccluders) return false;
  const size_t lines_begin = lines.size();
  size_t candidates = 0;  // lines tried, including those left out as not crossing
  const std::span<const Vec3> within = only_crossing ? cs : std::span<const Vec3>();
  const Vec3 g = average(cs);
  std::vector<std::vector<Vec3>> occ{size_t(root_count)};
  for (int k = 0; k < root_count; ++k) {
    S.a.assign(pool[size_t(k)].poly.begin(), pool[size_t(k)].poly.end());
    clip_keep(S.a, ns, os, S.b);
    clip_keep(S.b, nt, ot, occ[size_t(k)]);
  }
  auto project = [&](const Vec3& c, std::span<const Vec3> P, bool target) {
    const size_t m = P.size();
    if (std::abs(ns.dot(c) - os) <= eps) {
      // c on the source's plane: x lines up with c and a point of the segment only within the plane, i.e.
      // on the line through c and a corner that lies on the plane too (a leg's foot and a wall's foot).
      candidates += m;
      for (const Vec3& q : P)
        if (std::abs(ns.dot(q) - os) <= eps && (q - c).norm() > eps) {
          // The plane through c, q and the source's normal meets the source's plane in the line cq.
          Critical L;
          if (critical_line(c, q, Vec3(q + ns * (q - c).norm()), ns, os, g, target, L)) lines.push_back(L);
        }
      return;
    }
    candidates += m;
    for (size_t k = 0; k < m; ++k) project_critical(c, P[k], P[(k + 1) % m], ns, os, g, target, eps, lines, within);
  };
  // A face of a closed convex solid (convex_solids) matters only through the solid's silhouette: a target corner
  // lines up with a silhouette edge only through the face of that edge it sees from the front (of the edge's two
  // faces, exactly one faces the corner), and the silhouette changes its corners only where x crosses a face's
  // plane (the traces made for every occluder below). A corner on a face's plane sees that face edge-on and keeps
  // its lines (within 100 eps, 1e-8 of the scene: the merge moves corners by up to 1e-9 of it). window_room.obj's
  // cupboard has a corner on a wall triangle's corner, and the line where the cupboard's bottom starts to hide that
  // triangle (from the triangle's corner and the bottom's far edge) was left out with `>=`: integrated from the side
  // wall, F 1.8e-6 high with an estimate of 6.6e-9.
  const double on_face = 100 * eps;
  // Lines of a closed convex solid's corners and edges that are on its silhouette from no point of the source are
  // no events: their projections stay inside the solid's shadow, whatever the target's corners and edges do there
  // (room with a block: 7 % of the points). A face's facing from x is linear in x, so the source's corners decide it
  // for all of the source; a corner on (within on_face of) a face's plane decides nothing.
  // Per occluder: +1 if every corner of cs sees it from the front, -1 if every one from behind, 0 if mixed, on its
  // plane, or not a solid's face.
  std::vector<int> facing_of(occ.size(), 0);
  for (size_t k = 0; k < occ.size(); ++k) {
    const Occluder& o = pool[k];
    if (o.solid < 0 || !o.cull) continue;
    int front = 0, back = 0;
    for (const Vec3& c : cs) {
      const double d = o.inner.dot(c) - o.inner_offset;
      if (d < -on_face) ++front;
      else if (d > on_face) ++back;
      else front = back = 1;
    }
    facing_of[k] = back == 0 ? 1 : front == 0 ? -1 : 0;
  }
  auto solid_face = [&](size_t j, int solid) { return pool[j].solid == solid && solid >= 0 && pool[j].cull; };
  auto on_plane = [&](const Occluder& o, const Vec3& q) { return std::abs(o.inner.dot(q) - o.inner_offset) <= on_face; };
  // The edge [a, b] of face k: on the silhouette only where k and the other face through it (a face of the solid
  // in another plane with a and b on it) face x differently. Kept if that face is not among the pair's occluders
  // (an open facet, or one classify left out).
  auto never_silhouette_edge = [&](size_t k, const Vec3& a, const Vec3& b) {
    if (!solid_face(k, pool[k].solid)) return false;
    const int fk = facing_of[k];
    if (fk == 0) return false;
    for (size_t j = 0; j < pool.size(); ++j)
      if (j != k && solid_face(j, pool[k].solid) && std::abs(pool[j].inner.dot(pool[k].inner)) < 1 - 1e-9 &&
          on_plane(pool[j], a) && on_plane(pool[j], b))
        return facing_of[j] == fk;
    return false;
  };
  // The corner w of face k: on the silhouette only where the faces around it do not all face x the same way. Only
  // if those faces are all among the occluders: every edge of each at w must lie on another one's plane (a closed
  // fan; a face classify left out, or an open facet, would break it).
  auto never_silhouette_corner = [&](size_t k, const Vec3& w) {
    const int solid = pool[k].solid;
    if (!solid_face(k, solid)) return false;
    int common = 2, faces = 0;  // the facing all of them share (2: none seen yet)
    for (size_t j = 0; j < pool.size(); ++j) {
      if (!solid_face(j, solid) || !on_plane(pool[j], w)) continue;
      const auto P = pool[j].poly;
      const size_t m = P.size();
      size_t at = m;
      for (size_t c = 0; c < m && at == m; ++c)
        if ((P[c] - w).lpNorm<Eigen::Infinity>() <= on_face) at = c;
      if (at == m) return false;  // w not a corner of this face (inside one of its edges)
      for (const Vec3& nb : {P[(at + m - 1) % m], P[(at + 1) % m]}) {
        bool matched = false;
        for (size_t i = 0; i < pool.size() && !matched; ++i)
          matched = i != j && solid_face(i, solid) && on_plane(pool[i], w) && on_plane(pool[i], nb);
        if (!matched) return false;
      }
      const int f = facing_of[j];
      if (f == 0 || (common != 2 && f != common)) return false;
      common = f;
      ++faces;
    }
    return faces >= 3;
  };
  std::vector<char> silhouette_edge;
  std::vector<Vec3> corners_done;  // occluder corners whose lines against the target's edges are made
  for (size_t k = 0; k < occ.size(); ++k) {
    const auto& O = occ[k];
    if (O.size() < 3) continue;
    const Occluder& src = pool[k];
    const size_t m = O.size();
    silhouette_edge.resize(m);
    for (size_t e = 0; e < m; ++e)
      silhouette_edge[e] = facing_of[k] == 0 || !never_silhouette_edge(k, O[e], O[(e + 1) % m]);
    for (const Vec3& v : ct) {
      if (src.cull && src.inner.dot(v) > src.inner_offset + on_face) continue;
      if (std::abs(ns.dot(v) - os) <= eps) {
        project(v, O, true);
        continue;
      }
      candidates += m;
      for (size_t e = 0; e < m; ++e)
        if (silhouette_edge[e]) project_critical(v, O[e], O[(e + 1) % m], ns, os, g, true, eps, lines, within);
    }
    for (const Vec3& w : O) {
      if (!(facing_of[k] == 0 || !never_silhouette_corner(k, w))) continue;
      // A corner shared by several faces (a block's, three) gives the same lines from each: made once (counted as
      // before for the cap on lines).
      if (std::find(corners_done.begin(), corners_done.end(), w) != corners_done.end()) {
        candidates += ct.size();
        continue;
      }
      corners_done.push_back(w);
      project(w, ct, true);
    }
    // The trace of the occluder's plane: crossing it, x sees the occluder from its other side (its projection
    // shrinks to a segment there, and a solid's face joins or leaves its silhouette). That segment lies in the
    // occluder's plane: an event only if the target has corners strictly on both sides of it.
    const Vec3 no = mesh::newell_normal(O).normalized();
    bool below = false, above = false;
    for (const Vec3& v : ct) {
      const double d = no.dot(v - O[0]);
      below = below || d < -eps, above = above || d > eps;
    }
    for (size_t a = 1; below && above && a + 1 < O.size(); ++a) {  // the plane: the first corner and a non-collinear pair
      Critical L;
      if (critical_line(O[0], O[a], O[a + 1], ns, os, g, false, L)) {
        ++candidates;
        if (within.empty() || !one_side(O[0], (O[a] - O[0]).cross(O[a + 1] - O[0]), within)) lines.push_back(L);
        break;
      }
    }
  }
  // A corner of one occluder against an edge of another, for up to kMaxInterOccluders units (a convex solid's
  // faces are one unit: between them the plane traces above suffice); against a solid's face, only from corners
  // in front of it (as for the target's corners).
  auto unit = [&](size_t k) { return pool[k].solid >= 0 ? pool[k].solid : -1 - int(k); };
  std::vector<int> units;
  for (size_t k = 0; k < occ.size(); ++k) units.push_back(unit(k));
  std::sort(units.begin(), units.end());
  const bool inter = std::unique(units.begin(), units.end()) - units.begin() <= kMaxInterOccluders;
  if (with_inter) *with_inter = inter;
  // Such an event changes the hidden part only if the line of sight through the corner and the edge meets the
  // target: each edge is cut to the part inside the double cone from the corner through the (convex) target.
  const bool cone = convex_polygon(ct, nt);
  if (inter)
    for (size_t a = 0; a < occ.size(); ++a)
      for (size_t b = 0; b < occ.size(); ++b)
        if (unit(a) != unit(b) && occ[a].size() >= 3 && occ[b].size() >= 3)
          for (const Vec3& w : occ[a]) {
            if (pool[b].cull && pool[b].inner.dot(w) > pool[b].inner_offset + on_face) continue;
            if (!cone || std::abs(ns.dot(w) - os) <= eps) {
              project(w, occ[b], false);
              continue;
            }
            const std::vector<Vec3>& B = occ[b];
            for (size_t k = 0; k < B.size(); ++k) {
              double lo, hi;
              if (!sight_through(w, B[k], B[(k + 1) % B.size()], ct, lo, hi)) continue;
              const Vec3 e = B[(k + 1) % B.size()] - B[k];
              ++candidates;
              project_critical(w, B[k] + lo * e, B[k] + hi * e, ns, os, g, false, eps, lines, within);
            }
          }
  if (only_crossing && candidates > kMaxLines) {  // rare: decide the cap on every line, as without the test
    lines.resize(lines_begin);
    return critical_lines_of(cs, ct, ns, os, nt, ot, pool, eps, S, lines, false, with_inter);
  }
  if (lines.size() - lines_begin > kMaxLines) {
    lines.resize(lines_begin);
    if (with_inter) *with_inter = false;
    return false;
  }
  return true;
}

// 2D polygons (counter-clockwise) for the extended projections below.
using Poly2 = std::vector<std::array<double, 2>>;

// Keeps the part of the convex or simple polygon `in` whose side value side(i) of corner i is >= 0, linear between
// corners (Sutherland-Hodgman), into `out`.
template <class Side>
void clip_by_side(const Poly2& in, const Side& side, Poly2& out) {
  out.clear();
  const size_t k = in.size();
  if (k < 3) return;
  double dp = side(k - 1);
  for (size_t i = 0; i < k; ++i) {
    const auto& prev = in[i == 0 ? k - 1 : i - 1];
    const auto& cur = in[i];
    const double dc = side(i);
    auto cut = [&] {
      const double w = dp / (dp - dc);
      out.push_back({prev[0] + (cur[0] - prev[0]) * w, prev[1] + (cur[1] - prev[1]) * w});
    };
    if (dc >= 0) {
      if (dp < 0) cut();
      out.push_back(cur);
    } else if (dp > 0) {
      cut();
    }
    dp = dc;
  }
  if (out.size() < 3) out.clear();
}

// Keeps the part of the convex or simple polygon `in` with a . p <= b (Sutherland-Hodgman) into `out`.
void clip_half_plane(const Poly2& in, double ax, double ay, double b, Poly2& out) {
  clip_by_side(in, [&](size_t i) { return b - (ax * in[i][0] + ay * in[i][1]); }, out);
}

double signed_area(const Poly2& p) {
  double a = 0;
  for (size_t k = 0; k < p.size(); ++k) {
    const auto &q = p[k], &r = p[(k + 1) % p.size()];
    a += q[0] * r[1] - q[1] * r[0];
  }
  return 0.5 * a;
}

// Drops corners within `tol` of the previous one: what is left is the convex hull of fewer corners (inside the
// polygon, if it is convex), and no edge is so short that its direction is rounding noise (a clip along it then cuts
// at a random angle).
void drop_short_edges(Poly2& p, double tol) {
  size_t w = 0;
  for (size_t k = 0; k < p.size(); ++k)
    if (w == 0 || std::hypot(p[k][0] - p[w - 1][0], p[k][1] - p[w - 1][1]) > tol) p[w++] = p[k];
  while (w > 1 && std::hypot(p[w - 1][0] - p[0][0], p[w - 1][1] - p[0][1]) <= tol) --w;
  p.resize(w < 3 ? 0 : w);
}

// Intersects the convex counter-clockwise polygon `x` with the convex counter-clockwise polygon `c` (in place).
void intersect_convex(Poly2& x, const Poly2& c, Poly2& tmp) {
  for (size_t k = 0; k < c.size() && !x.empty(); ++k) {
    const auto &a = c[k], &b = c[(k + 1) % c.size()];
    // Inside: left of the edge a -> b, i.e. n . p <= n . a with n its outward normal.
    const double nx = b[1] - a[1], ny = a[0] - b[0], c0 = nx * a[0] + ny * a[1];
    // An edge with all of x inside leaves it as it is (clip_half_plane would copy it unchanged): most edges of a
    // target leave a shadow whole. Else x is clipped from the side values just tested.
    constexpr size_t kMax = 64;
    const size_t n = x.size();
    if (n < 3 || n > kMax) {
      bool all_in = n >= 3;
      for (size_t i = 0; i < n && all_in; ++i) all_in = c0 - (nx * x[i][0] + ny * x[i][1]) >= 0;
      if (all_in) continue;
      clip_half_plane(x, nx, ny, c0, tmp);
      std::swap(x, tmp);
      continue;
    }
    double d[kMax];
    bool all_in = true;
    for (size_t i = 0; i < n; ++i) {
      d[i] = c0 - (nx * x[i][0] + ny * x[i][1]);
      all_in = all_in && d[i] >= 0;
    }
    if (all_in) continue;
    clip_by_side(x, [&](size_t i) { return d[i]; }, tmp);
    std::swap(x, tmp);
  }
}

// A bound on F(x -> the part of ct left visible) for every x in the convex hull of `corners` (an element of the
// source, or the whole clipped source), INFINITY if no proof is found; 0 when every segment from there to ct meets
// one of the occluders. Occluder fusion by extended
// projections (Durand, Drettakis, Thollot & Puech 2000): for a convex occluder piece O, the points y of the target's
// plane that O hides from every corner c of the element are hidden by O from every point of the element (segments
// from y to two corners meet O at o1 and o2; the segment o1 o2 lies in O and crosses the segment from y to any point
// between the corners), so the intersection over the corners of O's projections from them (O cut to the slab in front
// of both planes and nearer to the target's plane than the corner) is O's extended projection; if the union of all
// the pieces' extended projections covers the target, the pair (element, target) is hidden, exactly. Non-convex
// occluders enter as their triangles. Conservative under rounding: each extended projection is shrunk by 4 of
// Clipper's units plus 1e-8 of the scene (the float error of projections magnified up to 1e4) before it is snapped,
// so its snapped polygon lies inside it, and the snapped target, grown by 1.5 units, must be covered by their union
// (corners of the target within 1e-9 of its size of their neighbour are dropped; the growth, 2.8e-9 of its size,
// covers them).
double hidden_from_all_of(std::span<const Vec3> corners, std::span<const Vec3> ct, const Vec3& ns, double os,
                          const Vec3& nt, double ot, std::span<const Occluder> occ, double eps, double scale,
                          ExactScratch& S) {
  constexpr double kFail = INFINITY;
  const size_t mc = corners.size(), mt = ct.size();
  if (mc < 3 || mt < 3 || occ.empty()) return kFail;
  double hc[8];
  if (mc > 8) return kFail;
  double hmin = INFINITY;
  for (size_t k = 0; k < mc; ++k) {
    hc[k] = nt.dot(corners[k] - ct[0]) + (nt.dot(ct[0]) - ot);
    if (!(hc[k] > 1e3 * eps)) return kFail;  // a corner on (or near) the target's plane sees it edge-on
    hmin = std::min(hmin, hc[k]);
  }
  // Occluder pieces and corners are moved to an origin at the target's first corner before they are clipped and
  // projected: the rounding then scales with the scene, not with where it sits (a model 1e6 m from the origin); the
  // planes' offsets, computed once from absolute coordinates, keep a margin of that rounding.
  const Vec3 o3 = ct[0];
  const double os_l = os - ns.dot(o3), ot_l = ot - nt.dot(o3);
  const double at = 4e-16 * (o3.cwiseAbs().maxCoeff() + scale);
  Vec3 cl[8];
  for (size_t k = 0; k < mc; ++k) cl[k] = corners[k] - o3;
  const Vec3 tc = average(ct) - o3;
  Vec3 u = Vec3::Zero();
  for (size_t k = 0; k < mt && !(u.squaredNorm() > 0); ++k) u = ct[(k + 1) % mt] - ct[k];
  u.normalize();
  const Vec3 v = nt.cross(u);
  double R = 0;
  for (const Vec3& p : ct) R = std::max({R, std::abs(u.dot(p - o3 - tc)), std::abs(v.dot(p - o3 - tc))});
  if (!(R > 0)) return kFail;
  const double box = 1.5 * R;  // extended projections are cut to this square around the target (bounded coordinates)
  const double delta = 4 * R / kSnap + 1e-8 * scale;
  if (!(delta < 0.1 * R)) return kFail;
  const double sc = kSnap / R;
  auto snap = [&](double a) { return ClipperLib::cInt(std::llround(a * sc)); };
  Poly2 X, P, tmp;
  const Poly2 square = {{-box, -box}, {box, -box}, {box, box}, {-box, box}};
  S.subject.clear();
  std::vector<std::array<int, 3>> tris;
  std::vector<Vec3> piece;
  auto add_piece = [&](std::span<const Vec3> poly) {
    // In front of the source's plane and the target's (strictly: a point on either plane blocks nothing).
    S.a.clear();
    for (const Vec3& q : poly) S.a.push_back(q - o3);
    clip_keep(S.a, ns, os_l + eps + at, S.b);
    clip_keep(S.b, nt, ot_l + eps + at, S.a);
    if (S.a.empty()) return;
    X = square;
    for (size_t k = 0; k < mc && !X.empty(); ++k) {
      // Nearer to the target's plane than the corner (what a segment from it can meet), magnification <= 1e4.
      clip_keep(S.a, -nt, -(ot_l + hc[k] * (1 - 1e-4)), S.b);
      if (S.b.empty()) {
        X.clear();
        break;
      }
      P.clear();
      for (const Vec3& q : S.b) {
        const double hq = nt.dot(q) - ot_l;
        const Vec3 y = cl[k] + (q - cl[k]) * (hc[k] / (hc[k] - hq));
        P.push_back({u.dot(y - tc), v.dot(y - tc)});
      }
      if (signed_area(P) < 0) std::reverse(P.begin(), P.end());
      drop_short_edges(P, 1e-9 * R);
      if (P.size() < 3) {  // a projection without area (a sliver seen edge-on) hides nothing, not everything
        X.clear();
        break;
      }
      intersect_convex(X, P, tmp);
    }
    drop_short_edges(X, 1e-9 * R);
    if (X.size() < 3) return;
    // Shrunk by delta: each edge moved inwards (X is convex).
    const Poly2 edges = X;
    for (size_t k = 0; k < edges.size() && !X.empty(); ++k) {
      const auto &a = edges[k], &b = edges[(k + 1) % edges.size()];
      double nx = b[1] - a[1], ny = a[0] - b[0];
      const double len = std::hypot(nx, ny);
      if (!(len > 0)) continue;
      nx /= len, ny /= len;
      clip_half_plane(X, nx, ny, nx * a[0] + ny * a[1] - delta, tmp);
      std::swap(X, tmp);
    }
    if (X.size() < 3) return;
    ClipperLib::Path path;
    for (const auto& p : X) path.push_back({snap(p[0]), snap(p[1])});
    S.subject.push_back(std::move(path));
  };
  for (const Occluder& o : occ) {
    if (o.convex) {
      add_piece(o.poly);
      continue;
    }
    const Vec3 nq = mesh::newell_normal(o.poly);
    if (!(nq.norm() > 0)) continue;
    tris = mesh::triangulate_polygon(o.poly, nq.normalized());
    for (const auto& T : tris) {
      piece = {o.poly[size_t(T[0])], o.poly[size_t(T[1])], o.poly[size_t(T[2])]};
      add_piece(piece);
    }
  }
  if (S.subject.empty()) return kFail;
  // The target, counter-clockwise in (u, v). If convex, it is moved outwards by 1.5 units before it is snapped (each
  // corner along its miter), so its snapped polygon contains it; else the band its snapping may lose is added below.
  X.clear();
  for (const Vec3& p : ct) X.push_back({u.dot(p - o3 - tc), v.dot(p - o3 - tc)});
  if (signed_area(X) < 0) std::reverse(X.begin(), X.end());
  drop_short_edges(X, 1e-9 * R);
  if (X.size() < 3) return kFail;
  bool convex_target = true;
  const size_t mx = X.size();
  for (size_t k = 0; k < mx && convex_target; ++k) {
    const auto &a = X[k], &b = X[(k + 1) % mx], &c = X[(k + 2) % mx];
    convex_target = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]) > 0;
  }
  double uncovered = 0;
  S.clip_path.clear();
  if (convex_target) {
    const double grow = 1.5 * R / kSnap;
    for (size_t k = 0; k < mx; ++k) {
      const auto &a = X[(k + mx - 1) % mx], &b = X[k], &c = X[(k + 1) % mx];
      double n1x = b[1] - a[1], n1y = a[0] - b[0], n2x = c[1] - b[1], n2y = b[0] - c[0];  // outward normals
      const double l1 = std::hypot(n1x, n1y), l2 = std::hypot(n2x, n2y);
      n1x /= l1, n1y /= l1, n2x /= l2, n2y /= l2;
      const double c12 = n1x * n2x + n1y * n2y;
      if (c12 >= -0.5) {  // miter: b + grow (n1 + n2) / (1 + n1 . n2), at most 2 grow from b
        const double m = grow / (1 + c12);
        S.clip_path.push_back({snap(b[0] + m * (n1x + n2x)), snap(b[1] + m * (n1y + n2y))});
      } else {
        // A sharp corner (under 60 degrees): its miter would run far out (to infinity for a sliver, beyond Clipper's
        // range); bevelled instead through b + 2 grow n1, b + 2 grow n, b + 2 grow n2 (n the bisector), whose chords
        // pass at least 2 grow cos(45 degrees) > grow from b.
        double bx = n1x + n2x, by = n1y + n2y;
        const double lb = std::hypot(bx, by);
        if (lb > 0) bx /= lb, by /= lb;
        else bx = b[0] - 0.5 * (a[0] + c[0]), by = b[1] - 0.5 * (a[1] + c[1]);  // a spike: along it
        const double g2 = 2 * grow, lbb = std::hypot(bx, by);
        S.clip_path.push_back({snap(b[0] + g2 * n1x), snap(b[1] + g2 * n1y)});
        if (lbb > 0) S.clip_path.push_back({snap(b[0] + g2 * bx / lbb), snap(b[1] + g2 * by / lbb)});
        S.clip_path.push_back({snap(b[0] + g2 * n2x), snap(b[1] + g2 * n2y)});
      }
    }
  } else {
    for (const auto& p : X) S.clip_path.push_back({snap(p[0]), snap(p[1])});
    double perimeter = 0;
    for (size_t k = 0; k < mt; ++k) perimeter += (ct[(k + 1) % mt] - ct[k]).norm();
    uncovered = perimeter * (R / kSnap);
  }
  S.clipper.Clear();
  S.clipper.AddPath(S.clip_path, ClipperLib::ptSubject, true);
  S.clipper.AddPaths(S.subject, ClipperLib::ptClip, true);
  S.clipper.Execute(ClipperLib::ctDifference, S.result, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
  // What is left uncovered bounds F(x -> visible part of ct) by its area / (pi h^2), h the element's smallest height
  // above the target's plane.
  for (const ClipperLib::Path& path : S.result)
    if (path.size() >= 3) uncovered += std::abs(ClipperLib::Area(path)) / (sc * sc);
  return uncovered / (kPi * hmin * hmin);
}

}  // namespace

double fused_hidden_bound(std::span<const Vec3> corners, const Vec3& ns, std::span<const Vec3> target, const Vec3& nt,
                          std::span<const Occluder> occluders, double scale, ExactScratch& scratch) {
  return hidden_from_all_of(corners, target, ns, ns.dot(corners[0]), nt, nt.dot(target[0]), occluders, 1e-10 * scale,
                            scale, scratch);
}

ExactPairResult exact_hidden_pair(std::span<const Vec3> s, const Vec3& ns, double area_s, bool s_convex,
                                  std::span<const Vec3> t, const Vec3& nt, bool t_convex,
                                  std::span<const Occluder> candidates, double tol, double scale,
                                  ExactScratch& S) {
  ExactPairResult res;
  const double eps = 1e-10 * scale;
  // The parts of s and t in front of each other: only those exchange light.
  clip_front(s, nt, nt.dot(t[0]), eps, S.cs);
  clip_front(t, ns, ns.dot(s[0]), eps, S.ct);
  if (S.cs.size() < 3 || S.ct.size() < 3 || candidates.empty()) return res;
  const std::vector<Vec3> cs = S.cs, ct = S.ct;
  const double os = ns.dot(s[0]), ot = nt.dot(t[0]);
  std::vector<Occluder> pool;  // occluder lists of the elements: [begin, begin + count) per element
  const int root_outcome = classify(cs, ct, ns, nt, os, ot, candidates, eps, S, pool, true);
  if (root_outcome == ExactPairResult::kClear || root_outcome == ExactPairResult::kHidden) {
    res.outcome = ExactPairResult::Outcome(root_outcome);
    return res;
  }
  // Occluders hidden behind another from all of cs add nothing, and their lines are no events (floorplan.obj: pairs
  // with fewer than kMaxInterOccluders occluders left then get the lines between them).
  const int root_count = int(drop_hidden_occluders(cs, pool, eps, S.gone));
  // Hidden by several occluders together (a building's walls, a row of them): proven without integrating.
  // A proof may leave a sliver uncovered (where the target meets a plane the occluders stand on, segments graze it):
  // accepted if F to it is within 1 % of the tolerance, as the pair's error.
  const double proof_tol = 0.01 * tol;
  // Only where several occluders stand between the two: one convex occluder hiding the pair is found by classify,
  // and the faces of one convex solid leave no gap for a proof to close (room with a block: 9 % more time).
  bool fusion = root_count >= kMinFusionOccluders;
  if (fusion) {
    bool one_solid = pool[0].solid >= 0;
    for (int k = 1; k < root_count && one_solid; ++k) one_solid = pool[size_t(k)].solid == pool[0].solid;
    fusion = !one_solid;
  }
  if (fusion) {
    const double b = hidden_from_all_of(cs, ct, ns, os, nt, ot, pool, eps, scale, S);
    if (b <= proof_tol) {
      res.outcome = ExactPairResult::kHidden;
      res.error = b;
      return res;
    }
  }
  res.outcome = ExactPairResult::kIntegrated;
  int cur_begin = 0, cur_count = 0;  // the occluder list f() uses
  int sample_kind = -1;  // combined kind of the samples since the last reset
  bool unoccluded = false;  // the element is hidden: F_hidden = F(p -> t), no clipping
  auto f = [&](const Vec3& p) {
    ++res.points;
    if (unoccluded) {
      sample_kind = combine(sample_kind, 1);
      return contour_sum(p, ns, ct);
    }
    int kind = -1;
    const double h = hidden_point_to_polygon(
        p, ns, ct, nt, t_convex, std::span<const Occluder>(pool.data() + cur_begin, size_t(cur_count)), S, &kind);
    // Within the union's rounding (~1e-9 of F(p -> t), see hidden_point_to_polygon) of nothing or of everything:
    // a sample that saw no shadow (or all of it). A residue of 1e-15 from an occluder grazing the target's plane
    // (a wall standing on the floor it borders) counted as "partly hidden" once, so the element stopped being
    // force-refined and a table leg's shadow that its 6 samples missed was never found (storey.stl: row 1.0025).
    // One convex solid's shadow says which by its area (no second contour sum).
    if (kind < 0) {
      const double whole = h > 0 ? contour_sum(p, ns, ct) : 0;
      kind = h <= 1e-9 * whole ? 0 : h >= (1 - 1e-9) * whole ? 1 : 2;
    }
    sample_kind = combine(sample_kind, kind);
    return h;
  };
  // Genz-Malik on the unit square of (s, t): the centre, (+-l2, 0), (0, +-l2), (+-l3, 0), (0, +-l3), (+-l4, +-l4),
  // (+-l5, +-l5) in half-widths; weights normalised to sum 1 (the element's integral is their sum times f J).
  // With a budget (>= 0), Genz-Malik's degree-5 rule on 13 of the 17 points comes first, its error estimated by the
  // degree-3 rule on the centre and the four diagonal points at l4 (weights 17/27 and 5/54, both of the same samples):
  // that difference is the degree-3 rule's error, far above the degree-5 rule's where the integrand is smooth. It is
  // kept if within the budget, or if its samples all saw the target hidden and `forced` says the element is refined
  // whatever its rule says; else the last 4 points give the degree-7 rule, exactly as without a budget.
  // The centre's value and kind when push evaluated it first (kind -1: not), for rule to take as its first sample.
  std::pair<double, int> centre = {0.0, -1};
  auto rule = [&](Elem& e, double budget = -1, bool forced = false) {
    sample_kind = -1;
    unoccluded = e.hidden;
    auto jacobian = [&](double a, double b) {
      const Vec3 ds = (1 - b) * (e.v[1] - e.v[0]) + b * (e.v[2] - e.v[3]);
      const Vec3 dt = (1 - a) * (e.v[3] - e.v[0]) + a * (e.v[2] - e.v[1]);
      return std::abs(ds.cross(dt).dot(ns));
    };
    auto g = [&](double a, double b) { return jacobian(a, b) * f(bilinear(e.v, a, b)); };
    constexpr double l2 = 0.35856858280031809199 / 2, l3 = 0.94868329805051379960 / 2, l4 = l3,
                     l5 = 0.68824720161168529772 / 2;  // sqrt(9/70), sqrt(9/10), sqrt(9/10), sqrt(9/19), halved
    double c;
    if (centre.second >= 0) {
      c = jacobian(0.5, 0.5) * centre.first;
      sample_kind = centre.second;
      centre.second = -1;
    } else {
      c = g(0.5, 0.5);
    }
    const double s2a = g(0.5 - l2, 0.5) + g(0.5 + l2, 0.5), s2b = g(0.5, 0.5 - l2) + g(0.5, 0.5 + l2);
    const double s3a = g(0.5 - l3, 0.5) + g(0.5 + l3, 0.5), s3b = g(0.5, 0.5 - l3) + g(0.5, 0.5 + l3);
    const double s4 = g(0.5 - l4, 0.5 - l4) + g(0.5 + l4, 0.5 - l4) + g(0.5 + l4, 0.5 + l4) + g(0.5 - l4, 0.5 + l4);
    // Fourth differences (l2 / l3)^2 = 1/7.
    const double da = std::abs(s2a - 2 * c - (s3a - 2 * c) / 7), db = std::abs(s2b - 2 * c - (s3b - 2 * c) / 7);
    e.dir = da > db ? 0 : db > da ? 1 : -1;
    e.has_Q = true;
    const double q5 = (-1942.0 * c + 735.0 * (s2a + s2b) + 65.0 * (s3a + s3b) + 50.0 * s4) / 1458.0;
    if (budget >= 0) {
      const double q3 = (34.0 * c + 5.0 * s4) / 54.0;
      if (std::abs(q5 - q3) <= budget || (forced && sample_kind == 1)) {
        e.Q = q5;
        e.E = std::abs(q5 - q3);
        e.kind = sample_kind;
        return;
      }
    }
    const double s5 = g(0.5 - l5, 0.5 - l5) + g(0.5 + l5, 0.5 - l5) + g(0.5 + l5, 0.5 + l5) + g(0.5 - l5, 0.5 + l5);
    const double q7 = (-3816.0 * c + 2940.0 * (s2a + s2b) + 1020.0 * (s3a + s3b) + 200.0 * s4 + 6859.0 / 4 * s5) / 19683.0;
    e.Q = q7;
    e.E = std::abs(q7 - q5);
    e.kind = sample_kind;
  };
  const double goal = tol * area_s;
  std::priority_queue<Leaf> heap;
  double total_err = 0;
  long long lazy_splits = 0;  // counted against the point cap as the 17 points each would have cost
  // An element is classified against its parent's occluders first: one no occluder reaches contributes 0 with
  // no point evaluated; one whose samples all see no shadow although an occluder reaches it keeps being refined
  // (error = its unoccluded contribution), so a shadow smaller than the sample spacing is never missed.
  std::vector<Vec3> corners;
  // Critical lines of the pair (see Critical) from its occluders clipped to the slab in front of both planes:
  // an element no line crosses has a smooth integrand, and there a shadow cannot appear or vanish.
  std::vector<Critical> lines;
  std::vector<int> lpool;  // line lists of the elements: [begin, begin + count) per element
  bool all_lines = false;  // lines between occluders too: every kink of F_hidden lies on one (EEE curves aside)
  const bool have_lines =
      critical_lines_of(cs, ct, ns, os, nt, ot, std::span<const Occluder>(pool.data(), size_t(root_count)), eps, S, lines,
                        true, &all_lines);
  // Where an occluder touches the source's plane (a corner or an edge of it on the plane, such as a worktop's top
  // meeting the edge face below it or a wall standing on the floor, or the segment where it passes through the plane),
  // F_hidden has a singular derivative: the samples of an element reaching it can all lie in the smooth part while
  // both embedded rules miss the steep part next to it by the same amount (floorplan.obj, a worktop's edge face at the
  // L's inner corner: one element's estimate 2.4e-12, its error 4.7e-8). The elements touching such a contact take
  // their error from their pieces instead (see push).
  std::vector<std::array<Vec3, 2>> contacts;
  std::vector<Occluder> touching;  // the occluders that make them
  for (int k = 0; k < root_count; ++k) {
    const size_t contacts_before = contacts.size();
    const auto q = pool[size_t(k)].poly;
    Vec3 first = Vec3::Zero(), dir = Vec3::Zero(), lo = Vec3::Zero(), hi = Vec3::Zero();  // crossings: their span
    double tlo = 0, thi = 0;
    int crossings = 0;
    for (size_t c = 0; c < q.size(); ++c) {
      const Vec3 &a = q[c], &b = q[(c + 1) % q.size()];
      // On the plane within the merge's snapping (corners of merged occluders move by up to 1e-9 of their region:
      // examples/room.obj, a shelf's corners 1.2e-9 off the wall it hangs on, were no contact at eps).
      const double da = ns.dot(a) - os, db = ns.dot(b) - os;
      const bool on_a = std::abs(da) <= 10 * eps, on_b = std::abs(db) <= 10 * eps;
      if (on_a && on_b) contacts.push_back({a, b});
      else if (on_a) contacts.push_back({a, a});
      else if (!on_b && (da > 0) != (db > 0)) {
        const Vec3 x = a + (b - a) * (da / (da - db));  // all on the line where q's plane meets the source's
        if (crossings == 0) first = lo = hi = x;
        if (crossings == 1) dir = x - first;
        const double along = dir.dot(x - first);
        if (along < tlo) tlo = along, lo = x;
        if (along > thi) thi = along, hi = x;
        ++crossings;
      }
    }
    if (crossings > 0) contacts.push_back({lo, hi});
    if (contacts.size() > contacts_before) touching.push_back(pool[size_t(k)]);
  }
  // Without the pair's lines (too many occluders), the lines of the occluders touching the source's plane still
  // split the elements along a contact where the shadow steepens: next to a wall's 2 cm foot, F_hidden rises by a
  // quarter within 0.3 mm of it (floorplan.obj, faces 1360 -> 1236 behind its 116 unmerged patches: the elements
  // along the foot were 5 cm wide, their rules agreed with their halves' to 1e-15, and H came out 1.3e-4 of itself
  // low). These lines mark where the shadows of those occluders change; no line crossing an element still says
  // nothing about the other occluders' kinks, so the pair stays "without lines" for everything else.
  if (!have_lines && !touching.empty() &&
      !critical_lines_of(cs, ct, ns, os, nt, ot, touching, eps, S, lines, true))
    lines.clear();
  for (size_t k = 0; k < lines.size(); ++k) lpool.push_back(int(k));
  const int root_lines = int(lpool.size());
  // An element touches a contact if it comes within 1e-8 of the scene of it, not eps: its corners come from
  // intersections of critical lines, and lines through a contact point meet a source edge up to ~1e-8 away from it
  // (floorplan.obj, faces 1014 -> 136: a door head's underside ending at the source's edge made a contact point that
  // the element next to it missed by 1.7e-8; that element's value came out 1.2e-3 of itself low, with an estimate a
  // ninth of its error, and F 1.46e-8 high).
  const double contact_eps = 100 * eps;
  auto contact_of = [&](const std::array<Vec3, 4>& v) -> const std::array<Vec3, 2>* {
    for (const auto& c : contacts)
      if (touches(v, c[0], c[1], ns, contact_eps)) return &c;
    return nullptr;
  };
  // The two halves of e across s (d = 0) or t (d = 1), inheriting what e has proven.
  auto bisect = [](const Elem& e, int d, std::array<Elem, 3>& kids) {
    if (d == 0) {
      const Vec3 m0 = bilinear(e.v, 0.5, 0), m1 = bilinear(e.v, 0.5, 1);
      kids[0].v = {e.v[0], m0, m1, e.v[3]};
      kids[1].v = {m0, e.v[1], e.v[2], m1};
    } else {
      const Vec3 m0 = bilinear(e.v, 0, 0.5), m1 = bilinear(e.v, 1, 0.5);
      kids[0].v = {e.v[0], e.v[1], m1, m0};
      kids[1].v = {m0, m1, e.v[2], e.v[3]};
    }
    for (int k = 0; k < 2; ++k) {
      kids[size_t(k)] = Elem{kids[size_t(k)].v};
      kids[size_t(k)].hidden = e.hidden;
      kids[size_t(k)].hidden_bound = e.hidden_bound;
      kids[size_t(k)].failed_area = e.failed_area;
    }
  };
  bool root_classified = false;  // the next push is the convex quad cs itself, classified at the start
  auto push = [&](Elem e, int parent_begin, int parent_count, int parent_lbegin, int parent_lcount, int parent_kind) {
    Leaf l;
    corners.assign(e.v.begin(), e.v.end());
    l.occ_begin = int(pool.size());
    int outcome = ExactPairResult::kIntegrated;
    if (root_classified) {  // classify(cs) at the start: the same corners, the same list and outcome
      root_classified = false;
      pool.reserve(pool.size() + size_t(parent_count));
      for (int k = 0; k < parent_count; ++k) pool.push_back(pool[size_t(parent_begin + k)]);
    } else {
      // classify appends at most parent_count occluders to the pool: reserved, the parent's stay where they are.
      const size_t need = pool.size() + size_t(parent_count);
      if (pool.capacity() < need) pool.reserve(std::max(need, 2 * pool.capacity()));  // geometric: no quadratic copies
      const std::span<const Occluder> parent(pool.data() + parent_begin, size_t(parent_count));
      bool one_solid_parent = !parent.empty() && parent[0].solid >= 0;
      for (const Occluder& o : parent) one_solid_parent = one_solid_parent && o.solid == parent[0].solid;
      outcome = classify(corners, ct, ns, nt, os, ot, parent, eps, S, pool, !one_solid_parent);
    }
    l.occ_count = int(pool.size()) - l.occ_begin;
    if (outcome == ExactPairResult::kClear) return;  // F_hidden = 0 on e, exactly
    cur_begin = l.occ_begin, cur_count = l.occ_count;
    // Hidden from all of e: F_hidden = F(x -> t) there, smooth (no critical line matters, no shadow to find).
    if (!e.hidden && outcome == ExactPairResult::kHidden) e.hidden = true;
    // Tried where the target may well be hidden from all of e: its parent's samples saw it hidden, or (no samples
    // of the parent: a root, or split along a line before its rule) e's centre sees it hidden.
    const double A = 0.5 * std::abs((e.v[2] - e.v[0]).cross(e.v[3] - e.v[1]).dot(ns));
    bool try_proof = fusion && !e.hidden && outcome == ExactPairResult::kIntegrated && parent_kind != 0 &&
                     parent_kind != 2 && l.occ_count >= 2 && A <= 0.25 * e.failed_area;
    if (try_proof && parent_kind < 0) {
      sample_kind = -1;
      unoccluded = false;
      f(bilinear(e.v, 0.5, 0.5));
      try_proof = sample_kind == 1;
    }
    if (try_proof) {
      const double b =
          hidden_from_all_of(corners, ct, ns, os, nt, ot,
                             std::span<const Occluder>(pool.data() + l.occ_begin, size_t(l.occ_count)), eps, scale, S);
      e.hidden = b <= proof_tol;
      if (e.hidden) e.hidden_bound = b;
      else e.failed_area = A;
    }
    // The critical lines through e; the one nearest its centre splits it.
    l.line_begin = int(lpool.size());
    int pick = -1;
    double pick_side = INFINITY;
    if (outcome == ExactPairResult::kIntegrated && !e.hidden)
      for (int k = 0; k < parent_lcount; ++k) {
        const int id = lpool[size_t(parent_lbegin + k)];
        double side = 0;
        if (!crosses(lines[size_t(id)], e.v, ns, eps, &side)) continue;
        lpool.push_back(id);
        if (std::abs(side) < pick_side) pick_side = std::abs(side), pick = id;
      }
    l.line_count = int(lpool.size()) - l.line_begin;
    if (pick >= 0) {
      l.nkids = split_along(e.v, lines[size_t(pick)], l.kids);
      for (int k = 0; k < l.nkids; ++k) l.kids[size_t(k)].failed_area = e.failed_area;
    }
    if (pick >= 0 && l.nkids == 0) pick = -1;  // the line grazes a corner: bisect instead
    // Until no line crosses an element its rules can agree while all of them miss a kink or a sliver of shadow
    // between their samples (a block's side and bottom: the root rule and its split agreed to 1e-12 and were
    // both 2 % off): above kLineForcedArea its error is bounded by its unoccluded contribution, and it is split on.
    // Its rules are not evaluated then (their values would not change that): only if it is still a leaf at the end
    // (after the refinement loop).
    l.lazy = pick >= 0 && A > area_s * kLineForcedArea;
    if (l.lazy) {
      l.e = e;
      l.err = A * contour_sum(bilinear(e.v, 0.5, 0.5), ns, ct);
      ++lazy_splits;
      total_err += l.err;
      heap.push(l);
      return;
    }
    const std::array<Vec3, 2>* contact = contacts.empty() ? nullptr : contact_of(e.v);
    auto one_solid = [&] {
      const int s0 = pool[size_t(l.occ_begin)].solid;
      for (int k = 0; k < l.occ_count; ++k)
        if (pool[size_t(l.occ_begin + k)].solid != s0) return false;
      return s0 >= 0;
    };
    if (!e.has_Q) {
      // No line crosses e, every kink of the pair lies on a line, e touches no contact, and its occluders are one
      // convex polygon or the faces of one convex solid in front of a convex target (their projections are convex:
      // no three edges line up, no EEE curve): its integrand is smooth, and the degree-5 rule may do (a room with a
      // block: 14 % fewer points). Not with several occluders: in floorplan.obj (faces 3403 -> 2469, lines between
      // all of them) the degree-5 and degree-3 rules of an element agreed to 1e-11 and were 1.5e-8 off. The budget:
      // its area's share of the pair's goal, a hundredth of it as a margin (a tenth moved the turned room's entries
      // by up to 1.2e-9, against 9e-10 with the degree-7 rule). Forced: refined below whatever its rule says if its
      // samples all see the target hidden (see `force` below).
      const bool one_convex =
          t_convex && l.occ_count >= 1 && (one_solid() || (l.occ_count == 1 && pool[size_t(l.occ_begin)].convex));
      if (pick < 0 && have_lines && all_lines && !contact && one_convex) {
        const bool forced = outcome == ExactPairResult::kIntegrated && !e.hidden && l.occ_count > 2 &&
                            A > area_s * kForcedArea && !(l.line_count == 0 && one_solid());
        // Its shadow keeps one structure (no line crosses it, no EEE curve): the centre decides what all of it sees.
        // No shadow there (exactly): none anywhere, F_hidden = 0 on e from one point instead of 13 (every sample of
        // 380,671 such elements of the room with a block was 0 to 1e-25). The whole target hidden there: hidden from
        // all of e, integrated without clipping. Else the centre's value is the rule's first sample.
        if (!e.hidden) {
          sample_kind = -1;
          unoccluded = false;
          const double hc = f(bilinear(e.v, 0.5, 0.5));
          if (sample_kind == 0 && hc == 0) {
            e.Q = 0, e.E = 0, e.kind = 0, e.dir = -1, e.has_Q = true;
          } else if (sample_kind == 1) {
            e.hidden = true;
          } else {
            centre = {hc, sample_kind};
          }
        }
        if (!e.has_Q) rule(e, 0.01 * goal * (A / area_s), forced);
      } else {
        rule(e);
      }
    }
    l.e = e;
    l.value = e.Q;
    l.err = e.E;
    int bisect_dir = -1;
    if (pick < 0) {
      // Bisection across the direction of the larger fourth difference; with none (the samples carry no
      // information), across the longer pair of sides. (Cutting elements at a contact edge parallel to it instead
      // was tried: CornellBox-Original.obj then had 6 pairs at the point cap instead of 2.)
      int d = e.dir;
      if (d < 0)
        d = (e.v[1] - e.v[0]).norm() + (e.v[2] - e.v[3]).norm() >= (e.v[3] - e.v[0]).norm() + (e.v[2] - e.v[1]).norm()
                ? 0
                : 1;
      bisect(e, d, l.kids);
      l.nkids = 2;
      bisect_dir = d;
    }
    // A line crosses it and its samples saw both shadow and light (the integrand has a kink or a step between
    // samples, where the embedded rules' difference can be 1e-6 of the true error: a 5-line sliver, estimate 2.6e-14,
    // error 4.6e-8), or the pair's lines leave some kinks out (no lines, or none between occluders: an element no
    // line crosses can still hold a kink where one occluder's edge passes another's corner; floorplan.obj, a window
    // sill, face 595, to the ceiling: estimate 2.6e-9, error 4.8e-6) and its samples saw both, or it touches a
    // contact (above): its error is the change from its rule to the sum of its pieces' rules (the pieces it is split
    // into; they keep their values for when it is split), and its value that sum.
    // With lines between occluders, a kink can still lie on a curve where three edges line up (an EEE event: an
    // edge of each of two occluders and one of the target), which no line marks: an element above kForcedArea of the
    // source behind two occluders that are not faces of one solid is checked as well. floorplan.obj, faces 2872 ->
    // 2748 (lines between all of its 9 occluders): such a leaf's rules agreed to 1e-12 and left the entry 1.9e-8 off
    // the unmerged pair (estimate 3.3e-9); now 4e-11. `bench_exact_scan ... 3000 7`: floor plan 6 % more points,
    // largest difference 5.4e-9 -> 1.6e-9; room.obj +4 %, CornellBox-Original +11 %. Every such element instead (no
    // area floor) also fixed faces 1694 -> 956 (3.9e-8 off: a leaf under 1/1000 of the source, at a notch of the
    // target) but cost CornellBox-Original 118 % more points and 12 more pairs at the point cap: not done.
    const bool mixed_unsafe =
        e.kind == 2 && (pick >= 0 || !have_lines ||
                        (l.occ_count >= 2 && !one_solid() && (!all_lines || A > area_s * kForcedArea)));
    if (l.nkids > 0 && (mixed_unsafe || contact)) {
      double sum = 0;
      for (int k = 0; k < l.nkids; ++k) {
        rule(l.kids[size_t(k)]);
        sum += l.kids[size_t(k)].Q;
      }
      double change = std::abs(sum - e.Q);
      if (bisect_dir >= 0) {
        // Bisected: its halves across the other direction too. One pair of halves can agree with e's rule while a
        // kink runs across the other (window_room.obj, faces 0 -> 25: strips of the ceiling along a window, cut only
        // across, one off by 1.9e-7 with an estimate of 2.5e-9); e is split where they differ more, its error the
        // larger difference. For mixed elements only, faces 2 -> 32 of the same model (elements touching the jamb's
        // contact) stayed 4e-8 off; a corner of udales_shape.obj takes 34 % more points (26 % for mixed ones only).
        std::array<Elem, 3> other;
        bisect(e, 1 - bisect_dir, other);
        double sum2 = 0;
        for (int k = 0; k < 2; ++k) {
          rule(other[size_t(k)]);
          sum2 += other[size_t(k)].Q;
        }
        if (std::abs(sum2 - e.Q) > change) {
          change = std::abs(sum2 - e.Q);
          sum = sum2;
          l.kids = other;
        }
      }
      l.err = std::max(l.err, change);
      l.value = sum;
    }
    const int kind = e.kind;
    // Every sample saw nothing hidden, or the whole target hidden, although the element is neither provably
    // clear nor provably hidden: a shadow edge (or a gap between shadows) may pass between the samples. With
    // critical lines, an element no line crosses keeps one combinatorial structure: if its samples saw nothing
    // hidden, nothing is (a shadow appears only where an occluder's vertex or edge passes the target's); if they
    // saw everything hidden, a gap can still open where three occluders' edges line up (an EEE curve): those,
    // and every such element when the pair has too many occluders for lines, are refined down to 1/64 of the
    // source (a shadow narrower than that may be missed). Elements that lines cross are split along them above.
    // Not when the element's occluders are all faces of one closed convex solid (convex_solids): they hide its
    // silhouette, a convex region whose corners are the solid's, and no gap opens without crossing a critical line
    // (room 16 / 5: 37.6 M -> 20.1 M points, row sums unchanged).
    if ((kind == 0 || kind == 1) && outcome == ExactPairResult::kIntegrated && !e.hidden) {
      bool force;
      // A line crosses it: the shadow's structure changes inside, so samples that all saw the same thing say nothing
      // about a shadow (or a gap) between them, at any size (below kLineForcedArea such an element was trusted to its
      // rule: a sofa's end face touching a wall patch at its notch hid a wedge the samples of a sliver missed, and
      // that pair's H was 56 % low with an estimated error of 2e-13; examples/floorplan.obj, row sum 1 + 6.6e-6).
      if (pick >= 0) force = true;
      else if (!have_lines) force = A > area_s * kForcedArea;
      else force = kind == 1 && l.occ_count > 2 && A > area_s * kForcedArea && !(l.line_count == 0 && one_solid());
      if (force) {
        const Vec3 c = bilinear(e.v, 0.5, 0.5);
        l.err = std::max(l.err, A * contour_sum(c, ns, ct));
      }
    }
    if (e.hidden) l.err += e.hidden_bound * A;
    total_err += l.err;
    heap.push(l);
  };
  // Roots: the clipped source as one bilinear quad if it is a convex quad, else three quads per triangle.
  bool convex_quad = false;
  if (cs.size() == 4 && s_convex) {
    convex_quad = true;
    for (int k = 0; k < 4; ++k)
      convex_quad = convex_quad && (cs[(k + 1) % 4] - cs[k]).cross(cs[(k + 2) % 4] - cs[(k + 1) % 4]).dot(ns) > 0;
  }
  if (convex_quad) {
    Elem e;
    e.v = {cs[0], cs[1], cs[2], cs[3]};
    root_classified = true;
    push(e, 0, root_count, 0, root_lines, -1);
  } else {
    std::vector<std::array<int, 3>> tris;
    if (!s_convex) tris = mesh::triangulate_polygon(cs, ns);
    if (tris.empty())
      for (int k = 1; k + 1 < int(cs.size()); ++k) tris.push_back({0, k, k + 1});
    // Each triangle as three quads (a corner, the midpoints of its two edges, the centroid): every element is
    // then a quad, whose bisections can halve it across either pair of sides. A triangle's bisections (a
    // median) never narrow it towards one of its edges, so a kink or a steep hidden part along a source edge
    // (an occluder standing on it: a leg on the floor) was resolved only by ever finer fans of slivers along it
    // (examples/storey.stl: 1,249 pairs stopped at the point cap; 557 with quads, in 22 % less time).
    auto three_quads = [&](const Vec3& a, const Vec3& b, const Vec3& c) {
      const Vec3 g = (a + b + c) / 3.0, mab = 0.5 * (a + b), mbc = 0.5 * (b + c), mca = 0.5 * (c + a);
      for (const std::array<Vec3, 4>& q : {std::array<Vec3, 4>{a, mab, g, mca}, std::array<Vec3, 4>{b, mbc, g, mab},
                                           std::array<Vec3, 4>{c, mca, g, mbc}}) {
        Elem e;
        e.v = q;
        push(e, 0, root_count, 0, root_lines, -1);
      }
    };
    // A needle (its shortest edge under a third of the longer edge from the opposite corner, its length; as
    // imprinting leaves beside a leg) is cut first into K strips across its length from that corner (K = length /
    // shortest edge rounded up, at most kMaxStrips): trapezoids about as long as wide, and the three quads of the
    // small triangle at the apex. As three quads alone its elements stayed needles, and a shadow at its wide end was
    // missed: examples/storey.stl, a 2.6 m x 6 mm floor sliver (patch 34) to a shelf strip, H 2.2 % low with an
    // estimate of 1e-10, its row 1 + 2.0e-6.
    constexpr int kMaxStrips = 64;
    for (const auto& T : tris) {
      int apex = 0;
      double shortest = INFINITY;
      for (int k = 0; k < 3; ++k) {
        const double l = (cs[T[(k + 1) % 3]] - cs[T[(k + 2) % 3]]).norm();
        if (l < shortest) shortest = l, apex = k;
      }
      const Vec3 &a = cs[T[apex]], &b = cs[T[(apex + 1) % 3]], &c = cs[T[(apex + 2) % 3]];  // T's winding
      const double length = std::max((b - a).norm(), (c - a).norm());
      const int K = shortest > 0 ? int(std::min(double(kMaxStrips), std::ceil(length / shortest))) : kMaxStrips;
      if (K < 4) {
        three_quads(a, b, c);
        continue;
      }
      for (int k = 1; k < K; ++k) {
        const double u0 = double(k) / K, u1 = double(k + 1) / K;
        Elem e;
        e.v = {a + u0 * (b - a), a + u1 * (b - a), a + u1 * (c - a), a + u0 * (c - a)};
        push(e, 0, root_count, 0, root_lines, -1);
      }
      three_quads(a, a + (b - a) / double(K), a + (c - a) / double(K));
    }
  }
  // Pairs behind tens of occluders with hundreds of lines need more than 2^14 points for 1e-8 (storey.stl: 47 pairs
  // stopped there, row bound 6.8e-6; at 2^16 12 pairs, 5.0e-7, for 50 % more time).
  constexpr long long kMaxPoints = 1 << 16;
  // The estimates are refined to a third of the goal: independent references (bench_exact_scan's strips and grids)
  // found single leaves whose embedded rules agreed while they were off by up to 6x their estimate (window_room.obj
  // faces 2 -> 32, a line-crossed mixed leaf: 2.0e-8 off, estimate 3.3e-9; storey.obj 15 -> 0, a mixed leaf among 5
  // occluders: 2.3e-8, estimate 1.7e-10; storey.obj 48 -> 1, a large smooth leaf behind one lamp: 1.05e-8, estimate
  // 1.1e-9), entries up to 2.4x the tolerance, and floorplan.obj's assembled entries up to 1.7e-7 off (faces 3162 ->
  // 3393; bench_exact_entries). With a third, no scanned entry is off by more than 7.7e-9, and none of the floor plan's
  // 115 entries that moved is off by more than 7.8e-9. A pair within the goal itself stops at kSoftPoints rather than
  // chase the third up to the cap (those were the costly ones). Cost: room 32 / 10 +0.8 % points, storey.stl +4.5 %,
  // the c40 corner of udales +2.1 %, the floor plan +5.1 % (+2.2 % time).
  constexpr double kGoalShare = 1.0 / 3;
  constexpr long long kSoftPoints = 1 << 13;
  while (total_err > kGoalShare * goal && res.points + 17 * lazy_splits < kMaxPoints && !heap.empty() &&
         !(total_err <= goal && res.points + 17 * lazy_splits >= kSoftPoints)) {
    const Leaf top = heap.top();
    heap.pop();
    total_err -= top.err;
    for (int k = 0; k < top.nkids; ++k)
      push(top.kids[size_t(k)], top.occ_begin, top.occ_count, top.line_begin, top.line_count, top.lazy ? -1 : top.e.kind);
  }
  double H = 0, err = 0;
  while (!heap.empty()) {
    Leaf l = heap.top();
    heap.pop();
    if (l.lazy) {  // its value; its error is its bound unless its rule's own estimate is larger
      cur_begin = l.occ_begin, cur_count = l.occ_count;
      rule(l.e);
      l.value = l.e.Q;
      l.err = std::max(l.err, l.e.E);
    }
    H += l.value;
    err += l.err;
  }
  res.H = H / area_s;
  res.error = err / area_s;
  res.over_tolerance = err > goal;
  return res;
}

std::vector<CriticalSegment> pair_critical_lines(std::span<const Vec3> s, const Vec3& ns, std::span<const Vec3> t,
                                                const Vec3& nt, std::span<const Occluder> candidates, double scale) {
  std::vector<CriticalSegment> out;
  const auto S = make_exact_scratch();
  const double eps = 1e-10 * scale;
  clip_front(s, nt, nt.dot(t[0]), eps, S->cs);
  clip_front(t, ns, ns.dot(s[0]), eps, S->ct);
  if (S->cs.size() < 3 || S->ct.size() < 3 || candidates.empty()) return out;
  const std::vector<Vec3> cs = S->cs, ct = S->ct;
  const double os = ns.dot(s[0]), ot = nt.dot(t[0]);
  std::vector<Occluder> pool;
  if (classify(cs, ct, ns, nt, os, ot, candidates, eps, *S, pool, true) != ExactPairResult::kIntegrated) return out;
  std::vector<Critical> lines;
  critical_lines_of(cs, ct, ns, os, nt, ot, pool, eps, *S, lines);
  for (const Critical& L : lines) out.push_back({L.p, L.d, L.t0, L.t1});
  return out;
}

namespace {
std::vector<Occluder> as_occluders(const std::vector<std::vector<Vec3>>& polys) {
  std::vector<Occluder> out;
  for (const auto& q : polys) {
    if (q.size() < 3) continue;
    const Vec3 nq = mesh::newell_normal(q);
    if (!(nq.norm() > 0)) continue;
    out.push_back({std::span<const Vec3>(q), convex_polygon(q, nq)});
  }
  return out;
}
}  // namespace

ConvexSolids find_convex_solids(const mesh::PatchGeometry& g, const std::vector<int>& occluders, double scale) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  ConvexSolids out;
  out.of_patch.assign(size_t(g.size()), -1);
  const size_t n = occluders.size();
  if (!(scale > 0) || n < 2) return out;
  const double eps = 1e-9 * scale;
  // Signed distance of q from the plane of occluder k (positive in front of it).
  auto dist = [&](size_t k, const Vec3& q) {
    const int p = occluders[k];
    return g.normal[size_t(p)].dot(q - g.centroid[size_t(p)]);
  };
  auto max_dist = [&](size_t k, size_t of) {
    double m = -INFINITY;
    for (const Vec3& q : g.polygon(occluders[of])) m = std::max(m, dist(k, q));
    return m;
  };
  auto min_dist = [&](size_t k, size_t of) {
    double m = INFINITY;
    for (const Vec3& q : g.polygon(occluders[of])) m = std::min(m, dist(k, q));
    return m;
  };
  // True if a and b share a piece of boundary: two corners (of either, farther apart than eps) lie within eps of
  // both boundaries (an edge, or part of one at a T-junction; not a single corner).
  auto on_boundary = [&](const Vec3& q, size_t b) {
    const auto B = g.polygon(occluders[b]);
    for (size_t e = 0; e < B.size(); ++e) {
      const Vec3 &p0 = B[e], &p1 = B[(e + 1) % B.size()], d = p1 - p0;
      const double L2 = d.squaredNorm(), t = L2 > 0 ? std::clamp((q - p0).dot(d) / L2, 0.0, 1.0) : 0.0;
      if ((q - (p0 + t * d)).norm() <= eps) return true;
    }
    return false;
  };
  auto share_edge = [&](size_t a, size_t b) {
    Vec3 first = Vec3::Zero();
    bool have = false;
    for (const auto& [x, y] : {std::pair{a, b}, std::pair{b, a}})
      for (const Vec3& q : g.polygon(occluders[x])) {
        if (!on_boundary(q, y)) continue;
        if (have && (q - first).norm() > eps) return true;
        if (!have) first = q, have = true;
      }
    return false;
  };
  // Faces that share an edge (or part of one: T-junctions) and lie behind each
  // other's planes (a convex edge between outward faces) are joined. Not joined: a floor and a box standing on it (the
  // floor lies in front of the box's sides), a table's underside and a leg under it (the leg's side lies in front of
  // the underside's plane), a room's inward walls and its floor. Then faces in one plane facing the same way (one
  // facet meshed in pieces) are joined where they touch if they are already in one component or one of them has no
  // joint of the first kind (a piece inside a facet): a leg flush with the side of the slab it carries stays apart.
  std::vector<Eigen::AlignedBox3d> box(n);
  std::vector<size_t> order(n);
  for (size_t k = 0; k < n; ++k) {
    for (const Vec3& q : g.polygon(occluders[k])) box[k].extend(q);
    box[k].min().array() -= eps, box[k].max().array() += eps;
    order[k] = k;
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return box[a].min().x() < box[b].min().x(); });
  // Two partitions: `all` joins every such pair; `skeleton` joins coplanar pieces only within a component of the
  // first kind of joint or to a piece that has none. A component of `all` that is not convex (a leg under a slab,
  // flush with its side) is tried again as its `skeleton` components.
  std::vector<size_t> all(n), skel(n);
  for (size_t k = 0; k < n; ++k) all[k] = skel[k] = k;
  auto root = [](std::vector<size_t>& parent, size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<std::pair<size_t, size_t>> coplanar_pairs;
  std::vector<char> jointed(n, 0);
  for (size_t ia = 0; ia < n; ++ia) {
    const size_t a = order[ia];
    for (size_t ib = ia + 1; ib < n && box[order[ib]].min().x() <= box[a].max().x(); ++ib) {
      const size_t b = order[ib];
      if (!box[a].intersects(box[b])) continue;
      const Vec3 &na = g.normal[size_t(occluders[a])], &nb = g.normal[size_t(occluders[b])];
      const bool coplanar = std::abs(na.dot(nb)) >= 1 - 1e-9 && max_dist(a, b) <= eps && min_dist(a, b) >= -eps;
      if (coplanar ? na.dot(nb) < 0 : max_dist(a, b) > eps || max_dist(b, a) > eps) continue;
      if (!share_edge(a, b)) continue;
      all[root(all, a)] = root(all, b);
      if (coplanar) {
        coplanar_pairs.push_back({a, b});
        continue;
      }
      jointed[a] = jointed[b] = 1;
      skel[root(skel, a)] = root(skel, b);
    }
  }
  for (const auto& [a, b] : coplanar_pairs)
    if (root(skel, a) == root(skel, b) || !jointed[a] || !jointed[b]) skel[root(skel, a)] = root(skel, b);
  auto try_solid = [&](const std::vector<size_t>& M) {
    if (M.size() < 2) return false;
    std::vector<Vec3> corners;
    for (size_t k : M)
      for (const Vec3& q : g.polygon(occluders[k])) corners.push_back(q);
    if (double(M.size()) * double(corners.size()) > 1e8) return false;
    // Convex, wound outward: every corner of the component behind or on every face's plane.
    bool ok = true;
    for (size_t k : M)
      for (size_t c = 0; c < corners.size() && ok; ++c) ok = dist(k, corners[c]) <= eps;
    if (!ok) return false;
    bool flat = true;  // pieces of one plane (a meshed floor): no volume, no hull to build
    for (size_t c = 0; c < corners.size() && flat; ++c) flat = std::abs(dist(M[0], corners[c])) <= eps;
    if (flat) return false;
    // The convex polytope P of the corners and its facets (hull triangles grouped by plane, outward normals).
    std::vector<K::Point_3> pts;
    for (const Vec3& q : corners) pts.emplace_back(q.x(), q.y(), q.z());
    CGAL::Surface_mesh<K::Point_3> hull;
    CGAL::convex_hull_3(pts.begin(), pts.end(), hull);
    if (hull.number_of_faces() < 4) return false;
    struct Facet {
      Vec3 n;
      double o, area, covered;
    };
    std::vector<Facet> facets;
    for (auto f : hull.faces()) {
      std::array<Vec3, 3> t;
      int k = 0;
      for (auto v : CGAL::vertices_around_face(hull.halfedge(f), hull)) {
        const auto& P = hull.point(v);
        if (k < 3) t[size_t(k)] = Vec3(P.x(), P.y(), P.z());
        ++k;
      }
      const Vec3 N = (t[1] - t[0]).cross(t[2] - t[0]);
      const double A2 = N.norm();
      if (!(A2 > 0)) continue;
      const Vec3 u = N / A2;
      const double o = u.dot(t[0]);
      bool found = false;
      for (Facet& F : facets)
        if (F.n.dot(u) >= 1 - 1e-9 && std::abs(F.o - o) <= eps) {
          F.area += 0.5 * A2, found = true;
          break;
        }
      if (!found) facets.push_back({u, o, 0.5 * A2, 0.0});
    }
    // Each face covers part of the facet in its plane; a facet its faces do not cover entirely is open.
    for (size_t k : M) {
      const int p = occluders[k];
      bool found = false;
      for (Facet& F : facets)
        if (F.n.dot(g.normal[size_t(p)]) >= 1 - 1e-6 && std::abs(F.n.dot(g.centroid[size_t(p)]) - F.o) <= eps) {
          F.covered += g.area[size_t(p)], found = true;
          break;
        }
      ok = ok && found;
    }
    std::vector<std::array<double, 4>> open;
    for (const Facet& F : facets) {
      if (F.covered > F.area * (1 + 1e-6)) ok = false;  // overlapping faces: not a surface
      if (F.covered < F.area * (1 - 1e-9)) open.push_back({F.n.x(), F.n.y(), F.n.z(), F.o});
    }
    if (!ok || open.size() == facets.size()) return false;
    const int id = int(out.open.size());
    for (size_t k : M) out.of_patch[size_t(occluders[k])] = id;
    out.open.push_back(std::move(open));
    return true;
  };
  std::vector<std::vector<size_t>> members(n);
  for (size_t k = 0; k < n; ++k) members[root(all, k)].push_back(k);
  std::vector<std::vector<size_t>> retry(n);
  for (const std::vector<size_t>& M : members)
    if (M.size() >= 2 && !try_solid(M))
      for (size_t k : M) retry[root(skel, k)].push_back(k);
  for (const std::vector<size_t>& M : retry)
    if (M.size() >= 2 && M.size() < members[root(all, M[0])].size()) try_solid(M);
  return out;
}

std::vector<int> convex_solids(const mesh::PatchGeometry& g, const std::vector<int>& occluders, double scale) {
  return find_convex_solids(g, occluders, scale).of_patch;
}

bool solid_usable(const std::vector<std::array<double, 4>>& open, std::span<const Vec3> a, std::span<const Vec3> b,
                  double eps) {
  for (const auto& F : open)
    for (std::span<const Vec3> P : {a, b})
      for (const Vec3& q : P)
        if (F[0] * q.x() + F[1] * q.y() + F[2] * q.z() - F[3] > eps) return false;
  return true;
}

namespace {
// The centre of each solid of convex_solids: the mean of its faces' centroids, strictly inside it (convex, not flat).
std::vector<Vec3> solid_centres(const mesh::PatchGeometry& g, const std::vector<int>& solid_of_patch) {
  std::vector<Vec3> centre;
  std::vector<int> faces;
  for (size_t p = 0; p < solid_of_patch.size(); ++p) {
    const int id = solid_of_patch[p];
    if (id < 0) continue;
    if (id >= int(centre.size())) centre.resize(size_t(id) + 1, Vec3::Zero()), faces.resize(size_t(id) + 1, 0);
    centre[size_t(id)] += g.centroid[p];
    ++faces[size_t(id)];
  }
  for (size_t k = 0; k < faces.size(); ++k) centre[k] /= double(faces[k]);
  return centre;
}
}  // namespace

namespace {
// A simple integer polygon (a merged region) cut into convex pieces along diagonals between its corners (CGAL's
// Hertel-Mehlhorn partition: at most four times the fewest pieces), each counter-clockwise; none if the polygon is
// not simple or the pieces do not tile it exactly (their areas, in 128-bit integers, must add up to its area).
std::vector<ClipperLib::Path> convex_pieces(const ClipperLib::Path& path) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;  // integer coordinates below 2^30: exact
  using Traits = CGAL::Partition_traits_2<K>;
  Traits::Polygon_2 poly;
  for (const auto& ip : path) poly.push_back(Traits::Point_2(double(ip.X), double(ip.Y)));
  if (poly.size() < 4 || !poly.is_simple()) return {};
  if (poly.is_clockwise_oriented()) poly.reverse_orientation();
  std::vector<Traits::Polygon_2> pieces;
  CGAL::approx_convex_partition_2(poly.vertices_begin(), poly.vertices_end(), std::back_inserter(pieces), Traits());
  auto twice_area = [](const ClipperLib::Path& q) {
    Int128 a = 0;
    for (size_t k = 0; k < q.size(); ++k) {
      const auto &p0 = q[k], &p1 = q[(k + 1) % q.size()];
      a += Int128(p0.X) * p1.Y - Int128(p1.X) * p0.Y;
    }
    return a;
  };
  std::vector<ClipperLib::Path> out;
  Int128 sum = 0;
  for (const auto& piece : pieces) {
    ClipperLib::Path q;
    for (auto it = piece.vertices_begin(); it != piece.vertices_end(); ++it)
      q.push_back({ClipperLib::cInt(it->x()), ClipperLib::cInt(it->y())});
    for (size_t k = 0; k < q.size(); ++k) {  // convex: no right turn (in integers, exact)
      const auto &a = q[k], &b = q[(k + 1) % q.size()], &c = q[(k + 2) % q.size()];
      if (Int128(b.X - a.X) * (c.Y - b.Y) - Int128(b.Y - a.Y) * (c.X - b.X) < 0) return {};
    }
    const Int128 a = twice_area(q);
    if (a <= 0) return {};
    sum += a;
    out.push_back(std::move(q));
  }
  const Int128 whole = twice_area(path);
  if (sum != (whole < 0 ? -whole : whole)) return {};
  return out;
}
}  // namespace

MergedOccluders merge_coplanar_occluders(const mesh::PatchGeometry& g, const std::vector<int>& occluders,
                                         double scale) {
  MergedOccluders out;
  constexpr int kUnset = -2;  // a region's solid before its members are seen
  out.of_patch.assign(size_t(g.size()), -1);
  if (!(scale > 0)) return out;
  ConvexSolids solids = find_convex_solids(g, occluders, scale);
  out.solid_of_patch = std::move(solids.of_patch);
  out.solid_open = std::move(solids.open);
  out.solid_centre = solid_centres(g, out.solid_of_patch);
  // Occluders grouped by their unoriented plane (mesh::plane_ids), groups in order of first appearance.
  const std::vector<int> plane = mesh::plane_ids(g, occluders, scale);
  std::vector<std::vector<int>> groups;
  for (int p : occluders) {
    const int id = plane[size_t(p)];
    if (id >= int(groups.size())) groups.resize(size_t(id) + 1);
    groups[size_t(id)].push_back(p);
  }
  for (const std::vector<int>& members : groups) {
    if (members.size() < 2) continue;
    Vec3 n = g.normal[members[0]];
    if (n.x() < 0 || (n.x() == 0 && (n.y() < 0 || (n.y() == 0 && n.z() < 0)))) n = -n;
    const Vec3 o = g.centroid[members[0]];
    const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized(), v = n.cross(u);
    double R = 0;
    for (int p : members)
      for (const Vec3& q : g.polygon(p)) R = std::max({R, std::abs(u.dot(q - o)), std::abs(v.dot(q - o))});
    if (!(R > 0)) continue;
    R *= 1 + 1e-6;
    const double S = kSnap / R, inv = R / kSnap;
    ClipperLib::Paths in;
    for (int p : members) {
      ClipperLib::Path path;
      for (const Vec3& q : g.polygon(p))
        path.push_back({ClipperLib::cInt(std::llround(u.dot(q - o) * S)), ClipperLib::cInt(std::llround(v.dot(q - o) * S))});
      if (!ClipperLib::Orientation(path)) ClipperLib::ReversePath(path);
      in.push_back(path);
    }
    ClipperLib::Clipper c;
    c.AddPaths(in, ClipperLib::ptSubject, true);
    ClipperLib::Paths uni;
    c.Execute(ClipperLib::ctUnion, uni, ClipperLib::pftNonZero, ClipperLib::pftNonZero);
    bool hole = false;
    for (const auto& path : uni) hole = hole || !ClipperLib::Orientation(path);
    if (hole || uni.size() >= members.size()) continue;  // holes are not supported; nothing merged: keep patches
    const int first = int(out.polys.size());
    for (const auto& path : uni) {
      std::vector<Vec3> poly;
      for (const auto& ip : path) poly.push_back(o + (double(ip.X) * inv) * u + (double(ip.Y) * inv) * v);
      bool convex = true;
      for (size_t k = 0; k < poly.size() && convex; ++k)
        convex = (poly[(k + 1) % poly.size()] - poly[k]).cross(poly[(k + 2) % poly.size()] - poly[(k + 1) % poly.size()]).dot(n) >= 0;
      std::vector<std::vector<Vec3>> parts;
      if (!convex) {
        auto lift = [&](const ClipperLib::IntPoint& ip) { return o + (double(ip.X) * inv) * u + (double(ip.Y) * inv) * v; };
        for (const ClipperLib::Path& piece : convex_pieces(path)) {
          parts.emplace_back();
          for (const auto& ip : piece) parts.back().push_back(lift(ip));
        }
      }
      out.polys.push_back(std::move(poly));
      out.convex.push_back(convex);
      out.parts.push_back(std::move(parts));
      out.solid.push_back(kUnset);
    }
    // Each member belongs to the region containing its centroid (strictly inside a convex patch's own corners).
    for (size_t k = 0; k < members.size(); ++k) {
      const Vec3& c0 = g.centroid[members[k]];
      const ClipperLib::IntPoint ip{ClipperLib::cInt(std::llround(u.dot(c0 - o) * S)),
                                    ClipperLib::cInt(std::llround(v.dot(c0 - o) * S))};
      for (size_t r = 0; r < uni.size(); ++r)
        if (ClipperLib::PointInPolygon(ip, uni[r]) != 0) {
          out.of_patch[size_t(members[k])] = first + int(r);
          // A region is a face of a convex solid when every member in it is a face of that one solid (a roof among
          // others at its height, a wall in line with its neighbours' along a street).
          int& sol = out.solid[size_t(first) + r];
          const int own = out.solid_of_patch[size_t(members[k])];
          sol = sol == kUnset || sol == own ? own : -1;
          break;
        }
    }
    for (size_t r = size_t(first); r < out.solid.size(); ++r)
      if (out.solid[r] == kUnset) out.solid[r] = -1;
  }
  // Non-convex occluders left as they are (a wall piece cut around a door by the imprint): their own triangles.
  for (int p : occluders) {
    if (out.of_patch[size_t(p)] >= 0 || convex_polygon(g.polygon(p), g.normal[p])) continue;
    auto& parts = out.patch_parts[p];
    for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
      const auto& T = g.triangles[size_t(t)];
      parts.push_back({g.points[T[0]], g.points[T[1]], g.points[T[2]]});
    }
  }
  return out;
}

namespace {
// The plane of o oriented towards the centre of its solid (strictly inside it), if the centre is off the plane by
// more than eps (a flat two-sided plate's is not: its faces are never left out).
void set_inner(Occluder& o, const Vec3& n, const Vec3& centre, double eps) {
  const double d = n.dot(centre - o.poly[0]);
  if (!(std::abs(d) > eps)) return;
  o.inner = d > 0 ? n : Vec3(-n);
  o.inner_offset = o.inner.dot(o.poly[0]);
  o.cull = true;
}
}  // namespace

bool in_plane_of(const PatchData& P, double scale, int p, int i) {
  const double cth = P.nrm[p].dot(P.nrm[i]);
  if (std::abs(cth) < 1 - 1e-9) return false;
  return std::abs(P.offset[p] - (cth > 0 ? P.offset[i] : -P.offset[i])) <= 1e-9 * scale;
}

void pair_occluders(const mesh::PatchGeometry& g, const PatchData& P, double scale, std::span<const int> candidates,
                    int i, int j, const MergedOccluders& merged, const std::vector<std::uint8_t>& convex,
                    std::vector<int>& merged_ids, std::vector<Occluder>& occ) {
  // Patches in one plane (the back of a two-sided face, coincident faces) never block each other's rays.
  auto coplanar = [&](int p, int q) { return in_plane_of(P, scale, p, q); };
  occ.clear();
  merged_ids.clear();
  // A solid with open facets is one only for pairs behind them (solid_usable); decided once per solid and pair.
  std::vector<std::pair<int, bool>> usable;
  auto solid_for_pair = [&](int id) {
    if (id < 0 || merged.solid_open[size_t(id)].empty()) return id;
    for (const auto& [s, u] : usable)
      if (s == id) return u ? id : -1;
    const bool u = solid_usable(merged.solid_open[size_t(id)], g.polygon(i), g.polygon(j), 1e-9 * scale);
    usable.push_back({id, u});
    return u ? id : -1;
  };
  for (int p : candidates) {
    if (coplanar(p, i) || coplanar(p, j)) continue;
    const int m = merged.of_patch.empty() ? -1 : merged.of_patch[size_t(p)];
    if (m >= 0) {
      merged_ids.push_back(m);
      continue;
    }
    Occluder o{g.polygon(p), convex[size_t(p)] != 0};
    if (!o.convex)
      if (const auto it = merged.patch_parts.find(p); it != merged.patch_parts.end()) o.parts = it->second;
    if (!merged.solid_of_patch.empty() && solid_for_pair(merged.solid_of_patch[size_t(p)]) >= 0) {
      o.solid = merged.solid_of_patch[size_t(p)];
      set_inner(o, P.nrm[p], merged.solid_centre[size_t(o.solid)], 1e-9 * scale);
    }
    occ.push_back(o);
  }
  std::sort(merged_ids.begin(), merged_ids.end());
  merged_ids.erase(std::unique(merged_ids.begin(), merged_ids.end()), merged_ids.end());
  for (int m : merged_ids) {
    Occluder o{merged.polys[size_t(m)], merged.convex[size_t(m)] != 0, solid_for_pair(merged.solid[size_t(m)])};
    o.parts = merged.parts[size_t(m)];
    if (o.solid >= 0)
      set_inner(o, mesh::newell_normal(o.poly).normalized(), merged.solid_centre[size_t(o.solid)], 1e-9 * scale);
    occ.push_back(o);
  }
}

}  // namespace lambert::formfactor::detail

namespace lambert::formfactor {

double visible_point_to_polygon(const Vec3& x, const Vec3& n, std::span<const Vec3> polygon,
                                const std::vector<std::vector<Vec3>>& occluders) {
  if (polygon.size() < 3) return 0;
  const Vec3 np = mesh::newell_normal(polygon);
  std::vector<std::vector<Vec3>> kept;
  for (const auto& q : occluders) {  // occluders in the polygon's plane block nothing
    bool in_plane = true;
    const double scale = std::max(1e-300, std::sqrt(np.norm()));
    for (const Vec3& v : q) in_plane = in_plane && std::abs(np.normalized().dot(v - polygon[0])) <= 1e-12 * scale;
    if (!in_plane) kept.push_back(q);
  }
  const auto occ = detail::as_occluders(kept);
  return detail::visible_point_to_polygon(x, n, polygon, occ);
}

PairResult visible_polygon_to_polygon(std::span<const Vec3> Pi, std::span<const Vec3> Pj,
                                      const std::vector<std::vector<Vec3>>& occluders, double tolerance) {
  PairResult r = polygon_to_polygon(Pi, Pj, tolerance);
  if (!(r.F > 0) || occluders.empty()) return r;
  const Vec3 Ni = mesh::newell_normal(Pi), Nj = mesh::newell_normal(Pj);
  const double Ai = 0.5 * Ni.norm(), Aj = 0.5 * Nj.norm();
  const Vec3 ni = Ni.normalized(), nj = Nj.normalized();
  Eigen::AlignedBox3d box;
  for (const Vec3& v : Pi) box.extend(v);
  for (const Vec3& v : Pj) box.extend(v);
  for (const auto& q : occluders)
    for (const Vec3& v : q) box.extend(v);
  const double scale = box.diagonal().norm();
  // Occluders in either patch's plane block nothing (as in the assembly).
  std::vector<std::vector<Vec3>> kept;
  for (const auto& q : occluders) {
    bool in_i = true, in_j = true;
    for (const Vec3& v : q) {
      in_i = in_i && std::abs(ni.dot(v - Pi[0])) <= 1e-9 * scale;
      in_j = in_j && std::abs(nj.dot(v - Pj[0])) <= 1e-9 * scale;
    }
    if (!in_i && !in_j) kept.push_back(q);
  }
  auto occ = detail::as_occluders(kept);
  // Closed convex solids among the occluders, as the assembly finds them (convex_solids).
  if (occ.size() >= 4) {
    std::vector<std::vector<Vec3>> polys;
    for (const auto& o : occ) polys.emplace_back(o.poly.begin(), o.poly.end());
    const auto g = mesh::PatchGeometry::from_polygons(polys);
    std::vector<int> all(occ.size());
    for (size_t k = 0; k < all.size(); ++k) all[k] = int(k);
    const detail::ConvexSolids solids = detail::find_convex_solids(g, all, scale);
    const std::vector<int>& id = solids.of_patch;
    const std::vector<Vec3> centre = detail::solid_centres(g, id);
    for (size_t k = 0; k < occ.size(); ++k) {
      if (id[k] < 0 || !detail::solid_usable(solids.open[size_t(id[k])], Pi, Pj, 1e-9 * scale)) continue;
      occ[k].solid = id[k];
      detail::set_inner(occ[k], g.normal[k], centre[size_t(id[k])], 1e-9 * scale);
    }
  }
  const bool swap = detail::source_is_j(Ai, Aj);  // integrate from the smaller patch, as polygon_to_polygon does
  const auto s = swap ? Pj : Pi, t = swap ? Pi : Pj;
  const Vec3 &ns = swap ? nj : ni, &nt = swap ? ni : nj;
  const double As = swap ? Aj : Ai, At = swap ? Ai : Aj;
  auto scratch = detail::make_exact_scratch();
  const detail::ExactPairResult h = detail::exact_hidden_pair(s, ns, As, detail::convex_polygon(s, ns), t, nt,
                                                              detail::convex_polygon(t, nt), occ, tolerance, scale, *scratch);
  const double Fst = swap ? r.F_reverse : r.F;
  double Fv = Fst, err = 0;
  if (h.outcome == detail::ExactPairResult::kHidden) Fv = 0, err = h.error;
  if (h.outcome == detail::ExactPairResult::kIntegrated) Fv = std::max(0.0, Fst - h.H), err = h.error;
  const double Fts = Fv * As / At;
  r.F = swap ? Fts : Fv;
  r.F_reverse = swap ? Fv : Fts;
  r.error_estimate += swap ? err * As / At : err;
  return r;
}

}  // namespace lambert::formfactor
