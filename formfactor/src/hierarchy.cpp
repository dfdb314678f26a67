// Hierarchical operator: the cluster tree and the refinement oracle that creates the links (hierarchy.hpp).
#include <tbb/enumerable_thread_specific.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <map>
#include <memory>
#include <numeric>
#include <span>
#include <string>

#include "batch.hpp"
#include "hierarchy_internal.hpp"
#include "internal.hpp"
#include "enclosures.hpp"
#include "portals.hpp"
#include "exact_visibility.hpp"
#include "sampling.hpp"

namespace lambert::formfactor {

using detail::Box;
using detail::HNode;
using detail::kPi;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Angle between unit vectors, accurate near 0 (atan2, not acos).
double angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

// ---------------------------------------------------------------------------------------------------------
// The tree.

struct TreeBuilder {
  const mesh::PatchGeometry& g;
  std::vector<HNode>& nodes;
  std::vector<int>& perm;
  std::vector<Box> pbox;
  std::span<const int> cell;   // per patch: its room (portals.hpp) or cell (enclosures.hpp), or empty
  std::span<const int> outer;  // per patch: its cell (enclosures.hpp), which holds whole rooms, or empty
  // Values closer than this are one value (centroid coordinates; normals' use 1e-9): set to 1e-9 of the scene's size,
  // so that the tree does not depend on where the model sits. A model moved by 4,000 km has its corners rounded by
  // ~1e-9 m: coordinates equal in the file (a lattice city's rows of buildings) come out unequal by that much, and
  // ordering them by their exact values (or picking the larger of two equal extents) built another tree.
  double eps_c = 0;
  std::vector<int> rank;  // scratch, per patch: the index of its run of equal values among its node's patches

  bool mixed(std::span<const int> c, int begin, int end) const {
    if (c.empty()) return false;
    for (int k = begin + 1; k < end; ++k)
      if (c[perm[k]] != c[perm[begin]]) return true;
    return false;
  }

  int build(int begin, int end, int parent, int level) {
    const int id = int(nodes.size());
    nodes.emplace_back();
    nodes[id].begin = begin;
    nodes[id].end = end;
    nodes[id].parent = parent;
    nodes[id].level = level;
    if (end - begin == 1) {
      leaf(id, perm[begin]);
      return id;
    }
    // Split key: the largest of the centroids' extents and the normals' extents times half the node's size.
    Box cb, nb;
    for (int k = begin; k < end; ++k) {
      cb.add(g.centroid[perm[k]]);
      nb.add(g.normal[perm[k]]);
    }
    const Vec3 ce = cb.hi - cb.lo, ne = (nb.hi - nb.lo) * (0.5 * ce.norm());
    // The largest extent; extents within 1e-9 of it (relative) or within 2 eps_c (what two rounded values can move
    // an extent: two 5 cm patches side by side diagonally in a moved model) count as equal to it, and the first of
    // them wins.
    double best = 0;
    for (int k = 0; k < 3; ++k) best = std::max({best, ce[k], ne[k]});
    const double tie = best - std::max(best * 1e-9, 2 * eps_c);
    int key = 0;
    for (int k = 0, found = 0; k < 3 && !found; ++k) {
      if (ce[k] >= tie) key = k, found = 1;
      else if (ne[k] >= tie) key = 3 + k, found = 1;
    }
    int mid = (begin + end) / 2;
    auto value = [&](int p) { return key < 3 ? g.centroid[p][key] : g.normal[p][key - 3]; };
    // Order by value, values within eps of their neighbour in that order being one value (a run), ties by patch.
    // rank[p] = the run's index (the same for every patch of it).
    const double eps = key < 3 ? eps_c : 1e-9;
    std::sort(perm.begin() + begin, perm.begin() + end, [&](int a, int b) {
      const double va = value(a), vb = value(b);
      return va < vb || (va == vb && a < b);
    });
    if (rank.size() < g.centroid.size()) rank.resize(g.centroid.size());
    for (int k = begin, run = 0, start = begin; k <= end; ++k) {
      if (k < end && k > begin && value(perm[k]) - value(perm[k - 1]) <= eps) continue;
      if (k > begin) std::sort(perm.begin() + start, perm.begin() + k);  // within a run: by patch
      for (int j = start; j < k; ++j) rank[size_t(perm[j])] = run;
      start = k, ++run;
    }
    // Patches of several cells (enclosures.hpp), else of several rooms: whole cells (rooms) go to one side, ordered
    // by their mean key, and the split falls between them nearest the median, so that the nodes below hold one cell
    // (room) each and the refinement can refuse pairs across cells at once. Cells first: a node above them holds
    // whole cells, and meets any node outside it in none of them (Refiner::setup).
    const std::span<const int> group = mixed(outer, begin, end) ? outer : mixed(cell, begin, end) ? cell : std::span<const int>();
    if (!group.empty()) {
      // Cells ordered by their mean rank (sums of integers: equal means are equal exactly), then by cell.
      std::map<int, std::pair<long long, long long>> mean;
      for (int k = begin; k < end; ++k) {
        auto& m = mean[group[perm[k]]];
        m.first += rank[size_t(perm[k])];
        ++m.second;
      }
      struct Key {
        long long sum, count;
        int cell;
        int r;
        int p;
      };
      std::vector<Key> keys;
      keys.reserve(size_t(end - begin));
      for (int k = begin; k < end; ++k) {
        const int p = perm[k];
        const auto& m = mean[group[p]];
        keys.push_back({m.first, m.second, group[p], rank[size_t(p)], p});
      }
      std::sort(keys.begin(), keys.end(), [](const Key& x, const Key& y) {
        if (x.cell != y.cell) {
          __extension__ typedef __int128 Wide;  // sums of ranks times counts: beyond 64 bits above ~3 M patches
          const Wide lx = Wide(x.sum) * y.count, ly = Wide(y.sum) * x.count;
          return lx < ly || (lx == ly && x.cell < y.cell);
        }
        return x.r < y.r || (x.r == y.r && x.p < y.p);
      });
      for (int k = begin; k < end; ++k) perm[k] = keys[size_t(k - begin)].p;
      int best_mid = -1;
      for (int k = begin + 1; k < end; ++k)
        if (group[perm[k]] != group[perm[k - 1]] && (best_mid < 0 || std::abs(k - mid) < std::abs(best_mid - mid)))
          best_mid = k;
      mid = best_mid;
    }  // else: perm is in (rank, patch) order already, split at the median
    const int l = build(begin, mid, id, level + 1);
    const int r = build(mid, end, id, level + 1);
    nodes[id].left = l;
    nodes[id].right = r;
    merge(id);
    return id;
  }

  void leaf(int id, int p) {
    HNode& nd = nodes[id];
    nd.c = g.centroid[p];
    nd.area = g.area[p];
    nd.S = g.area[p] * g.normal[p];
    nd.axis = g.normal[p];
    nd.cone = 0;
    nd.flat = true;
    nd.box = pbox[p];
    double R = 0, lo = INFINITY, hi = -INFINITY;
    for (const Vec3& v : g.polygon(p)) {
      R = std::max(R, (v - nd.c).norm());
      const double h = nd.axis.dot(v - nd.c);
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
    nd.R = R;
    nd.slab_lo = lo;
    nd.slab_hi = hi;
  }

  void merge(int id) {
    HNode& nd = nodes[id];
    const HNode &a = nodes[nd.left], &b = nodes[nd.right];
    nd.area = a.area + b.area;
    nd.c = (a.area * a.c + b.area * b.c) / nd.area;
    nd.S = a.S + b.S;
    nd.box = a.box;
    nd.box.add(b.box);
    nd.R = std::max((a.c - nd.c).norm() + a.R, (b.c - nd.c).norm() + b.R);
    const double sn = nd.S.norm();
    if (!(sn > 1e-12 * nd.area)) {
      nd.axis = Vec3::UnitZ();
      nd.cone = kPi;
    } else {
      nd.axis = nd.S / sn;
      nd.cone = std::min(kPi, std::max(angle(nd.axis, a.axis) + a.cone, angle(nd.axis, b.axis) + b.cone));
    }
    nd.cos_cone = std::cos(nd.cone);
    nd.sin_cone = std::sin(nd.cone);
    nd.flat = nd.cone <= detail::kFlatCone && a.flat && b.flat;
    if (nd.flat) {
      double lo = INFINITY, hi = -INFINITY;
      for (const HNode* c : {&a, &b}) {
        const double shift = nd.axis.dot(c->c - nd.c), tilt = (nd.axis - c->axis).norm() * c->R;
        lo = std::min(lo, c->slab_lo + shift - tilt);
        hi = std::max(hi, c->slab_hi + shift + tilt);
      }
      nd.slab_lo = lo;
      nd.slab_hi = hi;
    }
  }
};

// ---------------------------------------------------------------------------------------------------------
// Links.

struct FarRecord {
  int a, b;          // unordered node pair
  float vis;
  float err_ab, err_ba;    // admitted F error for receivers in a (from b), in b (from a)
  float lerr_ab, lerr_ba;  // the same times Lmax of the source, relative to L_ref
};
struct LeafRecord {
  int s, t;    // the pair's source (the smaller area) and target
  double Fst;  // stored once: apply() forms F_ts = F_st A_s / A_t
};
// A leaf link's records go into buckets of kBucketRows consecutive sources (per thread), so that the build can
// sort and store them a bucket at a time, freeing each bucket's records as it goes: the records and the stored
// entries (index + factor, 12 bytes) are not all in memory at once.
constexpr int kBucketLog = 12, kBucketRows = 1 << kBucketLog;
// Bytes a link holds at the build's peak: its record, and some slack for partly filled blocks.
constexpr std::size_t kLinkPeakBytes = sizeof(LeafRecord) + 4;

// Append-only storage in fixed blocks of 2^BlockLog: growing it copies nothing and leaves no doubling slack (the
// link records of a 300k-patch building are gigabytes).
template <class T, int BlockLog = 15>
class Chunked {
 public:
  void push_back(const T& v) {
    if (size_ % kBlock == 0) blocks_.emplace_back(new T[kBlock]);
    blocks_.back()[size_ % kBlock] = v;
    ++size_;
  }
  std::size_t size() const { return size_; }
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t k = 0; k < size_; ++k) f(blocks_[k / kBlock][k % kBlock]);
  }
  void clear() {
    blocks_.clear();
    blocks_.shrink_to_fit();
    size_ = 0;
  }

