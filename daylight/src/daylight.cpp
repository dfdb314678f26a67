// Sky irradiance on patches, glazing, and gathering at points (docs/physics.md §9).
#include "lambert/daylight/daylight.hpp"

#include <boost/polygon/polygon.hpp>
#include <polyclipping/clipper.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>

#include "lambert/formfactor/kernel.hpp"
#include "clip.hpp"

namespace lambert::daylight {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Sample {
  Vec3 p;
  double area;
};

// Stratified points on a patch: each triangle of its triangulation split into s^2 congruent sub-triangles
// (s the smallest with 2-ish x s^2 x triangles >= count), one point per sub-triangle with its area, jittered inside
// it (uniform in a copy shrunk by 0.9 about its centroid, seeded by patch, triangle and index). Not the centroids:
// in a model on a lattice (a voxel city, integer coordinates) the rays from sensors on a lattice to centroids at
// thirds passed exactly through building corners, where float rounding decided them: the same city 1e6 m away
// gave 88 of 1,600 sensors up to 1e-3 different.
void patch_samples(const mesh::PatchGeometry& g, int p, int count, std::vector<Sample>& out) {
  out.clear();
  const int nt = g.triangle_offsets[p + 1] - g.triangle_offsets[p];
  int s = 1;
  while (s * s * nt < count) ++s;
  for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
    const Vec3 &A = g.points[g.triangles[t][0]], &B = g.points[g.triangles[t][1]], &C = g.points[g.triangles[t][2]];
    const double area = 0.5 * (B - A).cross(C - A).norm() / double(s * s);
    const Vec3 u = (B - A) / double(s), v = (C - A) / double(s);
    std::uint64_t seed = splitmix64(std::uint64_t(p) * 0x100000001ull + std::uint64_t(t));
    // A point of the unit triangle (a, b >= 0, a + b <= 1), uniform in its copy shrunk by 0.9 about (1/3, 1/3).
    auto jitter = [&](double& a, double& b) {
      seed = splitmix64(seed);
      a = double(seed >> 11) * 0x1.0p-53;
      seed = splitmix64(seed);
      b = double(seed >> 11) * 0x1.0p-53;
      if (a + b > 1) a = 1 - a, b = 1 - b;
      a = 1.0 / 3 + 0.9 * (a - 1.0 / 3);
      b = 1.0 / 3 + 0.9 * (b - 1.0 / 3);
    };
    for (int i = 0; i < s; ++i)
      for (int j = 0; i + j < s; ++j) {
        double a, b;
        jitter(a, b);
        out.push_back({A + (i + a) * u + (j + b) * v, area});  // upright sub-triangle
        if (i + j + 1 < s) {
          jitter(a, b);
          out.push_back({A + (i + 1 - a) * u + (j + 1 - b) * v, area});  // inverted one
        }
      }
  }
}

namespace bp = boost::polygon;
constexpr double kGridScale = double(1 << 28);  // hemicube face coordinates [-1, 1] -> integers

// One face of the hemicube around n: direction f, in-face axes ea, eb; the face is [-1, 1] x [b0, 1] in
// (p.ea / p.f, p.eb / p.f) (b0 = 0 for the side faces: only directions with n . p >= 0).
struct CubeFace {
  Vec3 f, ea, eb;
  double b0;
};

// The scene's patches merged per plane (coplanar patches united: far fewer, larger polygons to clip).
struct Merged {
  std::vector<std::vector<Vec3>> polygons;  // outer boundaries
  // Per polygon, its holes (wound against its boundary in its plane). Not keyholed into the boundary: after
  // projection and rounding a keyhole's bridge edges can cross (udales_shape.obj's ground, 201 corners, projected
  // onto a wall patch's hemicube face: its signed area 9 % below the area it covers, a loop wound backwards, which
  // the non-zero fill counted as covered).
  std::vector<std::vector<std::vector<Vec3>>> holes;
  std::vector<int> group;                   // polygon -> plane group
  std::vector<int> patch_group;             // patch -> plane group
  int groups = 0;
  // A bounding volume hierarchy over the polygons (boxes in double; leaves of a few polygons), so that a point
  // visits only the polygons in the part of its hemicube that is still open, nearest first.
  struct Node {
    Vec3 lo, hi;
    int first = 0, count = 0;  // leaf: items [first, first + count); inner: count 0, children first and first + 1
  };
  std::vector<Node> nodes;
  std::vector<int> items;  // polygon indices in leaf order

