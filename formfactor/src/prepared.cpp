// Assembly-wide patch data: structure-of-arrays copy of PatchData for the SIMD kernels.
#include "prepared.hpp"

#include <algorithm>

namespace lambert::formfactor::detail {

double* Prepared::column(size_t n) {
  store.emplace_back(n + kBatchPad, 0.0);
  return store.back().data();
}

Prepared::Prepared(const mesh::PatchGeometry& g) : P(prepare(g)), points(P) {
  const int n = P.n;
  store.reserve(40);
  auto fill = [&](auto f) {
    double* c = column(n);
    for (int p = 0; p < n; ++p) c[p] = f(p);
    return c;
  };
  soa.cx = fill([&](int p) { return P.c[p].x(); });
  soa.cy = fill([&](int p) { return P.c[p].y(); });
  soa.cz = fill([&](int p) { return P.c[p].z(); });
  soa.nx = points.soa.nx;
  soa.ny = points.soa.ny;
  soa.nz = points.soa.nz;
  soa.off = fill([&](int p) { return P.offset[p]; });
  soa.area = fill([&](int p) { return P.area[p]; });
  soa.radius = fill([&](int p) { return P.radius[p]; });
  for (int c = 0; c < 4; ++c) {
    soa.qx[c] = points.soa.qx[c];
    soa.qy[c] = points.soa.qy[c];
    soa.qz[c] = points.soa.qz[c];
  }
  for (int k = 0; k < 6; ++k) soa.M[k] = fill([&](int p) { return P.M[p][k]; });
  soa.fast = fill([&](int p) { return P.kind[p] <= 2 ? 1.0 : 0.0; });
  soa.sym = fill([&](int p) { return P.kind[p] == 1 ? 1.0 : 0.0; });
  soa.rerr = fill([&](int p) { return P.rerr[p]; });
  for (int m : {6, 8}) {  // larger rules are mapped per pair from cached reference rules (no locking)
    square_rule[m] = gauss_square(m);
    triangle_rule[m] = gauss_triangle(m);
  }
  soa.eps = P.scene_eps;
  box.resize(n);
  for (int p = 0; p < n; ++p)
    for (const Vec3& v : g.polygon(p)) box[p].add(v);
}

}  // namespace lambert::formfactor::detail