 private:
  static constexpr std::size_t kBlock = std::size_t(1) << BlockLog;
  std::vector<std::unique_ptr<T[]>> blocks_;
  std::size_t size_ = 0;
};

// Rows [0, rows) of a CSR (off, src, val) in the order the records came: each row's entries sorted by source
// (a link's two nodes or patches are one pair only once, so the order is unique: the same for any thread count).
// first(s) true comes before false (the hierarchy's flat sources before the others).
template <class V, class First>
void sort_rows(const std::vector<std::int64_t>& off, std::vector<int>& src, std::vector<V>& val, First first) {
  const int rows = int(off.size()) - 1;
  tbb::parallel_for(tbb::blocked_range<int>(0, rows, 512), [&](const tbb::blocked_range<int>& r) {
    std::vector<std::pair<int, V>> row;
    for (int k = r.begin(); k < r.end(); ++k) {
      const std::int64_t e0 = off[size_t(k)], e1 = off[size_t(k) + 1];
      row.clear();
      for (std::int64_t e = e0; e < e1; ++e) row.push_back({src[size_t(e)], val[size_t(e)]});
      std::sort(row.begin(), row.end(), [&](const auto& x, const auto& y) {
        const bool fx = first(x.first), fy = first(y.first);
        return fx != fy ? fx : x.first < y.first;
      });
      for (std::int64_t e = e0; e < e1; ++e) {
        src[size_t(e)] = row[size_t(e - e0)].first;
        val[size_t(e)] = row[size_t(e - e0)].second;
      }
    }
  });
}

struct Local {
  Chunked<FarRecord> far;  // links that carry light (blocked links keep only their admitted error, below)
  std::vector<Chunked<LeafRecord, 12>> leaf;  // per bucket of sources (kBucketRows; blocks of 2^12 records, 64 kB)
  std::vector<double> leaf_err, leaf_sig2;    // per patch: admitted error and visibility variance of its leaf links
  std::vector<double> blocked_err, blocked_lerr;  // per node: admitted error of its blocked links (or empty)
  long long culled = 0, cell_culled = 0, portal_culled = 0, dark_culled = 0, shaft_clear = 0, ray_tested = 0, rays = 0, blocked = 0, pair_ray_tested = 0, pair_shaft_clear = 0;
  long long exact_clear = 0, exact_hidden = 0, exact_integrated = 0, exact_points = 0, exact_over = 0;
  detail::SampleBuffers sb;
  std::vector<Vec3> pa, pb;
  // A cluster link's rays, traced a batch at a time: ends, patches, weights, results.
  std::vector<Vec3> ray_from, ray_to;
  std::vector<int> ray_pa, ray_pb;
  std::vector<double> ray_w;  // per ray drawn: its weight, or -1 where the points do not face each other
  std::vector<std::uint8_t> ray_hidden;
  int hint = -1;
  double progress_pending = 0;  // Refiner::progress
  long long progress_calls = 0, links_pending = 0;
  detail::ExactScratchPtr exact = detail::make_exact_scratch();
  std::vector<int> cand, merged_ids, seen;
  std::vector<detail::Occluder> occ;
};

// The far field's error model's constant (try_far).
constexpr double kExpansionConstant = 0.005;
constexpr int kMaxBlockedRays = 256;
// Rays that all agree (all blocked, or all free) bound the other kind's share by kRayConfidence / rays: 3 is the
// "rule of three", a 95 % upper confidence bound (1 would be 63 %).
constexpr double kRayConfidence = 3.0;
// A link whose error (times its source's brightness) is below this fraction of the link tolerance is accepted
// whatever its relative error (grazing and distant links).
constexpr double kAbsolute = 0.002;
// Automatic per-entry tolerance of the leaf pairs, as a fraction of the link tolerance (build_hierarchy).
constexpr double kEntryShare = 1e-3;

struct VisResult {
  double V = 1, uncertainty = 0;
  bool refine = false;  // the shaft may be blocked and rays were not worth casting, or they ruled the link out
  int cast = 0;         // rays drawn (blocked links: each patch of a node had cast / its patch count of them)
};

// Which outcomes of a cluster link's rays the link would accept (try_far), so the rays can stop once decided.
struct RayGoals {
  bool visible_ok = true;  // every ray free: V = 1, uncertainty kRayConfidence / cluster_rays
  bool mixed_ok = true;    // free and blocked rays: V estimated, uncertainty 0.5
  int max_rays = 0;        // rays worth casting to certify a blocked link (0: cluster_rays only)
  // Every one of `cast` rays blocked: accepted if the transmittance they may have missed times k_hi A (kB =
  // k_hi A_B, kA = k_hi A_A) and the source's brightness is within tol, either way, for every receiving patch: the
  // rays go to each node's patches in turn, so each patch of A had cast / mA of them (at least), and what they may
  // have missed is kRayConfidence / (cast / mA) of what that patch receives. The same expression, in the same order,
  // as try_far's test of the result.
  double kB = 0, lb = 0, kA = 0, la = 0, tol = 1;
  int mA = 1, mB = 1;
  bool blocked_ok(int cast) const {
    const int ca = cast / mA, cb = cast / mB;
    if (ca == 0 || cb == 0) return false;
    return kB * (kRayConfidence / ca) * lb <= tol && kA * (kRayConfidence / cb) * la <= tol;
  }
};

class Refiner {
 public:
  Refiner(const mesh::PatchGeometry& g, const HierarchyOptions& o, HierarchicalOperator::Impl& d, double etol,
          std::size_t limit)
      : g_(g), o_(o), d_(d), etol_(etol), limit_(limit), psoa_(d.P) {}

