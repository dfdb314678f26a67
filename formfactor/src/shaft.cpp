#include "shaft.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace lambert::formfactor::detail {

Shaft make_shaft(const Box& a, const Box& b) {
  Shaft s;
  s.box = a;
  s.box.add(b);
  // For two axes (u, v) and sides (su, sv): if the joint box's face on (u, su) comes from one box only and
  // its face on (v, sv) from the other only, the hull has a face through the corresponding edges of the two
  // boxes, parallel to the third axis.
  for (int u = 0; u < 3; ++u)
    for (int v = u + 1; v < 3; ++v)
      for (int su = 0; su < 2; ++su)
        for (int sv = 0; sv < 2; ++sv) {
          auto face = [](const Box& x, int axis, int side) { return side ? x.hi[axis] : x.lo[axis]; };
          auto beyond = [&](const Box& x, const Box& y, int axis, int side) {
            return side ? face(x, axis, side) > face(y, axis, side) : face(x, axis, side) < face(y, axis, side);
          };
          const bool a_u = beyond(a, b, u, su), b_u = beyond(b, a, u, su);
          const bool a_v = beyond(a, b, v, sv), b_v = beyond(b, a, v, sv);
          if (!((a_u && b_v) || (b_u && a_v))) continue;
          const double pu = face(a, u, su), pv = face(a, v, sv), qu = face(b, u, su), qv = face(b, v, sv);
          // Line through (pu, pv) and (qu, qv); its normal points towards the (su, sv) corner.
          double nu = qv - pv, nv = -(qu - pu);
          const double su_sign = su ? 1 : -1, sv_sign = sv ? 1 : -1;
          if (nu * su_sign + nv * sv_sign < 0) {
            nu = -nu;
            nv = -nv;
          }
          Vec3 n = Vec3::Zero();
          n[u] = nu;
          n[v] = nv;
          s.n[s.planes] = n;
          s.d[s.planes] = nu * pu + nv * pv;
          s.len[s.planes] = std::hypot(nu, nv);
          s.u[s.planes] = std::uint8_t(u);
          s.v[s.planes] = std::uint8_t(v);
          s.su[s.planes] = nu > 0 ? 0 : 1;
          s.sv[s.planes] = nv > 0 ? 0 : 1;
          ++s.planes;
        }
  return s;
}

Shaft grown_box_shaft(Box a, Box b, double pad, double eps) {
  for (Box* x : {&a, &b}) {
    x->lo.array() -= pad;
    x->hi.array() += pad;
  }
  Shaft s = make_shaft(a, b);
  s.ni = s.nj = Vec3::Zero();
  s.oi = s.oj = -INFINITY;
  s.eps = eps;
  return s;
}

