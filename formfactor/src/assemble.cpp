// Dense assembly: tiles of (source block, target block) pairs, each unordered pair computed once.
#include "lambert/formfactor/assemble.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <new>
#include <string>

#include "batch.hpp"
#include "internal.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "shaft.hpp"

namespace lambert::formfactor {
namespace {

using detail::kMethodCount;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr int kBlock = 64;  // tile edge: 64 x 64 pairs, both matrix blocks stay in L2 while written

// Structure-of-arrays copy of the patch data for the SIMD kernels, padded for 8-wide loads.
struct Prepared {
  detail::PatchData P;
  std::vector<std::vector<double>> store;
  std::array<detail::Rule2D, 9> square_rule, triangle_rule;  // reference rules for m = 6, 8
  std::vector<detail::Box> box;
  detail::SoA soa{};

  double* column(size_t n) {
    store.emplace_back(n + detail::kBatchPad, 0.0);
    return store.back().data();
  }
  explicit Prepared(const mesh::PatchGeometry& g) : P(detail::prepare(g)) {
    const int n = P.n;
    store.reserve(40);
    auto fill = [&](auto f) {
      double* c = column(n);
      for (int p = 0; p < n; ++p) c[p] = f(p);
      return c;
    };
    soa.cx = fill([&](int p) { return P.c[p].x(); });
    soa.cy = fill([&](int p) { return P.c[p].y(); });
    soa.cz = fill([&](int p) { return P.c[p].z(); });
    soa.nx = fill([&](int p) { return P.nrm[p].x(); });
    soa.ny = fill([&](int p) { return P.nrm[p].y(); });
    soa.nz = fill([&](int p) { return P.nrm[p].z(); });
    soa.off = fill([&](int p) { return P.offset[p]; });
    soa.area = fill([&](int p) { return P.area[p]; });
    soa.rho = fill([&](int p) { return P.rho[p]; });
    for (int c = 0; c < 4; ++c) {
      auto corner = [&, c](int p, int axis) {
        const auto poly = g.polygon(p);
        return poly[std::min<size_t>(c, poly.size() - 1)][axis];
      };
      soa.qx[c] = fill([&](int p) { return corner(p, 0); });
      soa.qy[c] = fill([&](int p) { return corner(p, 1); });
      soa.qz[c] = fill([&](int p) { return corner(p, 2); });
    }
    for (int k = 0; k < 6; ++k) soa.M[k] = fill([&](int p) { return P.M[p][k]; });
    soa.fast = fill([&](int p) { return P.kind[p] <= 2 ? 1.0 : 0.0; });
    soa.sym = fill([&](int p) { return P.kind[p] == 1 ? 1.0 : 0.0; });
    for (int m : {6, 8}) {  // larger rules are mapped per pair from cached reference rules (no locking)
      square_rule[m] = detail::gauss_square(m);
      triangle_rule[m] = detail::gauss_triangle(m);
    }
    soa.eps = P.scene_eps;
    box.resize(n);
    for (int p = 0; p < n; ++p)
      for (const Vec3& v : g.polygon(p)) box[p].add(v);
  }
};

std::uint64_t mix(std::uint64_t x) {  // splitmix64
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double jitter(std::uint64_t seed, int k) {  // in [0.05, 0.95]: samples stay inside their stratum
  return 0.05 + 0.9 * double(mix(seed + std::uint64_t(k)) >> 11) * 0x1.0p-53;
}

// n stratified points on patch p (grid of strata in the patch's own parameterisation, jittered inside each
// stratum, so no point lies on the patch boundary).
void sample_patch(const mesh::PatchGeometry& g, const detail::PatchData& P, int p, int k1, int k2,
                  std::uint64_t seed, std::vector<Vec3>& out) {
  out.clear();
  const auto poly = g.polygon(p);
  const int n = k1 * k2;
  if (P.kind[p] == 1 || P.kind[p] == 2) {
    for (int a = 0; a < k1; ++a)
      for (int b = 0; b < k2; ++b) {
        const int k = a * k2 + b;
        const double s = (a + jitter(seed, 2 * k)) / k1, t = (b + jitter(seed, 2 * k + 1)) / k2;
        out.push_back((1 - s) * (1 - t) * poly[0] + s * (1 - t) * poly[1] + s * t * poly[2] + (1 - s) * t * poly[3]);
      }
    return;
  }
  // Triangles of the patch by cumulative area; within a triangle, the square-to-triangle map.
  const int t0 = g.triangle_offsets[p], t1 = g.triangle_offsets[p + 1];
  for (int a = 0; a < k1; ++a)
    for (int b = 0; b < k2; ++b) {
      const int k = a * k2 + b;
      double u = (k + jitter(seed, 2 * k)) / n * P.area[p];
      int t = t0;
      double at = 0;
      for (; t < t1; ++t) {
        const auto& T = g.triangles[t];
        at = 0.5 * (g.points[T[1]] - g.points[T[0]]).cross(g.points[T[2]] - g.points[T[0]]).norm();
        if (u <= at || t == t1 - 1) break;
        u -= at;
      }
      const double su = std::sqrt(std::clamp(u / at, 0.0, 1.0)), v = jitter(seed, 2 * k + 1);
      const auto& T = g.triangles[t];
      out.push_back((1 - su) * g.points[T[0]] + su * (1 - v) * g.points[T[1]] + su * v * g.points[T[2]]);
    }
}

// n stratified points on a planar polygon with unit normal `normal` (the part of a patch in front of another
// patch's plane): triangles by cumulative area, the square-to-triangle map inside each.
void sample_polygon(std::span<const Vec3> poly, const Vec3& normal, int n, std::uint64_t seed, std::vector<Vec3>& out) {
  out.clear();
  std::vector<std::array<int, 3>> tris = mesh::triangulate_polygon(poly, normal);
  if (tris.empty())  // a clipped non-convex patch with bridge edges: fan, weighted by unsigned area
    for (int k = 1; k + 1 < int(poly.size()); ++k) tris.push_back({0, k, k + 1});
  std::vector<double> area(tris.size());
  double total = 0;
  for (size_t t = 0; t < tris.size(); ++t) {
    const auto& T = tris[t];
    area[t] = 0.5 * (poly[T[1]] - poly[T[0]]).cross(poly[T[2]] - poly[T[0]]).norm();
    total += area[t];
  }
  if (!(total > 0)) return;
  for (int k = 0; k < n; ++k) {
    double u = (k + jitter(seed, 2 * k)) / n * total;
    size_t t = 0;
    for (; t + 1 < tris.size() && u > area[t]; ++t) u -= area[t];
    const double su = std::sqrt(std::clamp(area[t] > 0 ? u / area[t] : 0.0, 0.0, 1.0)), v = jitter(seed, 2 * k + 1);
    const auto& T = tris[t];
    out.push_back((1 - su) * poly[T[0]] + su * (1 - v) * poly[T[1]] + su * v * poly[T[2]]);
  }
}

// True if some corner of patch a lies strictly behind the plane of patch b (relative tolerance 1e-12).
bool behind_plane(const mesh::PatchGeometry& g, int a, int b) {
  const Vec3& n = g.normal[b];
  const double offset = n.dot(g.centroid[b]), eps = 1e-12 * std::sqrt(std::max(g.area[a], g.area[b]));
  for (const Vec3& p : g.polygon(a))
    if (n.dot(p) - offset < -eps) return true;
  return false;
}

struct Counters {
  long long culled = 0, shaft_culled = 0, ray_tested = 0, rays = 0, over_tolerance = 0, reused = 0, fixed = 0;
  double tile_seconds = 0, visibility_seconds = 0;  // thread time in tiles, and in their visibility step
  std::array<long long, kMethodCount> by_method{};
  long long outside = 0;
  double recip = 0;
  std::vector<double> row_sum;
};

struct TileBuffers {
  std::vector<std::int8_t> code;
  std::vector<int> ps, pt, pslot, ss, st, pair_i, pair_j, cs, ct, cslot;
  std::vector<double> lx, ly, lz, lw;  // outer-rule lanes: point and weight
  std::vector<std::uint8_t> pair_swap;
  std::vector<double> out, val, row, rowj;
  std::vector<int> rest_j;
  std::vector<Vec3> xs, ys, from, to;
  std::vector<std::uint8_t> hidden;
  std::vector<double> fx;
  int blocker = -1;  // the occluder that blocked the last shaft tested (OccluderTree::may_block's cache)
};

class Assembler {
 public:
  Assembler(const mesh::PatchGeometry& g, const Options& o, Stats& st) : g_(g), o_(o), st_(st) {}
  DenseMatrixOperator run();

 private:
  void tile(int bi, int bj, TileBuffers& b, Counters& c);
  void fixed_rule(int i0, int i1, int j0, int j1, bool diagonal, Counters& c);
  bool reused(int i, int j) const { return !old_.empty() && old_[i] >= 0 && old_[j] >= 0; }
  double visible_ratio(int s, int t, int m, TileBuffers& b, Counters& c) const;

  const mesh::PatchGeometry& g_;
  const Options& o_;
  Stats& st_;
  std::unique_ptr<Prepared> prep_;
  DenseMatrixOperator::Matrix* F_ = nullptr;
  std::shared_ptr<const Visibility> caster_;
  detail::OccluderTree tree_;
  bool occlusion_ = false;
  int rays_ = 1;  // rays per pair (times m^4 for pairs carrying a large share of a row)
  std::vector<int> old_;                        // Options::reuse->previous_index, or empty
  std::vector<int> rule_off_;                   // Rule::Gauss: points of patch p in [rule_off_[p], rule_off_[p+1])
  std::vector<std::array<double, 4>> rule_pts_;  // x, y, z, weight (summing to 1 per patch)
};

// Rule::Point and Rule::Gauss: each pair from the smaller patch (F of the larger by reciprocity in step 5).
void Assembler::fixed_rule(int i0, int i1, int j0, int j1, bool diagonal, Counters& c) {
  const detail::PatchData& P = prep_->P;
  auto& F = *F_;
  for (int i = i0; i < i1; ++i) {
    if (diagonal) F(i, i) = 0;
    for (int j = diagonal ? i + 1 : j0; j < j1; ++j) {
      if (reused(i, j)) {
        F(i, j) = o_.reuse->previous->matrix()(old_[i], old_[j]);
        ++c.reused;
        continue;
      }
      const bool swap = P.area[j] < P.area[i];
      const int src = swap ? j : i, tgt = swap ? i : j;
      double f = 0;
      if (o_.rule == Rule::Point) {
        const Vec3 d = P.c[tgt] - P.c[src];
        const double r2 = d.squaredNorm(), ci = P.nrm[src].dot(d), cj = -P.nrm[tgt].dot(d);
        if (ci > 0 && cj > 0 && r2 > 0) f = ci * cj * P.area[tgt] / (detail::kPi * r2 * r2);
      } else {
        const auto poly = g_.polygon(tgt);
        for (int k = rule_off_[src]; k < rule_off_[src + 1]; ++k) {
          const auto& X = rule_pts_[k];
          f += X[3] * point_to_polygon(Vec3(X[0], X[1], X[2]), P.nrm[src], poly);
        }
      }
      if (f > 0) {
        ++c.fixed;
      } else {
        ++c.culled;
        ++c.by_method[detail::kCulled];
      }
      F(i, j) = swap ? f * P.area[src] / P.area[tgt] : f;  // A_i F_ij = A_j F_ji
    }
  }
}

double Assembler::visible_ratio(int s, int t, int m, TileBuffers& b, Counters& c) const {
  // R rays between R stratified points on each patch, paired by a random permutation ("padding"): every
  // ray has its own source and target stratum, so both patches are sampled R-fold, not sqrt(R)-fold as
  // with all pairs of sqrt(R) points per side (same rays, several times smaller error on shadow edges).
  const int R = rays_ * m * m * m * m;
  int k1 = std::max(1, int(std::floor(std::sqrt(double(R))))), k2 = std::max(1, R / k1);
  const std::uint64_t seed = mix(std::uint64_t(s) * 0x100000001ull + std::uint64_t(t));
  const Vec3 &ns = g_.normal[s], &nt = g_.normal[t];
  // Patches crossing each other's planes exchange light only between the parts in front of each other:
  // sample those parts, or a thin visible strip may get no sample at all (and a pair seen through a wall
  // would be taken as unoccluded).
  const bool straddle = behind_plane(g_, s, t) || behind_plane(g_, t, s);
  if (straddle) {
    const double eps = 1e-12 * std::sqrt(std::max(g_.area[s], g_.area[t]));
    std::vector<Vec3> ps, pt;
    detail::clip_front(g_.polygon(s), nt, nt.dot(g_.centroid[t]), eps, ps);
    detail::clip_front(g_.polygon(t), ns, ns.dot(g_.centroid[s]), eps, pt);
    sample_polygon(ps, ns, k1 * k2, seed, b.xs);
    sample_polygon(pt, nt, k1 * k2, mix(seed), b.ys);
  } else {
    sample_patch(g_, prep_->P, s, k1, k2, seed, b.xs);
    sample_patch(g_, prep_->P, t, k1, k2, mix(seed), b.ys);
  }
  // Pairing: a seeded Fisher-Yates permutation of the target points.
  const size_t count = std::min(b.xs.size(), b.ys.size());
  for (size_t k = count; k > 1; --k) std::swap(b.ys[k - 1], b.ys[mix(seed + 7 * k) % k]);
  // Rays between stratified points of the two patches; each sample pair is weighted by the kernel
  // cos cos / r^2, so the ratio estimates int int K V / int int K. Pairs of points that do not see each
  // other's front (straddling patches) carry no weight and cast no ray.
  b.from.clear();
  b.to.clear();
  b.fx.clear();
  for (size_t k = 0; k < count; ++k) {
    const Vec3 &x = b.xs[k], &y = b.ys[k], d = y - x;
    const double cx = ns.dot(d), cy = -nt.dot(d);
    if (!(cx > 0 && cy > 0)) continue;
    const double r2 = d.squaredNorm();
    b.from.push_back(x);
    b.to.push_back(y);
    b.fx.push_back(cx * cy / (r2 * r2));
  }
  b.hidden.assign(b.from.size(), 0);
  if (!b.from.empty()) caster_->occluded(b.from, b.to, s, t, b.hidden);
  c.rays += (long long)b.from.size();
  double num = 0, den = 0;
  for (size_t k = 0; k < b.from.size(); ++k) {
    den += b.fx[k];
    if (!b.hidden[k]) num += b.fx[k];
  }
  // No sample pair sees the other even after clipping: the parts in front of each other have (numerically)
  // no area, so nothing is exchanged. Never 1 here: that let light through walls (a leak).
  if (!(den > 0)) return 0.0;
  return num / den;  // <= 1: num sums a subset of den's non-negative terms in the same order
}

void Assembler::tile(int bi, int bj, TileBuffers& b, Counters& c) {
  const Prepared& pr = *prep_;
  const detail::SoA& s = pr.soa;
  const detail::BatchKernels& K = detail::batch_kernels();
  const int n = pr.P.n;
  const int i0 = bi * kBlock, i1 = std::min(n, i0 + kBlock), j0 = bj * kBlock, j1 = std::min(n, j0 + kBlock);
  const double tol = o_.tolerance;
  const double* area = pr.P.area.data();
  auto& F = *F_;
  b.code.resize(kBlock + 16);
  b.lx.clear(), b.ly.clear(), b.lz.clear(), b.lw.clear(), b.ps.clear(), b.pt.clear(), b.pslot.clear();
  b.ss.clear(), b.st.clear();
  b.cs.clear(), b.ct.clear(), b.cslot.clear();
  b.pair_i.clear(), b.pair_j.clear(), b.pair_swap.clear();
  long long counts[2] = {0, 0};
  b.rest_j.resize(kBlock + 16);
  // 1. Classification, with tiers 0/1 evaluated in the same pass straight into row i of the matrix (F_ij),
  // over runs of pairs not copied from a previous assembly.
  auto classify_run = [&](int i, int js, int je) {
    const int nrest = K.classify(s, i, js, je, tol, &F(i, js), b.code.data(), b.rest_j.data(), counts);
    for (int r = 0; r < nrest; ++r) {
      const int code = b.code[r], j = b.rest_j[r];
      if (code == detail::kCodeSlow) {
        b.ss.push_back(i);
        b.st.push_back(j);
        continue;
      }
      const bool swap = code > detail::kCodeSwap;
      const int t = (code & 15) - 1;
      const int src = swap ? j : i, tgt = swap ? i : j;
      const int k = int(b.pair_i.size());
      b.pair_i.push_back(i);
      b.pair_j.push_back(j);
      b.pair_swap.push_back(swap);
      ++c.by_method[detail::tier_method(t)];
      if (t == 1) {
        b.cs.push_back(src);
        b.ct.push_back(tgt);
        b.cslot.push_back(k);
        continue;
      }
      const int m = detail::kTierM[t];
      // Lanes for this pair: resize once, then fill (push_back per field was measurable here).
      const auto poly = g_.polygon(src);
      const size_t cnt = m <= 4 ? size_t(pr.P.rule_off[m][src + 1] - pr.P.rule_off[m][src])
                                : (poly.size() == 3 ? pr.triangle_rule[m].w.size() : pr.square_rule[m].w.size());
      const size_t base = b.lw.size();
      for (auto* v : {&b.lx, &b.ly, &b.lz, &b.lw}) v->resize(base + cnt);
      b.ps.resize(base + cnt, src);
      b.pt.resize(base + cnt, tgt);
      b.pslot.resize(base + cnt, k);
      auto lane = [&](size_t q, const Vec3& X, double w) {
        b.lx[base + q] = X.x();
        b.ly[base + q] = X.y();
        b.lz[base + q] = X.z();
        b.lw[base + q] = w;
      };
      if (m <= 4) {
        const int p0 = pr.P.rule_off[m][src];
        for (size_t q = 0; q < cnt; ++q) {
          const auto& X = pr.P.rule_pts[m][p0 + q];
          lane(q, Vec3(X[0], X[1], X[2]), X[3]);
        }
      } else if (poly.size() == 3) {
        // Map the reference rule onto the source (a triangle or a convex quad on this path).
        const detail::Rule2D& rule = pr.triangle_rule[m];
        for (size_t q = 0; q < cnt; ++q)
          lane(q, poly[0] + rule.xi[q][0] * (poly[1] - poly[0]) + rule.xi[q][1] * (poly[2] - poly[0]), rule.w[q]);
      } else {
        const detail::Rule2D& rule = pr.square_rule[m];
        const Vec3& ns = pr.P.nrm[src];
        double total = 0;
        for (size_t q = 0; q < cnt; ++q) {
          const double u = rule.xi[q][0], v = rule.xi[q][1];
          const Vec3 du = (1 - v) * (poly[1] - poly[0]) + v * (poly[2] - poly[3]);
          const Vec3 dv = (1 - u) * (poly[3] - poly[0]) + u * (poly[2] - poly[1]);
          const double w = rule.w[q] * du.cross(dv).dot(ns);
          lane(q, (1 - u) * (1 - v) * poly[0] + u * (1 - v) * poly[1] + u * v * poly[2] + (1 - u) * v * poly[3], w);
          total += w;
        }
        for (size_t q = 0; q < cnt; ++q) b.lw[base + q] /= total;
      }
    }
  };
  if (o_.rule != Rule::Adaptive) {
    fixed_rule(i0, i1, j0, j1, bi == bj, c);
    b.pair_i.clear();
    b.ss.clear();
  }
  for (int i = i0; i < i1 && o_.rule == Rule::Adaptive; ++i) {
    const int js = bi == bj ? i + 1 : j0;
    if (bi == bj) F(i, i) = 0;
    if (js >= j1) continue;
    if (old_.empty() || old_[i] < 0) {
      classify_run(i, js, j1);
      continue;
    }
    for (int j = js; j < j1;) {
      if (old_[j] >= 0) {
        F(i, j) = (*o_.reuse->previous).matrix()(old_[i], old_[j]);
        ++c.reused;
        ++j;
        continue;
      }
      int je = j + 1;
      while (je < j1 && old_[je] < 0) ++je;
      classify_run(i, j, je);
      j = je;
    }
  }
  c.culled += counts[0];
  c.by_method[detail::kCulled] += counts[0];
  c.by_method[detail::kFarField] += counts[1];
  // 2. Tier 1 (analytic from the centroid) and the outer Gauss rules, 8 lanes at a time.
  if (!b.pair_i.empty()) {
    b.val.assign(b.pair_i.size(), 0.0);
    if (!b.cs.empty()) {
      b.out.resize(b.cs.size());
      K.eval_centroid(s, b.cs.data(), b.ct.data(), int(b.cs.size()), b.out.data());
      for (size_t k = 0; k < b.cs.size(); ++k) b.val[b.cslot[k]] = b.out[k];
    }
    if (!b.lw.empty()) {
      b.out.resize(b.lw.size());
      K.eval_points(s, b.lx.data(), b.ly.data(), b.lz.data(), b.lw.data(), b.ps.data(), b.pt.data(), int(b.lw.size()),
                    b.out.data());
      for (size_t k = 0; k < b.lw.size(); ++k) b.val[b.pslot[k]] += b.out[k];
    }
    for (size_t k = 0; k < b.pair_i.size(); ++k) {
      const int i = b.pair_i[k], j = b.pair_j[k];
      F(i, j) = b.pair_swap[k] ? b.val[k] * area[j] / area[i] : b.val[k];
    }
  }
  // 3. Scalar path: near, straddling or general polygons; integrated from the smaller patch.
  for (size_t k = 0; k < b.ss.size(); ++k) {
    const int i = b.ss[k], j = b.st[k];
    const bool swap = area[j] < area[i];
    const detail::PairEval e = detail::pair_scalar(pr.P, swap ? j : i, swap ? i : j, tol);
    ++c.by_method[e.method];
    if (e.method == detail::kCulled) ++c.culled;
    if (e.error > tol) ++c.over_tolerance;
    F(i, j) = swap ? e.F * area[j] / area[i] : e.F;
  }
  // 4. Visibility: only for pairs whose segments may meet an occluder. Shafts are tested hierarchically:
  // the whole tile, then 8 x 8 sub-tiles, then single pairs. The visible fraction is symmetric.
  const auto t_visibility = Clock::now();
  if (occlusion_) {
    auto block_box = [&](int a0, int a1) {
      detail::Box bx;
      for (int p = a0; p < a1; ++p) bx.add(pr.box[p]);
      return bx;
    };
    auto clear_between = [&](int a0, int a1, int c0, int c1) {
      detail::Shaft ts = detail::make_shaft(block_box(a0, a1), block_box(c0, c1));
      ts.ni = ts.nj = Vec3::Zero();
      ts.oi = ts.oj = -INFINITY;
      return !tree_.may_block(ts, -1, -1);
    };
    const bool tile_clear = o_.cull_occlusion && clear_between(i0, i1, j0, j1);
    constexpr int kSub = 8;
    for (int si = i0; si < i1; si += kSub)
      for (int sj = j0; sj < j1; sj += kSub) {
        const int si1 = std::min(i1, si + kSub), sj1 = std::min(j1, sj + kSub);
        if (bi == bj && sj1 <= si + 1) continue;  // entirely on or below the diagonal
        bool sub_clear = tile_clear;
        if (!sub_clear && o_.cull_occlusion) {
          bool any = false;
          for (int i = si; i < si1 && !any; ++i)
            for (int j = std::max(sj, bi == bj ? i + 1 : sj); j < sj1 && !any; ++j) any = F(i, j) > 0 && !reused(i, j);
          if (!any) continue;
          sub_clear = clear_between(si, si1, sj, sj1);
        }
        for (int i = si; i < si1; ++i)
          for (int j = std::max(sj, bi == bj ? i + 1 : sj); j < sj1; ++j) {
            if (!(F(i, j) > 0) || reused(i, j)) continue;
            if (!sub_clear) {
              detail::Shaft sh = detail::make_shaft(pr.box[i], pr.box[j]);
              sh.ni = pr.P.nrm[i];
              sh.oi = pr.P.offset[i];
              sh.nj = pr.P.nrm[j];
              sh.oj = pr.P.offset[j];
              sh.eps = pr.P.scene_eps;
              if (!o_.cull_occlusion || tree_.may_block(sh, i, j, &b.blocker)) {
                ++c.ray_tested;
                const bool swap = area[j] < area[i];
                // A pair that carries a large share of a row dominates that row's visibility error: give it
                // more samples per side (x2 per side = 16x rays from 2% of the row, x3 = 81x from 10%).
                const double share = std::max(F(i, j), F(i, j) * area[i] / area[j]);
                const int m = share >= 0.1 ? 3 : share >= 0.02 ? 2 : 1;
                F(i, j) *= visible_ratio(swap ? j : i, swap ? i : j, m, b, c);
                continue;
              }
            }
            ++c.shaft_culled;
          }
      }
  }
  c.visibility_seconds += seconds_since(t_visibility);
  // 5. The other direction by reciprocity, as a blocked transpose (the I x J block is still in cache), with
  // the row sums and checks of what is stored.
  b.row.assign(size_t(kBlock), 0.0);
  b.rowj.assign(size_t(kBlock) + 8, 0.0);
  K.transpose(area, F.data(), F.cols(), i0, i1, j0, j1, bi == bj, b.row.data(), b.rowj.data(), &c.outside, &c.recip);
  for (int i = i0; i < i1; ++i) c.row_sum[i] += b.row[i - i0];
  for (int j = j0; j < j1; ++j) c.row_sum[j] += b.rowj[j - j0];
}

std::size_t default_max_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return std::size_t(8) << 30;
  return std::size_t(0.8 * double(pages) * double(page));
}

DenseMatrixOperator Assembler::run() {
  const auto t_setup = Clock::now();
  const int n = g_.size();
  st_ = Stats{};
  st_.patches = n;
  st_.rule = to_string(o_.rule, o_.order);
  st_.tolerance = o_.tolerance;
  st_.visibility = o_.visibility;
  st_.rays_per_pair = o_.rays_per_pair;
  st_.pairs_total = (long long)n * (n - 1) / 2;
  if (!(o_.tolerance > 0) || !std::isfinite(o_.tolerance))
    throw InputError("form factors: tolerance must be a positive number (got " + std::to_string(o_.tolerance) + ")");
  if (o_.rule == Rule::Gauss && (o_.order < 1 || o_.order > 8))
    throw InputError("form factors: Gauss order must be in 1..8 (got " + std::to_string(o_.order) + ")");
  if (o_.reuse) {
    const Reuse& r = *o_.reuse;
    const int m = r.previous ? r.previous->size() : -1;
    if (m < 0 || r.previous_index.size() != size_t(n))
      throw InputError("form factors: reuse needs the previous matrix and one index per patch (" + std::to_string(n) +
                       "), got " + std::to_string(r.previous_index.size()));
    std::vector<char> seen(size_t(std::max(m, 0)), 0);
    for (int p = 0; p < n; ++p) {
      const int q = r.previous_index[p];
      if (q < -1 || q >= m || (q >= 0 && seen[q]++))
        throw InputError("form factors: reuse index of patch " + std::to_string(p) + " is " + std::to_string(q) +
                         " (out of range or repeated; previous matrix has " + std::to_string(m) + " patches)");
    }
    old_ = r.previous_index;
  }
  if (o_.rays_per_pair < 1)
    throw InputError("form factors: rays per pair must be >= 1 (got " + std::to_string(o_.rays_per_pair) + ")");
  const std::size_t bytes = DenseMatrixOperator::bytes_for(std::size_t(n));
  const std::size_t limit = o_.max_bytes ? o_.max_bytes : default_max_bytes();
  st_.bytes = bytes;
  if (bytes > limit)
    throw InputError("form factors: the dense matrix for " + std::to_string(n) + " patches needs " +
                     std::to_string(bytes) + " bytes (" + std::to_string(n) + "^2 doubles), more than the " +
                     std::to_string(limit) + " bytes allowed" +
                     (o_.max_bytes ? std::string(" (max_bytes)") : std::string(" (80% of physical memory)")) +
                     "; use fewer patches");
  prep_ = std::make_unique<Prepared>(g_);
  if (o_.rule == Rule::Gauss) {
    rule_off_.assign(1, 0);
    std::vector<std::array<int, 3>> local;  // the patch's triangles, indexing its own corners
    for (int p = 0; p < n; ++p) {
      local.clear();
      for (int k = g_.triangle_offsets[p]; k < g_.triangle_offsets[p + 1]; ++k) {
        const auto& T = g_.triangles[size_t(k)];
        local.push_back({T[0] - g_.offsets[p], T[1] - g_.offsets[p], T[2] - g_.offsets[p]});
      }
      detail::outer_rule(g_.polygon(p), local, o_.order, rule_pts_);
      rule_off_.push_back(int(rule_pts_.size()));
    }
  }
  st_.seconds["setup"] = seconds_since(t_setup);

  const auto t_bvh = Clock::now();
  if (o_.visibility && n > 1) {
    const std::vector<int> occ = potential_occluders(g_);
    st_.occluders = int(occ.size());
    st_.scene_can_occlude = !occ.empty();
    if (st_.scene_can_occlude) {
      caster_ = o_.caster ? o_.caster : std::shared_ptr<const Visibility>(make_embree_visibility(g_, occ));
      tree_ = detail::OccluderTree(g_, occ);
      occlusion_ = true;
    }
  }
  rays_ = o_.rays_per_pair;
  st_.seconds["bvh"] = seconds_since(t_bvh);

  const auto t_ff = Clock::now();
  DenseMatrixOperator::Matrix F;
  try {
    F.resize(n, n);
  } catch (const std::bad_alloc&) {
    throw InputError("form factors: cannot allocate the dense matrix for " + std::to_string(n) + " patches (" +
                     std::to_string(bytes) + " bytes)");
  }
  F_ = &F;
  // Transparent huge pages for the big matrix: 512x fewer page faults and TLB misses when writing it.
  if (bytes >= (std::size_t(64) << 20)) {
    const std::uintptr_t b0 = (reinterpret_cast<std::uintptr_t>(F.data()) + (std::uintptr_t(2) << 20) - 1) &
                              ~((std::uintptr_t(2) << 20) - 1);
    const std::uintptr_t b1 = (reinterpret_cast<std::uintptr_t>(F.data()) + bytes) & ~((std::uintptr_t(2) << 20) - 1);
    if (b1 > b0) madvise(reinterpret_cast<void*>(b0), b1 - b0, MADV_HUGEPAGE);  // advisory: failure is harmless
  }
  const int nb = (n + kBlock - 1) / kBlock;
  std::vector<std::pair<int, int>> tiles;
  tiles.reserve(size_t(nb) * (nb + 1) / 2);
  for (int bi = 0; bi < nb; ++bi)
    for (int bj = bi; bj < nb; ++bj) tiles.emplace_back(bi, bj);
  tbb::enumerable_thread_specific<Counters> counters([&] {
    Counters c;
    c.row_sum.assign(n, 0.0);
    return c;
  });
  tbb::enumerable_thread_specific<TileBuffers> buffers;
  std::atomic<long long> done{0};
  std::mutex progress_mutex;
  auto last = Clock::now();
  const double total_tiles = double(tiles.size());
  auto body = [&](const tbb::blocked_range<size_t>& r) {
    Counters& c = counters.local();
    TileBuffers& b = buffers.local();
    const auto t0 = Clock::now();
    for (size_t t = r.begin(); t != r.end(); ++t) tile(tiles[t].first, tiles[t].second, b, c);
    c.tile_seconds += seconds_since(t0);
    const long long d = done.fetch_add((long long)r.size()) + (long long)r.size();
    if (o_.progress) {
      std::unique_lock lock(progress_mutex, std::try_to_lock);
      if (lock.owns_lock() && seconds_since(last) >= 0.1) {
        last = Clock::now();
        o_.progress(double(d) / total_tiles);
      }
    }
  };
  auto loop = [&] { tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles.size(), 1), body); };
  if (o_.threads > 0) {
    tbb::task_arena arena(o_.threads);
    arena.execute(loop);
  } else {
    loop();
  }
  if (n == 1) F(0, 0) = 0;
  if (o_.progress) o_.progress(1.0);
  st_.seconds["form_factors"] = seconds_since(t_ff);

