#pragma once
// mesh::Scene: validated patches (OpenMesh faces) with materials, ready for form factors.
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>

#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/soup.hpp"

namespace lambert::mesh {

struct MeshTraits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;  // double precision: scenes span 1e-3 m to 1e3 m
  using Normal = OpenMesh::Vec3d;
};
using PolyMesh = OpenMesh::PolyMesh_ArrayKernelT<MeshTraits>;

// What validation found and fixed. Every fix or drop is counted here and reported, never silent.
struct Report {
  std::map<std::string, long> counts;  // e.g. "duplicate_vertices", "nonplanar_faces_triangulated"
  std::vector<std::string> warnings;   // one human-readable line each
  double worst_nonplanarity = 0;       // metres, largest corner distance from a face's plane
  int worst_nonplanar_face = -1;       // input face index of that face
  // Wall time of each preparation stage (weld, orient, imprint, ...), seconds, in the order run.
  std::vector<std::pair<std::string, double>> seconds;
  void warn(const std::string& key, long count, const std::string& message);
};

struct BuildOptions {
  // A polygon is non-planar when a corner lies farther than this from its best plane, relative to
  // the square root of its area (1e-6: far below any modelling precision, above round-off).
  double planarity_tolerance = 1e-6;
  // Warn when no material emits ("the solution will be zero"): for callers that solve. Form factors alone
  // need no emitter.
  bool warn_no_emitter = true;
};

struct Scene {
  std::string source;            // input file
  PolyMesh mesh;                 // face k of the mesh is patch k
  PatchGeometry geometry;        // flat copy of patch polygons, normals, areas (same order)
  std::vector<int> face_id;      // per patch: index of the input face it came from (0-based, file order)
  std::vector<int> material;     // per patch: index into materials
  std::vector<int> group;        // per patch: index into groups, -1 = none
  std::vector<int> side;         // per patch: 0 the face as given, 1 the back of a two-sided face
                                 // (SoupFace::side; empty = all 0)
  std::vector<Material> materials;
  std::vector<std::string> groups;
  int input_faces = 0;           // faces in the input file
  Report report;

  int patches() const { return geometry.size(); }
  const RGB& reflectance(int p) const { return materials[material[p]].reflectance; }
  const RGB& emission(int p) const { return materials[material[p]].emission; }
  bool grey() const;             // every material used by a patch has equal R, G, B reflectance and emission
  RGB emitted_power() const;     // W per channel: pi * sum_p A_p Le_p (Lambertian, one side)
  ColorField reflectance_field() const;  // patches x 3
  ColorField emission_field() const;     // patches x 3, W m^-2 sr^-1
};

// Validates the soup and builds the scene. Throws InputError naming the file, line or face for:
// reflectance outside [0,1), negative or non-finite emission, zero-area faces, faces with repeated
// or out-of-range corners. Non-planar polygons are triangulated (counted, worst deviation reported);
// duplicate vertices, inconsistent orientation and a scene without emitters are warnings.
Scene build_scene(const PolygonSoup& soup, const BuildOptions& options = {});

// Per-vertex output topology: corners of faces around a mesh vertex are grouped into one output
// vertex only within one material and one smooth surface (adjacent across an edge with normals
// within crease_angle_deg). Vertices are split elsewhere.
struct VertexSplit {
  std::vector<Vec3> points;               // output vertex positions
  std::vector<int> corner_vertex;         // per patch corner (same order as geometry.points)
  static constexpr double kDefaultCreaseDeg = 30.0;
};
VertexSplit split_vertices(const Scene& scene, double crease_angle_deg = VertexSplit::kDefaultCreaseDeg);

// Area-weighted average of a per-patch field onto the split vertices: rows = split.points.size().
ColorField average_to_vertices(const Scene& scene, const VertexSplit& split, const ColorField& per_patch);

}  // namespace lambert::mesh
