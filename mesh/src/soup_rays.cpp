#include "soup_rays.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "prepare_internal.hpp"

namespace lambert::mesh::detail {

// A bounding volume hierarchy over the soup's triangles, in double precision, and the watertight ray-triangle
// test of Woop, Benthin and Wald (2013, "Watertight ray/triangle intersection", JCGT 2(1)): a ray through an edge
// or a corner shared by triangles hits at least one of them, so a ray cannot leak through a closed surface
// between its triangles. This replaced CGAL's AABB tree (first_intersection), whose per-triangle constructions
// made the rays half of mesh::prepare's time on a building (30k faces: 4.9 s of orientation rays); Embree, which
// formfactor uses, is single precision and lives in formfactor only.
struct SoupRays::Impl {
  struct Node {
    Vec3 lo, hi;    // box, padded by a few units of round-off
    int first = 0;  // leaf: first triangle; inner: index of the second child (the first is this node + 1)
    int count = 0;  // leaf: triangles (> 0); inner: 0
    int axis = 0;   // inner: the axis the children were split along
  };
  std::vector<std::array<Vec3, 3>> tris;  // in leaf order
  std::vector<int> face;                  // soup face of each triangle
  std::vector<Node> nodes;
  double pad = 0;

  void build(std::vector<std::array<Vec3, 3>> in, std::vector<int> in_face);
  int build_node(std::vector<int>& idx, int begin, int end, const std::vector<Vec3>& centre,
                 const std::vector<std::array<Vec3, 2>>& box, int depth);
};

namespace {
constexpr int kLeaf = 4;   // triangles per leaf at most, unless they cannot be separated
constexpr int kBins = 16;  // binned surface-area heuristic

double half_area(const Vec3& lo, const Vec3& hi) {
  const Vec3 e = (hi - lo).cwiseMax(0.0);
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}
}  // namespace

void SoupRays::Impl::build(std::vector<std::array<Vec3, 3>> in, std::vector<int> in_face) {
  const int n = static_cast<int>(in.size());
  if (n == 0) return;
  std::vector<Vec3> centre(n);
  std::vector<std::array<Vec3, 2>> box(n);
  double largest = 0;
  for (int i = 0; i < n; ++i) {
    const auto& t = in[i];
    box[i] = {t[0].cwiseMin(t[1]).cwiseMin(t[2]), t[0].cwiseMax(t[1]).cwiseMax(t[2])};
    centre[i] = 0.5 * (box[i][0] + box[i][1]);
    largest = std::max({largest, box[i][0].cwiseAbs().maxCoeff(), box[i][1].cwiseAbs().maxCoeff()});
  }
  // Boxes padded by 64 units of round-off of the largest coordinate: the slab test's rounding cannot miss a box
  // that a hit lies in (the triangle test decides the hit).
  pad = 64 * std::numeric_limits<double>::epsilon() * largest + std::numeric_limits<double>::min();
  std::vector<int> idx(n);
  for (int i = 0; i < n; ++i) idx[i] = i;
  nodes.reserve(2 * static_cast<size_t>(n) / kLeaf + 1);
  build_node(idx, 0, n, centre, box, 0);
  tris.resize(n);
  face.resize(n);
  for (int i = 0; i < n; ++i) {
    tris[i] = in[idx[i]];
    face[i] = in_face[idx[i]];
  }
}

int SoupRays::Impl::build_node(std::vector<int>& idx, int begin, int end, const std::vector<Vec3>& centre,
                               const std::vector<std::array<Vec3, 2>>& box, int depth) {
  const int self = static_cast<int>(nodes.size());
  nodes.emplace_back();
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  Vec3 clo = lo, chi = hi;
  for (int i = begin; i < end; ++i) {
    lo = lo.cwiseMin(box[idx[i]][0]);
    hi = hi.cwiseMax(box[idx[i]][1]);
    clo = clo.cwiseMin(centre[idx[i]]);
    chi = chi.cwiseMax(centre[idx[i]]);
  }
  nodes[self].lo = lo - Vec3::Constant(pad);
  nodes[self].hi = hi + Vec3::Constant(pad);
  const int n = end - begin;
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const double extent = chi[axis] - clo[axis];
  if (n <= kLeaf || !(extent > 0)) {
    nodes[self].first = begin;
    nodes[self].count = n;
    return self;
  }
  // Binned SAH along the widest axis of the centres; the median when deep (a bound on the recursion).
  int mid = -1;
  if (depth < 48) {
    std::array<int, kBins> count{};
    std::array<Vec3, kBins> blo, bhi;
    blo.fill(Vec3::Constant(std::numeric_limits<double>::infinity()));
    bhi.fill(Vec3::Constant(-std::numeric_limits<double>::infinity()));
    auto bin_of = [&](int t) { return std::min(kBins - 1, int(kBins * (centre[t][axis] - clo[axis]) / extent)); };
    for (int i = begin; i < end; ++i) {
      const int b = bin_of(idx[i]);
      ++count[b];
      blo[b] = blo[b].cwiseMin(box[idx[i]][0]);
      bhi[b] = bhi[b].cwiseMax(box[idx[i]][1]);
    }
    std::array<double, kBins> right_cost{};
    Vec3 rlo = blo[kBins - 1], rhi = bhi[kBins - 1];
    int rn = 0;
    for (int b = kBins - 1; b > 0; --b) {
      rlo = rlo.cwiseMin(blo[b]);
      rhi = rhi.cwiseMax(bhi[b]);
      rn += count[b];
      right_cost[b] = rn ? rn * half_area(rlo, rhi) : 0;
    }
    Vec3 llo = blo[0], lhi = bhi[0];
    int ln = 0, best = -1;
    double best_cost = std::numeric_limits<double>::infinity();
    for (int b = 1; b < kBins; ++b) {
      llo = llo.cwiseMin(blo[b - 1]);
      lhi = lhi.cwiseMax(bhi[b - 1]);
      ln += count[b - 1];
      if (ln == 0 || ln == n) continue;
      const double cost = ln * half_area(llo, lhi) + right_cost[b];
      if (cost < best_cost) best_cost = cost, best = b;
    }
    if (best > 0) {
      mid = static_cast<int>(std::partition(idx.begin() + begin, idx.begin() + end,
                                            [&](int t) { return bin_of(t) < best; }) -
                             idx.begin());
    }
  }
  if (mid < 0) {
    mid = begin + n / 2;
    std::nth_element(idx.begin() + begin, idx.begin() + mid, idx.begin() + end,
                     [&](int a, int b) { return centre[a][axis] < centre[b][axis]; });
  }
  build_node(idx, begin, mid, centre, box, depth + 1);
  const int second = build_node(idx, mid, end, centre, box, depth + 1);
  nodes[self].first = second;
  nodes[self].axis = axis;
  return self;
}

SoupRays::SoupRays(const PolygonSoup& s, const std::vector<char>& include) : impl_(std::make_unique<Impl>()) {
  const int nf = static_cast<int>(s.faces.size());
  normal_.assign(nf, Vec3::Zero());
  tris_of_.resize(nf);
  cum_area_.resize(nf);
  std::vector<std::array<Vec3, 3>> all;
  std::vector<int> all_face;
  for (int k = 0; k < nf; ++k) {
    if (!include[k]) continue;
    const auto poly = corners(s, k);
    const Vec3 nn = newell_normal(poly);
    if (!(nn.norm() > 0)) continue;
    normal_[k] = nn.normalized();
    double cum = 0;
    for (const auto& t : triangulate_polygon(poly, normal_[k])) {
      const std::array<Vec3, 3> tri{poly[t[0]], poly[t[1]], poly[t[2]]};
      const double area = 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).norm();
      if (!(area > 0)) continue;  // degenerate (collinear corners)
      all.push_back(tri);
      all_face.push_back(k);
      tris_of_[k].push_back(tri);
      cum += area;
      cum_area_[k].push_back(cum);
    }
  }
  impl_->build(std::move(all), std::move(all_face));
}