namespace {
// Strict: a box that only touches the shaft's boundary (a face of the joint box, or a hull plane through edges of
// the two boxes) is outside. A segment between the two patches (or clusters) reaches such a supporting plane only
// where it lies in it, i.e. with both ends in it; pairs of points doing so have positive measure only for patches
// lying in that plane, which are coplanar and exchange nothing. So walls meeting a pair's patches at a room's
// corners, coplanar neighbours and a floor under a cluster standing on it need no ray.
// Touching is within s.eps (the scene's 1e-10): a wall meeting the boundary exactly at the origin meets it within
// rounding once the model is moved, on either side (examples/floorplan.obj moved by 1e6 m: 3,152 pairs refused by the
// portal test at one place and not at the other). What lies less than eps inside blocks at most the segments within
// eps of the boundary.
bool box_outside(const Shaft& s, const Box& c) {
  for (int k = 0; k < 3; ++k)
    if (c.hi[k] <= s.box.lo[k] + s.eps || c.lo[k] >= s.box.hi[k] - s.eps) return true;
  // Extreme corners, not centre and half extent: evaluated corner by corner, the test is monotone under rounding
  // (a box inside a box that is outside is outside), so the tree's pruning and a test of one occluder agree and
  // the answer does not depend on where a traversal starts (may_block's hint, hence on the thread count).
  auto lowest = [&](const Vec3& n) {  // min over the box of n . x
    return n.x() * (n.x() > 0 ? c.lo.x() : c.hi.x()) + n.y() * (n.y() > 0 ? c.lo.y() : c.hi.y()) +
           n.z() * (n.z() > 0 ? c.lo.z() : c.hi.z());
  };
  // The hull planes: n has zero third component, so lowest(n) = n_u c_u + n_v c_v (adding the exact zero term
  // changes nothing: the same value, bit for bit), with the corners chosen once per shaft.
  const double* corner[2] = {c.lo.data(), c.hi.data()};
  for (int p = 0; p < s.planes; ++p) {
    const Vec3& n = s.n[p];
    if (n[s.u[p]] * corner[s.su[p]][s.u[p]] + n[s.v[p]] * corner[s.sv[p]][s.v[p]] >= s.d[p] - s.eps * s.len[p])
      return true;
  }
  // Entirely in the closed back half-space of either patch: the open segments run strictly in front.
  if (-lowest(-s.ni) - s.oi <= s.eps) return true;
  if (-lowest(-s.nj) - s.oj <= s.eps) return true;
  return false;
}
}  // namespace

OccluderTree::OccluderTree(const mesh::PatchGeometry& g, const std::vector<int>& occluders) : g_(&g) {
  if (occluders.empty()) return;
  items_ = occluders;
  boxes_.resize(g.size());
  centers_.resize(g.size());
  for (int p : occluders) {
    Box b;
    for (const Vec3& v : g.polygon(p)) b.add(v);
    boxes_[p] = b;
    centers_[p] = 0.5 * (b.lo + b.hi);
  }
  nodes_.reserve(2 * occluders.size());
  build(0, int(items_.size()), 0);
}

int OccluderTree::build(int begin, int end, int depth) {
  const int id = int(nodes_.size());
  nodes_.emplace_back();
  Box b;
  for (int k = begin; k < end; ++k) b.add(boxes_[items_[k]]);
  nodes_[id].box = b;
  nodes_[id].begin = begin;
  nodes_[id].end = end;
  if (end - begin <= 4) return id;
  // Binned surface-area heuristic (Wald 2007): the split, over 3 axes x 31 bin boundaries of the centroids, that
  // minimises the children's box areas times their counts. Shafts inside a room then visit fewer nodes than with
  // a median split, whose boxes mix a room's walls with the next room's.
  Box cb;
  for (int k = begin; k < end; ++k) cb.add(centers_[items_[k]]);
  constexpr int kBins = 32;
  auto half_area = [](const Box& x) {
    const Vec3 e = (x.hi - x.lo).cwiseMax(0.0);
    return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
  };
  int best_axis = -1, best_bin = 0;
  double best_cost = INFINITY;
  // Past depth 32 the median split of the widest axis (at most log2(n) more levels: the traversal's stack of 64).
  for (int axis = 0; axis < 3 && depth < 32; ++axis) {
    const double lo = cb.lo[axis], width = cb.hi[axis] - cb.lo[axis];
    if (!(width > 0)) continue;
    std::array<Box, kBins> bin_box;
    std::array<int, kBins> bin_count{};
    auto bin_of = [&](int p) { return std::min(kBins - 1, int(kBins * (centers_[p][axis] - lo) / width)); };
    for (int k = begin; k < end; ++k) {
      const int p = items_[k], j = bin_of(p);
      ++bin_count[j];
      bin_box[j].add(boxes_[p]);
    }
    std::array<double, kBins> right_cost{};
    Box acc;
    int cnt = 0;
    for (int j = kBins - 1; j > 0; --j) {
      acc.add(bin_box[j]);
      cnt += bin_count[j];
      right_cost[j] = cnt ? half_area(acc) * cnt : 0.0;
    }
    acc = Box();
    cnt = 0;
    for (int j = 0; j < kBins - 1; ++j) {
      acc.add(bin_box[j]);
      cnt += bin_count[j];
      if (cnt == 0 || cnt == end - begin) continue;
      const double cost = half_area(acc) * cnt + right_cost[j + 1];
      if (cost < best_cost) best_cost = cost, best_axis = axis, best_bin = j;
    }
  }
  int mid = (begin + end) / 2;
  if (best_axis >= 0) {
    const int axis = best_axis;
    const double lo = cb.lo[axis], width = cb.hi[axis] - cb.lo[axis];
    auto it = std::partition(items_.begin() + begin, items_.begin() + end, [&](int p) {
      return std::min(kBins - 1, int(kBins * (centers_[p][axis] - lo) / width)) <= best_bin;
    });
    mid = int(it - items_.begin());
  } else {
    int axis = 0;
    const Vec3 ext = cb.hi - cb.lo;
    if (ext[1] > ext[axis]) axis = 1;
    if (ext[2] > ext[axis]) axis = 2;
    std::nth_element(items_.begin() + begin, items_.begin() + mid, items_.begin() + end,
                     [&](int x, int y) { return centers_[x][axis] < centers_[y][axis] || (centers_[x][axis] == centers_[y][axis] && x < y); });
  }
  const int l = build(begin, mid, depth + 1);
  const int r = build(mid, end, depth + 1);
  nodes_[id].left = l;
  nodes_[id].right = r;
  return id;
}

