#pragma once
// Hierarchical (clustered) transport operator: F applied in O(links + N) time and memory instead of N^2.
//
// Clusters. A binary tree over the patches (leaves = the patches themselves, so every output stays per patch),
// split at the median of the largest extent among the three centroid axes and the normal spread scaled by the
// node's size (clusters of like-facing patches). Per node: area, centroid, bounding radius R, normal cone
// (axis, half-angle) and, for flat nodes, the range of axis . x over their corners.
//
// Links. A refinement oracle walks pairs of nodes (A, B) from (root, root):
//   - no exchange (every receiver of A faces away from B, or the reverse, by normal cones or flat slabs): nothing;
//   - both leaves: the patch pair's exact entry F_ij, F_ji (the dense kernel: tiers or adaptive contour, to the
//     per-entry form-factor tolerance) times the visible fraction (Visibility rays, as assembled densely);
//   - every receiver of A facing every point of B and vice versa (normal cones widened by the angle the clusters
//     subtend, or a flat cluster with the other on or in front of its plane) and s = (R_A + R_B)/D < 0.5: a far
//     link, the third-order expansion of the point kernel k = (n_i.u)(-n_j.u) / (pi |u|^4), u = q - p, about
//     both centres (each cluster gathers sum_j A_j x_j n_j and its first, second and third moments; receivers get
//     n_i . (g - J a + H[a, a] / 2 - C[a, a, a] / 6), a = c_i - c_A, so orientation is per patch, never averaged;
//     where both clusters are flat, the scalar kernel of their two normals, a third of the work). Its error per
//     receiver and unit source area is estimated as 0.005 s^3 (10 c_A c_B + 4 c_A + 4 c_B + 1) / (pi d_min^2)
//     (c the largest cosines, d_min = D - R_A - R_B; the second-order expansion's estimate, kept: about 10x above
//     the third order's actual errors, docs/physics.md §10). Accepted when that error plus the visibility uncertainty, times the source's
//     brightness (Lmax_B / L_ref: Options::brightness, relative to the brightest), is within the link tolerance
//     relative to the link's smallest value, or below 0.2% of the link tolerance in absolute terms; otherwise
//     the larger node is split. Link tolerance: Options::tolerance x min(1, (1 - rho_max) / rho_max).
// Visibility of a far link: 1 when the shaft between the clusters' boxes is proven empty of occluders;
// otherwise a kernel-weighted ray estimate (cluster_rays rays between area-sampled points of both clusters),
// with uncertainty 0.5 when the rays disagree (a shadow edge across the link: split) and 3/rays when they agree
// (a 95 % bound); a pair every ray finds blocked stores nothing when 3 F_max / rays times the source's
// brightness is within the link tolerance (rooms behind walls), its possible transmittance counted in the
// admitted error. The rays stop as soon as the outcome is decided (the same links as reading all of them).
// The one visibility call is link_visibility() in src/hierarchy.cpp (rays today; exact visibility can replace it).
// Before any of that, node pairs whose patches face different cells of the closed surfaces (src/enclosures.hpp) are
// refused, and so are node pairs in different rooms whose shaft meets no portal of a surface between the rooms
// (src/portals.hpp: each opening, a hole in the union of one plane's patches, closed by a virtual portal; a segment
// from inside a closed surface to outside it crosses the surface, and only a portal lets it through).
//
// Error admitted. Each link adds its error estimate (F units) to its receivers' rows (pushed down the tree),
// the patch pairs their integration bounds: HierarchyStats::row_error[_max]; ::radiance_error_max the same
// weighted by the sources' brightness, relative to L_ref; ::row_visibility_sigma the patch pairs' ray error.
// The solve amplifies a row error delta to about rho delta / (1 - rho) (docs/physics.md §5).
//
// apply() is deterministic and independent of the thread count: links are stored sorted per receiver and
// each receiver sums its own links in that order.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/operator.hpp"
#include "lambert/formfactor/visibility.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor {

