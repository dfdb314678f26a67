// VTK output: what write_vtu writes is read back with VTK's own XML reader and compared with the scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkType.h>
#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "lambert/io/atomic_file.hpp"
#include "lambert/io/vtk.hpp"
#include "lambert/mesh/scene.hpp"

namespace fs = std::filesystem;
using lambert::ColorField;
using lambert::Vec3;
namespace mesh = lambert::mesh;
namespace io = lambert::io;

namespace {

// A bent strip of four quads plus two separate polygons:
//   q0: x in [0,1], q1: x in [1,3] (both material "paintA", flat, normal +z; q1 has twice q0's area),
//   q2: x in [3,4] ("paintB", flat), q3: wall at x = 4 rising to z = 1 ("paintB", normal -x: 90 deg crease),
//   a triangle ("paintA") and a concave quad, a dart ("paintB"), away from the strip.
// Strip vertices: 10. Split: the 2 at x = 3 by material (q1 | q2), the 2 at x = 4 by the crease (q2 | q3)
// -> 14 output vertices; plus 3 + 4 for the separate polygons = 21.
constexpr int kSplitPoints = 21;
constexpr int kPointsWithoutCreaseSplit = 19;  // crease angle above 90 deg: only the material split remains

mesh::PolygonSoup strip_soup() {
  mesh::PolygonSoup s = mesh::make_empty_soup("strip.obj");
  mesh::Material a, b;
  a.name = "paintA";
  a.reflectance = {0.3, 0.4, 0.5};
  b.name = "paintB";
  b.reflectance = {0.6, 0.5, 0.2};
  b.emission = {1.0, 2.0, 3.0};
  s.materials.push_back(a);  // index 1
  s.materials.push_back(b);  // index 2
  const double xs[4] = {0, 1, 3, 4};
  for (double x : xs)
    for (double y : {0.0, 1.0}) s.positions.push_back(Vec3(x, y, 0));  // index 2 * i + j
  s.positions.push_back(Vec3(4, 0, 1));                                  // 8
  s.positions.push_back(Vec3(4, 1, 1));                                  // 9
  auto v = [](int i, int j) { return 2 * i + j; };
  auto face = [&](std::vector<int> vs, int material) {
    mesh::SoupFace f;
    f.vertices = std::move(vs);
    f.material = material;
    f.line = static_cast<int>(s.faces.size()) + 100;
    s.faces.push_back(f);
  };
  face({v(0, 0), v(1, 0), v(1, 1), v(0, 1)}, 1);
  face({v(1, 0), v(2, 0), v(2, 1), v(1, 1)}, 1);
  face({v(2, 0), v(3, 0), v(3, 1), v(2, 1)}, 2);
  face({v(3, 1), v(3, 0), 8, 9}, 2);
  const int t = static_cast<int>(s.positions.size());
  for (Vec3 p : {Vec3(0, 0, -1), Vec3(1, 0, -1), Vec3(0, 1, -1)}) s.positions.push_back(p);
  face({t, t + 1, t + 2}, 1);
  const int d = static_cast<int>(s.positions.size());
  for (Vec3 p : {Vec3(0, 0, -2), Vec3(2, 1, -2), Vec3(0, 2, -2), Vec3(0.5, 1, -2)}) s.positions.push_back(p);
  face({d, d + 1, d + 2, d + 3}, 2);  // reflex corner at (0.5, 1)
  return s;
}

// Distinct, easily recognised values per patch and channel.
ColorField field(int n, double base) {
  ColorField f(n, 3);
  for (int p = 0; p < n; ++p) f.row(p) << base + p, 10 * base + 2 * p + 0.25, 100 * base + 3 * p + 0.5;
  return f;
}

class VtkOutput : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("lambert_test_vtk_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    scene_ = mesh::build_scene(strip_soup());
    ASSERT_EQ(scene_.patches(), 6) << "the strip scene's polygons are planar and must stay one patch each";
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::vector<std::string> files_in(const fs::path& d) const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(d)) names.push_back(e.path().filename().string());
    return names;
  }

  int patch_of_face(int face) const {
    for (int p = 0; p < scene_.patches(); ++p)
      if (scene_.face_id[p] == face) return p;
    ADD_FAILURE() << "input face " << face << " is not a patch";
    return 0;
  }

  vtkSmartPointer<vtkUnstructuredGrid> read(const fs::path& path) {
    auto reader = vtkSmartPointer<vtkXMLUnstructuredGridReader>::New();
    reader->SetFileName(path.c_str());
    reader->Update();
    EXPECT_EQ(reader->GetErrorCode(), 0u) << path;
    return reader->GetOutput();
  }

  // Output points at `x`, exact match: positions are written as Float64 and read back unchanged.
  static std::vector<vtkIdType> points_at(vtkUnstructuredGrid* g, const Vec3& x) {
    std::vector<vtkIdType> ids;
    for (vtkIdType i = 0; i < g->GetNumberOfPoints(); ++i) {
      double q[3];
      g->GetPoint(i, q);
      if (q[0] == x.x() && q[1] == x.y() && q[2] == x.z()) ids.push_back(i);
    }
    return ids;
  }

  fs::path dir_;
  mesh::Scene scene_;
};