  // occ: the potential occluders (potential_occluders); cell: per patch, the cells of the closed surfaces
  // (enclosures.hpp), or empty.
  // rooms: the closed surfaces with the openings closed by portals (portals.hpp), or null.
  void setup(const std::vector<int>& occ, std::span<const int> cell, const detail::Rooms* rooms = nullptr) {
    const int n = d_.n;
    const int cells = cell.empty() ? 0 : std::max(0, *std::max_element(cell.begin(), cell.end()) + 1);
    // Brightness per node (max over its patches), relative to the brightest.
    lmax_.assign(d_.nodes.size(), 1.0);
    lref_ = 1;
    if (!o_.brightness.empty()) {
      lref_ = 0;
      for (double b : o_.brightness) lref_ = std::max(lref_, b);
      if (!(lref_ > 0)) lref_ = 1;
      // A closed cell without an emitter is dark: no light enters it from another cell (the refinement refuses
      // pairs across cells on the same grounds), so its radiance is 0 in any solution.
      std::vector<std::uint8_t> dark;
      if (!o_.emission.empty() && !cell.empty()) {
        std::vector<std::uint8_t> emits(size_t(cells), 0);
        for (int p = 0; p < n; ++p)
          if (cell[p] >= 0 && o_.emission[size_t(p)] > 0) emits[size_t(cell[p])] = 1;
        dark.assign(size_t(n), 0);
        for (int p = 0; p < n; ++p) dark[size_t(p)] = cell[p] >= 0 && !emits[size_t(cell[p])];
        for (int c = 0; c < cells; ++c) dark_cells += !emits[size_t(c)];
      }
      for (int k = int(d_.nodes.size()) - 1; k >= 0; --k) {
        const HNode& nd = d_.nodes[k];
        const int p = d_.perm[nd.begin];
        lmax_[k] = nd.leaf() ? (!dark.empty() && dark[size_t(p)] ? 0.0 : o_.brightness[size_t(p)])
                             : std::max(lmax_[nd.left], lmax_[nd.right]);
        if (nd.leaf() && lmax_[k] == 0) ++dark_patches;
      }
    }
    pbox_.resize(n);
    for (int p = 0; p < n; ++p)
      for (const Vec3& v : g_.polygon(p)) pbox_[p].add(v);
    if (o_.visibility && n > 1) {
      if (!occ.empty()) {
        caster_ = o_.caster ? o_.caster : std::shared_ptr<const Visibility>(make_embree_visibility(g_, occ));
        tree_ = detail::OccluderTree(g_, occ);
        occlusion_ = true;
        if (o_.visibility_method != VisibilityMethod::Rays) {
          Eigen::AlignedBox3d box;
          for (const Vec3& v : g_.points) box.extend(v);
          scale_ = box.diagonal().norm();
          convex_.assign(size_t(n), 0);
          for (int p = 0; p < n; ++p) convex_[size_t(p)] = d_.P.kind[p] <= 2;  // triangle, parallelogram, convex quad
          merged_ = detail::merge_coplanar_occluders(g_, occ, scale_);
          tree_.set_groups(merged_.of_patch);
        }
      }
    }
    total_ = 0.5 * d_.nodes[0].area * d_.nodes[0].area;
    // Cells of the closed surfaces, per node: the common cell of its patches, or -1.
    node_cell_.assign(d_.nodes.size(), -1);
    if (occlusion_ && !cell.empty())
      for (int k = int(d_.nodes.size()) - 1; k >= 0; --k) {
        const HNode& nd = d_.nodes[k];
        node_cell_[k] = nd.leaf() ? cell[d_.perm[nd.begin]]
                                  : (node_cell_[nd.left] == node_cell_[nd.right] ? node_cell_[nd.left] : -1);
      }
    // Nodes that hold every patch of each cell they touch, and no patch of unknown cell (bit 0), and nodes that hold
    // a patch of unknown cell (bit 1): no patch outside a node of the first kind shares a cell with one inside it.
    node_cells_.assign(d_.nodes.size(), 0);
    if (occlusion_ && !cell.empty()) {
      std::vector<int> first(size_t(cells), n), last(size_t(cells), -1);
      for (int k = 0; k < n; ++k)
        if (const int c = cell[d_.perm[k]]; c >= 0) first[size_t(c)] = std::min(first[size_t(c)], k), last[size_t(c)] = k;
      std::vector<int> lo(d_.nodes.size()), hi(d_.nodes.size());
      for (int k = int(d_.nodes.size()) - 1; k >= 0; --k) {
        const HNode& nd = d_.nodes[k];
        std::uint8_t unknown = 0;
        if (nd.leaf()) {
          const int c = cell[d_.perm[nd.begin]];
          unknown = c < 0;
          lo[k] = c < 0 ? -1 : first[size_t(c)];
          hi[k] = c < 0 ? n : last[size_t(c)];
        } else {
          unknown = (node_cells_[nd.left] | node_cells_[nd.right]) & 2;
          lo[k] = std::min(lo[nd.left], lo[nd.right]);
          hi[k] = std::max(hi[nd.left], hi[nd.right]);
        }
        node_cells_[k] = unknown ? 2 : (lo[k] >= nd.begin && hi[k] < nd.end ? 1 : 0);
      }
    }
    // Rooms (cells with the openings closed) per node.
    node_room_.assign(d_.nodes.size(), -1);
    if (occlusion_ && rooms && !rooms->empty()) {
      rooms_ = rooms;
      for (int k = int(d_.nodes.size()) - 1; k >= 0; --k) {
        const HNode& nd = d_.nodes[k];
        node_room_[k] = nd.leaf() ? rooms->cell[size_t(d_.perm[nd.begin])]
                                  : (node_room_[nd.left] == node_room_[nd.right] ? node_room_[nd.left] : -1);
      }
    }
  }

  void run() { refine(0, 0); }

  // Nodes in different rooms: light between them crosses every surface that holds one and not the other, and
  // only through its portals (its other faces are opaque). False when the shaft between the nodes (as
  // link_visibility's) meets no portal of one of those surfaces: nothing passes.
  bool portal_path(const HNode& A, const HNode& B, int ra, int rb) const {
    return rooms_->path(node_shaft(A, B), ra, rb);
  }

  // The shaft between two nodes' boxes, in front of the planes of flat ones: where the segments between them run.
  detail::Shaft node_shaft(const HNode& A, const HNode& B) const {
    detail::Shaft sh = detail::make_shaft(A.box, B.box);
    sh.ni = A.flat ? A.axis : Vec3::Zero();
    sh.oi = A.flat ? A.axis.dot(A.c) + A.slab_lo : -INFINITY;
    sh.nj = B.flat ? B.axis : Vec3::Zero();
    sh.oj = B.flat ? B.axis.dot(B.c) + B.slab_lo : -INFINITY;
    sh.eps = d_.P.scene_eps;
    return sh;
  }

  tbb::enumerable_thread_specific<Local> locals;
  double lref() const { return lref_; }
  long long dark_cells = 0, dark_patches = 0;  // setup
  const std::vector<double>& lmax() const { return lmax_; }

 private:
  static constexpr int kParallelLevels = 14;
  // Pairs of at most kFrontierPatches patches find their shaft's frontier in the occluder tree (nodes of at most
  // kFrontierItems occluders) for the pairs below them.
  // (10k building, user time, minimum of three: 64 / 32 as good as any of 16-256 / 8-32.)
  static constexpr int kFrontierPatches = 64;
  static constexpr int kFrontierItems = 32;
  static constexpr int kCoarsePatches = 4096;
  static constexpr int kCoarseItems = 1024;
  static std::span<const int> walk_from(const std::vector<int>* from) {
    return from ? std::span<const int>(*from) : detail::OccluderTree::root();
  }

  // Per thread, flushed every 1,024 calls: the shared counter, lock and clock once per call cost ~3 % of the build.
  void progress(double amount, Local& loc) {
    if (!o_.progress) return;
    loc.progress_pending += amount;
    if ((++loc.progress_calls & 1023) != 0) return;
    const double d = done_.fetch_add(loc.progress_pending) + loc.progress_pending;
    loc.progress_pending = 0;
    std::unique_lock lock(progress_mutex_, std::try_to_lock);
    if (lock.owns_lock() && since(last_) >= 0.1) {
      last_ = Clock::now();
      o_.progress(std::min(1.0, d / total_));
    }
  }

  // Links counted per thread, checked against the limit every 4,096 of a thread's links.
  void check_memory(Local& loc) {
    if ((++loc.links_pending & 4095) != 0) return;
    const long long k = links_.fetch_add(4096) + 4096;
    if (std::size_t(k) * kLinkPeakBytes + d_.bytes() > limit_)
      throw InputError("hierarchical operator: the links outgrow the memory limit (" + std::to_string(k) +
                       " links so far, ~" + std::to_string((std::size_t(k) * kLinkPeakBytes + d_.bytes()) >> 20) +
                       " MB, limit " +
                       std::to_string(limit_ >> 20) +
                       " MB); raise --hierarchy-tolerance, use fewer patches (--max-edge) or more memory");
  }

  // max over y's corners of n . (q - c_y) (n unit).
  static double support(const HNode& y, const Vec3& n) {
    const Vec3 ctr = 0.5 * (y.box.lo + y.box.hi), half = 0.5 * (y.box.hi - y.box.lo);
    const double by_box = n.dot(ctr - y.c) + n.cwiseAbs().dot(half);
    if (!y.flat) return by_box;
    const double a = n.dot(y.axis);
    return std::min(by_box, std::max(a * y.slab_hi, a * y.slab_lo) + (n - a * y.axis).norm() * y.R);
  }

  // Every receiver of x sees nothing of y (each patch of y is behind or in the plane of each patch of x).
  bool faces_away(const HNode& x, const HNode& y) const {
    const Vec3 U = y.c - x.c;
    const double D = U.norm();
    if (x.flat) {
      const Vec3& n = x.axis;
      const double sup = support(y, n);
      const double eps = d_.P.scene_eps + x.cone * (D + x.R + y.R);
      return n.dot(U) + sup <= x.slab_lo + eps;
    }
    if (!(D > x.R + y.R)) return false;
    // angle(axis, U) - cone - delta >= pi/2, delta = asin((R_x + R_y) / D), without trigonometric calls:
    // needs theta >= pi/2 and cone + delta <= pi/2, then cos(theta - cone - delta) <= 0.
    const double sd = (x.R + y.R) / D, cd = std::sqrt(1 - sd * sd);
    const double c1 = x.axis.dot(U) / D;
    if (c1 > 0) return false;
    const double s1 = x.axis.cross(U).norm() / D;
    const double cad = x.cos_cone * cd - x.sin_cone * sd;  // cos(cone + delta)
    if (cad < 0) return false;
    const double sad = x.sin_cone * cd + x.cos_cone * sd;
    return c1 * cad + s1 * sad <= 0;  // cos(theta - (cone + delta))
  }