  void build_tree() {
    const int m = int(polygons.size());
    items.resize(size_t(m));
    std::vector<Vec3> lo(static_cast<size_t>(m)), hi(static_cast<size_t>(m)), centre(static_cast<size_t>(m));
    for (int j = 0; j < m; ++j) {
      items[size_t(j)] = j;
      lo[size_t(j)] = hi[size_t(j)] = polygons[size_t(j)][0];
      for (const Vec3& v : polygons[size_t(j)]) {
        lo[size_t(j)] = lo[size_t(j)].cwiseMin(v);
        hi[size_t(j)] = hi[size_t(j)].cwiseMax(v);
      }
      centre[size_t(j)] = 0.5 * (lo[size_t(j)] + hi[size_t(j)]);
    }
    nodes.clear();
    if (m == 0) return;
    nodes.reserve(size_t(2 * m));
    // Median split of the centres along the box's widest axis; children stored side by side.
    struct Task {
      int node, begin, end;
    };
    std::vector<Task> todo{{0, 0, m}};
    nodes.emplace_back();
    while (!todo.empty()) {
      const Task t = todo.back();
      todo.pop_back();
      Node nd;
      nd.lo = lo[size_t(items[size_t(t.begin)])];
      nd.hi = hi[size_t(items[size_t(t.begin)])];
      Vec3 clo = centre[size_t(items[size_t(t.begin)])], chi = clo;
      for (int k = t.begin; k < t.end; ++k) {
        const int j = items[size_t(k)];
        nd.lo = nd.lo.cwiseMin(lo[size_t(j)]);
        nd.hi = nd.hi.cwiseMax(hi[size_t(j)]);
        clo = clo.cwiseMin(centre[size_t(j)]);
        chi = chi.cwiseMax(centre[size_t(j)]);
      }
      int axis = 0;
      (chi - clo).maxCoeff(&axis);
      if (t.end - t.begin <= 4 || !(chi[axis] > clo[axis])) {
        nd.first = t.begin;
        nd.count = t.end - t.begin;
        nodes[size_t(t.node)] = nd;
        continue;
      }
      const int mid = (t.begin + t.end) / 2;
      std::nth_element(items.begin() + t.begin, items.begin() + mid, items.begin() + t.end,
                       [&](int a, int b) { return centre[size_t(a)][axis] < centre[size_t(b)][axis]; });
      nd.first = int(nodes.size());
      nd.count = 0;
      nodes[size_t(t.node)] = nd;
      nodes.emplace_back();
      nodes.emplace_back();
      todo.push_back({nd.first, t.begin, mid});
      todo.push_back({nd.first + 1, mid, t.end});
    }
  }
};

constexpr double kCrack = 4;  // grid units (2^-28 of a hemicube face's half-width)
constexpr int kBatch = 32;  // polygons subtracted from the open region at a time

// A conservative raster of a hemicube face's open region (64 x 64 cells over [-S, S]^2 in grid units): a cell is
// marked when an edge of the open paths passes through it or next to it (one cell's margin) or when the paths enclose
// its centre (even-odd: Clipper's outer boundaries and holes never cross; a cell no edge reaches lies wholly on one
// side of every path). A polygon, or a tree node, whose projection's bounding rectangle meets no marked cell lies in
// directions already covered. In a city the open region's bounding box stays the whole width of a side face (a
// street open to the horizon), so without it every building in that quarter of the sky was projected and clipped.
struct OpenCells {
  static constexpr int kCells = 64, kShift = 23;  // cell width 2^23 grid units: 2^29 / 64
  std::array<std::uint64_t, kCells> row{};
  static int cell(ClipperLib::cInt q) {
    return int(std::clamp<ClipperLib::cInt>((q + ClipperLib::cInt(kGridScale)) >> kShift, 0, kCells - 1));
  }
  void mark(int c0, int c1, int r0, int r1) {
    c0 = std::max(c0, 0), c1 = std::min(c1, kCells - 1), r0 = std::max(r0, 0), r1 = std::min(r1, kCells - 1);
    if (c0 > c1) return;
    const std::uint64_t m = (c1 - c0 == 63 ? ~std::uint64_t(0) : ((std::uint64_t(1) << (c1 - c0 + 1)) - 1)) << c0;
    for (int r = r0; r <= r1; ++r) row[size_t(r)] |= m;
  }
  void build(const ClipperLib::Paths& paths) {
    row.fill(0);
    const double S = kGridScale, w = 2 * S / kCells;
    for (const auto& path : paths)
      for (size_t k = 0; k < path.size(); ++k) {
        const auto &a = path[k], &b = path[(k + 1) % path.size()];
        const int ca = cell(a.X), cb = cell(b.X);
        if (ca == cb) {
          mark(ca - 1, ca + 1, cell(std::min(a.Y, b.Y)) - 1, cell(std::max(a.Y, b.Y)) + 1);
          continue;
        }
        // Column by column: the rows the edge spans within the column's x range, one cell wider each way.
        const double ax = double(a.X), ay = double(a.Y), bx = double(b.X), by = double(b.Y);
        for (int c = std::min(ca, cb); c <= std::max(ca, cb); ++c) {
          const double x0 = std::max(std::min(ax, bx), -S + c * w), x1 = std::min(std::max(ax, bx), -S + (c + 1) * w);
          const double y0 = ay + (by - ay) * (x0 - ax) / (bx - ax), y1 = ay + (by - ay) * (x1 - ax) / (bx - ax);
          const int r0 = int(std::floor((std::min(y0, y1) + S) / w)), r1 = int(std::floor((std::max(y0, y1) + S) / w));
          mark(c - 1, c + 1, r0 - 1, r1 + 1);
        }
      }
    // Centres enclosed (even-odd along the row through them): each edge adds its crossings to the rows whose centre
    // line it crosses (found from its y range, one row of margin each way, then the exact test), instead of every
    // row testing every edge (64 x the edges: 12 % of a city's sky).
    for (auto& row_xs : xs_) row_xs.clear();
    auto centre = [&](int r) { return -S + (r + 0.5) * w; };
    for (const auto& path : paths)
      for (size_t k = 0; k < path.size(); ++k) {
        const auto &a = path[k], &b = path[(k + 1) % path.size()];
        if (a.Y == b.Y) continue;
        const double ylo = double(std::min(a.Y, b.Y)), yhi = double(std::max(a.Y, b.Y));
        const int r0 = std::max(0, int(std::floor((ylo + S) / w - 0.5)) - 1);
        const int r1 = std::min(kCells - 1, int(std::floor((yhi + S) / w - 0.5)) + 1);
        for (int r = r0; r <= r1; ++r) {
          const double y = centre(r);
          if ((double(a.Y) > y) == (double(b.Y) > y)) continue;
          xs_[size_t(r)].push_back(double(a.X) + (double(b.X) - double(a.X)) * (y - double(a.Y)) / (double(b.Y) - double(a.Y)));
        }
      }
    for (int r = 0; r < kCells; ++r) {
      std::vector<double>& xs = xs_[size_t(r)];
      std::sort(xs.begin(), xs.end());
      for (size_t k = 0; k + 1 < xs.size(); k += 2) {
        const int c0 = int(std::ceil((xs[k] + S) / w - 0.5)), c1 = int(std::floor((xs[k + 1] + S) / w - 0.5));
        if (c0 <= c1) mark(c0, c1, r, r);
      }
    }
  }
  std::array<std::vector<double>, kCells> xs_;  // per row: where the open region's edges cross its centre line
  // Some marked cell in the rectangle [u0, u1] x [v0, v1] (grid units).
  bool any(ClipperLib::cInt u0, ClipperLib::cInt u1, ClipperLib::cInt v0, ClipperLib::cInt v1) const {
    const int c0 = cell(u0), c1 = cell(u1), r0 = cell(v0), r1 = cell(v1);
    const std::uint64_t m = (c1 - c0 == 63 ? ~std::uint64_t(0) : ((std::uint64_t(1) << (c1 - c0 + 1)) - 1)) << c0;
    for (int r = r0; r <= r1; ++r)
      if (row[size_t(r)] & m) return true;
    return false;
  }
};

