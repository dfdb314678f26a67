// STL input (issue 11): binary and ASCII told apart by content, facet order = input-face order,
// errors naming the facet, welded by prepare, materials by --materials face ranges.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/shapes.hpp"
#include "soup_util.hpp"

namespace fs = std::filesystem;
using namespace lambert;
using namespace lambert::mesh;

namespace {

class Stl : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir = fs::temp_directory_path() / ("lambert_stl_" + std::to_string(rd()));
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string path(const std::string& name) const { return (dir / name).string(); }
  std::string write(const std::string& name, const std::string& bytes) const {
    std::ofstream(path(name), std::ios::binary) << bytes;
    return path(name);
  }
  fs::path dir;
};

// A unit cube of 12 triangles, outward, corners on a 1/8 grid shifted off the origin (exact in float).
PolygonSoup cube_triangles() {
  PolygonSoup s = make_empty_soup("cube");
  for (const auto& quad : shapes::box(Vec3(0.5, 1.25, -2), Vec3(1.5, 2.25, -1), 1, false)) {
    for (const auto& tri : {std::array<int, 3>{0, 1, 2}, std::array<int, 3>{0, 2, 3}}) {
      SoupFace f;
      for (int c : tri) {
        f.vertices.push_back(static_cast<int>(s.positions.size()));
        s.positions.push_back(quad[c]);
      }
      s.faces.push_back(f);
    }
  }
  return s;
}