  // from: the occluder tree's frontier for an enclosing pair's shaft (see below), or null.
  // level: what `from` is (0: none, the tree's root; 1: a coarse frontier; 2: a fine one).
  void refine(int a, int b, const std::vector<int>* from = nullptr, int level = 0) {
    const HNode &A = d_.nodes[a], &B = d_.nodes[b];
    if (a == b) {
      if (A.leaf()) {
        progress(0.5 * A.area * A.area, locals.local());
        return;
      }
      const int l = A.left, r = A.right;
      if (A.level < kParallelLevels)
        tbb::parallel_invoke([&] { refine(l, l, from, level); }, [&] { refine(r, r, from, level); },
                             [&] { refine(l, r, from, level); });
      else {
        refine(l, l, from, level);
        refine(r, r, from, level);
        refine(l, r, from, level);
      }
      return;
    }
    Local& loc = locals.local();
    if (faces_away(A, B) || faces_away(B, A)) {
      ++loc.culled;
      progress(A.area * B.area, loc);
      return;
    }
    if ((node_cell_[a] >= 0 && node_cell_[b] >= 0 && node_cell_[a] != node_cell_[b]) ||
        ((node_cells_[a] & 1) && !(node_cells_[b] & 2)) || ((node_cells_[b] & 1) && !(node_cells_[a] & 2))) {
      ++loc.cell_culled;
      progress(A.area * B.area, loc);
      return;
    }
    if (node_room_[a] >= 0 && node_room_[b] >= 0 && node_room_[a] != node_room_[b] &&
        !portal_path(A, B, node_room_[a], node_room_[b])) {
      ++loc.portal_culled;
      progress(A.area * B.area, loc);
      return;
    }
    if (o_.radiance_only && lmax_[a] == 0 && lmax_[b] == 0) {
      // Nothing either side can send (brightness 0: black non-emitters, dark cells): no link, no ray. Each side's
      // rows admit the largest form factor the other could give them: A_other cos cos / (pi d_min^2) <= that
      // without the cosines, or 1 where the nodes' spheres meet.
      const double dmin = (B.c - A.c).norm() - A.R - B.R;
      const double k = dmin > 0 ? 1 / (kPi * dmin * dmin) : INFINITY;
      ++loc.dark_culled;
      if (loc.blocked_err.empty()) {
        loc.blocked_err.assign(d_.nodes.size(), 0.0);
        loc.blocked_lerr.assign(d_.nodes.size(), 0.0);
      }
      loc.blocked_err[size_t(a)] += float(std::min(1.0, k * B.area));
      loc.blocked_err[size_t(b)] += float(std::min(1.0, k * A.area));
      progress(A.area * B.area, loc);
      return;
    }
    // Pairs in one order whichever way the recursion met them (the lower index first): the leaf pair's source among
    // equal areas and both kinds' ray samples depend on it.
    if (A.leaf() && B.leaf()) {
      leaf_pair(std::min(d_.perm[A.begin], d_.perm[B.begin]), std::max(d_.perm[A.begin], d_.perm[B.begin]), loc, from);
      progress(A.area * B.area, loc);
      return;
    }
    if (try_far(std::min(a, b), std::max(a, b), loc, from)) {
      progress(A.area * B.area, loc);
      return;
    }
    // Below a small enough pair, the shaft tests of the pairs under it (inside its shaft: their boxes lie in its
    // nodes' boxes) walk the occluder tree from this shaft's frontier instead of its root: the same answers
    // (OccluderTree::frontier) for fewer box tests. Boxes grown by 1e-9 of the scene (grown_box_shaft).
    // Two levels: pairs of at most kCoarsePatches patches find a coarse frontier from the root (nodes of at most
    // kCoarseItems occluders), pairs of at most kFrontierPatches the fine one from it (walks from the root for the
    // small pairs held 30 % of a profile window of the million-patch building; its whole build did not get faster).
    // The coarse shaft is grown by twice the fine one's margin, so the fine shaft stays inside it after rounding.
    std::vector<int> own;
    const std::vector<int>* pass = from;
    int pass_level = level;
    const int count = (A.end - A.begin) + (B.end - B.begin);
    if (occlusion_ && level < 2 && count <= kFrontierPatches) {
      tree_.frontier_from(detail::grown_box_shaft(A.box, B.box, 10 * d_.P.scene_eps, d_.P.scene_eps), kFrontierItems,
                          walk_from(from), own);
      pass = &own;
      pass_level = 2;
    } else if (occlusion_ && level < 1 && count <= kCoarsePatches) {
      tree_.frontier(detail::grown_box_shaft(A.box, B.box, 20 * d_.P.scene_eps, d_.P.scene_eps), kCoarseItems, own);
      pass = &own;
      pass_level = 1;
    }
    // The larger node is split; nodes within 1e-9 of each other's size count as equal (a regular grid's clusters,
    // whose sizes a moved model rounds either way: splitting the other one gives other links), the higher index
    // split then.
    const bool near_equal = std::abs(B.R - A.R) <= 1e-9 * std::max(A.R, B.R);
    const bool split_b = A.leaf() || (!B.leaf() && (near_equal ? b > a : B.R > A.R));
    const int keep = split_b ? a : b, s = split_b ? b : a;
    const int c0 = d_.nodes[s].left, c1 = d_.nodes[s].right;
    if (std::min(A.level, B.level) < kParallelLevels)
      tbb::parallel_invoke([&] { refine(keep, c0, pass, pass_level); }, [&] { refine(keep, c1, pass, pass_level); });
    else {
      refine(keep, c0, pass, pass_level);
      refine(keep, c1, pass, pass_level);
    }
  }

  // The far-field test and, if it passes, the link.
  bool try_far(int a, int b, Local& loc, const std::vector<int>* from) {
    const HNode &A = d_.nodes[a], &B = d_.nodes[b];
    const Vec3 U = B.c - A.c;
    const double D = U.norm();
    if (!(D > 0)) return false;
    const double s = (A.R + B.R) / D;
    // (Below 1/2 by a margin of 1e-8: a regular grid's clusters at exactly 1/2, such as 2 x 2 patches of 0.5 m two
    // clusters apart diagonally, are refined whatever the rounding of a moved model.)
    if (!(s < 0.5 * (1 - 1e-8))) return false;
    const Vec3 w = U / D;
    // Per side: m = cos(theta + cone + delta), the smallest cosine of a normal with a direction between the
    // clusters (theta the angle between the cone's axis and the centre direction, delta = asin(s) the angle the
    // clusters subtend), and cmax = cos(max(0, theta - cone - delta)), the largest; by angle addition.
    const double cd = std::sqrt(1 - s * s);
    auto cosines = [&](const HNode& X, const Vec3& dir, double& m, double& cmax) {
      const double c1 = X.axis.dot(dir), s1 = X.axis.cross(dir).norm();
      const double cm = X.cos_cone * cd - X.sin_cone * s, sm = X.sin_cone * cd + X.cos_cone * s;  // cone + delta
      cmax = c1 >= cm ? 1.0 : c1 * cm + s1 * sm;
      m = (c1 > 0 && X.cos_cone > 0 && c1 * X.cos_cone - s1 * X.sin_cone > 0) ? c1 * cm - s1 * sm : -1.0;
    };
    double ma, mb, ca, cb;
    cosines(A, w, ma, ca);
    cosines(B, -w, mb, cb);
    // The expansion needs every receiver to face every source point and vice versa (the kernel never clips):
    // m > 0, or for a flat cluster the other one on or in front of all its planes (a wall standing on a floor).
    auto in_front = [&](const HNode& X, const HNode& Y) {
      return X.flat && -support(Y, -X.axis) + X.axis.dot(Y.c - X.c) >= X.slab_hi - d_.P.scene_eps;
    };
    if (!(ma > 0 || in_front(A, B)) || !(mb > 0 || in_front(B, A))) return false;
    // Error of the third-order expansion per receiver, absolute (F units): modelled as
    // s^3 (10 ca cb + 4 ca + 4 cb + 1) / (pi d_min^2) per unit source area, times kExpansionConstant: the second-order
    // expansion's model and constant, kept. The third order's actual errors are ~10x below it where the far field
    // decides (test_hierarchy's worst ratio of the actual row error to the admitted one: 0.03 on the sphere and the
    // closed box, 0.15-0.19 where rays decide). A constant fitted to the third order (0.0005, ratios up to 0.39)
    // accepts coarser links where visibility then takes the budget: udales' sky box 5.8e-4 -> 1.0e-3 against dense,
    // the 10k building 15 % slower; on unoccluded scenes it only rescales the tolerance. The s^4 form of the
    // third-order remainder (with its own constant) gave the lit cube more error for its time: it accepts the largest
    // clusters too readily (docs/benchmarks.md, thirty-first session).
    const double dmin = D - A.R - B.R, dmax = D + A.R + B.R;
    const double k_hi = ca * cb / (kPi * dmin * dmin), k_lo = std::max(ma, 0.0) * std::max(mb, 0.0) / (kPi * dmax * dmax);
    const double e = kExpansionConstant * s * s * s * (10 * ca * cb + 4 * ca + 4 * cb + 1) / (kPi * dmin * dmin);
    const double la = std::max(lmax_[a], 0.0) / lref_, lb = std::max(lmax_[b], 0.0) / lref_;
    const double tol = link_tol_;
    // Accepted when the error times the source's brightness is within the tolerance relative to the link's
    // smallest value (relative), or is at most kAbsolute of the tolerance (absolute: grazing and distant links).
    auto ok = [&](double err_a, double err_b) {  // errors per unit area of the source
      return (err_a * lb <= tol * k_lo || err_a * B.area * lb <= kAbsolute * tol) &&
             (err_b * la <= tol * k_lo || err_b * A.area * la <= kAbsolute * tol);
    };
    if (!ok(e, e)) return false;
    // Rays cannot certify a shaft better than kRayConfidence/cluster_rays: if even that would fail, refine without
    // casting.
    const double e_rays = e + kRayConfidence * k_hi / std::max(1, o_.cluster_rays);
    // A link every ray finds blocked carries no light; what the rays may have missed (a transmittance up to
    // kRayConfidence/rays) is admitted when, times the source's brightness, it is within the link tolerance.
    // Up to kMaxBlockedRays rays are cast to certify a blocked pair (stopping at the first visible one).
    const int mA = A.end - A.begin, mB = B.end - B.begin;
    const double need = std::max(double(mA) * std::ceil(kRayConfidence * k_hi * B.area * lb / tol),
                                 double(mB) * std::ceil(kRayConfidence * k_hi * A.area * la / tol));
    const int max_rays = need <= kMaxBlockedRays ? int(need) : 0;
    // What each outcome of the rays would need: all free (V = 1, error e_rays), mixed (uncertainty 0.5), all
    // blocked (at least `need` rays). The rays stop as soon as the outcome is decided.
    RayGoals goals;
    // (The errors as try_far forms them from the result below, e + uncertainty * k_hi, to the last bit.)
    const double e_visible = e + (kRayConfidence / std::max(1, o_.cluster_rays)) * k_hi;
    goals.visible_ok = ok(e_visible, e_visible);
    const double e_mixed = e + 0.5 * k_hi;
    goals.mixed_ok = ok(e_mixed, e_mixed);
    goals.max_rays = max_rays;
    goals.kB = k_hi * B.area;
    goals.kA = k_hi * A.area;
    goals.lb = lb;
    goals.la = la;
    goals.tol = tol;
    goals.mA = mA;
    goals.mB = mB;
    const bool rays_could_pass = ok(e_rays, e_rays) || max_rays > 0;
    const VisResult v = link_visibility(A, B, a, b, loc, rays_could_pass, goals, from);
    if (v.refine) return false;
    const double err = e + v.uncertainty * k_hi;
    const bool blocked = v.V == 0 && v.uncertainty < 0.5;
    if (blocked) {
      if (!goals.blocked_ok(v.cast)) return false;
      // What each receiving patch may have missed (its share of the rays: blocked_ok).
      const double u_a = kRayConfidence / (v.cast / mA), u_b = kRayConfidence / (v.cast / mB);
      const double err_ab = std::min(1.0, k_hi * B.area * u_a), err_ba = std::min(1.0, k_hi * A.area * u_b);
      ++loc.blocked;
      if (loc.blocked_err.empty()) {
        loc.blocked_err.assign(d_.nodes.size(), 0.0);
        loc.blocked_lerr.assign(d_.nodes.size(), 0.0);
      }
      loc.blocked_err[size_t(a)] += float(err_ab);
      loc.blocked_err[size_t(b)] += float(err_ba);
      loc.blocked_lerr[size_t(a)] += float(err_ab * lb);
      loc.blocked_lerr[size_t(b)] += float(err_ba * la);
      return true;
    }
    if (!ok(err, err)) return false;
    const double err_ab = std::min(1.0, err * B.area), err_ba = std::min(1.0, err * A.area);
    check_memory(loc);
    loc.far.push_back({a, b, float(v.V), float(err_ab), float(err_ba), float(err_ab * lb), float(err_ba * la)});
    return true;
  }