// The open directions from x (no patch in them) by exact clipping: the polygons projected onto the hemicube's
// faces are subtracted from each face (Clipper, integer grid), and what is left is mapped back to directions and
// integrated. skip_group: the plane group left out (the point's own plane), or -1. first_group: null, or per group
// whether it is likely visible from x (a hint: those are subtracted first, all at once; the order changes the time
// and the grid's rounding, ~1e-8, not the result).
Moments open_moments(const Merged& M, const Vec3& x, const Vec3& n, const Vec3& up, int skip_group,
                     const std::vector<char>* first_group) {
  const Vec3 t1 = n.unitOrthogonal(), t2 = n.cross(t1);
  const CubeFace faces[5] = {{n, t1, t2, -1}, {t1, t2, n, 0}, {-t1, t2, n, 0}, {t2, t1, n, 0}, {-t2, t1, n, 0}};
  thread_local std::vector<Vec3> rel, a, b;
  thread_local ClipperLib::Path pts;
  thread_local ClipperLib::Paths covered, sky;
  thread_local ClipperLib::PolyTree tree;
  thread_local ClipperLib::Clipper clipper;
  thread_local std::vector<int> stack;
  thread_local OpenCells open_cells;
  Moments open;
  for (const CubeFace& F : faces) {
    const Vec3 planes[4] = {F.f - F.ea, F.f + F.ea, F.f - F.eb, F.b0 < 0 ? Vec3(F.f + F.eb) : F.eb};
    // Projects a ring onto this face into pts (as wound); false if it misses the face.
    auto project_ring = [&](const std::vector<Vec3>& poly) {
      rel.resize(poly.size());
      for (size_t k = 0; k < poly.size(); ++k) rel[k] = poly[k] - x;
      detail::clip_halfspace(rel, F.f, a);
      for (const Vec3& d : planes) {
        if (a.empty()) break;
        detail::clip_halfspace(a, d, b);
        std::swap(a, b);
      }
      pts.clear();
      if (a.size() < 3) return false;
      for (const Vec3& p : a) {
        const double w = F.f.dot(p);
        if (!(w > 0)) continue;  // the apex itself (x on the patch's boundary)
        const double u = std::clamp(F.ea.dot(p) / w, -1.0, 1.0), v = std::clamp(F.eb.dot(p) / w, F.b0, 1.0);
        pts.emplace_back(ClipperLib::cInt(std::lround(u * kGridScale)), ClipperLib::cInt(std::lround(v * kGridScale)));
      }
      return pts.size() >= 3;
    };
    // Adds polygon j projected onto this face to `covered`: its boundary counter-clockwise, its holes clockwise
    // (whichever side of the patch x sees), so that with positive fill the clip paths cover every point some
    // polygon covers, once however many overlap, and not a polygon's holes unless another covers them. pts keeps the
    // boundary. False if the boundary misses the face.
    auto add = [&](int j) {
      if (!project_ring(M.polygons[size_t(j)])) return false;
      const bool flip = !ClipperLib::Orientation(pts);
      if (flip) ClipperLib::ReversePath(pts);
      covered.push_back(pts);
      for (const auto& hole : M.holes[size_t(j)]) {
        const ClipperLib::Path boundary = std::move(pts);
        if (project_ring(hole)) {
          if (flip) ClipperLib::ReversePath(pts);
          covered.push_back(pts);
        }
        pts = boundary;
      }
      return true;
    };
    const ClipperLib::cInt S = ClipperLib::cInt(kGridScale), v0 = ClipperLib::cInt(F.b0 * kGridScale);
    sky.assign(1, ClipperLib::Path{{-S, v0}, {S, v0}, {S, S}, {-S, S}});
    open_cells.build(sky);
    // The bounding box of what is still open (grid units), and the planes through x bounding the directions in it.
    ClipperLib::cInt lo_u = -S, hi_u = S, lo_v = v0, hi_v = S;
    Vec3 cone[4];
    auto update_bounds = [&] {
      lo_u = lo_v = std::numeric_limits<ClipperLib::cInt>::max();
      hi_u = hi_v = std::numeric_limits<ClipperLib::cInt>::min();
      for (const auto& path : sky)
        for (const auto& q : path) {
          lo_u = std::min(lo_u, q.X);
          hi_u = std::max(hi_u, q.X);
          lo_v = std::min(lo_v, q.Y);
          hi_v = std::max(hi_v, q.Y);
        }
      // One grid unit wider than the box: rounding cannot drop a polygon reaching into it.
      const double u0 = double(lo_u - 1) / kGridScale, u1 = double(hi_u + 1) / kGridScale;
      const double w0 = double(lo_v - 1) / kGridScale, w1 = double(hi_v + 1) / kGridScale;
      cone[0] = F.ea - u0 * F.f;  // d . cone[k] >= 0 for every direction d in the box (F.f . d > 0)
      cone[1] = u1 * F.f - F.ea;
      cone[2] = F.eb - w0 * F.f;
      cone[3] = w1 * F.f - F.eb;
    };
    int batched = 0;  // polygons in `covered`
    auto subtract = [&] {
      batched = 0;
      if (covered.empty()) return;
      detail::difference(clipper, sky, covered, tree);
      // Seams dropped: an open piece narrower on average (2 area / perimeter) than kCrack grid units is where the
      // patches' rounded corners meet (walls, floor and ceiling), not open sky; left in, the seams kept every
      // room's hemicube open and its whole cone visited. Such a piece goes with the holes inside it; a hole (what
      // is covered) is never dropped, however thin.
      sky.clear();
      auto keep = [&](auto&& self, const ClipperLib::PolyNode* outer) -> void {
        const ClipperLib::Path& path = outer->Contour;
        double perimeter = 0;
        for (size_t k = 0; k < path.size(); ++k) {
          const auto &p = path[k], &q = path[(k + 1) % path.size()];
          perimeter += std::hypot(double(q.X - p.X), double(q.Y - p.Y));
        }
        if (2 * std::abs(ClipperLib::Area(path)) < kCrack * perimeter) return;
        sky.push_back(path);
        for (const ClipperLib::PolyNode* hole : outer->Childs) {
          sky.push_back(hole->Contour);
          for (const ClipperLib::PolyNode* island : hole->Childs) self(self, island);
        }
      };
      for (const ClipperLib::PolyNode* outer : tree.Childs) keep(keep, outer);
      covered.clear();
      if (!sky.empty()) update_bounds(), open_cells.build(sky);
    };
    auto in_box = [&] {  // pts' bounding box meets the open region's
      ClipperLib::cInt plo_u = pts[0].X, phi_u = plo_u, plo_v = pts[0].Y, phi_v = plo_v;
      for (const auto& q : pts) {
        plo_u = std::min(plo_u, q.X);
        phi_u = std::max(phi_u, q.X);
        plo_v = std::min(plo_v, q.Y);
        phi_v = std::max(phi_v, q.Y);
      }
      return !(phi_u <= lo_u || plo_u >= hi_u || phi_v <= lo_v || plo_v >= hi_v) &&
             open_cells.any(plo_u, phi_u, plo_v, phi_v);
    };
    auto skipped = [&](int j, bool hinted_pass) {
      const int grp = M.group[size_t(j)];
      if (grp == skip_group) return true;
      const bool first = first_group && (*first_group)[size_t(grp)] != 0;
      return first != hinted_pass;
    };
    covered.clear();
    // The likely-visible polygons first, all at once (they cover most of a room's hemicube).
    if (first_group) {
      for (int j = 0; j < int(M.polygons.size()); ++j)
        if (!skipped(j, true)) add(j);
      subtract();
    }
    if (sky.empty()) continue;
    update_bounds();
    // Then the others, nearest first, from the tree: a subtree whose box lies wholly outside the open region's
    // cone of directions (or behind the face) is not visited; kBatch polygons are subtracted at a time, after which
    // the open region and its cone shrink.
    auto outside = [&](const Merged::Node& nd) {
      auto reaches = [&](const Vec3& m) {  // max over the box of m . (corner - x) >= 0
        double s = 0;
        for (int k = 0; k < 3; ++k) s += std::max(m[k] * (nd.lo[k] - x[k]), m[k] * (nd.hi[k] - x[k]));
        return s >= 0;
      };
      if (!reaches(F.f)) return true;
      for (const Vec3& m : cone)
        if (!reaches(m)) return true;
      // The box's corners projected onto the face (all in front of x: the box's projection lies in their bounding
      // rectangle): no open cell there, nothing in the box can be seen.
      double u0 = INFINITY, u1 = -INFINITY, w0 = INFINITY, w1 = -INFINITY;
      for (int k = 0; k < 8; ++k) {
        const Vec3 q = Vec3(k & 1 ? nd.hi.x() : nd.lo.x(), k & 2 ? nd.hi.y() : nd.lo.y(), k & 4 ? nd.hi.z() : nd.lo.z()) - x;
        const double w = F.f.dot(q);
        if (!(w > 1e-9 * q.norm())) return false;
        const double u = F.ea.dot(q) / w, v = F.eb.dot(q) / w;
        u0 = std::min(u0, u), u1 = std::max(u1, u), w0 = std::min(w0, v), w1 = std::max(w1, v);
      }
      auto grid = [](double t) { return ClipperLib::cInt(std::clamp(t, -2.0, 2.0) * kGridScale); };
      return !open_cells.any(grid(u0) - 1, grid(u1) + 1, grid(w0) - 1, grid(w1) + 1);
    };
    auto distance2 = [&](const Merged::Node& nd) { return (x.cwiseMax(nd.lo).cwiseMin(nd.hi) - x).squaredNorm(); };
    stack.clear();
    if (!M.nodes.empty()) stack.push_back(0);
    while (!stack.empty() && !sky.empty()) {
      const Merged::Node& nd = M.nodes[size_t(stack.back())];
      stack.pop_back();
      if (outside(nd)) continue;
      if (nd.count > 0) {
        for (int k = nd.first; k < nd.first + nd.count; ++k) {
          const int j = M.items[size_t(k)];
          if (skipped(j, false)) continue;
          const size_t before = covered.size();
          if (!add(j)) continue;
          if (!in_box()) {
            covered.resize(before);
            continue;
          }
          if (++batched >= kBatch) subtract();
        }
        continue;
      }
      const int l = nd.first, r = nd.first + 1;
      const bool left_nearer = distance2(M.nodes[size_t(l)]) <= distance2(M.nodes[size_t(r)]);
      stack.push_back(left_nearer ? r : l);  // the nearer is popped first
      stack.push_back(left_nearer ? l : r);
    }
    subtract();
    // What is left open: outer boundaries counter-clockwise, holes clockwise (Clipper's output). polygon_moments
    // integrates a polygon's cone whatever its orientation, so holes are subtracted.
    for (const auto& path : sky) {
      if (path.size() < 3) continue;
      rel.clear();
      for (const auto& q : path)
        rel.push_back(x + F.f + (double(q.X) / kGridScale) * F.ea + (double(q.Y) / kGridScale) * F.eb);
      const Moments m = polygon_moments(x, n, up, rel);
      if (ClipperLib::Orientation(path)) {
        open += m;
      } else {
        open.cos_above -= m.cos_above;
        open.cos_up_above -= m.cos_up_above;
        open.cos_below -= m.cos_below;
      }
    }
  }
  return open;
}

}  // namespace