std::string expect_error(const std::string& file) {
  try {
    io::read_soup(file);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << file << " was accepted";
  return "";
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string binary_stl(const std::string& header, std::uint32_t count, const std::vector<std::array<float, 9>>& facets) {
  std::string b = header;
  b.resize(80, ' ');
  b.append(reinterpret_cast<const char*>(&count), 4);  // the test machine is little-endian (x86-64, arm64)
  for (const auto& f : facets) {
    const float n[3] = {0, 0, 0};
    b.append(reinterpret_cast<const char*>(n), 12);
    b.append(reinterpret_cast<const char*>(f.data()), 36);
    b.append(2, '\0');
  }
  return b;
}

}  // namespace

TEST_F(Stl, BinaryAndAsciiRoundTripsKeepFacetOrderAndCoordinates) {
  const PolygonSoup cube = cube_triangles();
  for (bool binary : {true, false}) {
    // Extensions that say nothing: the content decides.
    const std::string file = path(binary ? "cube.dat" : "cube.STL");
    io::write_stl(cube, file, binary);
    const PolygonSoup back = io::read_soup(file);
    ASSERT_EQ(back.faces.size(), cube.faces.size()) << binary;
    for (size_t k = 0; k < cube.faces.size(); ++k)
      for (int c = 0; c < 3; ++c)  // exact: 1/8-grid coordinates are floats, ASCII writes shortest round trips
        EXPECT_EQ(back.positions[back.faces[k].vertices[c]], cube.positions[cube.faces[k].vertices[c]])
            << (binary ? "binary" : "ascii") << " facet " << k << " corner " << c;
    for (const auto& f : back.faces) EXPECT_EQ(f.material, 0);
    EXPECT_EQ(back.materials[0].name, "default");
    EXPECT_EQ(back.faces_without_material, 0) << "STL has no materials: nothing to warn about";
    if (!binary) {
      EXPECT_EQ(back.faces[3].line, 2 + 7 * 3) << "ASCII facets know their line";
    }
    // prepare welds the 36 corners into the cube's 8 and keeps its (outward) winding.
    Report r;
    const PolygonSoup ready = prepare(back, {}, r);
    EXPECT_EQ(r.counts["vertices_merged"], 36 - 8);
    EXPECT_EQ(r.counts["faces_reoriented"], 0);
    const Scene scene = build_scene(ready);
    EXPECT_EQ(scene.patches(), 12);
    EXPECT_EQ(scene.face_id[11], 11);
  }
}

TEST_F(Stl, BinaryHeaderStartingWithSolidIsStillBinary) {
  const std::string file = write("solid.stl", binary_stl("solid but binary", 1, {{0, 0, 0, 1, 0, 0, 0, 1, 0}}));
  const PolygonSoup s = io::read_soup(file);
  ASSERT_EQ(s.faces.size(), 1u);
  EXPECT_EQ(s.positions[s.faces[0].vertices[1]], Vec3(1, 0, 0));
}

TEST_F(Stl, MalformedFilesAreErrorsNamingTheFacet) {
  const std::vector<std::array<float, 9>> three = {
      {0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 1, 1, 0, 1, 0, 1, 1}, {0, 0, 2, 1, 0, 2, 0, 1, 2}};
  // Truncated inside facet 2.
  std::string b = binary_stl("x", 3, three);
  b.resize(b.size() - 20);
  std::string e = expect_error(write("cut.stl", b));
  EXPECT_TRUE(has(e, "facet 2 is truncated") && has(e, "cut.stl")) << e;
  // A count that lies: 5 announced, 3 present (facet 3 missing); 2 announced, 3 present.
  e = expect_error(write("more.stl", binary_stl("x", 5, three)));
  EXPECT_TRUE(has(e, "facet 3 is truncated") && has(e, "says 5 facets")) << e;
  e = expect_error(write("fewer.stl", binary_stl("x", 2, three)));
  EXPECT_TRUE(has(e, "says 2 facets") && has(e, "after facet 1")) << e;
  // Non-finite coordinate.
  auto nan3 = three;
  nan3[1][4] = std::nanf("");
  e = expect_error(write("nan.stl", binary_stl("x", 3, nan3)));
  EXPECT_TRUE(has(e, "facet 1, vertex 1") && has(e, "non-finite")) << e;
  // Too short for a header.
  e = expect_error(write("short.stl", std::string(30, '\1')));
  EXPECT_TRUE(has(e, "too short")) << e;
  // ASCII: a vertex missing (line 9), a malformed number (line 5), the file ending inside a facet.
  const std::string good =
      "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\n";
  e = expect_error(write("missing.stl", good + " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n  endloop\n endfacet\nendsolid t\n"));
  EXPECT_TRUE(has(e, "missing.stl:13: facet 1: expected 'vertex x y z'")) << e;
  e = expect_error(write("number.stl", "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 zero 0\n"));
  EXPECT_TRUE(has(e, "number.stl:5") && has(e, "facet 0 y coordinate")) << e;
  e = expect_error(write("ends.stl", good + " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n"));
  EXPECT_TRUE(has(e, "ends.stl") && has(e, "facet 1") && has(e, "ends inside the facet")) << e;
  e = expect_error(write("four.stl", "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n   vertex 1 1 0\n"));
  EXPECT_TRUE(has(e, "four.stl:7: facet 0 has more than 3 vertices")) << e;
}

TEST_F(Stl, MaterialsJsonFaceRangesApply) {
  const PolygonSoup cube = cube_triangles();
  const std::string file = path("cube.stl");
  io::write_stl(cube, file, true);
  const std::string json = write("m.json", R"({"faces": [{"range": [2, 3], "reflectance": 0.2, "emission": 5}]})");
  PolygonSoup s = io::read_soup(file);
  io::apply_materials_json(s, json);
  for (int k = 0; k < 12; ++k) {
    const Material& m = s.materials[s.faces[k].material];
    EXPECT_EQ(m.emission[0], (k == 2 || k == 3) ? 5.0 : 0.0) << "facet " << k;
  }
}

TEST_F(Stl, CliExitsOneNamingTheFacet) {
  std::string b = binary_stl("x", 2, {{0, 0, 0, 1, 0, 0, 0, 1, 0}});
  const std::string file = write("bad.stl", b);
  const std::string cmd = std::string(LAMBERT_BINARY) + " info " + file + " > " + path("out.txt") + " 2>&1";
  const int st = std::system(cmd.c_str());
  std::ifstream in(path("out.txt"));
  const std::string out((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(WEXITSTATUS(st), 1) << out;
  EXPECT_TRUE(has(out, "facet 1 is truncated")) << out;
}