  const auto t_stats = Clock::now();
  std::vector<double> rows(n, 0.0);
  std::array<long long, kMethodCount> by{};
  long long fixed = 0;
  double tile_seconds = 0, visibility_seconds = 0;
  for (const Counters& c : counters) {
    tile_seconds += c.tile_seconds;
    visibility_seconds += c.visibility_seconds;
    for (int i = 0; i < n; ++i) rows[i] += c.row_sum[i];
    st_.pairs_orientation_culled += c.culled;
    st_.pairs_shaft_culled += c.shaft_culled;
    st_.pairs_ray_tested += c.ray_tested;
    st_.rays_cast += c.rays;
    st_.pairs_over_tolerance += c.over_tolerance;
    st_.pairs_reused += c.reused;
    fixed += c.fixed;
    st_.entries_outside_unit += c.outside;
    st_.reciprocity_residual = std::max(st_.reciprocity_residual, c.recip);
    for (int m = 0; m < kMethodCount; ++m) by[m] += c.by_method[m];
  }
  for (int m = 0; m < kMethodCount; ++m)
    if (by[m]) st_.pairs_by_method[detail::kMethodNames[m]] = by[m];
  if (fixed) st_.pairs_by_method[to_string(o_.rule, o_.order)] = fixed;
  if (st_.pairs_reused) st_.pairs_by_method["reused"] = st_.pairs_reused;
  if (n > 0) {
    st_.row_sum_min = *std::min_element(rows.begin(), rows.end());
    st_.row_sum_max = *std::max_element(rows.begin(), rows.end());
    double sum = 0;
    for (double r : rows) sum += r;
    st_.row_sum_mean = sum / n;
  }
  st_.seconds["stats"] = seconds_since(t_stats);
  // Wall-time share of visibility inside "form_factors" (integration and visibility interleave per tile).
  st_.seconds["visibility"] = tile_seconds > 0 ? st_.seconds["form_factors"] * visibility_seconds / tile_seconds : 0.0;
  return DenseMatrixOperator(std::move(F));
}

}  // namespace

std::string to_string(Rule rule, int order) {
  switch (rule) {
    case Rule::Point: return "point";
    case Rule::Gauss: return "gauss" + std::to_string(order);
    default: return "adaptive";
  }
}

void parse_rule(std::string_view text, Rule& rule, int& order) {
  if (text == "adaptive") {
    rule = Rule::Adaptive;
    return;
  }
  if (text == "point") {
    rule = Rule::Point;
    return;
  }
  if (text.size() == 6 && text.substr(0, 5) == "gauss" && text[5] >= '1' && text[5] <= '8') {
    rule = Rule::Gauss;
    order = text[5] - '0';
    return;
  }
  throw InputError("unknown form-factor rule '" + std::string(text) + "' (choose adaptive, point, gauss1..gauss8)");
}

DenseMatrixOperator assemble(const mesh::PatchGeometry& geometry, const Options& options, Stats* stats) {
  Stats local;
  Assembler a(geometry, options, stats ? *stats : local);
  return a.run();
}

}  // namespace lambert::formfactor