struct Gatherer::Impl {
  // The frame the clipping works in: a building turned in its site's coordinates is turned back
  // (mesh::alignment) and moved to its centre, so that the hemicubes' faces lie along its walls (turned by 30
  // degrees, the floor plan's sky took 1.13 -> 1.73 s, clipping slanted polygons). Queries come in the given frame:
  // x -> R (x - centre), directions -> R d. The moments are integrals over directions, the same in either frame.
  const mesh::PatchGeometry& given;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Vec3 centre = Vec3::Zero();
  std::unique_ptr<mesh::PatchGeometry> own;  // the turned copy, if any
  const mesh::PatchGeometry& g;               // what the clipping and the rays see: *own or given
  static std::unique_ptr<mesh::PatchGeometry> turned(const mesh::PatchGeometry& in, Eigen::Matrix3d& R, Vec3& c) {
    R = mesh::alignment(in);
    if (R.isIdentity(0)) return nullptr;
    Eigen::AlignedBox3d box;
    for (const Vec3& v : in.points) box.extend(v);
    c = box.center();
    return std::make_unique<mesh::PatchGeometry>(mesh::moved_and_turned(in, c, &R));
  }
  Vec3 point(const Vec3& x) const { return own ? Vec3(R * (x - centre)) : x; }
  Vec3 direction(const Vec3& d) const { return own ? Vec3(R * d) : d; }
  std::vector<std::vector<Sample>> samples;
  std::vector<double> offset;  // n_p . c_p
  std::unique_ptr<formfactor::Visibility> vis;
  bool occluders = false;  // some patch can block a segment between scene points
  double eps = 0, ray_offset = 0;
  mutable std::atomic<long long> rays{0};
  Merged merged;