void expect_array(vtkFieldData* data, const char* name, int components, vtkIdType tuples, const char* where) {
  vtkAbstractArray* a = data->GetAbstractArray(name);
  ASSERT_NE(a, nullptr) << where << " array '" << name << "' missing";
  EXPECT_EQ(a->GetNumberOfComponents(), components) << where << " " << name;
  EXPECT_EQ(a->GetNumberOfTuples(), tuples) << where << " " << name;
}

TEST_F(VtkOutput, EveryArrayRoundTripsWithItsShapeAndValues) {
  const int n = scene_.patches();
  const ColorField radiance = field(n, 1.0), irradiance = field(n, 7.0);
  const fs::path out = dir_ / "strip.vtu";
  io::write_vtu(out.string(), scene_, radiance, irradiance);
  auto g = read(out);
  ASSERT_EQ(g->GetNumberOfCells(), n);
  EXPECT_EQ(g->GetNumberOfPoints(), kSplitPoints);

  expect_array(g->GetPointData(), "radiance", 3, g->GetNumberOfPoints(), "point");
  for (const char* rgb : {"radiance", "irradiance", "reflectance", "emission"}) expect_array(g->GetCellData(), rgb, 3, n, "cell");
  for (const char* scalar : {"face_id", "area", "material_id"}) expect_array(g->GetCellData(), scalar, 1, n, "cell");
  expect_array(g->GetFieldData(), "material_names", 1, static_cast<vtkIdType>(scene_.materials.size()), "field");
  expect_array(g->GetFieldData(), "source", 1, 1, "field");
  if (HasFatalFailure()) return;

  vtkDataArray* face_id = g->GetCellData()->GetArray("face_id");
  vtkDataArray* material_id = g->GetCellData()->GetArray("material_id");
  const int id_type = face_id->GetDataType();
  EXPECT_TRUE((id_type == VTK_LONG || id_type == VTK_LONG_LONG || id_type == VTK_ID_TYPE) &&
              face_id->GetDataTypeSize() == 8)
      << "face_id must be Int64, got " << face_id->GetDataTypeAsString();
  EXPECT_TRUE(material_id->GetDataType() == VTK_INT && material_id->GetDataTypeSize() == 4)
      << "material_id must be Int32, got " << material_id->GetDataTypeAsString();

  // Float64 throughout: values must come back bit-identical.
  const ColorField rho = scene_.reflectance_field(), le = scene_.emission_field();
  const std::pair<const char*, const ColorField*> rgb_fields[] = {
      {"radiance", &radiance}, {"irradiance", &irradiance}, {"reflectance", &rho}, {"emission", &le}};
  for (auto [name, f] : rgb_fields) {
    vtkDataArray* a = g->GetCellData()->GetArray(name);
    for (int p = 0; p < n; ++p)
      for (int c = 0; c < 3; ++c) EXPECT_EQ(a->GetComponent(p, c), (*f)(p, c)) << name << " cell " << p << " channel " << c;
  }
  vtkDataArray* area = g->GetCellData()->GetArray("area");
  for (int p = 0; p < n; ++p) {
    EXPECT_EQ(face_id->GetTuple1(p), scene_.face_id[p]) << "cell " << p;
    EXPECT_EQ(material_id->GetTuple1(p), scene_.material[p]) << "cell " << p;
    EXPECT_EQ(area->GetTuple1(p), scene_.geometry.area[p]) << "cell " << p;
  }
  // Independent check of the areas from the construction: 1, 2, 1, 1, 0.5 and the dart 1.5 (shoelace).
  const double expected_area[6] = {1, 2, 1, 1, 0.5, 1.5};
  for (int f = 0; f < 6; ++f) EXPECT_NEAR(area->GetTuple1(patch_of_face(f)), expected_area[f], 1e-14) << "face " << f;

  auto* names = vtkStringArray::SafeDownCast(g->GetFieldData()->GetAbstractArray("material_names"));
  ASSERT_NE(names, nullptr) << "material_names must be a string array";
  for (size_t m = 0; m < scene_.materials.size(); ++m)
    EXPECT_EQ(names->GetValue(static_cast<vtkIdType>(m)), scene_.materials[m].name) << "material " << m;
  auto* source = vtkStringArray::SafeDownCast(g->GetFieldData()->GetAbstractArray("source"));
  ASSERT_NE(source, nullptr) << "source must be a string array";
  EXPECT_EQ(source->GetValue(0), scene_.source);
}

