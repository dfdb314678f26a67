#pragma once
// ParaView output: the solved scene as a VTK XML unstructured grid (.vtu).
#include <ostream>
#include <string>
#include <vector>

#include "lambert/mesh/scene.hpp"

namespace lambert::io {

// Writes an XML unstructured grid (.vtu, appended raw binary, zlib-compressed, Float64 values).
// Cells = patches in scene order (VTK_TRIANGLE; VTK_QUAD for convex quads; VTK_POLYGON otherwise),
// points = mesh::split_vertices(scene, crease_angle_deg), so vertex averages never cross a material
// boundary or a crease.
//   point data: "radiance" (3, W m^-2 sr^-1, area-weighted average of the adjacent cells' radiance)
//   cell data:  "radiance" (3, W m^-2 sr^-1), "irradiance" (3, W m^-2), "reflectance" (3),
//               "emission" (3, W m^-2 sr^-1), "face_id" (Int64, input face index, 0-based file order),
//               "area" (m^2), "material_id" (Int32, index into "material_names"),
//               "side" (Int32: 0 the face as given, 1 the back of a two-sided face)
//   field data: "material_names" (strings, one per scene material), "source" (scene.source)
// radiance and irradiance: patches x 3. Throws std::invalid_argument if their row count is not
// scene.patches() or the crease angle is outside [0, 180]. The file is written to a temporary sibling
// and renamed when complete; on failure the temporary is removed and lambert::InputError names `path`.
void write_vtu(const std::string& path, const mesh::Scene& scene, const ColorField& radiance,
               const ColorField& irradiance, double crease_angle_deg = mesh::VertexSplit::kDefaultCreaseDeg);
// The same .vtu content into a binary stream (io::OutputSet::write); VTK errors throw InputError, stream
// errors are the caller's to check.
void write_vtu(std::ostream& out, const mesh::Scene& scene, const ColorField& radiance, const ColorField& irradiance,
               double crease_angle_deg = mesh::VertexSplit::kDefaultCreaseDeg);

// An extra array: `components` values per cell (or point), row-major; with point_average, a cell array is also
// written as point data (area-weighted averages over the split vertices, as "radiance").
struct ExtraArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
  bool point_average = false;
};
// write_vtu with extra cell arrays (daylight: "sky_irradiance", "illuminance", "luminance", ...). Throws
// std::invalid_argument if an array's size is not patches x components.
void write_vtu(std::ostream& out, const mesh::Scene& scene, const ColorField& radiance, const ColorField& irradiance,
               double crease_angle_deg, const std::vector<ExtraArray>& extra_cell_arrays);

// Points (one VTK_VERTEX cell each) with point-data arrays of points.size() x components values: sensor grids.
void write_points_vtu(std::ostream& out, const std::vector<Vec3>& points, const std::vector<ExtraArray>& arrays);

}  // namespace lambert::io
