#pragma once
// One pair of a model's patches through the exact visibility path as the assembly integrates it, and through an
// independent route: shared by the tests (test_formfactor_exact_visibility.cpp) and bench/bench_exact_scan.cpp.
#include <cstdint>
#include <vector>

#include "../formfactor/src/exact_visibility.hpp"
#include "../formfactor/src/internal.hpp"
#include "lambert/formfactor/kernel.hpp"
#include "lambert/formfactor/visibility.hpp"
#include "lambert/mesh/scene.hpp"

namespace lambert::fftest {

struct ExactPairCheck {
  int outcome = 0;           // detail::ExactPairResult::Outcome of the merged pair
  double merged = 0;         // F_ij through the merged occluders (0 if proven hidden)
  double estimate = 0;       // its error estimate, on F_ij
  long long points = 0;      // its outer rule's points
  bool over_tolerance = false;  // it stopped at the point cap above the tolerance
  int occluders = 0;         // merged occluders handed to it
  double unmerged = 0;       // F_ij with every patch near the pair as a plain occluder, at 1e-10
  double unmerged_estimate = 0;
  std::vector<int> near;     // the patches whose boxes meet the pair's box
};

// The scene's occluders as the assembly prepares them: merged coplanar regions, convex flags.
class ExactPairChecker {
 public:
  explicit ExactPairChecker(const mesh::PatchGeometry& g) : g_(g) {
    Eigen::AlignedBox3d scene_box;
    for (const Vec3& v : g.points) scene_box.extend(v);
    scale_ = scene_box.diagonal().norm();
    P_ = formfactor::detail::prepare(g);
    merged_ = formfactor::detail::merge_coplanar_occluders(g, formfactor::potential_occluders(g), scale_);
    convex_.resize(size_t(g.size()));
    for (int p = 0; p < g.size(); ++p) convex_[size_t(p)] = P_.kind[p] <= 2;  // as the assembly
    boxes_.resize(size_t(g.size()));
    for (int p = 0; p < g.size(); ++p)
      for (const Vec3& v : g.polygon(p)) boxes_[size_t(p)].extend(v);
  }
  const Eigen::AlignedBox3d& box(int p) const { return boxes_[size_t(p)]; }
  double scale() const { return scale_; }  // the scene's bounding-box diagonal (m)

  double merged_tolerance = 1e-8;  // on H, the merged path's (formfactors --visibility exact uses 1e-8)
  // Integrate from the larger patch (the assembly integrates from the smaller one): the same pair through an outer
  // rule on the other patch, an independent route through the same method.
  bool from_larger = false;

  // The pair (i, j): merged at merged_tolerance on H, as formfactors --visibility exact does, with the candidates a
  // box test gives (the assembly's shaft may give fewer); the unmerged reference only if the merged pair was
  // integrated or proven hidden.
  ExactPairCheck check(int i, int j, formfactor::detail::ExactScratch& scratch) const {
    namespace d = formfactor::detail;
    ExactPairCheck r;
    Eigen::AlignedBox3d pair_box = box(i);
    pair_box.extend(box(j));
    std::vector<std::vector<Vec3>> patches;
    for (int q = 0; q < g_.size(); ++q) {
      if (q == i || q == j || !box(q).intersects(pair_box)) continue;
      r.near.push_back(q);
      patches.emplace_back(g_.polygon(q).begin(), g_.polygon(q).end());
    }
    std::vector<int> ids;
    std::vector<d::Occluder> occ;
    d::pair_occluders(g_, P_, scale_, r.near, i, j, merged_, convex_, ids, occ);
    const bool swap = (g_.area[j] < g_.area[i]) != from_larger;  // from the smaller patch, as the assembly does
    const int src = swap ? j : i, tgt = swap ? i : j;
    const auto e = d::exact_hidden_pair(g_.polygon(src), P_.nrm[src], g_.area[src], convex_[size_t(src)] != 0,
                                        g_.polygon(tgt), P_.nrm[tgt], convex_[size_t(tgt)] != 0, occ, merged_tolerance,
                                        scale_, scratch);
    r.outcome = e.outcome;
    r.points = e.points;
    r.over_tolerance = e.over_tolerance;
    r.occluders = int(occ.size());
    if (e.outcome != d::ExactPairResult::kIntegrated && e.outcome != d::ExactPairResult::kHidden) return r;
    const std::vector<Vec3> Pi(g_.polygon(i).begin(), g_.polygon(i).end()), Pj(g_.polygon(j).begin(), g_.polygon(j).end());
    const double to_i = swap ? g_.area[j] / g_.area[i] : 1.0;
    r.merged = e.outcome == d::ExactPairResult::kHidden ? 0.0 : formfactor::polygon_to_polygon(Pi, Pj, 1e-12).F - e.H * to_i;
    r.estimate = e.error * to_i;
    const formfactor::PairResult u = formfactor::visible_polygon_to_polygon(Pi, Pj, patches, 1e-10);
    r.unmerged = u.F;
    r.unmerged_estimate = u.error_estimate;
    return r;
  }

 private:
  const mesh::PatchGeometry& g_;
  double scale_ = 0;
  formfactor::detail::PatchData P_;
  formfactor::detail::MergedOccluders merged_;
  std::vector<std::uint8_t> convex_;
  std::vector<Eigen::AlignedBox3d> boxes_;
};

}  // namespace lambert::fftest
