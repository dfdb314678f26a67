// Per-vertex output topology (split_vertices) and area-weighted averaging onto it.
#include <cmath>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "lambert/mesh/scene.hpp"
#include "union_find.hpp"

namespace lambert::mesh {

namespace {

using detail::UnionFind;

}  // namespace

VertexSplit split_vertices(const Scene& scene, double crease_angle_deg) {
  const PatchGeometry& g = scene.geometry;
  const PolyMesh& mesh = scene.mesh;
  const int np = g.size();
  const int nc = static_cast<int>(g.points.size());
  if (static_cast<int>(mesh.n_faces()) != np)
    throw std::logic_error("split_vertices: mesh has " + std::to_string(mesh.n_faces()) + " faces, scene " +
                           std::to_string(np) + " patches");

  // Corner index of every face halfedge's target vertex. OpenMesh may start a face's halfedge
  // loop at any corner: align it with the geometry's corner order by the corner positions.
  std::vector<int> corner_of(mesh.n_halfedges(), -1);
  std::vector<PolyMesh::HalfedgeHandle> loop;
  for (int p = 0; p < np; ++p) {
    const auto fh = mesh.face_handle(static_cast<unsigned>(p));
    loop.clear();
    for (auto h : mesh.fh_range(fh)) loop.push_back(h);
    const int m = g.offsets[p + 1] - g.offsets[p];
    if (static_cast<int>(loop.size()) != m)
      throw std::logic_error("split_vertices: face " + std::to_string(p) + " has " + std::to_string(loop.size()) +
                             " halfedges, patch " + std::to_string(m) + " corners");
    int shift = -1;
    for (int r = 0; r < m && shift < 0; ++r) {
      bool ok = true;
      for (int k = 0; k < m && ok; ++k) {
        const auto& x = mesh.point(mesh.to_vertex_handle(loop[(k + r) % m]));
        ok = Vec3(x[0], x[1], x[2]) == g.points[g.offsets[p] + k];
      }
      if (ok) shift = r;
    }
    if (shift < 0)
      throw std::logic_error("split_vertices: face " + std::to_string(p) + " does not match patch corners");
    for (int k = 0; k < m; ++k) corner_of[loop[(k + shift) % m].idx()] = g.offsets[p] + k;
  }

  // Merge the corners at both ends of every smooth edge: same material, normals within the crease.
  // The small slack keeps coplanar neighbours together at crease 0 despite round-off in the normals.
  const double crease = crease_angle_deg * std::numbers::pi / 180.0 + 1e-9;
  UnionFind uf(nc);
  for (auto e : mesh.edges()) {
    if (e.is_boundary()) continue;
    const auto h0 = e.h0(), h1 = e.h1();
    const int f0 = h0.face().idx(), f1 = h1.face().idx();
    if (scene.material[f0] != scene.material[f1]) continue;
    const Vec3 &n0 = g.normal[f0], &n1 = g.normal[f1];
    if (std::atan2(n0.cross(n1).norm(), n0.dot(n1)) > crease) continue;
    // h0: a -> b in f0, h1: b -> a in f1.
    uf.unite(corner_of[h0.idx()], corner_of[h1.prev().idx()]);  // b
    uf.unite(corner_of[h0.prev().idx()], corner_of[h1.idx()]);  // a
  }

  VertexSplit split;
  split.corner_vertex.assign(nc, -1);
  std::vector<int> id_of_root(nc, -1);
  for (int c = 0; c < nc; ++c) {
    const int r = uf.find(c);
    if (id_of_root[r] < 0) {
      id_of_root[r] = static_cast<int>(split.points.size());
      split.points.push_back(g.points[c]);
    }
    split.corner_vertex[c] = id_of_root[r];
  }
  return split;
}

ColorField average_to_vertices(const Scene& scene, const VertexSplit& split, const ColorField& per_patch) {
  const PatchGeometry& g = scene.geometry;
  const int np = g.size();
  if (per_patch.rows() != np)
    throw std::invalid_argument("average_to_vertices: field has " + std::to_string(per_patch.rows()) +
                                " rows, scene " + std::to_string(np) + " patches");
  if (split.corner_vertex.size() != g.points.size())
    throw std::invalid_argument("average_to_vertices: split does not belong to this scene");
  const auto nv = static_cast<Eigen::Index>(split.points.size());
  ColorField sum = ColorField::Zero(nv, 3);
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(nv);
  for (int p = 0; p < np; ++p)
    for (int c = g.offsets[p]; c < g.offsets[p + 1]; ++c) {
      const int v = split.corner_vertex[c];
      sum.row(v) += g.area[p] * per_patch.row(p);
      weight[v] += g.area[p];
    }
  for (Eigen::Index v = 0; v < nv; ++v) sum.row(v) /= weight[v];
  return sum;
}

}  // namespace lambert::mesh