bool polygon_may_meet(const Shaft& s, const Box& box, std::span<const Vec3> poly) {
  if (box_outside(s, box)) return false;
  // Tighter: the polygon's own corners against the shaft planes and the two patch planes.
  for (int q = 0; q < s.planes; ++q) {
    bool out = true;
    for (const Vec3& v : poly)
      if (s.n[q].dot(v) < s.d[q] - s.eps * s.len[q]) {
        out = false;
        break;
      }
    if (out) return false;
  }
  bool behind_i = true, behind_j = true;
  for (const Vec3& v : poly) {
    behind_i = behind_i && s.ni.dot(v) - s.oi <= s.eps;
    behind_j = behind_j && s.nj.dot(v) - s.oj <= s.eps;
  }
  return !(behind_i || behind_j);
}

bool OccluderTree::item_may_block(const Shaft& s, int p) const { return polygon_may_meet(s, boxes_[p], g_->polygon(p)); }

// The roots in turn, each depth first (left child first), over the nodes whose box meets the shaft: the order of a
// walk from the tree's root, for a frontier of any size (one of more than 64 nodes used to be walked from the root
// instead). Nodes with skip(id) are passed over before their box test; at(id, node) says whether to go on to the
// node's children, not to, or to end the walk (which then returns true). The stack holds one pending right child per
// level below a root (depth <= 64: build).
template <class Skip, class At>
bool OccluderTree::walk(const Shaft& s, std::span<const int> roots, Skip&& skip, At&& at) const {
  int stack[72];
  for (const int r : roots) {
    int top = 0;
    stack[top++] = r;
    while (top > 0) {
      const int id = stack[--top];
      const Node& nd = nodes_[id];
      if (skip(id) || box_outside(s, nd.box)) continue;
      const Step step = at(id, nd);
      if (step == Step::Stop) return true;
      if (step == Step::Descend) {
        stack[top++] = nd.right;
        stack[top++] = nd.left;
      }
    }
  }
  return false;
}