SoupRays::~SoupRays() = default;

SoupRays::Hit SoupRays::first(const Vec3& o, const Vec3& d, const std::function<bool(int)>& skip, double t_max) const {
  Hit h;
  const Impl& m = *impl_;
  if (m.nodes.empty()) return h;
  // The ray's shear (Woop et al.): kz its largest component, the triangle's corners moved to the ray's frame.
  int kz = 0;
  d.cwiseAbs().maxCoeff(&kz);
  int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
  if (d[kz] < 0) std::swap(kx, ky);
  const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
  const Vec3 inv(1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z());
  const bool neg[3] = {inv.x() < 0, inv.y() < 0, inv.z() < 0};
  constexpr double kGrow = 1 + 8 * std::numeric_limits<double>::epsilon();

  double best_t = t_max;
  int best = -1;
  auto test = [&](int i) {
    const auto& t = m.tris[i];
    const Vec3 a = t[0] - o, b = t[1] - o, c = t[2] - o;
    const double ax = a[kx] - sx * a[kz], ay = a[ky] - sy * a[kz];
    const double bx = b[kx] - sx * b[kz], by = b[ky] - sy * b[kz];
    const double cx = c[kx] - sx * c[kz], cy = c[ky] - sy * c[kz];
    double u = cx * by - cy * bx, v = ax * cy - ay * cx, w = bx * ay - by * ax;
    if (u == 0 || v == 0 || w == 0) {  // on an edge in double: decided in extended precision
      using L = long double;
      u = double(L(cx) * L(by) - L(cy) * L(bx));
      v = double(L(ax) * L(cy) - L(ay) * L(cx));
      w = double(L(bx) * L(ay) - L(by) * L(ax));
    }
    if ((u < 0 || v < 0 || w < 0) && (u > 0 || v > 0 || w > 0)) return;
    const double det = u + v + w;
    if (det == 0) return;  // the ray lies in the triangle's plane
    const double tt = (u * sz * a[kz] + v * sz * b[kz] + w * sz * c[kz]) / det;
    if (!(tt >= 0) || tt > best_t || (tt == best_t && best >= 0 && i > best)) return;
    if (skip(m.face[i])) return;
    best_t = tt;
    best = i;
  };

  // The stack holds at most one entry per level below the root: depth <= 48 + log2(triangles) + 1 < 128.
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const int ni = stack[--top];
    const Impl::Node& nd = m.nodes[ni];
    double t0 = 0, t1 = best_t;
    for (int a = 0; a < 3; ++a) {
      // NaN (0 * inf, the ray in a slab's plane) is the second operand of min/max: it leaves the interval as it is.
      const double near = ((neg[a] ? nd.hi[a] : nd.lo[a]) - o[a]) * inv[a];
      const double far = ((neg[a] ? nd.lo[a] : nd.hi[a]) - o[a]) * inv[a] * kGrow;
      t0 = std::max(t0, near);
      t1 = std::min(t1, far);
    }
    if (t0 > t1) continue;
    if (nd.count > 0) {
      for (int i = nd.first; i < nd.first + nd.count; ++i) test(i);
      continue;
    }
    // The nearer child first (popped first): pushed last.
    const int left = ni + 1, right = nd.first;
    if (neg[nd.axis]) {
      stack[top++] = left;
      stack[top++] = right;
    } else {
      stack[top++] = right;
      stack[top++] = left;
    }
  }
  if (best < 0) return h;
  h.face = m.face[best];
  h.t = best_t;
  h.front = d.dot(normal_[h.face]) < 0;
  return h;
}

