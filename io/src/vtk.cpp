#include "lambert/io/vtk.hpp"

#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include <vtkCallbackCommand.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkExecutive.h>
#include <vtkFieldData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkTypeInt64Array.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "lambert/io/atomic_file.hpp"

namespace lambert::io {

namespace {

void check_rows(const ColorField& f, const mesh::Scene& scene, const char* what) {
  if (f.rows() != scene.patches())
    throw std::invalid_argument(std::string("write_vtu: ") + what + " has " + std::to_string(f.rows()) +
                                " rows, the scene has " + std::to_string(scene.patches()) + " patches");
}

vtkNew<vtkDoubleArray> rgb_array(const char* name, long rows) {
  vtkNew<vtkDoubleArray> a;
  a->SetName(name);
  a->SetNumberOfComponents(3);
  a->SetComponentName(0, "R");
  a->SetComponentName(1, "G");
  a->SetComponentName(2, "B");
  a->SetNumberOfTuples(rows);
  return a;
}

template <class Rows>
void fill_rgb(vtkDoubleArray* a, long rows, const Rows& row) {
  for (long i = 0; i < rows; ++i) {
    const auto v = row(i);
    const double t[3] = {v[0], v[1], v[2]};
    a->SetTypedTuple(i, t);
  }
}

// VTK_QUAD is split along a diagonal of VTK's choosing when rendered, wrong for a concave quad;
// such quads are written as VTK_POLYGON, which VTK triangulates correctly.
bool convex(std::span<const Vec3> poly, const Vec3& normal) {
  const size_t m = poly.size();
  for (size_t k = 0; k < m; ++k) {
    const Vec3 e0 = poly[(k + 1) % m] - poly[k];
    const Vec3 e1 = poly[(k + 2) % m] - poly[(k + 1) % m];
    if (e0.cross(e1).dot(normal) <= 0) return false;
  }
  return true;
}

int cell_type(std::span<const Vec3> poly, const Vec3& normal) {
  if (poly.size() == 3) return VTK_TRIANGLE;
  if (poly.size() == 4 && convex(poly, normal)) return VTK_QUAD;
  return VTK_POLYGON;
}

// Collects VTK error messages of one object instead of printing them.
struct ErrorCollector {
  std::string messages;
  static void callback(vtkObject*, unsigned long, void* client, void* call) {
    auto* self = static_cast<ErrorCollector*>(client);
    if (call) {
      if (!self->messages.empty()) self->messages += "; ";
      // VTK's text is "ERROR: In <source file>, line N\n<Class> (<address>): <message>\n\n": keep <message>.
      std::string m = static_cast<const char*>(call);
      while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
      if (const auto nl = m.rfind('\n'); nl != std::string::npos) m.erase(0, nl + 1);
      if (const auto colon = m.find("): "); colon != std::string::npos) m.erase(0, colon + 3);
      self->messages += m;
    }
  }
};

}  // namespace

// The grid as appended, zlib-compressed XML into `out` (VTK's errors collected into an InputError).
void write_grid(std::ostream& out, vtkUnstructuredGrid* grid);

void write_vtu(std::ostream& out, const mesh::Scene& scene, const ColorField& radiance,
               const ColorField& irradiance, double crease_angle_deg) {
  write_vtu(out, scene, radiance, irradiance, crease_angle_deg, {});
}

void write_vtu(std::ostream& out, const mesh::Scene& scene, const ColorField& radiance,
               const ColorField& irradiance, double crease_angle_deg, const std::vector<ExtraArray>& extra) {
  check_rows(radiance, scene, "radiance");
  check_rows(irradiance, scene, "irradiance");
  if (!(crease_angle_deg >= 0 && crease_angle_deg <= 180))
    throw std::invalid_argument("write_vtu: crease angle " + std::to_string(crease_angle_deg) +
                                " deg is outside [0, 180]");

  const mesh::PatchGeometry& g = scene.geometry;
  const long n = scene.patches();
  const mesh::VertexSplit split = mesh::split_vertices(scene, crease_angle_deg);
  const ColorField point_radiance = mesh::average_to_vertices(scene, split, radiance);
  const long np = static_cast<long>(split.points.size());

  vtkNew<vtkUnstructuredGrid> grid;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();  // scenes span millimetres to kilometres
  points->SetNumberOfPoints(np);
  for (long i = 0; i < np; ++i) points->SetPoint(i, split.points[i].data());
  grid->SetPoints(points);

  vtkNew<vtkCellArray> cells;
  cells->AllocateExact(n, static_cast<vtkIdType>(g.points.size()));
  vtkNew<vtkUnsignedCharArray> types;
  types->SetNumberOfValues(n);
  std::vector<vtkIdType> ids;
  for (int p = 0; p < n; ++p) {
    ids.clear();
    for (int c = g.offsets[p]; c < g.offsets[p + 1]; ++c) ids.push_back(split.corner_vertex[c]);
    cells->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
    types->SetValue(p, static_cast<unsigned char>(cell_type(g.polygon(p), g.normal[p])));
  }
  grid->SetCells(types, cells);

  auto pr = rgb_array("radiance", np);
  fill_rgb(pr, np, [&](long i) { return point_radiance.row(i); });
  grid->GetPointData()->AddArray(pr);
  grid->GetPointData()->SetActiveScalars("radiance");

  auto cr = rgb_array("radiance", n);
  fill_rgb(cr, n, [&](long i) { return radiance.row(i); });
  auto ci = rgb_array("irradiance", n);
  fill_rgb(ci, n, [&](long i) { return irradiance.row(i); });
  auto crho = rgb_array("reflectance", n);
  fill_rgb(crho, n, [&](long i) { return scene.reflectance(static_cast<int>(i)); });
  auto ce = rgb_array("emission", n);
  fill_rgb(ce, n, [&](long i) { return scene.emission(static_cast<int>(i)); });
  vtkNew<vtkTypeInt64Array> face_id;
  face_id->SetName("face_id");
  face_id->SetNumberOfValues(n);
  vtkNew<vtkDoubleArray> area;
  area->SetName("area");
  area->SetNumberOfValues(n);
  vtkNew<vtkIntArray> material_id;  // int is 32 bits on every platform VTK supports
  material_id->SetName("material_id");
  material_id->SetNumberOfValues(n);
  vtkNew<vtkIntArray> side;  // 0 front (the face as given), 1 back of a two-sided face
  side->SetName("side");
  side->SetNumberOfValues(n);
  for (int p = 0; p < n; ++p) {
    side->SetValue(p, p < static_cast<int>(scene.side.size()) ? scene.side[p] : 0);
    face_id->SetValue(p, scene.face_id[p]);
    area->SetValue(p, g.area[p]);
    material_id->SetValue(p, scene.material[p]);
  }
  vtkCellData* cd = grid->GetCellData();
  for (vtkAbstractArray* a : {static_cast<vtkAbstractArray*>(cr), static_cast<vtkAbstractArray*>(ci),
                              static_cast<vtkAbstractArray*>(crho), static_cast<vtkAbstractArray*>(ce),
                              static_cast<vtkAbstractArray*>(face_id), static_cast<vtkAbstractArray*>(area),
                              static_cast<vtkAbstractArray*>(material_id), static_cast<vtkAbstractArray*>(side)})
    cd->AddArray(a);
  cd->SetActiveScalars("radiance");
  for (const ExtraArray& e : extra) {
    if (e.components < 1 || e.values.size() != size_t(n) * size_t(e.components))
      throw std::invalid_argument("write_vtu: array " + e.name + " has " + std::to_string(e.values.size()) +
                                  " values; expected patches x components");
    vtkNew<vtkDoubleArray> a;
    a->SetName(e.name.c_str());
    a->SetNumberOfComponents(e.components);
    a->SetNumberOfTuples(n);
    for (long i = 0; i < n; ++i) a->SetTypedTuple(i, e.values.data() + size_t(i) * size_t(e.components));
    cd->AddArray(a);
    if (e.point_average && e.components <= 3) {
      ColorField f = ColorField::Zero(n, 3);
      for (long i = 0; i < n; ++i)
        for (int c = 0; c < e.components; ++c) f(i, c) = e.values[size_t(i) * size_t(e.components) + size_t(c)];
      const ColorField pf = mesh::average_to_vertices(scene, split, f);
      vtkNew<vtkDoubleArray> pa;
      pa->SetName(e.name.c_str());
      pa->SetNumberOfComponents(e.components);
      pa->SetNumberOfTuples(np);
      for (long i = 0; i < np; ++i)
        for (int c = 0; c < e.components; ++c) pa->SetComponent(i, c, pf(i, c));
      grid->GetPointData()->AddArray(pa);
    }
  }

  vtkNew<vtkStringArray> names;
  names->SetName("material_names");
  names->SetNumberOfValues(static_cast<vtkIdType>(scene.materials.size()));
  for (size_t m = 0; m < scene.materials.size(); ++m) names->SetValue(static_cast<vtkIdType>(m), scene.materials[m].name);
  vtkNew<vtkStringArray> source;
  source->SetName("source");
  source->InsertNextValue(scene.source);
  grid->GetFieldData()->AddArray(names);
  grid->GetFieldData()->AddArray(source);

  write_grid(out, grid);
}

void write_grid(std::ostream& out, vtkUnstructuredGrid* grid) {
  ErrorCollector errors;
  vtkNew<vtkCallbackCommand> observer;
  observer->SetCallback(&ErrorCollector::callback);
  observer->SetClientData(&errors);
  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  writer->AddObserver(vtkCommand::ErrorEvent, observer);
  writer->SetInputData(grid);
  // The pipeline executive reports the writer's failure once more; collect it too instead of printing.
  ErrorCollector pipeline_errors;
  vtkNew<vtkCallbackCommand> pipeline_observer;
  pipeline_observer->SetCallback(&ErrorCollector::callback);
  pipeline_observer->SetClientData(&pipeline_errors);
  writer->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, pipeline_observer);
  // Into memory, then into our stream: file errors (a full disk) are reported by the caller's stream
  // checks with a clear message, not by VTK's file layer.
  writer->WriteToOutputStringOn();
  writer->SetDataModeToAppended();
  writer->EncodeAppendedDataOff();  // raw binary: smaller and faster than base64
  writer->SetCompressorTypeToZLib();
  writer->SetHeaderTypeToUInt64();  // block sizes above 4 GiB stay representable
  const int ok = writer->Write();
  if (ok != 1 || writer->GetErrorCode() != 0 || !errors.messages.empty()) {
    const std::string& why = errors.messages.empty() ? pipeline_errors.messages : errors.messages;
    throw InputError("cannot write VTK data" + (why.empty() ? std::string() : ": " + why));
  }
  const std::string data = writer->GetOutputString();
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
}

