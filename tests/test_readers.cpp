// Scene file readers and writers: round trips, format features, and one test per input error.
// All comparisons are exact: readers and writers must not lose a bit (writers use the shortest
// decimal that reads back to the same double; binary PLY stores doubles).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "lambert/io/readers.hpp"
#include "soup_util.hpp"

namespace fs = std::filesystem;
using lambert::InputError;
using lambert::RGB;
using lambert::Vec3;
using lambert::mesh::Material;
using lambert::mesh::PolygonSoup;
using lambert::mesh::SoupFace;
namespace io = lambert::io;
using lambert::mesh::test_util::expect_same_soup;

namespace {

class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = fs::temp_directory_path() /
            ("lambert-readers-" + std::to_string(rd()) + "-" + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string path(const std::string& name) const { return (path_ / name).string(); }
  std::string write(const std::string& name, const std::string& content) const {
    std::ofstream(path(name), std::ios::binary) << content;
    return path(name);
  }

 private:
  fs::path path_;
};

// Runs fn, expects an InputError whose message contains every needle.
void expect_error(const std::function<void()>& fn, const std::vector<std::string>& needles) {
  try {
    fn();
  } catch (const InputError& e) {
    std::string msg = e.what();
    for (const std::string& n : needles)
      EXPECT_NE(msg.find(n), std::string::npos) << "message lacks '" << n << "': " << msg;
    return;
  }
  ADD_FAILURE() << "no InputError thrown; expected one mentioning '" << needles.back() << "'";
}

std::string base(const std::string& path) { return fs::path(path).filename().string(); }

// Coordinates whose shortest decimal forms are long, tiny, huge or negative zero.
PolygonSoup sample_soup() {
  PolygonSoup s = lambert::mesh::make_empty_soup("sample");
  const double odd[] = {0.1, 1.0 / 3.0, -2.0 / 7.0, 1e-7, 12345.678901234567, 1e22, -0.0, std::nextafter(1.0, 2.0)};
  for (int i = 0; i < 10; ++i)
    s.positions.push_back(Vec3(odd[i % 8] + i, odd[(i + 3) % 8] * (i + 1), odd[(i + 5) % 8] - i));
  auto face = [&](std::vector<int> v, int material, int group) {
    SoupFace f;
    f.vertices = std::move(v);
    f.material = material;
    f.group = group;
    s.faces.push_back(f);
  };
  Material white{"white", RGB(0.7, 0.7, 0.7), RGB::Zero(), false, {}};
  Material lamp{"lamp", RGB(0.1, 0.2, 1.0 / 3.0), RGB(10, 9.5, 1.0 / 7.0), false, {}};
  s.materials.push_back(white);
  s.materials.push_back(lamp);
  s.groups = {"floor", "light"};
  face({0, 1, 2}, 0, -1);  // before any material: counted as without material
  face({2, 3, 4, 5}, 1, 0);
  face({5, 6, 7, 8, 9}, 2, 1);
  face({9, 0, 3}, 0, 1);  // material 0 again, after others
  face({1, 4, 7}, 1, -1);
  s.faces_without_material = 1;
  return s;
}

// A soup whose materials are colours only (what PLY and OFF carry).
PolygonSoup colour_soup(bool byte_colours) {
  PolygonSoup s = sample_soup();
  for (auto& f : s.faces) f.group = -1;
  s.groups.clear();
  s.materials.resize(1);
  Material a{"a", byte_colours ? RGB(1.0, 0.0, 128 / 255.0) : RGB(0.3, 0.3, 0.3), RGB::Zero(), false, {}};
  Material b{"b", byte_colours ? RGB(17 / 255.0, 1.0, 1.0) : RGB(1.0 / 3.0, 1.0, 1e-3), RGB::Zero(), false, {}};
  s.materials.push_back(a);
  s.materials.push_back(b);
  return s;
}

std::string le32(std::uint32_t v) {
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((v >> (8 * i)) & 0xff);
  return s;
}
std::string be32(std::uint32_t v) {
  std::string s = le32(v);
  std::reverse(s.begin(), s.end());
  return s;
}
std::string lef(float f) { return le32(std::bit_cast<std::uint32_t>(f)); }
std::string bef(float f) { return be32(std::bit_cast<std::uint32_t>(f)); }

}  // namespace

// ---------------------------------------------------------------- round trips

