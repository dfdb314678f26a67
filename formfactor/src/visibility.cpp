// Occlusion casters: Embree 3 (single precision BVH) and brute force (double, every triangle).
#include "lambert/formfactor/visibility.hpp"

#include "embree_scene.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace lambert::formfactor {

bool Visibility::occluded(const Vec3& from, const Vec3& to, int ignore_a, int ignore_b) const {
  std::uint8_t hidden = 0;
  occluded(std::span<const Vec3>(&from, 1), std::span<const Vec3>(&to, 1), ignore_a, ignore_b,
           std::span<std::uint8_t>(&hidden, 1));
  return hidden != 0;
}

void Visibility::occluded(std::span<const Vec3> from, std::span<const Vec3> to, std::span<const int> ignore_a,
                          std::span<const int> ignore_b, std::span<std::uint8_t> hidden) const {
  for (size_t k = 0; k < from.size(); ++k)
    occluded(from.subspan(k, 1), to.subspan(k, 1), ignore_a[k], ignore_b[k], hidden.subspan(k, 1));
}

namespace {

// Embree's intersect context extended with the two patches to ignore; the context filter sees every
// candidate hit and rejects hits on those patches, so rays can start and end exactly on the surfaces.
// Patch planes n . x = d (x relative to a centre): a ray from a point of patch a leaves a's plane, so it
// can meet a patch in that plane only at its start, where it touches a coincident patch: the back of a
// two-sided face, or a one-sided face modelled back to back with a. Such hits are not occlusion.
struct Planes {
  std::vector<std::array<double, 4>> nd;  // per patch: n (unit) and d, together (one cache line per hit)
  double eps = 0;  // plane distance tolerance: 1e-9 x the scene's bounding-box diagonal
  Planes() = default;
  Planes(const mesh::PatchGeometry& g, const Vec3& centre) {
    Eigen::AlignedBox3d box;
    for (const Vec3& v : g.points) box.extend(v);
    eps = box.isEmpty() ? 0.0 : 1e-9 * box.diagonal().norm();
    nd.reserve(size_t(g.size()));
    for (int p = 0; p < g.size(); ++p) {
      const Vec3& n = g.normal[p];
      nd.push_back({n.x(), n.y(), n.z(), n.dot(g.centroid[p] - centre)});
    }
  }
  bool coplanar(int p, int q) const {
    const auto &a = nd[size_t(p)], &b = nd[size_t(q)];
    const double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if (std::abs(c) < 1 - 1e-9) return false;
    return std::abs(a[3] - (c > 0 ? b[3] : -b[3])) <= eps;
  }
  // A hit on patch p does not block a ray between patches a and b.
  bool ignored(int p, int a, int b) const {
    return p == a || p == b || (a >= 0 && coplanar(p, a)) || (b >= 0 && coplanar(p, b));
  }
};

// The open segment o -> o + d meets the closed triangle (A, B, C): Moller-Trumbore in double precision, the hit
// rule of the brute-force caster below.
bool segment_meets(const Vec3& o, const Vec3& d, const Vec3& A, const Vec3& B, const Vec3& C) {
  const Vec3 e1 = B - A, e2 = C - A, p = d.cross(e2);
  const double det = e1.dot(p);
  if (det == 0) return false;
  const double inv = 1.0 / det;
  const Vec3 s = o - A;
  const double u = s.dot(p) * inv;
  if (u < 0 || u > 1) return false;
  const Vec3 q = s.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < 0 || u + v > 1) return false;
  const double t = e2.dot(q) * inv;
  return t > 0 && t < 1;
}

// Per Embree primitive: its patch and 1 / its smallest altitude (1/m), together (one cache line per hit).
struct PrimInfo {
  int patch;
  float inv_height;
};

struct IgnoreContext {
  RTCIntersectContext ctx;
  const PrimInfo* prim_info;
  const Planes* planes;
  int a, b;
  // Per ray (indexed by the ray's id) when not null: the pair each ray ignores, instead of (a, b).
  const int* ray_a = nullptr;
  const int* ray_b = nullptr;
  // The segments of this call (indexed by the ray's id), in double precision, and the triangles by primitive.
  const Vec3* from = nullptr;
  const Vec3* to = nullptr;
  const Vec3* points = nullptr;
  const std::array<int, 3>* tris = nullptr;
  double slack = 0;                   // bound on a float hit point's error at normal incidence (m)
};