struct HierarchyOptions {
  // The one knob: radiance error admitted per link, relative to the scene's brightest patch, after the solve's
  // amplification: links are refined to tolerance * min(1, (1 - rho_max) / rho_max) (a row error delta becomes
  // about rho delta / (1 - rho) on the radiance, docs/physics.md §5), so bright closed interiors refine deeper.
  // > 0 and < 1.
  double tolerance = 1e-3;
  // Per patch: an upper estimate of its radiance (any unit, >= 0), e.g. a previous solve's; empty = all equal
  // (pure geometric refinement). Links from dark clusters are accepted coarser.
  std::vector<double> brightness;
  // Per patch (largest channel, >= 0), optional: the emitted radiance. With enclosures, a closed cell without an
  // emitting patch receives no light (cells exchange none), so its patches' brightness is taken as 0.
  std::vector<double> emission;
  // The operator serves a solve only, not form-factor output: node pairs whose patches all have brightness 0
  // (black non-emitters, dark cells) carry nothing to any solution either way and are refused without a link or a
  // ray; each receiver's row admits the pair's largest form factor as error (HierarchyStats::dark_patches).
  bool radiance_only = false;
  // Per-entry tolerance of the exact leaf pairs (F units, as formfactor::Options::tolerance); 0 = auto: the dense
  // assembly's automatic tolerance, or 1e-3 of the link tolerance if that is larger.
  double entry_tolerance = 0;
  double max_reflectance = -1;
  bool visibility = true;
  // Patch pairs that may be occluded: rays, or exact (occluders clipped out of the contour integral, as the dense
  // assembly's Options::visibility_method; Auto as there). With Exact or Auto, cluster pairs whose shaft may be
  // blocked are refined to patch pairs instead of linked with a ray-estimated transmittance.
  VisibilityMethod visibility_method = VisibilityMethod::Rays;
  int rays_per_pair = 16;      // leaf pairs that may be occluded (as the dense assembly)
  int cluster_rays = 32;       // far links whose shaft may be blocked
  // Closed surfaces (rooms, apartments, shut boxes; T-junctions allowed) split space into cells; node pairs whose
  // patches face different cells exchange no light and are refused without rays (with visibility only).
  bool enclosures = true;
  // With enclosures: openings (holes in the union of a plane's patches: doors, open windows) closed by virtual
  // portals split the closed surfaces into rooms; node pairs in different rooms whose shaft meets no portal of a
  // surface between them are refused without rays.
  bool portals = true;
  int threads = 0;             // 0 = all cores
  std::size_t max_bytes = 0;   // refuse to build beyond this (0 = system_memory_limit())
  std::shared_ptr<const Visibility> caster;  // null = Embree over the potential occluders
  std::function<void(double fraction_done)> progress;
};

struct HierarchyStats {
  int patches = 0, nodes = 0, levels = 0;   // tree depth (root = level 0)
  long long far_links = 0;                  // cluster (or patch-cluster) links, unordered
  long long leaf_links = 0;                 // exact patch-pair entries, unordered, nonzero
  long long pairs_culled = 0;               // node pairs found not to exchange light (no link)
  long long links_shaft_clear = 0, links_ray_tested = 0, rays_cast = 0;  // cluster pairs tested for a link
  long long pairs_ray_tested = 0, pairs_shaft_clear = 0;  // patch pairs: visibility by rays / proven clear
  long long links_blocked = 0;              // cluster pairs every ray found blocked: no link stored, error admitted
  long long pairs_cell_culled = 0;          // node pairs refused because their patches face different cells
  int enclosures = 0, cells = 0;                         // closed surfaces found; cells they split space into
  long long enclosure_patches = 0, cell_unknown = 0;     // patches on closed surfaces; patches of no known cell
  long long cell_crossed = 0;                            // of those: crossing, crossed by or touched inside by a surface
  double seconds_enclosures = 0;
  long long portals = 0, room_cells = 0;    // openings closed by portals; cells with them closed
  long long pairs_portal_culled = 0;        // node pairs in different rooms whose shaft meets no portal between them
  long long dark_cells = 0, dark_patches = 0;  // closed cells without an emitter (emission given); patches of brightness 0
  long long pairs_dark_culled = 0;          // radiance_only: node pairs of brightness 0 on both sides, refused
  double seconds_portals = 0;
  long long pairs_exact_clear = 0, pairs_exact_hidden = 0, pairs_exact_integrated = 0;  // exact visibility path
  long long exact_points = 0, pairs_exact_over_tolerance = 0;
  std::vector<long long> far_links_per_level;  // by the level of the deeper node
  double tolerance = 0, entry_tolerance = 0;
  double link_tolerance = 0;       // tolerance after the amplification factor (see HierarchyOptions::tolerance)
  std::vector<double> row_error;   // per patch: admitted row error, F units (links' estimates + leaf bounds)
  std::vector<std::uint8_t> row_dark;  // per patch (radiance_only): 1 if dark, its row unresolved (row_error <= 1)
  // per patch: standard error of the patch-pair entries' ray visibility, combined as independent errors
  // (as formfactor::Stats::row_visibility_sigma); the cluster links' visibility is in row_error.
  std::vector<double> row_visibility_sigma;
  double row_visibility_sigma_max = 0;
  double row_error_max = 0;        // largest admitted row error, F units (sum over the row)
  double radiance_error_max = 0;   // largest admitted radiance error of one gather, relative to L_ref
  double row_sum_min = 0, row_sum_max = 0, row_sum_mean = 0;
  // Rows summing above 1 by more than row_error + k row_visibility_sigma + 1e-11 (dark rows not counted), as
  // formfactor::Stats::rows_above_one. The links' errors are estimates, so this is evidence, not proof, of a wrong row.
  RowsAboveOne rows_above_one;
  std::size_t bytes = 0;           // memory held by the operator
  std::size_t bytes_estimate = 0;  // what was estimated before building
  double seconds_tree = 0, seconds_links = 0, seconds_total = 0;
  long long dense_pairs_equivalent = 0;  // N (N - 1) / 2, for comparison
};