TEST_F(VtkOutput, CellsAreThePatchPolygonsWithMatchingCellTypes) {
  const int n = scene_.patches();
  const fs::path out = dir_ / "cells.vtu";
  io::write_vtu(out.string(), scene_, field(n, 1), field(n, 2));
  auto g = read(out);
  ASSERT_EQ(g->GetNumberOfCells(), n);
  for (int p = 0; p < n; ++p) {
    const auto poly = scene_.geometry.polygon(p);
    vtkNew<vtkIdList> ids;
    g->GetCellPoints(p, ids);
    ASSERT_EQ(ids->GetNumberOfIds(), static_cast<vtkIdType>(poly.size())) << "cell " << p;
    for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k) {
      double q[3];
      g->GetPoint(ids->GetId(k), q);
      EXPECT_EQ(Vec3(q[0], q[1], q[2]), poly[k]) << "cell " << p << " corner " << k;
    }
  }
  // Strip quads are convex -> VTK_QUAD; the dart is a concave quad -> VTK_POLYGON (a VTK_QUAD would be
  // rendered split along the wrong diagonal).
  for (int f = 0; f < 4; ++f) EXPECT_EQ(g->GetCellType(patch_of_face(f)), VTK_QUAD) << "face " << f;
  EXPECT_EQ(g->GetCellType(patch_of_face(4)), VTK_TRIANGLE);
  EXPECT_EQ(g->GetCellType(patch_of_face(5)), VTK_POLYGON);
}

TEST_F(VtkOutput, PointRadianceIsAreaWeightedAndSplitAtMaterialAndCrease) {
  const int n = scene_.patches();
  const ColorField radiance = field(n, 1.0);
  const fs::path out = dir_ / "points.vtu";
  io::write_vtu(out.string(), scene_, radiance, field(n, 3.0));
  auto g = read(out);
  vtkDataArray* pr = g->GetPointData()->GetArray("radiance");
  ASSERT_NE(pr, nullptr);
  const int q0 = patch_of_face(0), q1 = patch_of_face(1), q2 = patch_of_face(2), q3 = patch_of_face(3);
  // Tolerance: the average is a two-term weighted sum, a few ulps of values <= 1e3.
  constexpr double tol = 1e-12;

  // (1,0,0) is shared by q0 (area 1) and q1 (area 2), same material, coplanar: one vertex.
  const auto mid = points_at(g, Vec3(1, 0, 0));
  ASSERT_EQ(mid.size(), 1u);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(pr->GetComponent(mid[0], c), (1.0 * radiance(q0, c) + 2.0 * radiance(q1, c)) / 3.0, tol) << "channel " << c;

  // (3,0,0): material boundary q1 | q2 -> two vertices carrying q1's and q2's values unmixed.
  // (4,0,0): 90 deg crease q2 | q3 -> two vertices carrying q2's and q3's values.
  const std::pair<Vec3, std::pair<int, int>> splits[] = {{Vec3(3, 0, 0), {q1, q2}}, {Vec3(4, 0, 0), {q2, q3}}};
  for (const auto& [x, pq] : splits) {
    const auto ids = points_at(g, x);
    ASSERT_EQ(ids.size(), 2u) << "vertex at " << x.transpose() << " must be split";
    std::vector<double> got = {pr->GetComponent(ids[0], 0), pr->GetComponent(ids[1], 0)};
    std::sort(got.begin(), got.end());
    std::vector<double> want = {radiance(pq.first, 0), radiance(pq.second, 0)};
    std::sort(want.begin(), want.end());
    EXPECT_NEAR(got[0], want[0], tol) << "at " << x.transpose();
    EXPECT_NEAR(got[1], want[1], tol) << "at " << x.transpose();
  }
}

TEST_F(VtkOutput, CreaseAngleAboveTheFoldKeepsCreaseVerticesJoined) {
  const int n = scene_.patches();
  const fs::path out = dir_ / "crease.vtu";
  io::write_vtu(out.string(), scene_, field(n, 1), field(n, 2), 120.0);  // fold is 90 deg < 120
  auto g = read(out);
  EXPECT_EQ(g->GetNumberOfPoints(), kPointsWithoutCreaseSplit);
  EXPECT_EQ(points_at(g, Vec3(4, 0, 0)).size(), 1u) << "crease vertex must not be split";
  EXPECT_EQ(points_at(g, Vec3(3, 0, 0)).size(), 2u) << "material boundary must still be split";
}