// Hits on the pair's own patches and their planes are ignored. Any other hit Embree reports (in single precision)
// counts only if the segment meets that triangle in double precision: within float rounding of a segment's ends
// (a table top touching the wall a ray ends on, a window jamb at the ray's start) Embree reported hits that are
// not there (6 of the floor plan's 8.5 M rays, each moving an entry by a sixteenth).
void ignore_filter(const RTCFilterFunctionNArguments* args) {
  const auto* c = reinterpret_cast<const IgnoreContext*>(args->context);
  for (unsigned k = 0; k < args->N; ++k) {
    if (args->valid[k] == 0) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, k);
    const PrimInfo info = c->prim_info[prim];
    const unsigned id = RTCRayN_id(args->ray, args->N, k);
    int a = c->a, b = c->b;
    if (c->ray_a) {
      a = c->ray_a[id];
      b = c->ray_b[id];
    }
    if (c->planes->ignored(info.patch, a, b)) {
      args->valid[k] = 0;
      continue;
    }
    // A hit farther than the float error from the triangle's edges and the segment's ends is a hit in double
    // precision too: kept without the test (it reads the double-precision corners, which at a million patches
    // are out of cache). The error grows as the ray grazes the triangle: 1 / cos, cos = |ng.d| / (|ng| |d|). The
    // margins err = slack / cos along the triangle (times 1 / its height in u, v) and err / |d| along the segment
    // (in t), compared multiplied out by |ng.d| (no division).
    const Vec3 from = c->from[id], d = c->to[id] - from;
    const Vec3 ng(RTCHitN_Ng_x(args->hit, args->N, k), RTCHitN_Ng_y(args->hit, args->N, k),
                  RTCHitN_Ng_z(args->hit, args->N, k));
    const double ng2 = ng.squaredNorm(), nd = std::abs(ng.dot(d)), nlen = std::sqrt(ng2), G = nlen * d.norm();
    if (nd > 1e-3 * G) {
      const double t = RTCRayN_tfar(args->ray, args->N, k) * nd;
      const double u = RTCHitN_u(args->hit, args->N, k) * nd, v = RTCHitN_v(args->hit, args->N, k) * nd;
      const double mb = c->slack * G * info.inv_height, mt = c->slack * nlen;
      if (t > mt && t < nd - mt && u > mb && v > mb && nd - u - v > mb) continue;
    }
    const std::array<int, 3>& T = c->tris[prim];
    if (!segment_meets(from, d, c->points[T[0]], c->points[T[1]], c->points[T[2]])) args->valid[k] = 0;
  }
}