  // The visible fraction of a far link: 1 if the shaft between the clusters' boxes is empty of occluders,
  // else a kernel-weighted ray estimate. The one visibility call for clusters (exact visibility may replace it).
  VisResult link_visibility(const HNode& A, const HNode& B, int a, int b, Local& loc, bool cast_rays,
                            const RayGoals& goals, const std::vector<int>* from) {
    if (!occlusion_) return {};
    const detail::Shaft sh = node_shaft(A, B);
    if (!tree_.may_block_from(sh, -1, -1, walk_from(from), &loc.hint)) {
      ++loc.shaft_clear;
      return {};
    }
    if (!cast_rays || o_.visibility_method != VisibilityMethod::Rays) return {1.0, 1.0, true};
    ++loc.ray_tested;
    const int R0 = std::max(1, o_.cluster_rays);
    const std::uint64_t seed = detail::mix(std::uint64_t(a) * 0x9E3779B97F4A7C15ull ^ std::uint64_t(b));
    double num = 0, den = 0;
    int hidden = 0, seen = 0, cast = 0;
    // Rays are read in order, one at a time, and stop as soon as the outcome is decided:
    // - free and blocked rays seen (mixed): R0 rays if the link accepts a mixed estimate, else refine now;
    // - only free rays so far: on to R0 if the link accepts that, else refine at the first blocked one... or now,
    //   when a mixed estimate would not do either;
    // - only blocked rays so far: stop (blocked) once there are as many as certify
    //   the link (blocked_ok), from R0 up to max(R0, max_rays); refine at the first free one unless mixed is accepted.
    //   (Fewer than R0 blocked rays, even where they would certify the link, let through light that 32 rays find:
    //   on the 10k building, 8 rays doubled the error against dense.)
    // They are drawn and traced a batch at a time and read in order, as one ray at a time would: the same
    // result for any batch size; the rays traced past the one that ends the loop are counted in the statistics.
    constexpr int kFirstBatch = 2, kSecondBatch = 8, kBatch = 32;
    const int total = std::max(R0, goals.max_rays);
    enum class Stop { kNo, kResult, kRefine };
    auto decide = [&]() {
      if (seen > 0 && hidden > 0) return goals.mixed_ok ? (cast >= R0 ? Stop::kResult : Stop::kNo) : Stop::kRefine;
      if (seen > 0) {  // only free rays so far
        if (!goals.visible_ok && !goals.mixed_ok) return Stop::kRefine;
        return cast >= R0 ? Stop::kResult : Stop::kNo;
      }
      if (hidden > 0) {  // only blocked rays so far
        if (cast >= R0 && goals.blocked_ok(cast)) return Stop::kResult;  // each patch: >= cast / m rays (below)
        if (cast >= total) return Stop::kResult;
        // Neither certifiable by more rays nor acceptable once a free ray turns up: refine now.
        if (!goals.mixed_ok && !goals.blocked_ok(total)) return Stop::kRefine;
        return Stop::kNo;
      }
      return cast >= R0 ? Stop::kResult : Stop::kNo;  // nothing traced yet (draws that face away)
    };
    // The rays' patches in turn, along the tree order from a random start: ray k takes patch (k + off_a) mod m_A of
    // A, and (k + off_b + floor(k / lcm(m_A, m_B))) mod m_B of B (the shift pairs every patch of A with every patch
    // of B over the periods). Each side is a whole cycle per period, so every patch has had at least cast / m of the
    // rays: a link every ray finds blocked is certified for each receiving patch, not for the node's area on
    // average. (Drawn by area, a patch of 1/800 of its node got none of the rays that certified the link and lost
    // all its light from the source: Hierarchy.BlockedLinksHoldForEachReceivingPatch. In udales' sky box this
    // rule took the rms error against dense from 2.4e-5 to 1.4e-5.) Each ray's kernel is weighted by its two
    // patches' areas over the mean (the estimate of V stays area-weighted); positions in a patch are random.
    const int mA = A.end - A.begin, mB = B.end - B.begin;
    const std::int64_t off_a = std::int64_t(detail::mix(seed ^ 0xA5A5A5A5ull) % std::uint64_t(mA));
    const std::int64_t off_b = std::int64_t(detail::mix(seed ^ 0x5A5A5A5Aull) % std::uint64_t(mB));
    const std::int64_t period = std::lcm(std::int64_t(mA), std::int64_t(mB));
    const double wa = mA / A.area, wb = mB / B.area;
    Stop stop = Stop::kNo;
    for (int k0 = 0, k1 = 0; k0 < total && stop == Stop::kNo; k0 = k1) {
      // 2 rays first (most links refined are decided by them), then up to 8, then on to R0, then 32 at a time.
      k1 = std::min(total, k0 == 0 ? kFirstBatch : k0 < kSecondBatch ? kSecondBatch : k0 < R0 ? R0 : k0 + kBatch);
      loc.ray_from.clear();
      loc.ray_to.clear();
      loc.ray_pa.clear();
      loc.ray_pb.clear();
      loc.ray_w.assign(size_t(k1 - k0), -1.0);
      for (int k = k0; k < k1; ++k) {
        const std::uint64_t sk = detail::mix(seed + std::uint64_t(k));
        const int pa = d_.perm[size_t(A.begin + (k + off_a) % mA)];
        const int pb = d_.perm[size_t(B.begin + (k + off_b + k / period) % mB)];
        detail::sample_patch(g_, d_.P, pa, 1, 1, detail::mix(sk + 1), loc.pa);
        detail::sample_patch(g_, d_.P, pb, 1, 1, detail::mix(sk + 2), loc.pb);
        const Vec3 x = loc.pa[0], y = loc.pb[0], dv = y - x;
        const double cx = g_.normal[pa].dot(dv), cy = -g_.normal[pb].dot(dv);
        if (!(cx > 0 && cy > 0)) continue;
        const double r2 = dv.squaredNorm();
        loc.ray_w[size_t(k - k0)] = cx * cy / (r2 * r2) * (g_.area[pa] * wa) * (g_.area[pb] * wb);
        loc.ray_from.push_back(x);
        loc.ray_to.push_back(y);
        loc.ray_pa.push_back(pa);
        loc.ray_pb.push_back(pb);
      }
      loc.ray_hidden.resize(loc.ray_from.size());
      caster_->occluded(loc.ray_from, loc.ray_to, loc.ray_pa, loc.ray_pb, loc.ray_hidden);
      loc.rays += static_cast<long long>(loc.ray_from.size());
      size_t traced = 0;
      for (int k = k0; k < k1 && stop == Stop::kNo; ++k) {
        ++cast;
        const double wgt = loc.ray_w[size_t(k - k0)];
        if (wgt >= 0) {
          den += wgt;
          if (loc.ray_hidden[traced++]) ++hidden;
          else {
            num += wgt;
            ++seen;
          }
        }
        stop = decide();
      }
    }
    if (stop == Stop::kRefine) return {1.0, 1.0, true};
    VisResult r;
    r.cast = cast;
    if (!(den > 0)) return {1.0, 0.5, false, cast};
    r.V = num / den;
    r.uncertainty = (hidden == 0 || seen == 0) ? kRayConfidence / cast : 0.5;
    return r;
  }

