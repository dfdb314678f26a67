#pragma once
// Internals of the hierarchical operator (hierarchy.hpp): the cluster tree and the stored links.
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "internal.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "shaft.hpp"

namespace lambert::formfactor {

namespace detail {

struct HNode {
  Vec3 c = Vec3::Zero();     // area centroid (m)
  Vec3 S = Vec3::Zero();     // sum of area * normal over the patches (m^2)
  Vec3 axis = Vec3::UnitZ(); // normal cone axis (unit)
  double cone = 0;           // normal cone half-angle (radians), pi = any direction
  double cos_cone = 1, sin_cone = 0;
  double R = 0;              // radius of a sphere about c holding every corner (m)
  double area = 0;           // m^2
  double slab_lo = 0, slab_hi = 0;  // flat nodes: range of axis . (x - c) over the corners (m)
  bool flat = false;         // every normal within kFlatCone of axis
  Box box;
  int left = -1, right = -1;  // children (leaf: -1)
  int begin = 0, end = 0;     // patches perm[begin, end)
  int parent = -1, level = 0;
  bool leaf() const { return left < 0; }
};

constexpr double kFlatCone = 1e-7;  // radians

}  // namespace detail

struct HierarchicalOperator::Impl {
  const mesh::PatchGeometry* g = nullptr;       // the caller's geometry, or `owned`
  std::unique_ptr<mesh::PatchGeometry> owned;  // a copy moved to the origin (far scenes)
  int n = 0;
  detail::PatchData P;
  std::vector<detail::HNode> nodes;  // pre-order: parents before children
  std::vector<int> perm;             // patches in tree order
  std::vector<int> leaf_of;          // patch -> its leaf node
  // Far links per receiver node (CSR over nodes; flat sources first, then the others, each sorted by source): the
  // source node and the visible fraction.
  std::vector<std::int64_t> far_off;
  std::vector<int> far_src;
  std::vector<float> far_vis;
  std::vector<std::int64_t> far_flat;  // per receiver node: how many of its first links come from flat sources
  // Per node, -1 or its slot in apply()'s vector arrays: vec_slot for its vector moments (non-flat nodes, and flat
  // ones a non-flat receiver reads), acc_slot for a vector local record (non-flat nodes, and flat ones with non-flat
  // sources or a non-flat parent). Every node has a scalar record and a scalar local record.
  std::vector<int> vec_slot, acc_slot;
  int vec_slots = 0, acc_slots = 0;
  // Exact leaf entries, each patch pair once (CSR over the pair's source s, the patch of smaller area; sorted by
  // target t): F_st. Row t's entry F_ts = F_st A_s / A_t is formed in apply() (scattered into leaf_blocks.size() - 1
  // fixed row blocks' own arrays, summed in block order: the same result for any thread count). Arrays allocated
  // without zeroing, so that their pages become resident only as the build fills them.
  std::vector<std::int64_t> leaf_off;
  std::unique_ptr<int[]> leaf_src;
  std::unique_ptr<double[]> leaf_F;
  std::int64_t leaf_count = 0;
  std::vector<int> leaf_blocks;  // row boundaries of the transposed scatter's blocks (first 0, last n)
  // The transposed rows, for for_each_in_row only (built on its first call): per target t, the entries e of leaf
  // arrays with leaf_src[e] == t, by source.
  mutable std::once_flag transpose_once;
  mutable std::vector<std::int64_t> tr_off, tr_entry;
  mutable std::vector<int> tr_src;
  std::vector<double> row_sums;
  // Work arrays of apply(), reused between products (one set per concurrent caller; hierarchy_apply.cpp).
  struct Scratch;
  mutable std::mutex scratch_mutex;
  mutable std::vector<std::unique_ptr<Scratch>> scratch;
  ~Impl();
  std::size_t bytes() const;
};

}  // namespace lambert::formfactor