  // Groups coplanar patches (either orientation) and unites each group in its plane (integer coordinates of
  // 2^-28 of the scene's size: edges move by at most ~1e-8 of it).
  void merge_planes(double diag) {
    // Patches grouped by their unoriented plane (mesh::plane_ids); each group's normal (largest component
    // positive) and a point of it.
    std::vector<int> all(size_t(g.size()));
    for (int p = 0; p < g.size(); ++p) all[size_t(p)] = p;
    merged.patch_group = mesh::plane_ids(g, all, diag);
    std::vector<std::vector<int>> members;
    std::vector<Vec3> gn;
    std::vector<Vec3> go;
    for (int p = 0; p < g.size(); ++p) {
      const int G = merged.patch_group[size_t(p)];
      if (G >= int(members.size())) {
        members.resize(size_t(G) + 1);
        Vec3 nn = g.normal[p];
        int big = 0;
        for (int c = 1; c < 3; ++c)
          if (std::abs(nn[c]) > std::abs(nn[big])) big = c;
        if (nn[big] < 0) nn = -nn;
        gn.push_back(nn);
        go.push_back(g.centroid[p]);
      }
      members[size_t(G)].push_back(p);
    }
    merged.groups = int(members.size());
    const double scale = double(1 << 28) / diag;
    for (size_t G = 0; G < members.size(); ++G) {
      if (members[G].size() == 1) {
        const auto poly = g.polygon(members[G][0]);
        merged.polygons.emplace_back(poly.begin(), poly.end());
        merged.holes.emplace_back();
        merged.group.push_back(int(G));
        continue;
      }
      const Vec3 e1 = gn[G].unitOrthogonal(), e2 = gn[G].cross(e1), o = go[G];
      bp::polygon_set_data<int> set;
      for (int p : members[G]) {
        std::vector<bp::point_data<int>> pts;
        for (const Vec3& v : g.polygon(p))
          pts.emplace_back(int(std::lround(e1.dot(v - o) * scale)), int(std::lround(e2.dot(v - o) * scale)));
        bp::polygon_data<int> pd;
        pd.set(pts.begin(), pts.end());
        set.insert(pd);
      }
      std::vector<bp::polygon_with_holes_data<int>> out;
      set.get(out);
      // A ring back in 3D, exactly in the plane, wound counter-clockwise about gn (boundary) or clockwise (hole).
      auto ring = [&](auto begin, auto end, bool boundary) {
        std::vector<Vec3> poly;
        double twice_area = 0;
        for (auto it = begin; it != end; ++it) {
          auto next = std::next(it) == end ? begin : std::next(it);
          twice_area += double(bp::x(*it)) * double(bp::y(*next)) - double(bp::x(*next)) * double(bp::y(*it));
          const Vec3 q = o + (double(bp::x(*it)) / scale) * e1 + (double(bp::y(*it)) / scale) * e2;
          poly.push_back(q + (gn[G].dot(o) - gn[G].dot(q)) * gn[G]);
        }
        if ((twice_area > 0) != boundary) std::reverse(poly.begin(), poly.end());
        return poly;
      };
      for (const auto& pd : out) {
        std::vector<Vec3> poly = ring(pd.begin(), pd.end(), true);
        if (poly.size() < 3) continue;
        std::vector<std::vector<Vec3>> hs;
        for (auto h = pd.begin_holes(); h != pd.end_holes(); ++h) {
          std::vector<Vec3> hole = ring(h->begin(), h->end(), false);
          if (hole.size() >= 3) hs.push_back(std::move(hole));
        }
        merged.polygons.push_back(std::move(poly));
        merged.holes.push_back(std::move(hs));
        merged.group.push_back(int(G));
      }
    }
  }