  // The exact entry of one patch pair (as the dense assembly computes it) and its visibility. The one
  // visibility call for patch pairs.
  void leaf_pair(int i, int j, Local& loc, const std::vector<int>* from) {
    const bool swap = detail::source_is_j(g_.area[i], g_.area[j]);
    const int s = swap ? j : i, t = swap ? i : j;
    const detail::PairEval e = detail::pair_scalar(d_.P, psoa_, s, t, etol_);
    if (e.method == detail::kCulled || !(e.F > 0)) {
      ++loc.culled;
      return;
    }
    double Fst = e.F, sigma = 0, exact_error = 0;
    if (occlusion_) {
      detail::Shaft sh = detail::make_shaft(pbox_[s], pbox_[t]);
      sh.ni = d_.P.nrm[s];
      sh.oi = d_.P.offset[s];
      sh.nj = d_.P.nrm[t];
      sh.oj = d_.P.offset[t];
      sh.eps = d_.P.scene_eps;
      const double share = std::max(Fst, Fst * g_.area[s] / g_.area[t]);
      const bool exact = o_.visibility_method == VisibilityMethod::Exact ||
                         (o_.visibility_method == VisibilityMethod::Auto && share > etol_);
      const bool may_block = tree_.may_block_from(sh, s, t, walk_from(from), &loc.hint);
      if (may_block && exact) {
        // As the dense assembly's exact path: F_st minus the integral of what the occluders hide.
        loc.cand.clear();
        tree_.collect_grouped_from(
            sh, s, t, walk_from(from),
            [&](int p) { return !detail::in_plane_of(d_.P, scale_, p, s) && !detail::in_plane_of(d_.P, scale_, p, t); },
            loc.cand, loc.seen);
        detail::pair_occluders(g_, d_.P, scale_, loc.cand, s, t, merged_, convex_, loc.merged_ids, loc.occ);
        const detail::ExactPairResult r = detail::exact_hidden_pair(
            g_.polygon(s), d_.P.nrm[s], g_.area[s], convex_[size_t(s)] != 0, g_.polygon(t), d_.P.nrm[t],
            convex_[size_t(t)] != 0, loc.occ, etol_, scale_, *loc.exact);
        switch (r.outcome) {
          case detail::ExactPairResult::kClear: ++loc.exact_clear; break;
          case detail::ExactPairResult::kHidden: ++loc.exact_hidden; Fst = 0; break;
          case detail::ExactPairResult::kIntegrated:
            ++loc.exact_integrated;
            Fst = std::max(0.0, Fst - r.H);
            break;
        }
        loc.exact_points += r.points;
        loc.exact_over += r.over_tolerance;
        exact_error = r.error;
      } else if (may_block) {
        ++loc.pair_ray_tested;
        const detail::VisibleRatio v =
            detail::visible_ratio(g_, d_.P, *caster_, s, t, detail::rays_for_share(o_.rays_per_pair, share), loc.sb);
        loc.rays += v.rays;
        sigma = Fst * v.sigma;
        Fst *= v.ratio;
      } else {
        ++loc.pair_shaft_clear;
      }
    }
    check_memory(loc);
    if (!(Fst > 0)) return;
    if (loc.leaf.empty()) {
      loc.leaf.resize(size_t((d_.n + kBucketRows - 1) >> kBucketLog));
      loc.leaf_err.assign(size_t(d_.n), 0.0);
      loc.leaf_sig2.assign(size_t(d_.n), 0.0);
    }
    loc.leaf[size_t(s >> kBucketLog)].push_back(LeafRecord{s, t, Fst});
    // F_ts's error and sigma are F_st's times A_s / A_t.
    const double es = e.error + exact_error, ratio = g_.area[s] / g_.area[t];
    loc.leaf_err[size_t(s)] += es;
    loc.leaf_err[size_t(t)] += es * ratio;
    loc.leaf_sig2[size_t(s)] += sigma * sigma;
    loc.leaf_sig2[size_t(t)] += sigma * sigma * ratio * ratio;
  }

  const mesh::PatchGeometry& g_;
  const HierarchyOptions& o_;
  HierarchicalOperator::Impl& d_;
  double etol_;
  std::size_t limit_;
  detail::PointSoA psoa_;  // the leaf pairs' Gauss rules in SIMD (15 doubles per patch, freed with the refiner)

 public:
  double link_tol_ = 0;

 private:
  std::vector<double> lmax_;
  std::vector<int> node_cell_, node_room_;
  std::vector<std::uint8_t> node_cells_;  // setup: bit 0 holds whole cells, bit 1 holds a patch of unknown cell
  const detail::Rooms* rooms_ = nullptr;
  std::vector<Box> pbox_;
  double lref_ = 1;
  std::shared_ptr<const Visibility> caster_;
  detail::OccluderTree tree_;
  bool occlusion_ = false;
  // Exact visibility (HierarchyOptions::visibility_method != Rays): scene size, convex flags, merged occluders.
  double scale_ = 0;
  std::vector<std::uint8_t> convex_;
  detail::MergedOccluders merged_;
  std::atomic<long long> links_{0};
  std::atomic<double> done_{0};
  double total_ = 1;
  std::mutex progress_mutex_;
  Clock::time_point last_ = Clock::now();
};

}  // namespace

std::size_t HierarchicalOperator::Impl::bytes() const {
  return nodes.capacity() * sizeof(detail::HNode) + perm.capacity() * 4 + leaf_of.capacity() * 4 +
         far_off.capacity() * 8 + far_flat.capacity() * 8 + (vec_slot.capacity() + acc_slot.capacity()) * 4 +
         far_src.capacity() * 4 + far_vis.capacity() * 4 + leaf_off.capacity() * 8 +
         std::size_t(leaf_count) * 12 + leaf_blocks.capacity() * 4 + row_sums.capacity() * 8 +
         (nodes.size() * (detail::kScalarRecord + detail::kTuples) + size_t(vec_slots) * detail::kVectorRecord +
          size_t(acc_slots) * detail::kLocalRecord) * 8 +  // one set of apply()'s work arrays
         (leaf_blocks.empty() ? 0 : (leaf_blocks.size() - 1) * std::size_t(n) * 8) +  // and its transposed scatter
         (tr_off.capacity() + tr_entry.capacity()) * 8 + tr_src.capacity() * 4 +
         std::size_t(n) * (sizeof(Vec3) * 2 + 8 * 5 + 48 + 1) +
         [&] {
           std::size_t b = 0;
           for (const auto& v : P.rule_pts) b += v.capacity() * 32;
           for (const auto& v : P.rule_off) b += v.capacity() * 4;
           return b;
         }();
}

std::size_t estimate_hierarchy_bytes(std::size_t n, double tolerance) {
  // Peak process memory measured on the lit cube at tolerance 1e-3 (docs/benchmarks.md, "Scaling"): 259 MB at
  // 10k patches, 976 MB at 100k, 4.5 GB at 1M, a log-log slope of 0.62 (the links per patch fall as clusters
  // grow); scaled by (1e-3 / tolerance)^0.3 (links grow as the tolerance shrinks). Occluded scenes need more (the
  // 10k-patch building: 540 MB); the build checks its links against the limit while it runs.
  if (n == 0) return 0;
  const double mb = 300.0 * std::pow(double(n) / 1e4, 0.62) * std::pow(1e-3 / std::clamp(tolerance, 1e-9, 0.5), 0.3);
  return std::size_t(mb * 1048576.0);
}