Vec3 SoupRays::sample(int k, std::mt19937_64& rng) const {
  std::uniform_real_distribution<double> u(0, 1);
  const double u0 = u(rng), u1 = u(rng), u2 = u(rng);
  return sample(k, u0, u1, u2);
}

Vec3 SoupRays::sample(int k, double u0, double u1, double u2) const {
  const auto& cum = cum_area_[k];
  const double a = u0 * cum.back();
  const size_t i = std::min(cum.size() - 1, size_t(std::upper_bound(cum.begin(), cum.end(), a) - cum.begin()));
  double r1 = u1, r2 = u2;
  if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
  const auto& t = tris_of_[k][i];
  return t[0] + r1 * (t[1] - t[0]) + r2 * (t[2] - t[0]);
}

Vec3 cosine_direction(const Vec3& n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const double u0 = u(rng), u1 = u(rng);
  return cosine_direction(n, u0, u1);
}

Vec3 cosine_direction(const Vec3& n, double u0, double u1) {
  const double r = std::sqrt(u0), phi = 2 * std::numbers::pi * u1;
  const Vec3 a = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 b = n.cross(a);
  return (r * std::cos(phi) * a + r * std::sin(phi) * b + std::sqrt(std::max(0.0, 1 - r * r)) * n).normalized();
}

}  // namespace lambert::mesh::detail
