#include "embree_scene.hpp"

namespace lambert::formfactor::detail {

void add_patch_triangles(RTCDevice device, RTCScene scene, const mesh::PatchGeometry& g, std::span<const int> patches,
                         const Vec3& centre, std::vector<int>& tri_patch) {
  std::vector<int> all;
  if (patches.empty()) {
    all.resize(size_t(g.size()));
    for (int p = 0; p < g.size(); ++p) all[size_t(p)] = p;
    patches = all;
  }
  size_t ntri = 0;
  for (int p : patches) ntri += size_t(g.triangle_offsets[p + 1] - g.triangle_offsets[p]);
  if (ntri == 0) return;
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * ntri));
  auto* ib = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), ntri));
  tri_patch.reserve(tri_patch.size() + ntri);
  size_t t = 0;
  for (int p : patches)
    for (int k = g.triangle_offsets[p]; k < g.triangle_offsets[p + 1]; ++k, ++t) {
      for (int c = 0; c < 3; ++c) {
        const Vec3 v = g.points[g.triangles[k][c]] - centre;
        for (int a = 0; a < 3; ++a) vb[9 * t + 3 * c + a] = float(v[a]);
        ib[3 * t + c] = unsigned(3 * t + c);
      }
      tri_patch.push_back(p);
    }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
}

}  // namespace lambert::formfactor::detail