namespace {

// The leaf records into the stored CSR over sources, one bucket of sources at a time (in parallel): gathered from
// every thread, sorted by (s, t) (unique pairs: the same order for any thread count), stored, and freed. The
// stored arrays are allocated without zeroing, so their pages become resident as the buckets fill them while the
// buckets' records are freed: the peak is about one record per link, not a record plus its entries. Each
// thread's per-patch admitted errors and visibility variances are summed into err (per node) and the stats.
void store_leaf_links(HierarchicalOperator::Impl& d, Refiner& rf, HierarchyStats& st, std::vector<double>& err) {
  const int n = d.n;
  std::vector<Local*> locals;
  for (Local& l : rf.locals) locals.push_back(&l);
  const int buckets = (n + kBucketRows - 1) >> kBucketLog;
  std::vector<std::int64_t> bucket_off(size_t(buckets) + 1, 0);
  for (const Local* l : locals)
    for (size_t b = 0; b < l->leaf.size(); ++b) bucket_off[b + 1] += std::int64_t(l->leaf[b].size());
  for (int b = 0; b < buckets; ++b) bucket_off[size_t(b) + 1] += bucket_off[size_t(b)];
  d.leaf_count = bucket_off[size_t(buckets)];
  st.leaf_links = d.leaf_count;
  d.leaf_src.reset(new int[size_t(d.leaf_count)]);
  d.leaf_F.reset(new double[size_t(d.leaf_count)]);
  d.leaf_off.assign(size_t(n) + 1, 0);
  // In rounds of one bucket per thread (at most about 32 rounds: each trim walks the heap); after each round the
  // freed records' pages go back to the system (the records' blocks come from malloc's heap, where freed memory
  // stays resident until trimmed). The rounds change only the memory, not the result.
  const int round = std::max({1, tbb::this_task_arena::max_concurrency(), (buckets + 31) / 32});
  for (int b0 = 0; b0 < buckets; b0 += round) {
    tbb::parallel_for(tbb::blocked_range<int>(b0, std::min(buckets, b0 + round), 1),
                      [&](const tbb::blocked_range<int>& r) {
      std::vector<LeafRecord> recs;
      for (int b = r.begin(); b < r.end(); ++b) {
        recs.clear();
        recs.reserve(size_t(bucket_off[size_t(b) + 1] - bucket_off[size_t(b)]));
        for (Local* l : locals) {
          if (size_t(b) >= l->leaf.size()) continue;
          l->leaf[size_t(b)].for_each([&](const LeafRecord& x) { recs.push_back(x); });
          l->leaf[size_t(b)].clear();
        }
        std::sort(recs.begin(), recs.end(), [](const LeafRecord& x, const LeafRecord& y) {
          return x.s != y.s ? x.s < y.s : x.t < y.t;
        });
        std::int64_t e = bucket_off[size_t(b)];
        for (const LeafRecord& x : recs) {
          d.leaf_src[size_t(e)] = x.t;
          d.leaf_F[size_t(e)] = x.Fst;
          ++e;
          ++d.leaf_off[size_t(x.s) + 1];  // rows of this bucket only
        }
      }
    });
    malloc_trim(0);
  }
  for (int k = 0; k < n; ++k) d.leaf_off[size_t(k) + 1] += d.leaf_off[size_t(k)];
  // The transposed scatter's row blocks: about equal entries, at most kLeafBlocks, from the stored rows only.
  constexpr int kLeafBlocks = 16;
  constexpr std::int64_t kMinBlockEntries = std::int64_t(1) << 14;
  const int blocks = int(std::clamp<std::int64_t>(d.leaf_count / kMinBlockEntries, 1, kLeafBlocks));
  d.leaf_blocks.assign(1, 0);
  for (int k = 1; k < blocks; ++k) {
    const std::int64_t target = d.leaf_count * k / blocks;
    const int row = int(std::lower_bound(d.leaf_off.begin(), d.leaf_off.end(), target) - d.leaf_off.begin());
    if (row > d.leaf_blocks.back() && row < n) d.leaf_blocks.push_back(row);
  }
  d.leaf_blocks.push_back(n);
  st.row_visibility_sigma.assign(size_t(n), 0.0);
  for (Local* l : locals) {
    if (l->leaf_err.empty()) continue;
    for (int p = 0; p < n; ++p) {
      err[size_t(d.leaf_of[p])] += l->leaf_err[size_t(p)];
      st.row_visibility_sigma[size_t(p)] += l->leaf_sig2[size_t(p)];
    }
    std::vector<double>().swap(l->leaf_err);
    std::vector<double>().swap(l->leaf_sig2);
    std::vector<Chunked<LeafRecord, 12>>().swap(l->leaf);
  }
}

}  // namespace

