// The adaptive refinement's local error indicators (see indicators.hpp).
#include "lambert/refine/indicators.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <numeric>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "lambert/formfactor/kernel.hpp"

namespace lambert::refine {
namespace {

struct Box {
  Vec3 lo, hi;
};

Box box_of(std::span<const Vec3> poly) {
  Box b{poly[0], poly[0]};
  for (const Vec3& v : poly) {
    b.lo = b.lo.cwiseMin(v);
    b.hi = b.hi.cwiseMax(v);
  }
  return b;
}

// Do some edge of a and some edge of b lie on one line and overlap by more than eps?
bool share_edge_segment(std::span<const Vec3> a, std::span<const Vec3> b, double eps) {
  const size_t na = a.size(), nb = b.size();
  for (size_t i = 0; i < na; ++i) {
    const Vec3& p0 = a[i];
    const Vec3 d = a[(i + 1) % na] - p0;
    const double len = d.norm();
    if (!(len > eps)) continue;
    const Vec3 u = d / len;
    for (size_t j = 0; j < nb; ++j) {
      const Vec3 q0 = b[j] - p0, q1 = b[(j + 1) % nb] - p0;
      const double t0 = q0.dot(u), t1 = q1.dot(u);
      if ((q0 - t0 * u).norm() > eps || (q1 - t1 * u).norm() > eps) continue;  // not on a's line
      const double overlap = std::min(len, std::max(t0, t1)) - std::max(0.0, std::min(t0, t1));
      if (overlap > eps) return true;
    }
  }
  return false;
}

// 3 points per triangle of patch p, at barycentric (2/3, 1/6, 1/6) and its permutations: strictly
// inside the patch even when it is not convex, and spread towards its corners.
void sample_points(const mesh::PatchGeometry& g, int p, std::vector<Vec3>& out) {
  out.clear();
  for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
    const Vec3 &a = g.points[g.triangles[t][0]], &b = g.points[g.triangles[t][1]], &c = g.points[g.triangles[t][2]];
    out.push_back((4 * a + b + c) / 6);
    out.push_back((a + 4 * b + c) / 6);
    out.push_back((a + b + 4 * c) / 6);
  }
}

// The scale every indicator is relative to: the largest reflected radiance L - Le (over patches and
// channels); 0 when nothing is reflected (then there is no resolution error to find).
double reflected_scale(const mesh::Scene& scene, const ColorField& radiance) {
  if (scene.patches() == 0) return 0;
  return (radiance - scene.emission_field()).maxCoeff();
}

}  // namespace

std::vector<double> jump_indicator(const mesh::Scene& scene, const ColorField& radiance) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  const double scale = reflected_scale(scene, radiance);
  if (!(scale > 0)) return ind;
  const auto& g = scene.geometry;

  std::vector<Box> boxes(n);
  Box all = box_of(g.polygon(0));
  for (int p = 0; p < n; ++p) {
    boxes[p] = box_of(g.polygon(p));
    all.lo = all.lo.cwiseMin(boxes[p].lo);
    all.hi = all.hi.cwiseMax(boxes[p].hi);
  }
  const double eps = 1e-9 * std::max((all.hi - all.lo).norm(), 1e-300);
  // Same smooth surface: normals within 30 degrees (VertexSplit's default crease), so that the jump
  // across a room's corner (orientation, not resolution) does not count.
  const double cos_crease = std::cos(mesh::VertexSplit::kDefaultCreaseDeg * std::numbers::pi / 180.0);

  // Sweep along x over boxes sorted by their low x.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return boxes[a].lo.x() < boxes[b].lo.x(); });
  for (int ia = 0; ia < n; ++ia) {
    const int p = order[ia];
    for (int ib = ia + 1; ib < n; ++ib) {
      const int q = order[ib];
      if (boxes[q].lo.x() > boxes[p].hi.x() + eps) break;
      if ((boxes[q].lo.array() > boxes[p].hi.array() + eps).any() ||
          (boxes[p].lo.array() > boxes[q].hi.array() + eps).any())
        continue;
      if (scene.material[p] != scene.material[q]) continue;
      if (g.normal[p].dot(g.normal[q]) < cos_crease) continue;
      if (!share_edge_segment(g.polygon(p), g.polygon(q), eps)) continue;
      const double jump = (radiance.row(p) - radiance.row(q)).cwiseAbs().maxCoeff() / scale;
      ind[p] = std::max(ind[p], jump);
      ind[q] = std::max(ind[q], jump);
    }
  }
  return ind;
}

