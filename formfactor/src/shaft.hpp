#pragma once
// Shaft culling (Haines & Wallace 1991): the convex hull of two boxes is bounded by their joint box and by
// planes through matching edges of the two boxes. A segment between the two patches lies in that shaft and
// in front of both patches' planes, so an occluder outside either cannot block it.
#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

struct Box {
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  void add(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
};

struct Shaft {
  Box box;
  int planes = 0;
  std::array<Vec3, 12> n;  // outward normals: the shaft is n.p <= d for every plane
  std::array<double, 12> d;
  std::array<double, 12> len;  // |n|: a plane's margin is eps * len
  // The same planes for the box test: the two axes u < v of each normal's nonzero components (the third is 0) and
  // which corner of a box is lowest along it per axis (0: lo, 1: hi).
  std::array<std::uint8_t, 12> u, v, su, sv;
  // Planes of the two patches: segments run in their strict front half-spaces.
  Vec3 ni, nj;
  double oi = 0, oj = 0, eps = 0;
};
Shaft make_shaft(const Box& a, const Box& b);
// The shaft between two boxes grown by `pad` on every side, with no patch planes (eps: the scene's plane tolerance):
// a frontier's shaft (OccluderTree::frontier). Haines-Wallace shafts nest only in exact arithmetic: an occluder that
// only touches this shaft may, after rounding, count as inside a shaft within it; grown by 1e-9 of the scene, the
// frontier still reaches it.
Shaft grown_box_shaft(Box a, Box b, double pad, double eps);
// False only if no segment of the shaft can meet the polygon (box: the polygon's bounding box) except on the shaft's
// boundary, where only segments between coplanar patches run: the polygon lies outside or on one of the shaft's
// planes or its box's faces, or in the closed back half-space of either patch. Conservative.
bool polygon_may_meet(const Shaft& s, const Box& box, std::span<const Vec3> polygon);

// Bounding-volume tree over the patches that can occlude anything.
class OccluderTree {
 public:
  OccluderTree() = default;
  OccluderTree(const mesh::PatchGeometry& g, const std::vector<int>& occluders);
  bool empty() const { return nodes_.empty(); }
  // False only if no occluder other than patches ia and ib can meet the shaft (conservative). `hint`, if
  // given, is tested first and set to the occluder found: neighbouring pairs are mostly blocked by the same
  // wall (an occluder cache; the answer is the same with or without it).
  bool may_block(const Shaft& s, int ia, int ib, int* hint = nullptr) const;
  // Every occluder other than ia and ib that may meet the shaft (same test as may_block), appended to out in
  // tree order (deterministic).
  void collect(const Shaft& s, int ia, int ib, std::vector<int>& out) const;
  // Shafts inside a larger one (the pairs below a pair of clusters) need not walk the tree from its root. The
  // larger shaft's frontier: the nodes its walk reaches that hold at most `items` occluders (or are leaves), in
  // walk order. A walk of a shaft inside it reaches only nodes under those, so the *_from versions, which walk
  // from them, give the same answers as may_block and collect, in the same order, for fewer box tests.
  void frontier(const Shaft& s, int items, std::vector<int>& out) const;
  // The same from a larger shaft's frontier (roots, in walk order) instead of the root: the same nodes in the same
  // order, for a shaft inside that larger one (a frontier within a frontier).
  void frontier_from(const Shaft& s, int items, std::span<const int> roots, std::vector<int>& out) const;
  // (An empty frontier: nothing in the larger shaft. root(): the frontier of any shaft, the tree's root.)
  static std::span<const int> root() {
    static constexpr int kRoot[1] = {0};
    return kRoot;
  }
  bool may_block_from(const Shaft& s, int ia, int ib, std::span<const int> from, int* hint = nullptr) const;
  void collect_from(const Shaft& s, int ia, int ib, std::span<const int> from, std::vector<int>& out) const;
  // Occluders in groups (group_of[p] >= 0: a merged coplanar polygon, see exact_visibility.hpp; -1 alone), for
  // collect_grouped_from (copied).
  void set_groups(const std::vector<int>& group_of);
  // As collect_from, among the occluders `accept` takes, but of each group only the first one found: the others,
  // and whole subtrees of that group, are not tested. The occluders outside groups come in the same order as from
  // collect_from, and a group is listed if and only if collect_from would list an accepted member of it. `seen`:
  // scratch.
  void collect_grouped_from(const Shaft& s, int ia, int ib, std::span<const int> from,
                            const std::function<bool(int)>& accept, std::vector<int>& out, std::vector<int>& seen) const;

 private:
  struct Node {
    Box box;
    int left = -1, right = -1, begin = 0, end = 0;  // leaf if left < 0; items [begin, end) of the subtree
  };
  int build(int begin, int end, int depth);
  enum class Step { Skip, Descend, Stop };
  template <class Skip, class At>
  bool walk(const Shaft& s, std::span<const int> roots, Skip&& skip, At&& at) const;
  template <class Visit>
  bool traverse(const Shaft& s, int ia, int ib, std::span<const int> roots, Visit&& visit) const;
  template <class SkipNode, class SkipItem, class Visit>
  bool traverse(const Shaft& s, int ia, int ib, std::span<const int> roots, SkipNode&& skip_node, SkipItem&& skip_item,
                Visit&& visit) const;
  bool item_may_block(const Shaft& s, int p) const;
  const mesh::PatchGeometry* g_ = nullptr;
  std::vector<Node> nodes_;
  std::vector<int> items_;  // patch ids
  std::vector<Box> boxes_;  // per item
  std::vector<Vec3> centers_;
  std::vector<int> group_of_;     // per patch (set_groups)
  std::vector<int> node_group_;  // per node: the group of all its items, or -1 (set_groups)
};

}  // namespace lambert::formfactor::detail
