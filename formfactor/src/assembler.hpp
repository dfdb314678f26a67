#pragma once
// The dense assembler (internal): tiles of (source block, target block) pairs, each unordered pair computed
// once. assemble.cpp runs it (checks, set-up, the parallel tile loop), tile.cpp computes one tile,
// stats.cpp gathers the per-thread counters into Stats.
#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "internal.hpp"
#include "lambert/formfactor/assemble.hpp"
#include "prepared.hpp"
#include "sampling.hpp"
#include "exact_visibility.hpp"
#include "separation.hpp"
#include "portals.hpp"
#include "shaft.hpp"

namespace lambert::formfactor::detail {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr int kBlock = 64;  // tile edge: 64 x 64 pairs, both matrix blocks stay in L2 while written

// Tile pair codes (TileBuffers::meth): classify's codes (batch.hpp: culled, 1 + tier (+ swap), scalar path),
// then kCodeScalar + Method for pairs the scalar path computed, kReusedMethod for reused pairs, kNoMethod for
// cells not computed. code_method() maps a code to its Method (kNoMethod if none).
constexpr std::uint8_t kNoMethod = 255, kReusedMethod = 254, kCodeScalar = 64;
const std::array<std::uint8_t, 256>& code_method();

// A pair offered to the independent reciprocity check: s the source (smaller patch), F_st unoccluded as
// assembled, err its error bound.
struct RecipCandidate {
  std::uint64_t key;
  int s, t, method;
  double F, err;
  bool operator<(const RecipCandidate& o) const { return key < o.key; }
};

// Per-thread counters, summed into Stats at the end (stats.cpp).
struct Counters {
  long long culled = 0, shaft_culled = 0, ray_tested = 0, rays = 0, over_tolerance = 0, reused = 0, fixed = 0;
  long long no_visible_sample = 0;
  long long exact_clear = 0, exact_hidden = 0, exact_integrated = 0, exact_points = 0, exact_over = 0;
  long long plane_hidden = 0, plane_tests = 0;  // pairs proven hidden by a separating plane; blocks and pairs tried
  long long cell_hidden = 0;                    // pairs facing different cells (enclosures.hpp)
  long long portal_hidden = 0;                  // pairs in different rooms, no portal between them (portals.hpp)
  double plane_seconds = 0;
  double tile_seconds = 0, visibility_seconds = 0;  // thread time in tiles, and in their visibility step
  double exact_seconds = 0, rays_seconds = 0;       // thread time of the two visibility paths
  std::array<long long, kMethodCount> by_method{};
  long long outside = 0, roundoff = 0;
  std::vector<double> row_sum, row_err, row_vis_var;  // per patch: row sum, its error bound, visibility variance
  std::array<std::vector<RecipCandidate>, kMethodCount> recip_candidates;  // max-heaps by key, per method
};

struct TileBuffers {
  std::vector<std::int8_t> code;
  std::vector<int> ps, pt, pslot, ss, st, pair_i, pair_j, cs, ct, cslot;
  std::vector<double> lx, ly, lz, lw;  // outer-rule lanes: point and weight
  std::vector<std::uint8_t> pair_swap;
  std::vector<double> out, val, row, rowj, erow, erowj;
  std::vector<double> err;          // kBlock x kBlock: error bound of F_ij in the tile
  std::vector<std::uint8_t> meth;   // kBlock x kBlock: pair code of F_ij (see kCodeScalar)
  std::vector<int> rest_j;
  SampleBuffers ray;
  ExactScratchPtr exact = make_exact_scratch();
  SeparationScratchPtr sep = make_separation_scratch();
  std::vector<Vec3> corners_a, corners_b;
  std::vector<int> walls;  // planes that proved sub-tiles of the current tile hidden (tried first)
  int searches = 0;        // full shaft searches for a proof in the current tile
  std::vector<int> cand, merged_ids, seen;
  std::vector<int> front;  // the occluder tree's frontier for the current sub-tile's shaft (OccluderTree::frontier)
  std::vector<Occluder> occ;
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
  void check_options();
  void collect_stats(const std::vector<Counters*>& counters);
  void check_reciprocity(const std::vector<Counters*>& counters);

  const mesh::PatchGeometry& g_;
  const Options& o_;
  Stats& st_;
  std::unique_ptr<Prepared> prep_;
  DenseMatrixOperator::Matrix* F_ = nullptr;
  std::shared_ptr<const Visibility> caster_;
  std::vector<std::uint8_t> convex_;  // per patch: convex polygon (triangle or convex quad), for the exact path
  double scale_ = 0;                  // the scene's size (bounding-box diagonal)
  MergedOccluders merged_;            // coplanar touching occluders merged (exact path)
  std::vector<int> plane_of_;         // per patch: its plane among the occluders (separation.hpp), or -1
  std::vector<int> cell_;             // per patch: its cell (enclosures.hpp), -1 unknown; empty: no closed surface
  Rooms rooms_;                       // the rooms with the openings closed by portals (portals.hpp), or empty
  std::vector<std::vector<int>> plane_members_;  // per plane: its occluders
  std::vector<Vec3> pbox_lo_, pbox_hi_;          // per patch: bounding box
  OccluderTree tree_;
  bool occlusion_ = false;
  double tol_ = 0;         // the tolerance used (Options::tolerance or the automatic one)
  int fault_method_ = -1;  // Options::fault_method as a Method, or -1
  int rays_ = 1;  // rays per pair (times m^4 for pairs carrying a large share of a row)
  std::vector<int> old_;                        // Options::reuse->previous_index, or empty
  std::vector<int> rule_off_;                   // Rule::Gauss: points of patch p in [rule_off_[p], rule_off_[p+1])
  std::vector<std::array<double, 4>> rule_pts_;  // x, y, z, weight (summing to 1 per patch)
};

// The dense matrix (memory.cpp): throws InputError if n^2 doubles exceed max_bytes (0 = 80% of physical RAM)
// or cannot be allocated; advises transparent huge pages for large matrices.
std::size_t default_max_bytes();
void check_matrix_size(int n, std::size_t max_bytes);
void allocate_matrix(DenseMatrixOperator::Matrix& F, int n);

}  // namespace lambert::formfactor::detail