  // The plane group to skip (that of `ignore`, or -1), and per group whether any member is likely visible.
  int skip_group(int ignore) const { return ignore >= 0 ? merged.patch_group[size_t(ignore)] : -1; }
  void first_flags(const std::vector<char>& likely, std::vector<char>& first) const {
    first.assign(size_t(merged.groups), 0);
    for (int j = 0; j < g.size(); ++j)
      if (likely[size_t(j)]) first[size_t(merged.patch_group[size_t(j)])] = 1;
  }

  Impl(const mesh::PatchGeometry& geometry, int count)
      : given(geometry), own(turned(geometry, R, centre)), g(own ? *own : geometry) {
    samples.resize(size_t(g.size()));
    offset.resize(size_t(g.size()));
    Eigen::AlignedBox3d box;
    for (const Vec3& v : g.points) box.extend(v);
    const double diag = box.isEmpty() ? 1.0 : box.diagonal().norm();
    eps = 1e-9 * diag;
    ray_offset = 1e-7 * diag;
    for (int p = 0; p < g.size(); ++p) {
      patch_samples(g, p, count, samples[size_t(p)]);
      offset[size_t(p)] = g.normal[p].dot(g.centroid[p]);
    }
    occluders = !formfactor::potential_occluders(g).empty();
    merge_planes(diag);
    merged.build_tree();
    vis = formfactor::make_embree_visibility(g);
  }

  bool coplanar(int p, int q) const {
    const double c = g.normal[p].dot(g.normal[q]);
    if (std::abs(c) < 1 - 1e-9) return false;
    return std::abs(offset[size_t(p)] - (c > 0 ? offset[size_t(q)] : -offset[size_t(q)])) <= eps;
  }

  // Kernel-weighted fraction of patch j visible from x (rays from x, nudged along n, to j's samples).
  double visible_fraction(const Vec3& x, const Vec3& n, int j, int ignore) const {
    const auto& S = samples[size_t(j)];
    thread_local std::vector<Vec3> from, to;
    thread_local std::vector<std::uint8_t> hidden;
    thread_local std::vector<double> w;
    from.assign(S.size(), x + ray_offset * n);
    to.resize(S.size());
    hidden.assign(S.size(), 0);
    w.resize(S.size());
    double wsum = 0;
    for (size_t k = 0; k < S.size(); ++k) {
      to[k] = S[k].p;
      const Vec3 d = S[k].p - x;
      const double r2 = d.squaredNorm();
      w[k] = r2 > 0 ? std::max(0.0, n.dot(d)) * std::abs(g.normal[j].dot(d)) / (r2 * r2) * S[k].area : 0.0;
      wsum += w[k];
    }
    if (!(wsum > 0)) {
      for (size_t k = 0; k < S.size(); ++k) w[k] = S[k].area;
      wsum = 0;
      for (double v : w) wsum += v;
    }
    vis->occluded(from, to, ignore, j, hidden);
    rays += (long long)S.size();
    double seen = 0;
    for (size_t k = 0; k < S.size(); ++k)
      if (!hidden[k]) seen += w[k];
    return seen / wsum;
  }
};