class HierarchicalOperator final : public TransportOperator {
 public:
  HierarchicalOperator();
  ~HierarchicalOperator() override;
  HierarchicalOperator(HierarchicalOperator&&) noexcept;
  HierarchicalOperator& operator=(HierarchicalOperator&&) noexcept;

  int size() const override;
  void apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const override;
  // Rows are not stored: throws InternalError (callers check has_rows()).
  double row_dot(int i, const Eigen::Ref<const Eigen::VectorXd>& x) const override;
  double diagonal(int) const override { return 0; }   // no self links (planar patches)
  double row_sum(int i) const override;               // from one apply(1) at build time
  bool has_rows() const override { return false; }

  // Row i of F entry by entry: f(j, F_ij) for every j with a link path to i (far links expanded to their
  // patches with the tier-0 kernel times the link's visibility; leaf entries as computed). Order: by node.
  void for_each_in_row(int i, const std::function<void(int j, double F)>& f) const;

  struct Impl;

 private:
  friend HierarchicalOperator build_hierarchy(const mesh::PatchGeometry&, const HierarchyOptions&, HierarchyStats*);
  std::unique_ptr<Impl> d_;
};

// Builds the operator (the geometry must outlive it). Throws InputError for bad options, and before
// building if estimate_hierarchy_bytes() exceeds the limit, or during the build if the links outgrow it
// (message: the estimate, the limit and what to change).
HierarchicalOperator build_hierarchy(const mesh::PatchGeometry& geometry, const HierarchyOptions& options = {},
                                     HierarchyStats* stats = nullptr);

// Peak bytes a hierarchical build of n patches is expected to need at this tolerance (fitted to measurements,
// docs/benchmarks.md; occluded scenes may need up to 2x: the build also checks its links while it runs).
std::size_t estimate_hierarchy_bytes(std::size_t n, double tolerance);

// Memory this process may use: the smallest of the cgroup limit (/sys/fs/cgroup/memory.max, or v1's
// memory.limit_in_bytes) minus the cgroup's current usage, MemAvailable (/proc/meminfo) and physical RAM;
// `source` names which one bound it.
struct MemoryLimit {
  std::size_t bytes = 0;
  std::string source;
};
MemoryLimit system_memory_limit();

// Face aggregation of a hierarchical operator's rows (as aggregate_to_faces), streamed: calls emit for each
// nonzero F_IJ >= min_factor, in (I, J) order. face_id[p] in [0, input_faces); faces' patches contiguous or not.
void stream_faces(const HierarchicalOperator& F, const mesh::PatchGeometry& g, const std::vector<int>& face_id,
                  int input_faces, double min_factor, const std::function<void(int I, int J, double F)>& emit);

}  // namespace lambert::formfactor