HierarchicalOperator build_hierarchy(const mesh::PatchGeometry& given, const HierarchyOptions& o, HierarchyStats* stats) {
  const auto t0 = Clock::now();
  // Far from the origin: built on (and owning) a copy moved there (detail::moved_to_origin), unless a caller's
  // caster is tied to the coordinates as given.
  std::unique_ptr<mesh::PatchGeometry> near = o.caster ? nullptr : detail::moved_to_origin(given);
  const mesh::PatchGeometry& g = near ? *near : given;
  HierarchyStats local;
  HierarchyStats& st = stats ? *stats : local;
  st = HierarchyStats{};
  const int n = g.size();
  if (!(o.tolerance > 0 && o.tolerance < 1))
    throw InputError("hierarchical operator: tolerance must be in (0, 1) (got " + std::to_string(o.tolerance) + ")");
  if (!(o.entry_tolerance >= 0) || !std::isfinite(o.entry_tolerance))
    throw InputError("hierarchical operator: entry tolerance must be >= 0 (got " + std::to_string(o.entry_tolerance) + ")");
  if (!(o.max_reflectance < 1))
    throw InputError("hierarchical operator: max_reflectance must be < 1 (got " + std::to_string(o.max_reflectance) + ")");
  if (o.rays_per_pair < 1 || o.cluster_rays < 1)
    throw InputError("hierarchical operator: rays per pair and per cluster link must be >= 1");
  // Per-patch values, when given: one per patch, finite and >= 0.
  auto check_per_patch = [n](const std::vector<double>& v, const char* what) {
    if (v.empty()) return;
    LAMBERT_CHECK(v.size() == size_t(n), std::string("hierarchical operator: ") + what + " needs one value per patch");
    for (int p = 0; p < n; ++p)
      if (!(v[p] >= 0) || !std::isfinite(v[p]))
        throw InputError(std::string("hierarchical operator: ") + what + " of patch " + std::to_string(p) + " is " +
                         std::to_string(v[p]) + " (must be finite and >= 0)");
  };
  check_per_patch(o.brightness, "brightness");
  check_per_patch(o.emission, "emission");
  const MemoryLimit sys = o.max_bytes ? MemoryLimit{o.max_bytes, "max_bytes"} : system_memory_limit();
  st.bytes_estimate = estimate_hierarchy_bytes(std::size_t(n), o.tolerance);
  if (st.bytes_estimate > sys.bytes)
    throw InputError("hierarchical operator: " + std::to_string(n) + " patches at tolerance " + std::to_string(o.tolerance) +
                     " are estimated to need " + std::to_string(st.bytes_estimate >> 20) + " MB, more than the " +
                     std::to_string(sys.bytes >> 20) + " MB available (" + sys.source +
                     "); raise --hierarchy-tolerance, use fewer patches (a larger --max-edge) or give the process more memory");
  st.patches = n;
  st.tolerance = o.tolerance;
  st.dense_pairs_equivalent = (long long)n * (n - 1) / 2;
  const double amplification = o.max_reflectance > 0 ? o.max_reflectance / (1 - o.max_reflectance) : 1.0;
  st.link_tolerance = o.tolerance / std::max(1.0, amplification);
  // Auto: the dense assembly's, or kEntryShare of the link tolerance if larger. A row holds a few hundred leaf
  // entries (udales under a sky: 211 on average), whose kernel errors then add up to a fraction of what one link
  // admits; integrating them to 1e-8 cost 20 % of the build for nothing (docs/benchmarks.md).
  const double etol = o.entry_tolerance > 0
                          ? o.entry_tolerance
                          : std::max(default_tolerance(o.max_reflectance), kEntryShare * st.link_tolerance);
  st.entry_tolerance = etol;

  HierarchicalOperator op;
  HierarchicalOperator::Impl& d = *op.d_;
  d.g = &g;
  d.owned = std::move(near);  // g stays valid: the object does not move
  d.n = n;
  if (n == 0) return op;
  auto body = [&] {
    const auto t_tree = Clock::now();
    // Without the precomputed outer rules (~0.9 kB per patch): the near pairs form theirs as they need them.
    d.P = detail::prepare(g, 1);
    // The closed surfaces' cells, first: the tree keeps cells apart where it can.
    std::vector<int> occ;
    detail::Enclosures enc;
    detail::Rooms rooms;
    if (o.visibility && n > 1) {
      occ = potential_occluders(g);
      if (!occ.empty() && o.enclosures) {
        enc = detail::find_enclosures(g);
        st.enclosures = enc.surfaces;
        st.cell_crossed = enc.crossed;
        st.enclosure_patches = enc.surface_patches;
        st.cells = enc.cells;
        st.cell_unknown = enc.unknown;
        st.seconds_enclosures = enc.seconds;
        if (o.portals) {  // the openings closed by portals: the closed surfaces again, now of rooms
          Eigen::AlignedBox3d box;
          for (const Vec3& v : g.points) box.extend(v);
          rooms = detail::find_rooms(g, detail::kEnclosureEps * box.diagonal().norm());
          st.portals = (long long)rooms.portals.size();
          st.room_cells = rooms.rooms;
          st.seconds_portals = rooms.seconds;
        }
      }
    }
    const std::span<const int> cells = !rooms.empty()   ? std::span<const int>(rooms.cell)
                                       : enc.surfaces > 0  ? std::span<const int>(enc.cell)
                                                           : std::span<const int>();
    d.perm.resize(n);
    std::iota(d.perm.begin(), d.perm.end(), 0);
    d.nodes.reserve(size_t(2 * n));
    TreeBuilder tb{g, d.nodes, d.perm, {}, cells,
                   !rooms.empty() && enc.surfaces > 0 ? std::span<const int>(enc.cell) : std::span<const int>(), 0.0, {}};
    {
      Box cbox;
      for (int p = 0; p < n; ++p) cbox.add(g.centroid[p]);
      tb.eps_c = n > 0 ? 1e-9 * (cbox.hi - cbox.lo).norm() : 0.0;
    }
    tb.pbox.resize(n);
    for (int p = 0; p < n; ++p)
      for (const Vec3& v : g.polygon(p)) tb.pbox[p].add(v);
    tb.build(0, n, -1, 0);
    d.leaf_of.assign(n, -1);
    for (int k = 0; k < int(d.nodes.size()); ++k) {
      st.levels = std::max(st.levels, d.nodes[k].level + 1);
      if (d.nodes[k].leaf()) d.leaf_of[d.perm[d.nodes[k].begin]] = k;
    }
    st.nodes = int(d.nodes.size());
    st.seconds_tree = since(t_tree);

    const auto t_links = Clock::now();
    Refiner rf(g, o, d, etol, sys.bytes);
    rf.link_tol_ = st.link_tolerance;
    rf.setup(occ, enc.surfaces > 0 ? std::span<const int>(enc.cell) : std::span<const int>(), &rooms);
    st.dark_cells = rf.dark_cells;
    st.dark_patches = rf.dark_patches;
    rf.run();
    // The records into the stored rows, thread by thread (each thread's records freed as soon as they are
    // placed: no merged copy), then each row sorted by source: the stored operator does not depend on the thread
    // count.
    long long far_records = 0;
    for (Local& l : rf.locals) {
      far_records += (long long)l.far.size();
      st.pairs_culled += l.culled;
      st.pairs_cell_culled += l.cell_culled;
      st.pairs_portal_culled += l.portal_culled;
      st.pairs_dark_culled += l.dark_culled;
      st.links_shaft_clear += l.shaft_clear;
      st.links_ray_tested += l.ray_tested;
      st.rays_cast += l.rays;
      st.links_blocked += l.blocked;
      st.pairs_exact_clear += l.exact_clear;
      st.pairs_exact_hidden += l.exact_hidden;
      st.pairs_exact_integrated += l.exact_integrated;
      st.exact_points += l.exact_points;
      st.pairs_exact_over_tolerance += l.exact_over;
      st.pairs_ray_tested += l.pair_ray_tested;
      st.pairs_shaft_clear += l.pair_shaft_clear;
    }
    st.far_links = far_records;
    st.far_links_per_level.assign(size_t(st.levels), 0);
    const int nn = int(d.nodes.size());
    std::vector<double> err(nn, 0.0), lerr(nn, 0.0);  // admitted per receiver node
    for (Local& l : rf.locals) {
      for (size_t k = 0; k < l.blocked_err.size(); ++k) err[k] += l.blocked_err[k], lerr[k] += l.blocked_lerr[k];
      std::vector<double>().swap(l.blocked_err);
      std::vector<double>().swap(l.blocked_lerr);
    }
    {
      d.far_off.assign(size_t(nn) + 1, 0);
      for (Local& l : rf.locals)
        l.far.for_each([&](const FarRecord& r) {
          if (r.vis > 0) ++d.far_off[size_t(r.a) + 1], ++d.far_off[size_t(r.b) + 1];  // vis 0: nothing to store
        });
      for (int k = 0; k < nn; ++k) d.far_off[k + 1] += d.far_off[k];
      d.far_src.resize(size_t(d.far_off[nn]));
      d.far_vis.resize(size_t(d.far_off[nn]));
      std::vector<std::int64_t> at(d.far_off.begin(), d.far_off.end() - 1);
      for (Local& l : rf.locals) {
        l.far.for_each([&](const FarRecord& r) {
          if (r.vis > 0) {
            const std::int64_t ea = at[size_t(r.a)]++, eb = at[size_t(r.b)]++;
            d.far_src[size_t(ea)] = r.b;
            d.far_vis[size_t(ea)] = r.vis;
            d.far_src[size_t(eb)] = r.a;
            d.far_vis[size_t(eb)] = r.vis;
            ++st.far_links_per_level[size_t(std::max(d.nodes[r.a].level, d.nodes[r.b].level))];
          }
          err[r.a] += r.err_ab;
          err[r.b] += r.err_ba;
          lerr[r.a] += r.lerr_ab;
          lerr[r.b] += r.lerr_ba;
        });
        l.far.clear();
      }
      // Flat sources first: a flat receiver takes them with the scalar kernel (hierarchy_apply.cpp).
      sort_rows(d.far_off, d.far_src, d.far_vis, [&](int s) { return d.nodes[size_t(s)].flat; });
      d.far_flat.assign(size_t(nn), 0);
      for (int k = 0; k < nn; ++k) {
        std::int64_t e = d.far_off[k];
        while (e < d.far_off[k + 1] && d.nodes[size_t(d.far_src[size_t(e)])].flat) ++e;
        d.far_flat[size_t(k)] = e - d.far_off[k];
      }
      std::vector<char> vec_source(size_t(nn), 0);
      for (int k = 0; k < nn; ++k)
        if (!d.nodes[size_t(k)].flat)
          for (std::int64_t e = d.far_off[k]; e < d.far_off[k] + d.far_flat[size_t(k)]; ++e)
            vec_source[size_t(d.far_src[size_t(e)])] = 1;
      d.vec_slot.assign(size_t(nn), -1);
      d.acc_slot.assign(size_t(nn), -1);
      d.vec_slots = d.acc_slots = 0;
      for (int k = 0; k < nn; ++k) {
        const HNode& nd = d.nodes[size_t(k)];
        if (!nd.flat || vec_source[size_t(k)]) d.vec_slot[size_t(k)] = d.vec_slots++;
        if (!nd.flat || d.far_off[k + 1] - d.far_off[k] > d.far_flat[size_t(k)] ||
            (nd.parent >= 0 && !d.nodes[size_t(nd.parent)].flat))
          d.acc_slot[size_t(k)] = d.acc_slots++;
      }
    }
    store_leaf_links(d, rf, st, err);
    // Admitted error per patch: the sum over its ancestors' links (push down).
    for (int k = 1; k < nn; ++k) {
      err[k] += err[d.nodes[k].parent];
      lerr[k] += lerr[d.nodes[k].parent];
    }
    for (double& v : st.row_visibility_sigma) {
      v = std::sqrt(v);
      st.row_visibility_sigma_max = std::max(st.row_visibility_sigma_max, v);
    }
    st.row_error.resize(n);
    const std::vector<double>& lmax = rf.lmax();
    for (int p = 0; p < n; ++p) {
      const int leaf = d.leaf_of[p];
      // A dark receiver's row (radiance_only) can miss up to its whole row sum: at most 1. Not in the maximum,
      // which stays what the solve relies on.
      const bool dark = o.radiance_only && lmax[size_t(leaf)] == 0;
      st.row_error[p] = dark ? std::min(1.0, err[leaf]) : err[leaf];
      if (dark) {
        if (st.row_dark.empty()) st.row_dark.assign(size_t(n), 0);
        st.row_dark[size_t(p)] = 1;
      }
      if (!dark) st.row_error_max = std::max(st.row_error_max, err[leaf]);
      st.radiance_error_max = std::max(st.radiance_error_max, lerr[d.leaf_of[p]]);
    }
    st.seconds_links = since(t_links);
    // Row sums: one product with the ones vector.
    d.row_sums.assign(n, 0.0);
    Eigen::VectorXd ones = Eigen::VectorXd::Ones(n), rs(n);
    op.apply(ones, rs);
    for (int p = 0; p < n; ++p) d.row_sums[p] = rs[p];
    st.row_sum_min = rs.minCoeff();
    st.row_sum_max = rs.maxCoeff();
    st.row_sum_mean = rs.mean();
    // Rows above 1 beyond their admitted error (as formfactor::Stats::rows_above_one; dark rows left out, their
    // rows unresolved; not without visibility, where a row counts hidden surfaces too).
    if (o.visibility)
      st.rows_above_one = detail::find_rows_above_one(d.row_sums, st.row_error, st.row_visibility_sigma, st.row_dark);
  };
  if (o.threads > 0) {
    tbb::task_arena arena(o.threads);
    arena.execute(body);
  } else {
    body();
  }
  if (o.progress) o.progress(1.0);
  st.bytes = d.bytes();
  st.seconds_total = since(t0);
  return op;
}

}  // namespace lambert::formfactor