// Visits, in tree order (left subtree first), every occluder other than ia and ib that may meet the shaft,
// until `visit` returns true; returns whether it did. From the root, or from `roots` (a frontier, in order).
// Subtrees with skip_node(node) and occluders with skip_item(p) are passed over without their tests.
template <class SkipNode, class SkipItem, class Visit>
bool OccluderTree::traverse(const Shaft& s, int ia, int ib, std::span<const int> roots, SkipNode&& skip_node,
                            SkipItem&& skip_item, Visit&& visit) const {
  if (nodes_.empty()) return false;
  return walk(s, roots, skip_node, [&](int, const Node& nd) {
    if (nd.left >= 0) return Step::Descend;
    for (int k = nd.begin; k < nd.end; ++k) {
      const int p = items_[k];
      if (p != ia && p != ib && !skip_item(p) && item_may_block(s, p) && visit(p)) return Step::Stop;
    }
    return Step::Skip;
  });
}

template <class Visit>
bool OccluderTree::traverse(const Shaft& s, int ia, int ib, std::span<const int> roots, Visit&& visit) const {
  auto none = [](int) { return false; };
  return traverse(s, ia, ib, roots, none, none, visit);
}

bool OccluderTree::may_block(const Shaft& s, int ia, int ib, int* hint) const {
  return may_block_from(s, ia, ib, root(), hint);
}

void OccluderTree::collect(const Shaft& s, int ia, int ib, std::vector<int>& out) const {
  collect_from(s, ia, ib, root(), out);
}

bool OccluderTree::may_block_from(const Shaft& s, int ia, int ib, std::span<const int> from, int* hint) const {
  if (hint && *hint >= 0 && *hint != ia && *hint != ib && item_may_block(s, *hint)) return true;
  return traverse(s, ia, ib, from, [&](int p) {
    if (hint) *hint = p;
    return true;
  });
}

void OccluderTree::collect_from(const Shaft& s, int ia, int ib, std::span<const int> from,
                                std::vector<int>& out) const {
  traverse(s, ia, ib, from, [&](int p) {
    out.push_back(p);
    return false;
  });
}

void OccluderTree::set_groups(const std::vector<int>& group_of) {
  group_of_ = group_of;
  node_group_.assign(nodes_.size(), -1);
  if (group_of.empty()) return;
  // Children come after their parent (build): bottom-up in reverse order.
  for (size_t id = nodes_.size(); id-- > 0;) {
    const Node& nd = nodes_[id];
    int g = -1;
    if (nd.left < 0) {
      g = group_of[size_t(items_[size_t(nd.begin)])];
      for (int k = nd.begin + 1; k < nd.end && g >= 0; ++k)
        if (group_of[size_t(items_[size_t(k)])] != g) g = -1;
    } else if (node_group_[size_t(nd.left)] == node_group_[size_t(nd.right)]) {
      g = node_group_[size_t(nd.left)];
    }
    node_group_[id] = g;
  }
}

void OccluderTree::collect_grouped_from(const Shaft& s, int ia, int ib, std::span<const int> roots,
                                        const std::function<bool(int)>& accept, std::vector<int>& out,
                                        std::vector<int>& seen) const {
  seen.clear();
  const bool groups = !group_of_.empty() && node_group_.size() == nodes_.size();
  auto listed = [&](int g) { return g >= 0 && std::find(seen.begin(), seen.end(), g) != seen.end(); };
  traverse(
      s, ia, ib, roots, [&](int node) { return groups && listed(node_group_[size_t(node)]); },
      [&](int p) { return groups && listed(group_of_[size_t(p)]); },
      [&](int p) {
        if (!accept(p)) return false;
        out.push_back(p);
        if (groups && group_of_[size_t(p)] >= 0) seen.push_back(group_of_[size_t(p)]);
        return false;
      });
}

void OccluderTree::frontier(const Shaft& s, int items, std::vector<int>& out) const { frontier_from(s, items, root(), out); }

void OccluderTree::frontier_from(const Shaft& s, int items, std::span<const int> roots, std::vector<int>& out) const {
  if (nodes_.empty()) return;
  walk(s, roots, [](int) { return false; }, [&](int id, const Node& nd) {
    if (nd.left >= 0 && nd.end - nd.begin > items) return Step::Descend;
    out.push_back(id);
    return Step::Skip;
  });
}

}  // namespace lambert::formfactor::detail