TEST_F(VtkOutput, FileIsAppendedRawBinaryZlibCompressed) {
  const int n = scene_.patches();
  const fs::path out = dir_ / "format.vtu";
  io::write_vtu(out.string(), scene_, field(n, 1), field(n, 2));
  std::ifstream in(out, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  EXPECT_NE(head.find("compressor=\"vtkZLibDataCompressor\""), std::string::npos) << head.substr(0, 400);
  EXPECT_NE(head.find("format=\"appended\""), std::string::npos);
  EXPECT_NE(head.find("encoding=\"raw\""), std::string::npos);
  EXPECT_EQ(files_in(dir_), std::vector<std::string>{"format.vtu"}) << "no temporary may remain";
}

TEST_F(VtkOutput, WrongFieldShapeThrowsInvalidArgumentAndWritesNothing) {
  const int n = scene_.patches();
  const fs::path out = dir_ / "bad.vtu";
  EXPECT_THROW(io::write_vtu(out.string(), scene_, field(n - 1, 1), field(n, 2)), std::invalid_argument);
  EXPECT_THROW(io::write_vtu(out.string(), scene_, field(n, 1), field(n + 1, 2)), std::invalid_argument);
  EXPECT_THROW(io::write_vtu(out.string(), scene_, field(n, 1), field(n, 2), -1.0), std::invalid_argument);
  EXPECT_TRUE(files_in(dir_).empty());
}

TEST_F(VtkOutput, WriteIntoMissingDirectoryThrowsInputErrorNamingPathAndLeavesNothing) {
  const int n = scene_.patches();
  const std::string out = (dir_ / "no_such_dir" / "x.vtu").string();
  try {
    io::write_vtu(out, scene_, field(n, 1), field(n, 2));
    FAIL() << "expected lambert::InputError";
  } catch (const lambert::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(out), std::string::npos) << e.what();
  }
  EXPECT_TRUE(files_in(dir_).empty()) << "neither the file nor a temporary may exist";
}

TEST_F(VtkOutput, FailedRenameRemovesTemporaryAndKeepsTarget) {
  // The target is an existing non-empty directory: the VTK writer succeeds on the temporary, the rename fails.
  const int n = scene_.patches();
  const fs::path out = dir_ / "occupied.vtu";
  fs::create_directories(out);
  std::ofstream(out / "keep.txt") << "keep";
  try {
    io::write_vtu(out.string(), scene_, field(n, 1), field(n, 2));
    FAIL() << "expected lambert::InputError";
  } catch (const lambert::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(out.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(files_in(dir_), std::vector<std::string>{"occupied.vtu"}) << "temporary left behind";
  EXPECT_TRUE(fs::is_directory(out));
  EXPECT_EQ(files_in(out), std::vector<std::string>{"keep.txt"});
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST_F(VtkOutput, AtomicWriteReplacesFileOnlyWhenFillSucceeds) {
  const fs::path out = dir_ / "table.csv";
  io::write_file_atomically(out.string(), [](std::ostream& o) { o << "a,b\n1,2\n"; });
  EXPECT_EQ(slurp(out), "a,b\n1,2\n");

  // fill throws: its exception propagates, the old content stays, no temporary remains.
  EXPECT_THROW(io::write_file_atomically(out.string(),
                                         [](std::ostream& o) {
                                           o << "partial";
                                           throw std::runtime_error("fill failed");
                                         }),
               std::runtime_error);
  EXPECT_EQ(slurp(out), "a,b\n1,2\n");
  // fill leaves the stream failed: InputError naming the path.
  try {
    io::write_file_atomically(out.string(), [](std::ostream& o) {
      o << "partial";
      o.setstate(std::ios::badbit);
    });
    FAIL() << "expected lambert::InputError";
  } catch (const lambert::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(out.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(out), "a,b\n1,2\n");
  EXPECT_EQ(files_in(dir_), std::vector<std::string>{"table.csv"});

  const std::string missing = (dir_ / "missing" / "t.json").string();
  EXPECT_THROW(io::write_file_atomically(missing, [](std::ostream& o) { o << "{}"; }), lambert::InputError);
  EXPECT_EQ(files_in(dir_), std::vector<std::string>{"table.csv"});
}

TEST(TemporarySibling, IsInTheSameDirectoryAndFreshEachCall) {
  const fs::path target = fs::path("/some/dir") / "out.vtu";
  const fs::path a = io::temporary_sibling(target.string()), b = io::temporary_sibling(target.string());
  EXPECT_EQ(a.parent_path(), target.parent_path());
  EXPECT_NE(a, b);
  EXPECT_NE(a, target);
  EXPECT_NE(a.filename().string().find("out.vtu"), std::string::npos) << a;
}

}  // namespace