std::vector<double> direct_indicator(const mesh::Scene& scene, const ColorField& radiance,
                                     const formfactor::Visibility* caster) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  const double scale = reflected_scale(scene, radiance);
  if (!(scale > 0)) return ind;
  const auto& g = scene.geometry;
  const ColorField Le = scene.emission_field();
  std::vector<int> emitters;
  for (int e = 0; e < n; ++e)
    if (Le.row(e).maxCoeff() > 0) emitters.push_back(e);
  if (emitters.empty()) return ind;
  std::unique_ptr<formfactor::Visibility> own;
  if (!caster) {
    const std::vector<int> occ = formfactor::potential_occluders(g);
    if (!occ.empty()) own = formfactor::make_embree_visibility(g, occ);
    caster = own.get();  // null: nothing can block anything
  }
  std::vector<std::vector<Vec3>> targets(n);
  for (int e : emitters) sample_points(g, e, targets[e]);

  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& r) {
    std::vector<Vec3> xs, from;
    std::vector<std::uint8_t> hidden;
    for (int p = r.begin(); p < r.end(); ++p) {
      const RGB rho = scene.reflectance(p);
      if (!(rho.maxCoeff() > 0)) continue;
      sample_points(g, p, xs);
      RGB lo = RGB::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (const Vec3& x : xs) {
        RGB D = RGB::Zero();
        for (int e : emitters) {
          if (e == p) continue;
          const double F = formfactor::point_to_polygon(x, g.normal[p], g.polygon(e));
          if (!(F > 0)) continue;
          double visible = 1;
          if (caster) {
            const auto& to = targets[e];
            from.assign(to.size(), x);
            hidden.assign(to.size(), 0);
            caster->occluded(from, to, p, e, hidden);
            long blocked = 0;
            for (auto h : hidden) blocked += h;
            visible = 1 - static_cast<double>(blocked) / static_cast<double>(to.size());
          }
          D += F * visible * Le.row(e).transpose().array();
        }
        D *= rho;
        lo = lo.min(D);
        hi = hi.max(D);
      }
      ind[p] = (hi - lo).maxCoeff() / scale;
    }
  });
  return ind;
}

std::vector<double> gather_indicator(const mesh::Scene& scene, const formfactor::DenseMatrixOperator& F,
                                     const ColorField& radiance) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  LAMBERT_CHECK(F.size() == n, "gather_indicator: matrix of " + std::to_string(F.size()) + " patches for " + std::to_string(n));
  if (n == 0) return ind;
  const auto& g = scene.geometry;
  const double scale = reflected_scale(scene, radiance);
  if (!(scale > 0)) return ind;
  const auto& M = F.matrix();
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& r) {
    for (int p = r.begin(); p < r.end(); ++p) {
      const RGB rho = scene.reflectance(p);
      if (!(rho.maxCoeff() > 0)) continue;
      const auto poly = g.polygon(p);
      double diam = 0;
      for (size_t a = 0; a < poly.size(); ++a)
        for (size_t b = a + 1; b < poly.size(); ++b) diam = std::max(diam, (poly[a] - poly[b]).norm());
      RGB sum = RGB::Zero();
      for (int j = 0; j < n; ++j) {
        const double f = M(p, j);
        if (!(f > 0)) continue;
        const double d = (g.centroid[j] - g.centroid[p]).norm();
        const double variation = d > diam ? diam / d : 1.0;
        sum += f * variation * radiance.row(j).transpose().array();
      }
      ind[p] = (rho * sum).maxCoeff() / scale;
    }
  });
  return ind;
}

}  // namespace lambert::refine