class EmbreeVisibility final : public Visibility {
 public:
  EmbreeVisibility(const mesh::PatchGeometry& g, const std::vector<int>& occluders) {
    // Default configuration: "threads=N" would cap the whole process's TBB parallelism (Embree uses a
    // tbb::global_control for it), and the callers' TBB threads trace the rays anyway.
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("Embree: cannot create device (error " +
                                           std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    // Embree works in float: coordinates relative to the centre of the scene's bounding box, so a
    // scene 5e6 m from the origin (georeferenced) is traced as precisely as the same scene at the
    // origin (float spacing ~ 1e-7 x the scene's size instead of ~0.5 m). Rays are shifted the same way.
    Eigen::AlignedBox3d box;
    for (const Vec3& v : g.points) box.extend(v);
    if (!box.isEmpty()) centre_ = box.center();
    planes_ = Planes(g, centre_);
    std::vector<int> tri_patch;  // per Embree primitive: its patch
    detail::add_patch_triangles(device_, scene_, g, occluders, centre_, tri_patch);
    // The same triangles in double precision, by primitive (add_patch_triangles' order), for the filter.
    points_ = g.points;
    tris_.reserve(tri_patch.size());
    auto add = [&](int p) {
      for (int k = g.triangle_offsets[p]; k < g.triangle_offsets[p + 1]; ++k) tris_.push_back(g.triangles[k]);
    };
    if (occluders.empty())
      for (int p = 0; p < g.size(); ++p) add(p);
    else
      for (int p : occluders) add(p);
    // Float coordinates relative to the centre are off by up to 2^-24 of the largest |coordinate|; Embree's
    // watertight test adds a few ulps of its translated coordinates. 256 x 2^-24 of the largest coordinate bounds
    // the hit point's error at normal incidence with a wide margin.
    double far = 0;
    for (const Vec3& v : g.points) far = std::max(far, (v - centre_).lpNorm<Eigen::Infinity>());
    slack_ = 256 * 0x1.0p-24 * far;
    prim_info_.reserve(tris_.size());
    for (size_t t = 0; t < tris_.size(); ++t) {
      const auto& T = tris_[t];
      const Vec3 &A = points_[T[0]], &B = points_[T[1]], &C = points_[T[2]];
      const double twice_area = (B - A).cross(C - A).norm();
      const double longest = std::max({(B - A).norm(), (C - B).norm(), (A - C).norm()});
      prim_info_.push_back({tri_patch[t], twice_area > 0 ? float(longest / twice_area) : INFINITY});
    }
    rtcCommitScene(scene_);
  }
  ~EmbreeVisibility() override {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  EmbreeVisibility(const EmbreeVisibility&) = delete;
  EmbreeVisibility& operator=(const EmbreeVisibility&) = delete;

  void occluded(std::span<const Vec3> from, std::span<const Vec3> to, int ignore_a, int ignore_b,
                std::span<std::uint8_t> hidden) const override {
    trace(from, to, ignore_a, ignore_b, nullptr, nullptr, hidden);
  }
  void occluded(std::span<const Vec3> from, std::span<const Vec3> to, std::span<const int> ignore_a,
                std::span<const int> ignore_b, std::span<std::uint8_t> hidden) const override {
    trace(from, to, -1, -1, ignore_a.data(), ignore_b.data(), hidden);
  }

 private:
  // Segments in chunks of 64, one rtcOccluded1M call each (a stream: Embree packs coherent rays); the ray's id is
  // its index in the call, which the filter uses to find a per-ray ignored pair.
  void trace(std::span<const Vec3> from, std::span<const Vec3> to, int ignore_a, int ignore_b, const int* ray_a,
             const int* ray_b, std::span<std::uint8_t> hidden) const {
    IgnoreContext c;
    rtcInitIntersectContext(&c.ctx);
    c.ctx.filter = &ignore_filter;
    c.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // one call = rays between two patches or two clusters
    c.prim_info = prim_info_.data();
    c.planes = &planes_;
    c.a = ignore_a;
    c.b = ignore_b;
    c.points = points_.data();
    c.tris = tris_.data();
    c.slack = slack_;
    constexpr size_t kChunk = 64;
    RTCRay rays[kChunk];
    for (size_t b = 0; b < from.size(); b += kChunk) {
      const size_t n = std::min(kChunk, from.size() - b);
      if (ray_a) {
        c.ray_a = ray_a + b;
        c.ray_b = ray_b + b;
      }
      c.from = from.data() + b;
      c.to = to.data() + b;
      for (size_t k = 0; k < n; ++k) {
        const Vec3 o = from[b + k] - centre_;
        const Vec3 d = to[b + k] - from[b + k];
        RTCRay& r = rays[k];
        r.org_x = float(o.x());
        r.org_y = float(o.y());
        r.org_z = float(o.z());
        r.dir_x = float(d.x());
        r.dir_y = float(d.y());
        r.dir_z = float(d.z());
        r.tnear = 0.0f;
        r.tfar = 1.0f;  // the open segment: endpoints lie on the ignored patches
        r.time = 0.0f;
        r.mask = 0xFFFFFFFFu;
        r.id = unsigned(k);
        r.flags = 0;
      }
      rtcOccluded1M(scene_, &c.ctx, rays, unsigned(n), sizeof(RTCRay));
      for (size_t k = 0; k < n; ++k) hidden[b + k] = rays[k].tfar < 0 ? 1 : 0;  // Embree sets tfar = -inf on a hit
    }
  }

  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  Vec3 centre_ = Vec3::Zero();  // subtracted from every coordinate before it becomes a float
  Planes planes_;
  std::vector<Vec3> points_;               // the geometry's corners (double)
  std::vector<std::array<int, 3>> tris_;  // per Embree primitive: its triangle's corners in points_
  std::vector<PrimInfo> prim_info_;        // per Embree primitive
  double slack_ = 0;                       // float error bound of a hit point at normal incidence (m)
};

class BruteForceVisibility final : public Visibility {
 public:
  using Visibility::occluded;  // the per-segment pairs: the base's loop over this one
  explicit BruteForceVisibility(const mesh::PatchGeometry& g) : g_(g), planes_(g, Vec3::Zero()) {
    for (int p = 0; p < g.size(); ++p)
      for (int k = g.triangle_offsets[p]; k < g.triangle_offsets[p + 1]; ++k) patch_.push_back(p);
  }
  void occluded(std::span<const Vec3> from, std::span<const Vec3> to, int ignore_a, int ignore_b,
                std::span<std::uint8_t> hidden) const override {
    for (size_t r = 0; r < from.size(); ++r) {
      const Vec3 o = from[r], d = to[r] - from[r];
      bool hit = false;
      for (size_t t = 0; t < patch_.size() && !hit; ++t) {
        if (planes_.ignored(patch_[t], ignore_a, ignore_b)) continue;
        const auto& T = g_.triangles[t];
        hit = segment_meets(o, d, g_.points[T[0]], g_.points[T[1]], g_.points[T[2]]);
      }
      hidden[r] = hit ? 1 : 0;
    }
  }

 private:
  mesh::PatchGeometry g_;  // a copy: the caster may outlive the caller's geometry
  Planes planes_;
  std::vector<int> patch_;
};

}  // namespace

std::unique_ptr<Visibility> make_embree_visibility(const mesh::PatchGeometry& geometry,
                                                   const std::vector<int>& occluders) {
  return std::make_unique<EmbreeVisibility>(geometry, occluders);
}

std::unique_ptr<Visibility> make_brute_force_visibility(const mesh::PatchGeometry& geometry) {
  return std::make_unique<BruteForceVisibility>(geometry);
}

}  // namespace lambert::formfactor
