// Independent row-sum check: cosine-weighted rays from sampled patches, first hits on front sides (Embree).
#include "lambert/formfactor/check.hpp"

#include "embree_scene.hpp"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "internal.hpp"
#include "sampling.hpp"

namespace lambert::formfactor {
namespace {

// The ray's context: the patch it leaves (ignored), and the nearest back side it passed. Back sides are not hits
// here: a ray meets the two sides of a two-sided face at the same distance, and Embree may report either. The
// patches of the two sides need not be twins (refinement splits one side and not the other; hidden fragments are
// removed from one side only), so the first hit's side is decided by distances: a front side within 1e-5 of the
// scene of the nearest back side is what the ray meets (front_hit).
struct FirstHitContext {
  RTCIntersectContext ctx;
  const int* tri_patch;
  const Vec3* normal;
  int self;
  Vec3 d;
  float nearest_back = INFINITY;
};

void front_sides_only(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<FirstHitContext*>(args->context);
  for (unsigned k = 0; k < args->N; ++k) {
    if (args->valid[k] == 0) continue;
    const int p = c->tri_patch[RTCHitN_primID(args->hit, args->N, k)];
    if (p == c->self) {
      args->valid[k] = 0;
    } else if (!(c->normal[p].dot(c->d) < 0)) {
      c->nearest_back = std::min(c->nearest_back, RTCRayN_tfar(args->ray, args->N, k));
      args->valid[k] = 0;
    }
  }
}

// Embree scene of every patch's triangles, recentred on the scene's bounding-box centre (single precision).
class FirstHit {
 public:
  explicit FirstHit(const mesh::PatchGeometry& g) {
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    for (const Vec3& p : g.points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    centre_ = g.points.empty() ? Vec3::Zero() : Vec3(0.5 * (lo + hi));
    size_ = g.points.empty() ? 1.0 : (hi - lo).norm();
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("Embree: cannot create device");
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
    detail::add_patch_triangles(device_, scene_, g, {}, centre_, tri_patch_);
    rtcCommitScene(scene_);
  }
  ~FirstHit() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  FirstHit(const FirstHit&) = delete;
  FirstHit& operator=(const FirstHit&) = delete;

  // Patch whose front side is hit first by the ray from o along d (unit), ignoring patch `self`; -1 if the ray
  // escapes or first meets a back side (by more than 1e-5 of the scene before any front side: two sides of one
  // face are met at the same distance to float precision).
  int front_hit(const mesh::PatchGeometry& g, const Vec3& o, const Vec3& d, int self) const {
    FirstHitContext c;
    rtcInitIntersectContext(&c.ctx);
    c.ctx.filter = &front_sides_only;
    c.tri_patch = tri_patch_.data();
    c.normal = g.normal.data();
    c.self = self;
    c.d = d;
    RTCRayHit rh{};
    const Vec3 oo = o - centre_ + 1e-6 * size_ * g.normal[self];
    rh.ray.org_x = float(oo.x());
    rh.ray.org_y = float(oo.y());
    rh.ray.org_z = float(oo.z());
    rh.ray.dir_x = float(d.x());
    rh.ray.dir_y = float(d.y());
    rh.ray.dir_z = float(d.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &c.ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return -1;
    if (double(c.nearest_back) < double(rh.ray.tfar) - 1e-5 * size_) return -1;
    return tri_patch_[rh.hit.primID];
  }

 private:
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  std::vector<int> tri_patch_;
  Vec3 centre_;
  double size_ = 1;
};

}  // namespace

RowSumCheck check_row_sums(const mesh::PatchGeometry& g, const TransportOperator& F, const Stats* stats,
                           const RowSumCheckOptions& o) {
  const int n = g.size();
  if (F.size() != n)
    throw InputError("row-sum check: the matrix has " + std::to_string(F.size()) + " rows, the scene " +
                     std::to_string(n) + " patches");
  if (o.patches < 1 || o.rays_per_patch < 1 || !(o.k_sigma > 0))
    throw InputError("row-sum check: patches and rays_per_patch must be >= 1 and k_sigma > 0");
  RowSumCheck out;
  if (n == 0) return out;
  // Evenly spaced over the rows the assembly resolved (Stats::row_unresolved: dark rows are skipped).
  std::vector<int> rows;
  const bool some_unresolved = stats && stats->row_unresolved.size() == size_t(n);
  for (int p = 0; p < n; ++p)
    if (!some_unresolved || !stats->row_unresolved[size_t(p)]) rows.push_back(p);
  out.rows_skipped = n - int(rows.size());
  const int nr_rows = int(rows.size());
  if (nr_rows == 0) return out;
  const int m = std::min(o.patches, nr_rows);
  std::vector<int> sample(static_cast<size_t>(m));
  for (int k = 0; k < m; ++k) sample[size_t(k)] = rows[size_t((k + 0.5) * nr_rows / m)];
  const detail::PatchData P = detail::prepare(g, 1);
  const FirstHit caster(g);
  const int R = o.rays_per_patch;
  std::vector<double> estimate(static_cast<size_t>(m));
  auto body = [&](int k) {
    const int p = sample[size_t(k)];
    const int k1 = std::max(1, int(std::floor(std::sqrt(double(R))))), k2 = std::max(1, R / k1), nr = k1 * k2;
    std::vector<Vec3> pts;
    const std::uint64_t seed = detail::mix(0x5EEDull + std::uint64_t(p));
    detail::sample_patch(g, P, p, k1, k2, seed, pts);
    // Tangent frame of the patch.
    const Vec3& nn = g.normal[p];
    const Vec3 t0 = (std::abs(nn.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(nn).normalized(), t1 = nn.cross(t0);
    long long hits = 0;
    for (int r = 0; r < nr; ++r) {
      // Cosine-weighted direction from its own stratum of the unit square (Malley: uniform disk, lifted), paired
      // with a point stratum by a seeded permutation (a multiplicative hash of r, coprime to nr).
      const int a = r / k2, b = r % k2;
      const double u1 = (a + 0.5 + 0.4 * (double(detail::mix(seed + 2 * r) >> 11) * 0x1.0p-53 - 0.5)) / k1;
      const double u2 = (b + 0.5 + 0.4 * (double(detail::mix(seed + 2 * r + 1) >> 11) * 0x1.0p-53 - 0.5)) / k2;
      const double rad = std::sqrt(u1), phi = 2 * detail::kPi * u2;
      const Vec3 d = (rad * std::cos(phi)) * t0 + (rad * std::sin(phi)) * t1 + std::sqrt(std::max(0.0, 1 - u1)) * nn;
      const Vec3& x = pts[size_t((std::uint64_t(r) * 2654435761ull + std::uint64_t(seed % nr)) % std::uint64_t(nr))];
      if (caster.front_hit(g, x, d.normalized(), p) >= 0) ++hits;
    }
    estimate[size_t(k)] = double(hits) / nr;
  };
  auto loop = [&] { tbb::parallel_for(0, m, body); };
  if (o.threads > 0) {
    tbb::task_arena arena(o.threads);
    arena.execute(loop);
  } else {
    loop();
  }
  out.patches_checked = m;
  for (int k = 0; k < m; ++k) {
    const int p = sample[size_t(k)];
    const int k1 = std::max(1, int(std::floor(std::sqrt(double(R))))), k2 = std::max(1, R / k1), nr = k1 * k2;
    out.rays += nr;
    const double row = F.row_sum(p), diff = std::abs(row - estimate[size_t(k)]);
    double vis = 0, bound = 0;
    if (stats && stats->row_visibility_sigma.size() == size_t(n)) vis = stats->row_visibility_sigma[size_t(p)];
    if (stats && stats->row_error_bound.size() == size_t(n)) bound = stats->row_error_bound[size_t(p)];
    // The rays' standard error, as the larger of the binomial's at the assembled row sum (what the rays would show
    // if the row is right: the hypothesis tested) and at their own estimate, at least one ray's worth. From the
    // estimate alone it is too small where few rays hit: a row of 0.0016 (6.5 hits expected of 4,096) that drew one
    // hit was rejected at 5.5 "standard errors" (1.1 % of such rows; CornellBox-Original.obj, exact visibility after
    // adaptive refinement: a right row, 0.28x the allowed with a million rays).
    const double f = estimate[size_t(k)], f0 = std::clamp(row, 0.0, 1.0);
    const double s = std::sqrt(std::max({f0 * (1 - f0), f * (1 - f), 1.0 / nr}) / nr);
    const double allowed = o.k_sigma * std::sqrt(s * s + vis * vis) + bound + 1e-4;
    out.max_difference = std::max(out.max_difference, diff);
    if (diff / allowed >= out.max_ratio) {
      out.max_ratio = diff / allowed;
      out.worst_patch = p;
      out.worst_row_sum = row;
      out.worst_estimate = estimate[size_t(k)];
      out.worst_allowed = allowed;
    }
  }
  out.passed = out.max_ratio <= 1;
  return out;
}

}  // namespace lambert::formfactor
