// One tile of the dense assembly: classification and tiers 0/1 (SIMD), outer Gauss rules (SIMD), the scalar
// path, visibility, and the reciprocal direction.
#include <algorithm>
#include <cmath>

#include "assembler.hpp"
#include "lambert/formfactor/kernel.hpp"

namespace lambert::formfactor::detail {

const std::array<std::uint8_t, 256>& code_method() {
  static const std::array<std::uint8_t, 256> lut = [] {
    std::array<std::uint8_t, 256> t{};
    for (int c = 0; c < 256; ++c) {
      int m = kNoMethod;
      if (c == kCodeCulled) m = kCulled;
      else if (c < kCodeScalar && c != kCodeSlow && (c & 15) >= 1 && (c & 15) <= kTiers) m = tier_method((c & 15) - 1);
      else if (c >= kCodeScalar && c < kCodeScalar + kMethodCount) m = c - kCodeScalar;
      t[size_t(c)] = std::uint8_t(m);
    }
    return t;
  }();
  return lut;
}

// Rule::Point and Rule::Gauss: each pair from the smaller patch (F of the larger by reciprocity in step 5).
void Assembler::fixed_rule(int i0, int i1, int j0, int j1, bool diagonal, Counters& c) {
  const PatchData& P = prep_->P;
  auto& F = *F_;
  for (int i = i0; i < i1; ++i) {
    if (diagonal) F(i, i) = 0;
    for (int j = diagonal ? i + 1 : j0; j < j1; ++j) {
      if (reused(i, j)) {
        F(i, j) = o_.reuse->previous->matrix()(old_[i], old_[j]);
        ++c.reused;
        continue;
      }
      const bool swap = source_is_j(P.area[i], P.area[j]);
      const int src = swap ? j : i, tgt = swap ? i : j;
      double f = 0;
      if (o_.rule == Rule::Point) {
        const Vec3 d = P.c[tgt] - P.c[src];
        const double r2 = d.squaredNorm(), ci = P.nrm[src].dot(d), cj = -P.nrm[tgt].dot(d);
        if (ci > 0 && cj > 0 && r2 > 0) f = ci * cj * P.area[tgt] / (kPi * r2 * r2);
      } else {
        const auto poly = P.g->polygon(tgt);
        for (int k = rule_off_[src]; k < rule_off_[src + 1]; ++k) {
          const auto& X = rule_pts_[k];
          f += X[3] * point_to_polygon(Vec3(X[0], X[1], X[2]), P.nrm[src], poly);
        }
      }
      if (f > 0) {
        ++c.fixed;
      } else {
        ++c.culled;
        ++c.by_method[kCulled];
      }
      F(i, j) = swap ? f * P.area[src] / P.area[tgt] : f;  // A_i F_ij = A_j F_ji
    }
  }
}

void Assembler::tile(int bi, int bj, TileBuffers& b, Counters& c) {
  const Prepared& pr = *prep_;
  const SoA& s = pr.soa;
  const BatchKernels& K = batch_kernels();
  const int n = pr.P.n;
  const int i0 = bi * kBlock, i1 = std::min(n, i0 + kBlock), j0 = bj * kBlock, j1 = std::min(n, j0 + kBlock);
  const double tol = tol_;
  const double* area = pr.P.area.data();
  auto& F = *F_;
  b.code.resize(kBlock + 16);
  b.err.assign(size_t(kBlock) * kBlock, 0.0);
  b.meth.assign(size_t(kBlock) * kBlock, kNoMethod);  // pair codes, see assembler.hpp
  auto slot = [&](int i, int j) { return size_t(i - i0) * kBlock + size_t(j - j0); };
  b.lx.clear(), b.ly.clear(), b.lz.clear(), b.lw.clear(), b.ps.clear(), b.pt.clear(), b.pslot.clear();
  b.ss.clear(), b.st.clear();
  b.cs.clear(), b.ct.clear(), b.cslot.clear();
  b.pair_i.clear(), b.pair_j.clear(), b.pair_swap.clear();
  long long counts[2] = {0, 0};
  b.rest_j.resize(kBlock + 16);
  // 1. Classification, with tiers 0/1 evaluated in the same pass straight into row i of the matrix (F_ij),
  // over runs of pairs not copied from a previous assembly.
  auto classify_run = [&](int i, int js, int je) {
    const int nrest = K.classify(s, i, js, je, tol, &F(i, js), &b.err[slot(i, js)],
                                 reinterpret_cast<std::int8_t*>(&b.meth[slot(i, js)]), b.code.data(), b.rest_j.data(),
                                 counts);
    for (int r = 0; r < nrest; ++r) {
      const int code = b.code[r], j = b.rest_j[r];
      if (code == kCodeSlow) {
        b.ss.push_back(i);
        b.st.push_back(j);
        continue;
      }
      const bool swap = code > kCodeSwap;
      const int t = (code & 15) - 1;
      const int src = swap ? j : i, tgt = swap ? i : j;
      const int k = int(b.pair_i.size());
      b.pair_i.push_back(i);
      b.pair_j.push_back(j);
      b.pair_swap.push_back(swap);
      ++c.by_method[tier_method(t)];
      if (t == 1) {
        b.cs.push_back(src);
        b.ct.push_back(tgt);
        b.cslot.push_back(k);
        continue;
      }
      const int m = kTierM[t];
      // Lanes for this pair: resize once, then fill (push_back per field was measurable here).
      const auto poly = pr.P.g->polygon(src);
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
        const Rule2D& rule = pr.triangle_rule[m];
        for (size_t q = 0; q < cnt; ++q)
          lane(q, poly[0] + rule.xi[q][0] * (poly[1] - poly[0]) + rule.xi[q][1] * (poly[2] - poly[0]), rule.w[q]);
      } else {
        const Rule2D& rule = pr.square_rule[m];
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
        b.meth[slot(i, j)] = kReusedMethod;
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
  c.by_method[kCulled] += counts[0];
  c.by_method[kFarField] += counts[1];
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
    const bool swap = source_is_j(area[i], area[j]);
    const PairEval e = pair_scalar(pr.P, swap ? j : i, swap ? i : j, tol);
    ++c.by_method[e.method];
    if (e.method == kCulled) ++c.culled;
    if (e.error > tol) ++c.over_tolerance;
    F(i, j) = swap ? e.F * area[j] / area[i] : e.F;
    b.err[slot(i, j)] = swap ? e.error * area[j] / area[i] : e.error;
    b.meth[slot(i, j)] = std::uint8_t(kCodeScalar + e.method);
  }
  // Fault injection (tests of the checks only): one method's results perturbed, both directions.
  if (fault_method_ >= 0)
    for (int i = i0; i < i1; ++i)
      for (int j = bi == bj ? i + 1 : j0; j < j1; ++j)
        if (code_method()[b.meth[slot(i, j)]] == fault_method_) F(i, j) *= 1 + o_.fault_relative;
  // Reciprocity-check candidates: per method present in the tile, the first kPerTile pairs met from a seeded
  // start, keyed by a hash of (tile, method, rank); the smallest keys over all tiles are checked (stats.cpp).
  if (o_.reciprocity_samples > 0 && o_.rule == Rule::Adaptive) {
    const std::uint64_t tile_id = std::uint64_t(bi) * 1000003ull + std::uint64_t(bj);
    const int cells = (i1 - i0) * kBlock, start = int(mix(tile_id) % std::uint64_t(cells));
    constexpr int kPerTile = 4;  // candidates per method and tile (small scenes have few tiles)
    std::array<int, kMethodCount> seen{};
    seen[kCulled] = kPerTile;
    const std::uint8_t* meth = b.meth.data();
    const std::uint8_t* lut = code_method().data();
    for (int k = 0, cell = start; k < cells; ++k, cell = cell + 1 == cells ? 0 : cell + 1) {
      const int m = lut[meth[cell]];
      if (m >= kMethodCount || seen[m] >= kPerTile) continue;  // most cells: a method already taken
      const int i = i0 + cell / kBlock, j = j0 + cell % kBlock;
      if (j >= j1 || (bi == bj && j <= i)) continue;
      const std::uint64_t key = mix((tile_id * 16 + std::uint64_t(m)) * kPerTile + std::uint64_t(seen[m]++));
      const bool swap = source_is_j(area[i], area[j]);
      const int src = swap ? j : i, tgt = swap ? i : j;
      RecipCandidate rc{key, src, tgt, m, F(i, j) * (swap ? area[i] / area[j] : 1.0),
                        b.err[slot(i, j)] * (swap ? area[i] / area[j] : 1.0)};
      auto& heap = c.recip_candidates[m];
      if (int(heap.size()) < o_.reciprocity_samples) {
        heap.push_back(rc);
        std::push_heap(heap.begin(), heap.end());
      } else if (rc.key < heap.front().key) {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = rc;
        std::push_heap(heap.begin(), heap.end());
      }
    }
  }
  // 4. Visibility: only for pairs whose segments may meet an occluder. Shafts are tested hierarchically:
  // the whole tile, then 8 x 8 sub-tiles, then single pairs. The visible fraction is symmetric.
  const auto t_visibility = Clock::now();
  if (occlusion_) {
    auto block_box = [&](int a0, int a1) {
      Box bx;
      for (int p = a0; p < a1; ++p) bx.add(pr.box[p]);
      return bx;
    };
    int blocker = -1;  // an occluder clear_between found in the last shaft it tested
    auto clear_between = [&](int a0, int a1, int c0, int c1) {
      Shaft ts = make_shaft(block_box(a0, a1), block_box(c0, c1));
      ts.ni = ts.nj = Vec3::Zero();
      ts.oi = ts.oj = -INFINITY;
      ts.eps = pr.P.scene_eps;
      blocker = -1;
      return !tree_.may_block(ts, -1, -1, &blocker);
    };
    // Exactly hidden: a wall or slab (occluders in one plane between the two blocks' boxes) covers every segment
    // between them (separation.hpp). Tried on whole tiles and on 8 x 8 sub-tiles: one proof replaces the rays of
    // up to 4,096 or 64 pairs.
    auto box_corners = [](const Box& bx, std::vector<Vec3>& out) {
      out.clear();
      for (int k = 0; k < 8; ++k)
        out.emplace_back(k & 1 ? bx.hi.x() : bx.lo.x(), k & 2 ? bx.hi.y() : bx.lo.y(), k & 4 ? bx.hi.z() : bx.lo.z());
    };
    auto hidden_between = [&](int a0, int a1, int c0, int c1) {
      const auto t0 = Clock::now();
      const Box ba = block_box(a0, a1), bc = block_box(c0, c1);
      box_corners(ba, b.corners_a);
      box_corners(bc, b.corners_b);
      ++c.plane_tests;
      // Planes tried, cheapest first: those that proved other sub-tiles of this tile (the same wall usually hides
      // its neighbours), the plane of the occluder the shaft test met first, then every plane in the shaft (once
      // per tile on the ray path, where a failed search costs more than the rays it could save: the floor plan
      // and the 10k building were fastest with one; always on the exact path). Per tile, in a fixed order: the
      // same proofs for any thread count.
      Box shaft_box = ba;
      shaft_box.add(bc);
      const double eps = 1e-9 * scale_;
      // Blocks touching the plane (a wall's own patches, floors meeting it): none of their patches lying in it
      // may face the other block.
      const TouchingCheck touching_ok = [&](const Vec3& nn, double oo) {
        for (int p = a0; p < a1; ++p)
          if (lies_in_plane_facing(g_, p, nn, oo, eps)) return false;
        for (int p = c0; p < c1; ++p)
          if (lies_in_plane_facing(g_, p, -nn, -oo, eps)) return false;
        return true;
      };
      auto try_plane = [&](int plane) {
        b.cand.clear();
        for (int p : plane_members_[size_t(plane)])
          if ((pbox_lo_[size_t(p)].array() <= shaft_box.hi.array()).all() &&
              (pbox_hi_[size_t(p)].array() >= shaft_box.lo.array()).all())
            b.cand.push_back(p);
        return hidden_by_plane(b.corners_a, b.corners_b, g_, plane_of_, b.cand, eps, *b.sep, touching_ok);
      };
      int proof = -1;
      for (size_t k = 0; k < b.walls.size() && proof < 0; ++k) proof = try_plane(b.walls[k]);
      const int first = blocker >= 0 ? plane_of_[size_t(blocker)] : -1;
      if (proof < 0 && first >= 0 && std::find(b.walls.begin(), b.walls.end(), first) == b.walls.end())
        proof = try_plane(first);
      if (proof < 0 && (b.searches < 1 || o_.visibility_method != VisibilityMethod::Rays)) {
        ++b.searches;
        Shaft ts = make_shaft(ba, bc);
        ts.ni = ts.nj = Vec3::Zero();
        ts.oi = ts.oj = -INFINITY;
        ts.eps = pr.P.scene_eps;
        b.cand.clear();
        tree_.collect(ts, -1, -1, b.cand);
        proof = hidden_by_plane(b.corners_a, b.corners_b, g_, plane_of_, b.cand, eps, *b.sep, touching_ok);
      }
      if (proof >= 0 && std::find(b.walls.begin(), b.walls.end(), proof) == b.walls.end()) b.walls.push_back(proof);
      const bool hidden = proof >= 0;
      c.plane_seconds += seconds_since(t0);
      return hidden;
    };
    b.walls.clear();
    b.searches = 0;
    // Patches facing different cells (enclosures.hpp): zero without rays; a tile of two cells is done at once.
    auto block_cell = [&](int a0, int a1) {
      if (cell_.empty()) return -1;
      const int cc = cell_[size_t(a0)];
      for (int p = a0 + 1; p < a1; ++p)
        if (cell_[size_t(p)] != cc) return -1;
      return cc;
    };
    auto apart = [&](int ca, int cb) { return ca >= 0 && cb >= 0 && ca != cb; };
    auto zero_cells = [&](int a0, int a1, int c0, int c1) {
      for (int i = a0; i < a1; ++i)
        for (int j = std::max(c0, bi == bj ? i + 1 : c0); j < c1; ++j)
          if (F(i, j) > 0 && !reused(i, j) && apart(cell_[size_t(i)], cell_[size_t(j)])) {
            F(i, j) = 0;  // exact: every segment between them crosses a closed surface
            ++c.cell_hidden;
          }
    };
    const int cell_i = block_cell(i0, i1), cell_j = block_cell(j0, j1);
    const bool tile_apart = apart(cell_i, cell_j);
    // Two blocks of one and the same cell: nothing to refuse; otherwise pair by pair (all pairs when apart).
    if (!cell_.empty() && (cell_i < 0 || cell_j < 0 || cell_i != cell_j)) zero_cells(i0, i1, j0, j1);
    const bool tile_clear = !tile_apart && o_.cull_occlusion && clear_between(i0, i1, j0, j1);
    auto zero_hidden = [&](int a0, int a1, int c0, int c1) {
      for (int i = a0; i < a1; ++i)
        for (int j = std::max(c0, bi == bj ? i + 1 : c0); j < c1; ++j)
          if (F(i, j) > 0 && !reused(i, j)) {
            F(i, j) = 0;  // exact: no segment between them is free
            ++c.plane_hidden;
          }
    };
    // Two blocks far apart in one storey, or on two storeys: one wall or slab may hide the whole tile.
    const bool tile_hidden =
        tile_apart || (o_.cull_occlusion && !tile_clear && bi != bj && hidden_between(i0, i1, j0, j1));
    if (tile_hidden) zero_hidden(i0, i1, j0, j1);
    constexpr int kSub = 8;
    for (int si = tile_hidden ? i1 : i0; si < i1; si += kSub)
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
          if (!sub_clear && hidden_between(si, si1, sj, sj1)) {
            zero_hidden(si, si1, sj, sj1);
            continue;
          }
        }
        // The pairs' shaft tests walk the occluder tree from the sub-tile's frontier, not its root: the same
        // answers for fewer box tests (boxes grown by 1e-9 of the scene: grown_box_shaft).
        std::span<const int> walk = OccluderTree::root();
        if (!sub_clear && o_.cull_occlusion) {
          b.front.clear();
          tree_.frontier(grown_box_shaft(block_box(si, si1), block_box(sj, sj1), 10 * pr.P.scene_eps, pr.P.scene_eps),
                         32, b.front);
          walk = b.front;
        }
        for (int i = si; i < si1; ++i)
          for (int j = std::max(sj, bi == bj ? i + 1 : sj); j < sj1; ++j) {
            if (!(F(i, j) > 0) || reused(i, j)) continue;
            if (!sub_clear) {
              Shaft sh = make_shaft(pr.box[i], pr.box[j]);
              sh.ni = pr.P.nrm[i];
              sh.oi = pr.P.offset[i];
              sh.nj = pr.P.nrm[j];
              sh.oj = pr.P.offset[j];
              sh.eps = pr.P.scene_eps;
              // In different rooms with no portal of a surface between them in the shaft: exact zero.
              if (!rooms_.empty()) {
                const int ri = rooms_.cell[size_t(i)], rj = rooms_.cell[size_t(j)];
                if (ri >= 0 && rj >= 0 && ri != rj && !rooms_.path(sh, ri, rj)) {
                  F(i, j) = 0;
                  ++c.portal_hidden;
                  continue;
                }
              }
              if (!o_.cull_occlusion || tree_.may_block_from(sh, i, j, walk, &b.blocker)) {
                const bool swap = source_is_j(area[i], area[j]);
                const int src = swap ? j : i, tgt = swap ? i : j;
                const double share = std::max(F(i, j), F(i, j) * area[i] / area[j]);
                const bool exact = o_.visibility_method == VisibilityMethod::Exact ||
                                   (o_.visibility_method == VisibilityMethod::Auto && share > tol);
                // auto: a pair whose whole F (either direction) is within the per-entry tolerance takes rays, whose
                // error is then below the tolerance whatever the visible fraction.
                if (exact) {
                  const auto t_exact = Clock::now();
                  // The occluder the shaft test met (or its merged polygon), if convex and crossed inside by every
                  // segment between the two patches' corners, hides the pair: classify would prove the same from the
                  // pair's occluders (segments between the clipped patches are among these), so the outcome does not
                  // depend on which occluder the test met first. Room with a block: 1.05 M of the 1.24 M pairs the
                  // exact path proves hidden, without collecting their occluders.
                  if (b.blocker >= 0) {
                    const int m = merged_.of_patch.empty() ? -1 : merged_.of_patch[size_t(b.blocker)];
                    const std::span<const Vec3> q =
                        m >= 0 ? std::span<const Vec3>(merged_.polys[size_t(m)]) : g_.polygon(b.blocker);
                    if (m >= 0 ? merged_.convex[size_t(m)] != 0 : convex_[size_t(b.blocker)] != 0) {
                      const Vec3 nq = mesh::newell_normal(q);
                      const double len = nq.norm();
                      if (len > 0 && convex_hides(g_.polygon(i), g_.polygon(j), q, nq / len, nq.dot(q[0]) / len,
                                                  1e-10 * scale_)) {
                        ++c.exact_hidden;
                        F(i, j) = 0;
                        c.exact_seconds += seconds_since(t_exact);
                        continue;
                      }
                    }
                  }
                  b.cand.clear();
                  // Of a merged polygon, one member is enough (pair_occluders takes the polygon once).
                  tree_.collect_grouped_from(
                      sh, i, j, walk,
                      [&](int p) { return !in_plane_of(pr.P, scale_, p, i) && !in_plane_of(pr.P, scale_, p, j); },
                      b.cand, b.seen);
                  pair_occluders(g_, pr.P, scale_, b.cand, i, j, merged_, convex_, b.merged_ids, b.occ);
                  // A wall or slab of several occluders hiding the pair entirely: proven without integrating.
                  const double eps = 1e-9 * scale_;
                  const TouchingCheck touching_ok = [&](const Vec3& nn, double oo) {
                    return !lies_in_plane_facing(g_, i, nn, oo, eps) && !lies_in_plane_facing(g_, j, -nn, -oo, eps);
                  };
                  // Not where one convex occluder (a polygon, or the faces of one closed convex solid) is all there
                  // is: classify decides that exactly, at a fraction of the cost.
                  bool one_convex = b.occ.size() == 1 && b.occ[0].convex;
                  if (!b.occ.empty() && b.occ[0].solid >= 0) {
                    one_convex = true;
                    for (const Occluder& o : b.occ) one_convex = one_convex && o.solid == b.occ[0].solid;
                  }
                  c.plane_tests += !one_convex;
                  // The plane proof unites every tile of a wall the shaft meets: the candidates in full.
                  if (!one_convex) {
                    b.cand.clear();
                    tree_.collect_from(sh, i, j, walk, b.cand);
                  }
                  if (!one_convex &&
                      hidden_by_plane(g_.polygon(i), g_.polygon(j), g_, plane_of_, b.cand, eps, *b.sep, touching_ok) >= 0) {
                    ++c.exact_hidden;
                    ++c.plane_hidden;
                    F(i, j) = 0;
                    c.exact_seconds += seconds_since(t_exact);
                    continue;
                  }
                  const ExactPairResult r =
                      exact_hidden_pair(g_.polygon(src), pr.P.nrm[src], area[src], convex_[src] != 0, g_.polygon(tgt),
                                        pr.P.nrm[tgt], convex_[tgt] != 0, b.occ, tol, scale_, *b.exact);
                  const double to_ij = swap ? area[j] / area[i] : 1.0;  // F_ij = F_st * to_ij
                  switch (r.outcome) {
                    case ExactPairResult::kClear: ++c.exact_clear; break;
                    case ExactPairResult::kHidden: ++c.exact_hidden; F(i, j) = 0; break;
                    case ExactPairResult::kIntegrated:
                      ++c.exact_integrated;
                      // The hidden part cannot exceed the whole: below zero only by the two integrals' errors.
                      F(i, j) = std::max(0.0, F(i, j) - r.H * to_ij);
                      break;
                  }
                  c.exact_points += r.points;
                  c.exact_over += r.over_tolerance;
                  c.over_tolerance += r.over_tolerance;  // the finding "pairs above tolerance" counts them too
                  b.err[slot(i, j)] += r.error * to_ij;
                  c.exact_seconds += seconds_since(t_exact);
                  continue;
                }
                const auto t_rays = Clock::now();
                ++c.ray_tested;
                // Rays by the pair's share of its rows (more where it dominates a row's visibility error).
                const VisibleRatio v = visible_ratio(g_, pr.P, *caster_, src, tgt, rays_for_share(rays_, share), b.ray);
                c.rays += v.rays;
                c.no_visible_sample += v.no_sample;
                const double sigma = F(i, j) * v.sigma, ratio = area[i] / area[j];
                c.row_vis_var[i] += sigma * sigma;
                c.row_vis_var[j] += sigma * sigma * ratio * ratio;
                F(i, j) *= v.ratio;
                c.rays_seconds += seconds_since(t_rays);
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
  b.erow.assign(size_t(kBlock), 0.0);
  b.erowj.assign(size_t(kBlock) + 8, 0.0);
  K.transpose(area, F.data(), F.cols(), i0, i1, j0, j1, bi == bj, b.err.data(), kBlock, b.row.data(), b.rowj.data(),
              b.erow.data(), b.erowj.data(), &c.outside, &c.roundoff);
  for (int i = i0; i < i1; ++i) {
    c.row_sum[i] += b.row[i - i0];
    c.row_err[i] += b.erow[i - i0];
  }
  for (int j = j0; j < j1; ++j) {
    c.row_sum[j] += b.rowj[j - j0];
    c.row_err[j] += b.erowj[j - j0];
  }
}

}  // namespace lambert::formfactor::detail