TEST(Readers, ObjRoundTripIsExact) {
  TempDir dir;
  PolygonSoup s = sample_soup();
  std::string path = dir.path("scene.obj");
  io::write_obj(s, path);
  ASSERT_TRUE(fs::exists(dir.path("scene.mtl")));
  PolygonSoup r = io::read_obj(path);
  expect_same_soup(s, r);
  // A second generation is identical too (the writer is deterministic).
  io::write_obj(r, dir.path("again.obj"));
  expect_same_soup(r, io::read_obj(dir.path("again.obj")));
}

// PLY/OFF carry reflectance as face colours, so the first read gives colour materials:
// per-face reflectance must match the original exactly; from then on the soup is a fixed point.
class ColourRoundTrip : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

TEST_P(ColourRoundTrip, IsExact) {
  auto [format, byte_colours] = GetParam();
  TempDir dir;
  PolygonSoup s = colour_soup(byte_colours);
  auto write = [&](const PolygonSoup& soup, const std::string& name) {
    std::string p = dir.path(name);
    if (format == "off") io::write_off(soup, p);
    else io::write_ply(soup, p, format == "ply-binary");
    return p;
  };
  std::string ext = format == "off" ? ".off" : ".ply";
  PolygonSoup r = io::read_soup(write(s, "first" + ext));
  ASSERT_EQ(r.positions.size(), s.positions.size());
  for (std::size_t i = 0; i < s.positions.size(); ++i)
    EXPECT_TRUE(r.positions[i] == s.positions[i]) << "position " << i;
  ASSERT_EQ(r.faces.size(), s.faces.size());
  for (std::size_t k = 0; k < s.faces.size(); ++k) {
    EXPECT_EQ(r.faces[k].vertices, s.faces[k].vertices) << "face " << k;
    const RGB& want = s.materials[s.faces[k].material].reflectance;
    const RGB& got = r.materials[r.faces[k].material].reflectance;
    EXPECT_TRUE((want == got).all()) << "face " << k << ": " << got.transpose() << " vs " << want.transpose();
    if (r.faces[k].material != 0) {
      EXPECT_EQ(r.materials[r.faces[k].material].name.rfind("color_", 0), 0u) << "face " << k;
    }
  }
  if (format == "off") {  // OFF colours are per face: default faces stay material 0
    for (std::size_t k = 0; k < s.faces.size(); ++k)
      EXPECT_EQ(r.faces[k].material == 0, s.faces[k].material == 0) << "face " << k;
  }
  expect_same_soup(r, io::read_soup(write(r, "second" + ext)));
}