Gatherer::Gatherer(const mesh::PatchGeometry& geometry, int rays) : impl_(std::make_unique<Impl>(geometry, std::max(1, rays))) {}
Gatherer::~Gatherer() = default;
long long Gatherer::rays_cast() const { return impl_->rays.load(); }

Gatherer::Result Gatherer::gather(const Vec3& x_given, const Vec3& n_given, const Vec3& up_given,
                                  const ColorField* radiance, int ignore) const {
  const Impl& I = *impl_;
  const mesh::PatchGeometry& g = I.g;
  const Vec3 x = I.point(x_given), n = I.direction(n_given), up = I.direction(up_given);
  Result r;
  // Occlusion is possible when some patch can block a segment from x: x behind some patch's plane, or patches
  // that can block segments between scene points.
  bool rays = I.occluders;
  for (int k = 0; k < g.size() && !rays; ++k)
    if (k != ignore && g.normal[k].dot(x) - I.offset[size_t(k)] < -I.eps && !(ignore >= 0 && I.coplanar(k, ignore)))
      rays = true;
  Moments covered;
  thread_local std::vector<char> first;  // patches x sees (a hint for the clipping)
  first.assign(size_t(g.size()), 0);
  for (int j = 0; j < g.size(); ++j) {
    if (j == ignore || (ignore >= 0 && I.coplanar(j, ignore))) continue;
    const bool lit = radiance && g.normal[j].dot(x) - I.offset[size_t(j)] > 0;
    if (rays && !lit) continue;  // only its coverage matters, and the clipping below takes it
    const auto poly = g.polygon(j);
    if (rays) {
      // Its light only (the clipping takes its coverage): nothing unless part of it lies in x's front hemisphere.
      const double F = formfactor::point_to_polygon(x, n, poly);
      if (!(F > 0)) continue;
      const double V = I.visible_fraction(x, n, j, ignore);
      first[size_t(j)] = V > 0;
      if (V > 0) r.from_patches += (V * kPi * F) * radiance->row(j).transpose().array();
      continue;
    }
    const Moments m = polygon_moments(x, n, up, poly);
    if (!(m.cos_above + m.cos_below > 0)) continue;  // outside x's front hemisphere
    covered += m;
    if (lit) {
      const double F = formfactor::point_to_polygon(x, n, poly);
      r.from_patches += (kPi * F) * radiance->row(j).transpose().array();
    }
  }
  if (rays) {
    thread_local std::vector<char> first_group;
    I.first_flags(first, first_group);
    r.open = open_moments(I.merged, x, n, up, I.skip_group(ignore), &first_group);
    r.clipped = true;
  } else {
    const Moments h = hemisphere_moments(n, up);
    r.open.cos_above = h.cos_above - covered.cos_above;
    r.open.cos_up_above = h.cos_up_above - covered.cos_up_above;
    r.open.cos_below = h.cos_below - covered.cos_below;
  }
  return r;
}

Moments Gatherer::open(const Vec3& x_given, const Vec3& n_given, const Vec3& up_given, int ignore,
                       const std::vector<char>& likely_visible) const {
  const Impl& I = *impl_;
  const Vec3 x = I.point(x_given), n = I.direction(n_given), up = I.direction(up_given);
  if (likely_visible.empty()) return open_moments(I.merged, x, n, up, I.skip_group(ignore), nullptr);
  thread_local std::vector<char> first_group;
  I.first_flags(likely_visible, first_group);
  return open_moments(I.merged, x, n, up, I.skip_group(ignore), &first_group);
}

const mesh::PatchGeometry& Gatherer::geometry() const { return impl_->given; }

namespace {

// Where a patch's sky is evaluated: its centroid when that lies on the patch, else (a non-convex patch, such as
// an L-shaped floor piece left around furniture, whose centroid lies in the notch, possibly inside the furniture)
// the centroid of its largest triangle.
Vec3 sky_point(const mesh::PatchGeometry& g, int p) {
  const Vec3& c = g.centroid[p];
  int largest = -1;
  double largest_area = -1;
  for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
    const Vec3 &A = g.points[g.triangles[t][0]], &B = g.points[g.triangles[t][1]], &C = g.points[g.triangles[t][2]];
    const Vec3 nn = (B - A).cross(C - A);
    const double twice = nn.norm();
    if (!(twice > 0)) continue;
    // Barycentric coordinates of c (in the patch's plane) from the signed areas of the sub-triangles.
    const double u = (C - B).cross(c - B).dot(nn), v = (A - C).cross(c - C).dot(nn), w = (B - A).cross(c - A).dot(nn);
    const double tol = -1e-9 * twice * twice;
    if (u >= tol && v >= tol && w >= tol) return c;
    if (twice > largest_area) largest_area = twice, largest = t;
  }
  if (largest < 0) return c;
  const auto& T = g.triangles[largest];
  return (g.points[T[0]] + g.points[T[1]] + g.points[T[2]]) / 3;
}

}  // namespace