void write_points_vtu(std::ostream& out, const std::vector<Vec3>& pts, const std::vector<ExtraArray>& arrays) {
  const long n = static_cast<long>(pts.size());
  vtkNew<vtkUnstructuredGrid> grid;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(n);
  for (long i = 0; i < n; ++i) points->SetPoint(i, pts[size_t(i)].data());
  grid->SetPoints(points);
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkUnsignedCharArray> types;
  types->SetNumberOfValues(n);
  for (long i = 0; i < n; ++i) {
    const vtkIdType id = i;
    cells->InsertNextCell(1, &id);
    types->SetValue(i, VTK_VERTEX);
  }
  grid->SetCells(types, cells);
  for (const ExtraArray& e : arrays) {
    if (e.components < 1 || e.values.size() != size_t(n) * size_t(e.components))
      throw std::invalid_argument("write_points_vtu: array " + e.name + " has " + std::to_string(e.values.size()) +
                                  " values; expected points x components");
    vtkNew<vtkDoubleArray> a;
    a->SetName(e.name.c_str());
    a->SetNumberOfComponents(e.components);
    a->SetNumberOfTuples(n);
    for (long i = 0; i < n; ++i) a->SetTypedTuple(i, e.values.data() + size_t(i) * size_t(e.components));
    grid->GetPointData()->AddArray(a);
  }
  write_grid(out, grid);
}

void write_vtu(const std::string& path, const mesh::Scene& scene, const ColorField& radiance,
               const ColorField& irradiance, double crease_angle_deg) {
  write_file_atomically(path, [&](std::ostream& os) { write_vtu(os, scene, radiance, irradiance, crease_angle_deg); });
}

}  // namespace lambert::io