INSTANTIATE_TEST_SUITE_P(Formats, ColourRoundTrip,
                         ::testing::Combine(::testing::Values("ply-ascii", "ply-binary", "off"), ::testing::Bool()),
                         [](const auto& p) {
                           std::string n = std::get<0>(p.param) + (std::get<1>(p.param) ? "_bytes" : "_doubles");
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

TEST(Readers, PlyWithoutColoursRoundTripKeepsDefaultMaterial) {
  TempDir dir;
  PolygonSoup s = colour_soup(true);
  for (auto& f : s.faces) f.material = 0;
  s.faces_without_material = static_cast<long>(s.faces.size());
  s.materials.resize(1);
  for (bool binary : {false, true}) {
    io::write_ply(s, dir.path("plain.ply"), binary);
    expect_same_soup(s, io::read_ply(dir.path("plain.ply")));
  }
}

// ---------------------------------------------------------------- OBJ features

TEST(Readers, ObjNegativeIndicesEqualPositive) {
  TempDir dir;
  const std::string verts = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  PolygonSoup pos = io::read_obj(dir.write("pos.obj", verts + "f 1 2 3 4\nv 0 0 1\nf 1 2 5\n"));
  PolygonSoup neg = io::read_obj(dir.write("neg.obj", verts + "f -4 -3 -2 -1\nv 0 0 1\nf -5 -4 -1\n"));
  expect_same_soup(pos, neg);
  EXPECT_EQ(neg.faces[1].vertices, (std::vector<int>{0, 1, 4}));
}

TEST(Readers, ObjFaceVertexFormsGiveSameIndices) {
  TempDir dir;
  const std::string head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n";
  PolygonSoup s = io::read_obj(dir.write("forms.obj", head + "f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1\n"));
  ASSERT_EQ(s.faces.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(s.faces[k].vertices, (std::vector<int>{0, 1, 2})) << "face " << k;
}

TEST(Readers, ObjGroupsKept) {
  TempDir dir;
  PolygonSoup s = io::read_obj(dir.write("groups.obj",
                                         "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                         "f 1 2 3\no lamp\nf 1 2 3\ng wall left\nf 1 2 3\ng\nf 1 2 3\ng lamp\nf 1 2 3\n"));
  ASSERT_EQ(s.faces.size(), 5u);
  EXPECT_EQ(s.groups, (std::vector<std::string>{"lamp", "wall left"}));
  std::vector<int> groups;
  for (auto& f : s.faces) groups.push_back(f.group);
  EXPECT_EQ(groups, (std::vector<int>{-1, 0, 1, -1, 0}));
  EXPECT_EQ(s.faces[2].line, 8);
}

TEST(Readers, MtlKdKeParsed) {
  TempDir dir;
  dir.write("a.mtl",
            "# comment\nnewmtl white\nKa 1 1 1\nKd 0.7 0.6 0.5\nKs 0 0 0\nNs 10\nillum 2\nmap_Kd tex.png\n"
            "newmtl lamp\nKd 0.25\nKe 12 11.5 10\n");
  dir.write("b b.mtl", "newmtl grey\nKe 2\n");
  PolygonSoup s = io::read_obj(dir.write("m.obj",
                                         "mtllib a.mtl\nmtllib b b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                         "f 1 2 3\nusemtl lamp\nf 1 2 3\nusemtl white\nf 3 2 1\nusemtl grey\nf 1 2 3\n"));
  ASSERT_EQ(s.materials.size(), 4u);
  const Material& white = s.materials[1];
  const Material& lamp = s.materials[2];
  const Material& grey = s.materials[3];
  EXPECT_EQ(white.name, "white");
  EXPECT_TRUE((white.reflectance == RGB(0.7, 0.6, 0.5)).all()) << white.reflectance.transpose();
  EXPECT_TRUE((white.emission == RGB::Zero()).all());
  EXPECT_TRUE((lamp.reflectance == RGB::Constant(0.25)).all()) << lamp.reflectance.transpose();
  EXPECT_TRUE((lamp.emission == RGB(12, 11.5, 10)).all()) << lamp.emission.transpose();
  EXPECT_TRUE((grey.reflectance == RGB::Constant(0.5)).all()) << "unset Kd keeps the default grey";
  EXPECT_TRUE((grey.emission == RGB::Constant(2)).all());
  EXPECT_EQ(base(lamp.defined_at.file), "a.mtl");
  EXPECT_EQ(lamp.defined_at.line, 9);
  EXPECT_EQ(base(grey.defined_at.file), "b b.mtl");
  std::vector<int> mats;
  for (auto& f : s.faces) mats.push_back(f.material);
  EXPECT_EQ(mats, (std::vector<int>{0, 2, 1, 3}));
  EXPECT_EQ(s.faces_without_material, 1);
}

TEST(Readers, ObjSeveralMtllibNamesOnOneLine) {
  TempDir dir;
  dir.write("x.mtl", "newmtl x\nKd 0.1\n");
  dir.write("y.mtl", "newmtl y\nKd 0.2\n");
  PolygonSoup s = io::read_obj(dir.write("xy.obj", "mtllib x.mtl y.mtl x.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl y\nf 1 2 3\n"));
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[s.faces[0].material].name, "y");
}

TEST(Readers, ObjIgnoredStatementsAreSummarised) {
  TempDir dir;
  PolygonSoup s = io::read_obj(dir.write("lp.obj",
                                         "v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\ns 1\nl 1 2\nl 2 3\np 1\n"
                                         "f 1 2 \\\n 3 # continued\n"));
  ASSERT_EQ(s.faces.size(), 1u);
  EXPECT_EQ(s.faces[0].vertices, (std::vector<int>{0, 1, 2}));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("2 line (l) and 1 point (p)"), std::string::npos) << s.warnings[0];
  EXPECT_TRUE(s.positions[1] == Vec3(1, 0, 0)) << "w and vertex colours are ignored";
}

// ---------------------------------------------------------------- PLY / OFF features

TEST(Readers, PlyFaceColoursBecomeNamedMaterials) {
  TempDir dir;
  PolygonSoup s = io::read_ply(dir.write("c.ply",
                                         "ply\nformat ascii 1.0\ncomment hi\nobj_info x\n"
                                         "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                         "property uchar red\n"
                                         "element face 3\nproperty list uchar int vertex_indices\n"
                                         "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
                                         "0 0 0 9\n1 0 0 9\n0 1 0 9\n3 0 1 2 255 0 0\n3 2 1 0 255 0 0\n3 0 2 1 0 128 255\n"));
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[1].name, "color_255_0_0");
  EXPECT_TRUE((s.materials[1].reflectance == RGB(1, 0, 0)).all());
  EXPECT_EQ(s.materials[2].name, "color_0_128_255");
  EXPECT_TRUE((s.materials[2].reflectance == RGB(0, 128 / 255.0, 1)).all()) << s.materials[2].reflectance.transpose();
  EXPECT_EQ(s.faces[0].material, 1);
  EXPECT_EQ(s.faces[1].material, 1);
  EXPECT_EQ(s.faces[2].material, 2);
  EXPECT_EQ(s.faces[2].line, 21);
  EXPECT_EQ(s.faces_without_material, 0);
  EXPECT_EQ(base(s.materials[1].defined_at.file), "c.ply");
}

// Binary data with extra vertex properties, a list in the vertex, and an unknown element
// between vertices and faces, in both byte orders.
TEST(Readers, PlyBinarySkipsOtherElementsInBothByteOrders) {
  TempDir dir;
  for (bool big : {false, true}) {
    auto u32 = big ? be32 : le32;
    auto f32 = big ? bef : lef;
    std::string h = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                    " 1.0\nelement vertex 4\nproperty float x\nproperty uchar flag\nproperty float y\n"
                    "property list uchar short extra\nproperty float z\n"
                    "element edge 2\nproperty int a\nproperty list ushort uint b\n"
                    "element face 2\nproperty list uchar uint vertex_index\nproperty float red\nproperty float green\n"
                    "property float blue\nend_header\n";
    const float p[4][3] = {{0, 0, 0}, {1.5f, 0, 0}, {0, 2.25f, 0}, {0, 0, -3}};
    for (auto& v : p) h += f32(v[0]) + "\x07" + f32(v[1]) + std::string("\x02\x00\x01\x00\x02", 5) + f32(v[2]);
    for (int e = 0; e < 2; ++e) h += u32(5) + (big ? std::string("\x00\x01", 2) : std::string("\x01\x00", 2)) + u32(9);
    h += std::string(1, '\x03') + u32(0) + u32(1) + u32(2) + f32(0.25f) + f32(0.5f) + f32(0.75f);
    h += std::string(1, '\x04') + u32(0) + u32(1) + u32(2) + u32(3) + f32(0.25f) + f32(0.5f) + f32(0.75f);
    PolygonSoup s = io::read_ply(dir.write(big ? "be.ply" : "le.ply", h));
    ASSERT_EQ(s.positions.size(), 4u) << (big ? "big" : "little");
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(s.positions[i] == Vec3(p[i][0], p[i][1], p[i][2])) << "vertex " << i;
    ASSERT_EQ(s.faces.size(), 2u);
    EXPECT_EQ(s.faces[1].vertices, (std::vector<int>{0, 1, 2, 3}));
    ASSERT_EQ(s.materials.size(), 2u);
    EXPECT_EQ(s.materials[1].name, "color_0.25_0.5_0.75");
    EXPECT_EQ(s.faces[0].material, 1);
    EXPECT_TRUE(s.warnings.empty()) << s.warnings[0];
  }
}

TEST(Readers, OffColoursIntegersAndDecimals) {
  TempDir dir;
  PolygonSoup s = io::read_off(dir.write("c.off",
                                         "COFF 4 4 0  # counts on the header line\n"
                                         "0 0 0 255 255 255 255\n1 0 0 1 1 1 1\n0 1 0 0 0 0 0\n0 0 1 0 0 0 0\n"
                                         "\n# a comment line\n"
                                         "3 0 1 2 255 0 0\n3 0 1 3 1.0 0 0.0 1\n3 1 2 3\n4 0 1 2 3 0.5 0.5 0.5\n"));
  ASSERT_EQ(s.faces.size(), 4u);
  EXPECT_EQ(s.faces[0].material, s.faces[1].material) << "255 and 1.0 are the same colour";
  EXPECT_EQ(s.materials[s.faces[0].material].name, "color_255_0_0");
  EXPECT_EQ(s.faces[2].material, 0);
  EXPECT_EQ(s.materials[s.faces[3].material].name, "color_0.5_0.5_0.5");
  EXPECT_TRUE((s.materials[s.faces[3].material].reflectance == RGB::Constant(0.5)).all());
  EXPECT_EQ(s.faces_without_material, 1);
  EXPECT_EQ(s.faces[3].line, 11);
  EXPECT_EQ(s.position_lines[0], 2);
}

TEST(Readers, ReadSoupDispatchesOnExtensionCaseInsensitively) {
  TempDir dir;
  PolygonSoup s = io::read_soup(dir.write("UPPER.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  EXPECT_EQ(s.faces.size(), 1u);
  EXPECT_EQ(io::read_soup(dir.write("t.Off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")).faces.size(), 1u);
  // .stl is read as STL now (an empty solid is an error naming the file); an unknown extension whose
  // content is no known format is still refused, listing the formats.
  std::string stl = dir.write("x.stl", "solid\n");
  expect_error([&] { io::read_soup(stl); }, {"x.stl:1", "expected 'endsolid'"});
  std::string xyz = dir.write("x.xyz", "1 2 3\n");
  expect_error([&] { io::read_soup(xyz); }, {"x.xyz", "unknown scene file extension", ".obj", ".ply", ".off", ".stl"});
}

TEST(Readers, JsonOverridesColourMaterialByName) {
  TempDir dir;
  PolygonSoup s = io::read_off(dir.write("c.off", "\xEF\xBB\xBFOFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n3 0 2 1\n"));
  io::apply_materials_json(s, dir.write("c.json", R"({"materials": {"color_255_0_0": {"emission": 5}}})"));
  const Material& m = s.materials.at(s.faces[0].material);
  EXPECT_EQ(m.name, "color_255_0_0");
  EXPECT_TRUE((m.reflectance == RGB(1, 0, 0)).all()) << m.reflectance.transpose();
  EXPECT_TRUE((m.emission == RGB::Constant(5)).all()) << m.emission.transpose();
  EXPECT_EQ(s.faces[1].material, 0);
}

// ---------------------------------------------------------------- errors: OBJ / MTL

const std::string kTri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

TEST(ReaderErrors, ObjOutOfRangeIndexNamesLine) {
  TempDir dir;
  std::string p = dir.write("oor.obj", kTri + "f 1 2 3\nf 1 2 4\n");
  expect_error([&] { io::read_obj(p); }, {"oor.obj:5: ", "out of range", "4", "3 vertices"});
  std::string q = dir.write("rel.obj", kTri + "f -1 -2 -4\n");
  expect_error([&] { io::read_obj(q); }, {"rel.obj:4: ", "out of range", "-4"});
}

TEST(ReaderErrors, ObjIndexZeroNamesLine) {
  TempDir dir;
  std::string p = dir.write("zero.obj", kTri + "f 0 1 2\n");
  expect_error([&] { io::read_obj(p); }, {"zero.obj:4: ", "index 0", "start at 1"});
}

TEST(ReaderErrors, ObjNanCoordinateNamesLine) {
  TempDir dir;
  std::string p = dir.write("nan.obj", "v 0 0 0\nv 1 nan 0\n");
  expect_error([&] { io::read_obj(p); }, {"nan.obj:2: ", "y coordinate", "not finite"});
  std::string q = dir.write("inf.obj", "v 0 0 -inf\n");
  expect_error([&] { io::read_obj(q); }, {"inf.obj:1: ", "z coordinate", "not finite"});
}

TEST(ReaderErrors, ObjMalformedNumberNamesLine) {
  TempDir dir;
  std::string p = dir.write("bad.obj", "v 0 0 0\nv 1 0x 0\n");
  expect_error([&] { io::read_obj(p); }, {"bad.obj:2: ", "malformed number", "'0x'"});
}

TEST(ReaderErrors, ObjFaceWithTwoVerticesNamesLine) {
  TempDir dir;
  std::string p = dir.write("two.obj", kTri + "f 1 2\n");
  expect_error([&] { io::read_obj(p); }, {"two.obj:4: ", "2 vertices", "at least 3"});
}

TEST(ReaderErrors, ObjMalformedFaceVertexNamesLine) {
  TempDir dir;
  std::string p = dir.write("fv.obj", kTri + "f 1/1/1/1 2 3\n");
  expect_error([&] { io::read_obj(p); }, {"fv.obj:4: ", "malformed face vertex", "'1/1/1/1'"});
}

TEST(ReaderErrors, ObjUnknownMaterialNamesLine) {
  TempDir dir;
  dir.write("u.mtl", "newmtl white\n");
  std::string p = dir.write("u.obj", "mtllib u.mtl\n" + kTri + "usemtl whte\nf 1 2 3\n");
  expect_error([&] { io::read_obj(p); }, {"u.obj:5: ", "unknown material", "'whte'", "white"});
}

TEST(ReaderErrors, ObjMissingMtlNamesObjLine) {
  TempDir dir;
  std::string p = dir.write("nomtl.obj", kTri + "mtllib missing.mtl\n");
  expect_error([&] { io::read_obj(p); }, {"nomtl.obj:4: ", "missing.mtl", "No such file"});
}

TEST(ReaderErrors, MtlMalformedNumberNamesMtlLine) {
  TempDir dir;
  dir.write("bad.mtl", "newmtl a\nKd 0.5 0.5 0.5\nnewmtl b\nKe 1 abc 1\n");
  std::string p = dir.write("m.obj", "mtllib bad.mtl\n" + kTri);
  expect_error([&] { io::read_obj(p); }, {"bad.mtl:4: ", "malformed number", "'abc'", "Ke"});
}

TEST(ReaderErrors, MtlWrongValueCountNamesMtlLine) {
  TempDir dir;
  dir.write("two.mtl", "newmtl a\nKd 0.5 0.5\n");
  std::string p = dir.write("m.obj", "mtllib two.mtl\n" + kTri);
  expect_error([&] { io::read_obj(p); }, {"two.mtl:2: ", "Kd", "2 values", "1 (grey) or 3"});
}

TEST(ReaderErrors, MtlMaterialDefinedTwice) {
  TempDir dir;
  dir.write("a.mtl", "newmtl white\nKd 1\n");
  dir.write("b.mtl", "\nnewmtl white\n");
  std::string p = dir.write("m.obj", "mtllib a.mtl b.mtl\n" + kTri);
  expect_error([&] { io::read_obj(p); }, {"b.mtl:2: ", "defined twice", "a.mtl:1"});
}

TEST(ReaderErrors, UnreadableFileNamesPathAndReason) {
  TempDir dir;
  std::string p = dir.path("absent.obj");
  expect_error([&] { io::read_obj(p); }, {p, "cannot read", "No such file or directory"});
  expect_error([&] { io::read_ply(dir.path("")); }, {"cannot read", "Is a directory"});
}

// ---------------------------------------------------------------- errors: PLY / OFF

const std::string kPlyHead =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n";

TEST(ReaderErrors, PlyTruncatedBinaryNamesElementAndIndex) {
  TempDir dir;
  std::string data = kPlyHead;
  for (int i = 0; i < 9; ++i) data += lef(static_cast<float>(i));
  data += std::string(1, '\x03') + le32(0) + le32(1) + le32(2);
  data += std::string(1, '\x03') + le32(0) + le32(1);  // second face cut short
  std::string p = dir.write("cut.ply", data);
  expect_error([&] { io::read_ply(p); }, {"cut.ply: ", "element 'face' 1", "truncated", "vertex_indices"});
  std::string q = dir.write("cutv.ply", kPlyHead + lef(1) + lef(2));
  expect_error([&] { io::read_ply(q); }, {"cutv.ply: ", "element 'vertex' 0", "truncated", "'z'"});
}

TEST(ReaderErrors, PlyBinaryOutOfRangeIndexNamesFace) {
  TempDir dir;
  std::string data = kPlyHead;
  for (int i = 0; i < 9; ++i) data += lef(static_cast<float>(i));
  data += std::string(1, '\x03') + le32(0) + le32(1) + le32(2) + std::string(1, '\x03') + le32(0) + le32(3) + le32(2);
  std::string p = dir.write("oor.ply", data);
  expect_error([&] { io::read_ply(p); }, {"oor.ply: ", "element 'face' 1", "vertex index 3", "out of range"});
}

TEST(ReaderErrors, PlyAsciiErrorsNameLine) {
  TempDir dir;
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string p = dir.write("a.ply", head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expect_error([&] { io::read_ply(p); }, {"a.ply:13: ", "vertex index 7", "out of range"});
  std::string q = dir.write("b.ply", head + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n");
  expect_error([&] { io::read_ply(q); }, {"b.ply:11: ", "'y'", "finite"});
  std::string r = dir.write("c.ply", head + "0 0 0\n1 0 0 5\n0 1 0\n3 0 1 2\n");
  expect_error([&] { io::read_ply(r); }, {"c.ply:11: ", "extra values"});
  std::string t = dir.write("d.ply", head + "0 0 0\n1 0 0\n");
  expect_error([&] { io::read_ply(t); }, {"d.ply:", "element 'vertex' 2", "the file ends"});
}

TEST(ReaderErrors, PlyBadHeaderNamesLine) {
  TempDir dir;
  std::string p = dir.write("h.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty real x\n");
  expect_error([&] { io::read_ply(p); }, {"h.ply:4: ", "unknown property type", "'real'"});
  std::string q = dir.write("m.ply", "PLY\n");
  expect_error([&] { io::read_ply(q); }, {"m.ply:1: ", "not a PLY file"});
  std::string r = dir.write("f.ply", "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int idx\nend_header\n");
  expect_error([&] { io::read_ply(r); }, {"f.ply:3: ", "vertex_indices"});
}

TEST(ReaderErrors, OffBadHeaderNamesLine) {
  TempDir dir;
  std::string p = dir.write("h.off", "# comment first\nOFFF\n3 1 0\n");
  expect_error([&] { io::read_off(p); }, {"h.off:2: ", "bad OFF header", "'OFFF'", "OFF"});
  std::string q = dir.write("n.off", "3 1 0\n0 0 0\n");
  expect_error([&] { io::read_off(q); }, {"n.off:1: ", "bad OFF header"});
}

TEST(ReaderErrors, OffDataErrorsNameLine) {
  TempDir dir;
  const std::string v = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  std::string p = dir.write("a.off", v + "3 0 1 3\n");
  expect_error([&] { io::read_off(p); }, {"a.off:6: ", "vertex index 3", "out of range"});
  std::string q = dir.write("b.off", v);
  expect_error([&] { io::read_off(q); }, {"b.off:5: ", "ends after 0 of 1 faces"});
  std::string r = dir.write("c.off", v + "3 0 1 2 0.5 0.5\n");
  expect_error([&] { io::read_off(r); }, {"c.off:6: ", "2 values after its indices", "r g b"});
  std::string s = dir.write("d.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n");
  expect_error([&] { io::read_off(s); }, {"d.off:4: ", "y coordinate", "not finite"});
}

// ---------------------------------------------------------------- materials JSON

class MaterialsJson : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_.write("s.mtl", "newmtl white\nKd 0.7\nKe 0\nnewmtl red\nKd 0.6 0.1 0.1\n");
    std::string obj = "mtllib s.mtl\n" + kTri;
    for (int k = 0; k < 6; ++k) obj += std::string(k == 2 ? "usemtl white\n" : k == 4 ? "usemtl red\n" : "") + "f 1 2 3\n";
    soup_ = io::read_obj(dir_.write("s.obj", obj));  // faces 0,1 default; 2,3 white; 4,5 red
  }
  std::string json(const std::string& text) { return dir_.write("m.json", text); }
  const Material& mat(int face) const { return soup_.materials.at(soup_.faces.at(face).material); }

  TempDir dir_;
  PolygonSoup soup_;
};

TEST_F(MaterialsJson, OverrideChangesOnlyGivenFields) {
  io::apply_materials_json(soup_, json(R"({"materials": {"white": {"emission": [1, 2, 3]},
                                                         "red": {"reflectance": 0.2},
                                                         "default": {"reflectance": [0.3]}}})"));
  EXPECT_TRUE((mat(2).reflectance == RGB::Constant(0.7)).all()) << "reflectance kept from the MTL";
  EXPECT_TRUE((mat(2).emission == RGB(1, 2, 3)).all()) << mat(2).emission.transpose();
  EXPECT_TRUE((mat(4).reflectance == RGB::Constant(0.2)).all());
  EXPECT_TRUE((mat(4).emission == RGB::Zero()).all());
  EXPECT_TRUE((mat(0).reflectance == RGB::Constant(0.3)).all());
  EXPECT_EQ(base(mat(2).defined_at.file), "m.json");
  EXPECT_TRUE(soup_.warnings.empty()) << soup_.warnings[0];
}

TEST_F(MaterialsJson, FaceRangesAssignAndLaterEntriesWin) {
  io::apply_materials_json(soup_, json(R"({
    "materials": {"lamp": {"emission": 10}, "spare": {}},
    "faces": [ {"range": [0, 3], "material": "lamp"},
               {"range": [3, 4], "reflectance": [0.1, 0.2, 0.3]},
               {"range": [1, 1], "material": "red"} ]})"));
  EXPECT_EQ(mat(0).name, "lamp");
  EXPECT_TRUE((mat(0).emission == RGB::Constant(10)).all());
  EXPECT_TRUE((mat(0).reflectance == RGB::Constant(0.5)).all()) << "new material: default grey";
  EXPECT_EQ(mat(1).name, "red");
  EXPECT_EQ(mat(2).name, "lamp");
  EXPECT_EQ(mat(3).name, "faces_3-4");
  EXPECT_EQ(mat(4).name, "faces_3-4");
  EXPECT_TRUE((mat(3).reflectance == RGB(0.1, 0.2, 0.3)).all());
  EXPECT_TRUE((mat(3).emission == RGB::Zero()).all()) << "missing inline emission is zero";
  EXPECT_EQ(mat(5).name, "red");
  EXPECT_EQ(soup_.faces_without_material, 0) << "both default faces were assigned";
  ASSERT_EQ(soup_.warnings.size(), 1u);
  EXPECT_NE(soup_.warnings[0].find("'spare'"), std::string::npos) << soup_.warnings[0];
}

TEST_F(MaterialsJson, SyntaxErrorNamesLineAndColumn) {
  std::string p = json("{\n  \"materials\": {\n    \"white\": {\"reflectance\": 0.5,}\n  }\n}\n");
  expect_error([&] { io::apply_materials_json(soup_, p); }, {"m.json:3: ", "column", "JSON syntax error"});
}

TEST_F(MaterialsJson, RangeOutOfBounds) {
  std::string p = json(R"({"faces": [{"range": [2, 6], "material": "white"}]})");
  expect_error([&] { io::apply_materials_json(soup_, p); }, {"m.json", "\"faces\"[0].range", "out of bounds", "6 faces"});
}

TEST_F(MaterialsJson, ReversedRange) {
  std::string p = json(R"({"faces": [{"range": [0, 1], "material": "white"}, {"range": [3, 2], "material": "white"}]})");
  expect_error([&] { io::apply_materials_json(soup_, p); }, {"m.json", "\"faces\"[1].range", "reversed"});
}

TEST_F(MaterialsJson, UnknownMaterialInFaces) {
  std::string p = json(R"({"faces": [{"range": [0, 1], "material": "wite"}]})");
  expect_error([&] { io::apply_materials_json(soup_, p); }, {"m.json", "unknown material", "'wite'"});
}

TEST_F(MaterialsJson, UnknownKeys) {
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"material": {}})")); },
               {"m.json", "unknown top-level key", "'material'"});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"materials": {"a": {"albedo": 1}}})")); },
               {"m.json", "\"materials\".\"a\"", "unknown key", "'albedo'"});
}

TEST_F(MaterialsJson, WrongTypesAndLengths) {
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"materials": {"a": {"reflectance": [1, 2]}}})")); },
               {"m.json", "reflectance", "length 2", "1 or 3"});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"materials": {"a": {"emission": "bright"}}})")); },
               {"m.json", "emission", "a string", "number"});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"materials": {"a": {"emission": [1, true, 1]}}})")); },
               {"m.json", "emission[1]", "boolean"});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"faces": [{"range": [0.5, 2], "material": "red"}]})")); },
               {"m.json", "range", "integer"});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"faces": [{"range": [0, 2]}]})")); },
               {"m.json", "\"faces\"[0]", "no \"material\""});
  expect_error([&] { io::apply_materials_json(soup_, json(R"({"materials": {"a": {"emission": 1e999}}})")); },
               {"m.json:1: column", "out of the range of a double", "1e999"});
}