std::vector<double> patch_sky_irradiance(const mesh::Scene& scene, const Sky& sky, const Gatherer& gather,
                                         PatchSkyStats* stats, const VisibilityHint& likely_visible,
                                         const std::function<void(double)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const mesh::PatchGeometry& g = scene.geometry;
  const int N = g.size();
  LAMBERT_CHECK(&gather.geometry() == &g, "patch_sky_irradiance: the Gatherer is not over this scene's geometry");
  std::vector<double> E(size_t(N), 0.0);
  std::vector<double> open(size_t(N), 0.0);  // the cosine-weighted share of the front hemisphere that sees no patch
  std::atomic<long long> points{0}, done{0};
  // A patch whose front lies inside a closed surface (a shut room; a room of a glazed building: the panes close it)
  // sees nothing at infinity: its sky is 0, exactly, without clipping. The clipping alone would leave the grid's
  // seams (~1e-8) and, for a non-convex patch whose centroid lies off the patch (an L-shaped floor piece around
  // furniture), measure from a point that may see out through hidden space.
  const std::vector<char> enclosed = formfactor::enclosed_patches(g);
  tbb::parallel_for(tbb::blocked_range<int>(0, N, 1), [&](const tbb::blocked_range<int>& range) {
    std::vector<char> likely;  // empty: no hint
    if (likely_visible) likely.assign(static_cast<size_t>(N), 0);
    for (int i = range.begin(); i < range.end(); ++i) {
      if (enclosed[size_t(i)]) {
        if (progress) progress(double(++done) / double(N));
        continue;
      }
      ++points;
      if (likely_visible) likely_visible(i, likely);
      const Moments m = gather.open(sky_point(g, i), g.normal[i], sky.up, i, likely);
      E[size_t(i)] = irradiance(sky, m);
      open[size_t(i)] = (m.cos_above + m.cos_below) / kPi;
      if (progress) progress(double(++done) / double(N));
    }
  });
  PatchSkyStats st;
  st.points = points.load();
  for (char e : enclosed) st.enclosed += e;
  for (int i = 0; i < N; ++i) {
    double& e = E[size_t(i)];
    if (e < 0) {  // round-off of the clipping where (almost) no sky is seen: counted, set to 0
      ++st.negative_set_to_zero;
      st.most_negative = std::min(st.most_negative, e);
      e = 0;
    }
    if (e > 1e-6 * sky.horizontal_irradiance()) ++st.patches_lit;
    if (open[size_t(i)] > 0.5) {
      const double c = g.normal[i].dot(sky.up);
      if (c > 0.5) st.area_facing_up += g.area[i];
      if (c < -0.5) st.area_facing_down += g.area[i];
    }
    if ((scene.materials[scene.material[i]].transmittance > 0).any()) ++st.glazing_patches;
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = st;
  return E;
}

std::vector<double> glazing_outside_irradiance(const mesh::Scene& scene, const Sky& sky, const Gatherer& gather) {
  const mesh::PatchGeometry& g = scene.geometry;
  std::vector<double> E(size_t(g.size()), 0.0);
  std::vector<int> glazing;
  for (int p = 0; p < g.size(); ++p)
    if ((scene.materials[scene.material[p]].transmittance > 0).any()) glazing.push_back(p);
  tbb::parallel_for(size_t(0), glazing.size(), [&](size_t k) {
    const int p = glazing[k];
    std::vector<Sample> S;
    patch_samples(g, p, 16, S);
    double sum = 0, area = 0;
    for (const Sample& s : S) {
      const Gatherer::Result r = gather.gather(s.p, -g.normal[p], sky.up, nullptr, p);
      sum += s.area * irradiance(sky, r.open);
      area += s.area;
    }
    E[size_t(p)] = area > 0 ? sum / area : 0.0;
  });
  return E;
}

ColorField daylight_emission(const mesh::Scene& scene, const std::vector<double>& sky_irradiance,
                             const std::vector<double>& outside_irradiance) {
  ColorField Le = scene.emission_field();
  for (int p = 0; p < scene.patches(); ++p) {
    const mesh::Material& m = scene.materials[scene.material[p]];
    const double es = p < int(sky_irradiance.size()) ? sky_irradiance[size_t(p)] : 0.0;
    const double eo = p < int(outside_irradiance.size()) ? outside_irradiance[size_t(p)] : 0.0;
    for (int c = 0; c < 3; ++c) Le(p, c) += (m.reflectance[c] * es + m.transmittance[c] * eo) / kPi;
  }
  return Le;
}

std::vector<SensorResult> evaluate_sensors(const std::vector<Sensor>& sensors, const Gatherer& gather,
                                           const ColorField& radiance, const Sky* sky, const Vec3& up,
                                           const std::function<void(double)>& progress) {
  std::vector<SensorResult> out(sensors.size());
  std::atomic<size_t> done{0};
  tbb::parallel_for(size_t(0), sensors.size(), [&](size_t k) {
    const Gatherer::Result r = gather.gather(sensors[k].position, sensors[k].normal, up, &radiance, -1);
    SensorResult& s = out[k];
    s.from_patches = r.from_patches;
    s.sky = sky ? irradiance(*sky, r.open) : 0.0;
    s.irradiance = s.from_patches + s.sky;
    const size_t d = ++done;
    if (progress) progress(double(d) / double(sensors.size()));
  });
  return out;
}

}  // namespace lambert::daylight
