// Issue 15, hostile inputs, end to end through the lambert binary: a run never destroys a file, never
// hangs, refuses before allocating, and has one exit code per class (1 = bad input, command-line errors
// included). One test per reported behaviour, named after the property it guards. Every run goes through
// `timeout`, so a hang fails the test (status 124) instead of stalling the suite.
// LAMBERT_TEST_BINARY=/path/to/lambert runs these tests against another build (to show they fail there).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct CliRun {
  int status;           // exit status; 124 = killed by timeout; -1 = by a signal
  std::string output;   // stdout and stderr together
  double seconds;
};

std::string binary() {
  const char* env = std::getenv("LAMBERT_TEST_BINARY");
  return env && *env ? env : LAMBERT_BINARY;
}

// Runs `lambert ARGS` in `dir` under `timeout SECONDS` (prefix: shell commands before it, e.g. ulimit).
CliRun run_in(const fs::path& dir, const std::string& args, int seconds = 60, const std::string& prefix = "") {
  const std::string cmd = "cd '" + dir.string() + "' && " + prefix + "exec timeout " + std::to_string(seconds) + " " +
                          binary() + " " + args + " 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  CliRun r{0, {}, 0};
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return {-1, "popen failed", 0};
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

class Hostile : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir = fs::temp_directory_path() / ("lambert_hostile_" + std::to_string(rd()));
    fs::create_directories(dir);
    put("two.mtl", "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 1 1 1\n");
    put("two.obj", two_squares(1.0));
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path at(const std::string& name) const { return dir / name; }
  void put(const std::string& name, const std::string& text) const { std::ofstream(at(name), std::ios::binary) << text; }
  CliRun run(const std::string& args, int seconds = 60, const std::string& prefix = "") const {
    return run_in(dir, args, seconds, prefix);
  }
  // Hidden temporaries (.NAME.tmp-...) left in dir.
  std::vector<std::string> temporaries() const {
    std::vector<std::string> v;
    for (auto& e : fs::directory_iterator(dir))
      if (e.path().filename().string().find(".tmp-") != std::string::npos) v.push_back(e.path().filename().string());
    return v;
  }
  // A unit square lamp facing a unit square floor 1 m below, coordinates times s.
  static std::string two_squares(double s) {
    std::ostringstream o;
    o.precision(17);
    o << "mtllib two.mtl\n";
    for (auto [x, y, z] : {std::array<double, 3>{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}})
      o << "v " << x * s << ' ' << y * s << ' ' << z * s << '\n';
    o << "usemtl floor\nf 1 2 3 4\nusemtl lamp\nf 5 8 7 6\n";
    return o.str();
  }
  fs::path dir;
};

const std::string kPrecious = "PRECIOUS\n";

// ---- files destroyed or left behind ---------------------------------------------------------------------

// A run that fails on one output (its --stats directory does not exist) changes none of the others, and
// refuses before solving.
TEST_F(Hostile, FailedStatsOutputLeavesTheOtherOutputUntouched) {
  for (const std::string cmd : {"solve", "formfactors"}) {
    SCOPED_TRACE(cmd);
    put("out.dat", kPrecious);
    const CliRun r = run(cmd + " two.obj -o out.dat --stats nodir/s.json --quiet");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("nodir"), std::string::npos) << r.output;
    EXPECT_EQ(slurp(at("out.dat")), kPrecious) << "the -o file was replaced by a run that failed";
    EXPECT_TRUE(temporaries().empty());
  }
}

// A write error on the second output (file size limit: the disk "fills" while writing --stats) keeps the
// first output's old content: outputs are renamed only when all were written.
TEST_F(Hostile, DiskFullOnStatsLeavesTheOtherOutputUntouched) {
  put("F.csv", kPrecious);
  // dash's ulimit -f counts 512-byte blocks: the two-line CSV fits, the ~2 KB stats JSON does not.
  const CliRun r = run("formfactors two.obj -o F.csv --stats s.json --quiet", 60, "trap '' XFSZ; ulimit -f 1; ");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(slurp(at("F.csv")), kPrecious) << r.output;
  EXPECT_FALSE(fs::exists(at("s.json")));
  EXPECT_TRUE(temporaries().empty());
}

// A full disk while writing the .vtu is reported as a write error naming the file, not as VTK internals.
TEST_F(Hostile, DiskFullOnVtuNamesTheFileAndSaysDiskFull) {
  put("out.vtu", kPrecious);
  const CliRun r = run("solve two.obj -o out.vtu --quiet --max-edge 0.05", 60, "trap '' XFSZ; ulimit -f 2; ");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("out.vtu"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("disk full"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("FORWARD_DIRECTION"), std::string::npos) << r.output;
  EXPECT_EQ(slurp(at("out.vtu")), kPrecious);
  EXPECT_TRUE(temporaries().empty());
}

// An output path that is an input of the run (scene, MTL, materials) or another output is refused
// (exit 1) and the file keeps its content.
TEST_F(Hostile, OutputThatIsAnInputOrAnotherOutputIsRefused) {
  put("m.json", "{\"materials\": {\"floor\": {\"reflectance\": 0.4}}}");
  put("other.obj", slurp(at("two.obj")));
  fs::create_symlink("two.obj", at("alias.obj"));
  struct Case {
    std::string args, victim;
  };
  const Case cases[] = {
      {"solve two.obj -o two.obj", "two.obj"},
      {"solve two.obj -o two.mtl", "two.mtl"},
      {"solve two.obj -o alias.obj", "two.obj"},
      {"solve two.obj -o m.json --materials m.json", "m.json"},
      {"formfactors two.obj -o two.obj", "two.obj"},
      {"solve two.obj -o other.obj --stats other.obj", "other.obj"},
      {"formfactors two.obj -o other.obj --stats ./other.obj", "other.obj"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.args);
    const std::string before = slurp(at(c.victim));
    const CliRun r = run(c.args + " --quiet");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("refusing"), std::string::npos) << r.output;
    EXPECT_EQ(slurp(at(c.victim)), before);
  }
}

// -o through a symbolic link writes the link's target; the link stays a link.
TEST_F(Hostile, SymlinkOutputIsWrittenThroughToItsTarget) {
  fs::create_directories(at("real"));
  put("real/target.vtu", kPrecious);
  fs::create_symlink("real/target.vtu", at("link.vtu"));
  const CliRun r = run("solve two.obj -o link.vtu --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::is_symlink(at("link.vtu")));
  EXPECT_NE(slurp(at("real/target.vtu")).find("<VTKFile"), std::string::npos);
  EXPECT_TRUE(temporaries().empty());
}

// Directories, FIFOs and device nodes are refused as outputs (exit 1, without blocking) and stay what they
// are; "-o -" streams to standard output. (Never aimed at the system's /dev/null or /dev/stdout: a build with
// the old behaviour, run as root, replaces them with regular files. The device here is a private null
// device node, made when the test runs as root.)
TEST_F(Hostile, DeviceFifoAndDirectoryOutputsAreRefused) {
  ASSERT_EQ(mkfifo(at("pipe.vtu").c_str(), 0644), 0);
  std::vector<std::string> outs = {"pipe.vtu", "."};
  const bool device = mknod(at("null.vtu").c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0;
  if (device) outs.push_back("null.vtu");
  for (const auto& out : outs) {
    SCOPED_TRACE(out);
    const CliRun r = run("solve two.obj -o " + out + " --quiet", 20);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("refusing"), std::string::npos) << r.output;
  }
  EXPECT_TRUE(fs::is_fifo(at("pipe.vtu")));
  if (device) {
    EXPECT_TRUE(fs::is_character_file(at("null.vtu"))) << "the device node was replaced by a regular file";
  }
  const CliRun stream = run("solve two.obj -o - --quiet");
  EXPECT_EQ(stream.status, 0) << stream.output;
  EXPECT_NE(stream.output.find("<VTKFile"), std::string::npos);
  EXPECT_FALSE(fs::exists(at("-")));
  if (!device) GTEST_SKIP() << "not root: no device node to test (FIFO and directory were tested)";
}

// ---- hangs and unbounded work -------------------------------------------------------------------------------

// A 50,000-corner polygon is triangulated in O(n log n): ear clipping took 11.8 s at 16,000 corners
// (quadratic: ~115 s here). Bound 20 s: 20x the measured 1 s on a loaded 2-core machine.
TEST_F(Hostile, LargePolygonIsTriangulatedInNLogNTime) {
  const int n = 50000;
  std::ostringstream o;
  o.precision(17);
  o << "mtllib two.mtl\n";
  for (int k = 0; k < n; ++k) o << "v " << std::cos(2 * M_PI * k / n) << ' ' << std::sin(2 * M_PI * k / n) << " 1\n";
  o << "usemtl lamp\nf";
  for (int k = n; k >= 1; --k) o << ' ' << k;  // clockwise seen from +z: faces down
  o << "\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nusemtl floor\nf " << n + 1 << ' ' << n + 2 << ' ' << n + 3 << ' ' << n + 4 << '\n';
  put("ngon.obj", o.str());
  const CliRun r = run("info ngon.obj", 60);
  ASSERT_EQ(r.status, 0) << r.output.substr(0, 2000);
  EXPECT_NE(r.output.find("patches      2"), std::string::npos) << r.output.substr(0, 2000);
  EXPECT_LT(r.seconds, 20.0);
}

// --materials with 4,000 face ranges: naming the inline materials faces_A-B_k took 109 s (cubic).
// Bound 20 s (measured 0.5 s).
TEST_F(Hostile, ManyMaterialFaceRangesAreAppliedInNLogNTime) {
  std::string json = "{\"faces\": [";
  for (int e = 0; e < 4000; ++e) json += std::string(e ? ", " : "") + "{\"range\": [0, 1], \"reflectance\": 0.25}";
  put("m.json", json + "]}");
  const CliRun r = run("info two.obj --materials m.json", 60);
  ASSERT_EQ(r.status, 0) << r.output.substr(0, 2000);
  EXPECT_NE(r.output.find("faces_0-1_4000"), std::string::npos) << "the last entry wins, with its unique name";
  EXPECT_LT(r.seconds, 20.0);
}

// Inputs must be regular files: "mtllib /dev/zero" read forever, a FIFO as the scene blocked forever.
TEST_F(Hostile, DeviceAndFifoInputsAreRefusedWithoutBlocking) {
  put("zero.obj", "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const CliRun z = run("info zero.obj", 20);
  EXPECT_EQ(z.status, 1) << z.output;
  EXPECT_NE(z.output.find("zero.obj:1"), std::string::npos) << z.output;
  EXPECT_NE(z.output.find("regular file"), std::string::npos) << z.output;
  ASSERT_EQ(mkfifo(at("fifo.obj").c_str(), 0644), 0);
  const CliRun f = run("info fifo.obj", 20);
  EXPECT_EQ(f.status, 1) << f.output;
  EXPECT_NE(f.output.find("FIFO"), std::string::npos) << f.output;
}

// ---- memory checked before allocating ---------------------------------------------------------------------

// Header counts cannot promise more than the file holds: nothing larger than the file is reserved, and the
// read stops where the data ends with file, line and element ("out of memory" without a location before).
TEST_F(Hostile, HeaderCountsBeyondTheFileSizeAreRefusedNamingTheLine) {
  put("v.ply",
      "ply\nformat ascii 1.0\nelement vertex 2147483647\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
  std::string list = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  list.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  const std::uint32_t count = 4000000000u;
  list.append(reinterpret_cast<const char*>(&count), 4);
  const std::int32_t idx[3] = {0, 1, 2};
  list.append(reinterpret_cast<const char*>(idx), sizeof idx);
  put("list.ply", list);
  put("c.off", "OFF\n2147483647 1 0\n0 0 0\n");
  put("f.off", "OFF\n3 2147483647 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const std::pair<const char*, const char*> cases[] = {
      {"v.ply", "header line 3"}, {"list.ply", "element 'face' 0"}, {"c.off", "counts at line 2"}, {"f.off", "counts at line 2"}};
  for (const auto& [file, expect] : cases) {
    SCOPED_TRACE(file);
    const CliRun r = run(std::string("info ") + file, 30);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(expect), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("out of memory"), std::string::npos) << r.output;
  }
}

// --max-edge: the refined count is estimated before refining and refused with the estimate and a
// --max-edge that fits (was 5.8 s and 3.5 GB, then "out of memory"); the split count no longer overflows
// an int (a 10 m triangle with 1e-9 m edges silently stayed 1 patch). The limit is what the operator can
// hold: 2e6 patches (--max-edge 0.001) fit a hierarchical operator on a large machine but never a dense one
// (32 TB); 2e10 (--max-edge 1e-5) fit neither.
TEST_F(Hostile, RefinementBeyondMemoryIsRefusedBeforeRefining) {
  put("tri.obj", "mtllib two.mtl\nv 0 0 0\nv 10 0 0\nv 0 10 0\nusemtl lamp\nf 1 2 3\n");
  for (const std::string args : {"info two.obj --max-edge 1e-9", "info two.obj --max-edge 1e-5", "info tri.obj --max-edge 1e-9",
                                 "solve two.obj -o r.vtu --operator dense --max-edge 0.001"}) {
    SCOPED_TRACE(args);
    const CliRun r = run(args, 60);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("--max-edge"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("patches"), std::string::npos) << r.output;
    EXPECT_LT(r.seconds, 10.0) << "refused before refining";
  }
}

// --adaptive-budget whose final matrix cannot fit in memory is refused before any work (was killed
// after 300 s). 10^9 patches need 8e18 bytes on any machine.
TEST_F(Hostile, AdaptiveBudgetBeyondMemoryIsRefusedUpFront) {
  const CliRun r = run("solve two.obj -o a.vtu --adaptive-budget 1000000000", 30);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--adaptive-budget"), std::string::npos) << r.output;
  EXPECT_LT(r.seconds, 10.0);
  EXPECT_FALSE(fs::exists(at("a.vtu")));
}

// ---- exit codes and messages ------------------------------------------------------------------------------------

// Every command-line error exits 1 (CLI11's own codes were 104..109), with a short message; --help and
// --version exit 0.
TEST_F(Hostile, CommandLineErrorsExitOneWithReadableMessages) {
  const std::string cases[] = {"solve -o x.vtu",        "solve two.obj --threads 0 -o x.vtu", "solve two.obj --rays 0 -o x.vtu",
                               "solve two.obj",          "solve two.obj -o x.vtu --bogus",     "solve two.obj -o x.vtu --tolerance 0",
                               "solve missing.obj -o x.vtu", "verify sphere --subdivisions 9", "frobnicate"};
  for (const auto& c : cases) {
    SCOPED_TRACE(c);
    const CliRun r = run(c, 30);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_LT(r.output.size(), 400u) << "no 309-digit DBL_MAX: " << r.output;
    EXPECT_EQ(r.output.find("17976931348623157"), std::string::npos) << r.output;
  }
  EXPECT_EQ(run("--help").status, 0);
  EXPECT_EQ(run("solve --help").status, 0);
  EXPECT_EQ(run("--version").status, 0);
}

// NaN and infinities are rejected for every numeric option, naming it (--ff-tolerance nan used the default,
// --rho nan ran with 0.9 and printed PASS, --crease nan solved and then exited 2).
TEST_F(Hostile, NaNAndInfinityAreRejectedForEveryNumericOption) {
  const std::string solve = "solve two.obj -o x.vtu ";
  const std::string cases[] = {solve + "--ff-tolerance", solve + "--tolerance", solve + "--crease", solve + "--max-edge",
                               solve + "--adaptive-tol", solve + "--rays", solve + "--threads", solve + "--max-iterations",
                               solve + "--adaptive-budget", solve + "--adaptive-rounds", "formfactors two.obj -o F.csv --tolerance",
                               "verify sphere --rho", "verify furnace --rho", "verify sphere --subdivisions",
                               "verify furnace --divisions", "info two.obj --max-edge"};
  for (const auto& c : cases)
    for (const char* bad : {"nan", "inf"}) {
      SCOPED_TRACE(c + " " + bad);
      const CliRun r = run(c + " " + bad, 30);
      EXPECT_EQ(r.status, 1) << r.output;
      const std::string flag = c.substr(c.rfind(' ') + 1);
      EXPECT_NE(r.output.find(flag), std::string::npos) << r.output;
      EXPECT_EQ(r.output.find("PASS"), std::string::npos) << r.output;
    }
  EXPECT_FALSE(fs::exists(at("x.vtu")));
}

// A number out of the range of a double in --materials JSON is reported with file, line and column (was
// nlohmann's exception text without a location).
TEST_F(Hostile, JsonNumberOverflowNamesLineAndColumn) {
  put("m.json", "{\n  \"materials\": {\n    \"floor\": {\"reflectance\": 1e400}\n  }\n}\n");
  const CliRun r = run("info two.obj --materials m.json", 30);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("m.json:3: column"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1e400"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("[json.exception"), std::string::npos) << r.output;
}

// One far vertex cannot weld the scene away: a closed 1 m box with a lamp, one corner moved to x = 2e5 or
// 1e6 (the bounding-box weld tolerance becomes 0.2 m / 1 m), keeps every face and its emitter (with the
// tolerance from the bounding box alone, 2e5 welded the lamp away and 1e6 left "no faces").
TEST_F(Hostile, OneFarVertexDoesNotWeldTheSceneAway) {
  for (double far : {2e5, 1e6}) {
    SCOPED_TRACE(far);
    std::ostringstream o;
    o << "mtllib two.mtl\n";
    // box corners 1..8 (x, y, z in {0, 1}), corner 7 = (1, 1, 1) moved out along x
    const double c[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {far, 1, 1}, {0, 1, 1}};
    for (auto& p : c) o << "v " << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
    // lamp: 0.2 m square 1 mm below the ceiling, facing down
    o << "v 0.4 0.999 0.4\nv 0.6 0.999 0.4\nv 0.6 0.999 0.6\nv 0.4 0.999 0.6\n";
    o << "usemtl floor\nf 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n";
    o << "usemtl lamp\nf 9 10 11 12\n";
    put("far.obj", o.str());
    const CliRun r = run("info far.obj", 30);
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("input faces  7"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("removed"), std::string::npos) << "no face may be lost\n" << r.output;
    EXPECT_EQ(r.output.find("no emitter"), std::string::npos) << r.output;
    // pi * 0.04 m^2 * 1 W m^-2 sr^-1: the lamp is intact.
    EXPECT_NE(r.output.find("emitted power 0.125664 W"), std::string::npos) << r.output;
  }
}

// ---- numerics at the edges ----------------------------------------------------------------------------------

// The solve is linear in the emission: Le = 1e-170 and 1e160 give 1e-170 and 1e160 times the radiance of
// Le = 1 (relative 1e-12: the scaling is by a power of two, only the solver's own round-off differs), where
// every method reported "divergence, residual -nan".
TEST_F(Hostile, RadianceScalesWithEmissionOverTheWholeDoubleRange) {
  auto floor_radiance = [&](const std::string& ke, const std::string& method) {
    put("two.mtl", "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0.3\nKe " + ke + "\n");
    const CliRun r = run("solve two.obj -o o.vtu --stats s.json --quiet --method " + method, 60);
    EXPECT_EQ(r.status, 0) << ke << " " << method << ": " << r.output;
    if (r.status != 0) return double(NAN);
    const auto j = nlohmann::json::parse(slurp(at("s.json")));
    return j["energy"]["absorbed_W"][0].get<double>();
  };
  for (const std::string method : {"gmres", "jacobi", "bicgstab", "gauss-seidel"}) {
    const double one = floor_radiance("1", method);
    for (double k : {1e-170, 1e-154, 1e160}) {
      std::ostringstream ke;
      ke << k;
      const double v = floor_radiance(ke.str(), method);
      EXPECT_NEAR(v / (one * k), 1.0, 1e-12) << method << " Ke " << k;
    }
  }
}

// Geometry outside the verified size range is refused with a message (row sums reached 1.0097 at 1e13 with
// exit 0); inside it (1e-9 .. 1e11 times a 1 m scene) the form factor is exact.
TEST_F(Hostile, SceneSizesOutsideTheExactRangeAreRefused) {
  for (double s : {1e-12, 1e13}) {
    put("s.obj", two_squares(s));
    const CliRun r = run("formfactors s.obj -o F.csv --quiet", 30);
    EXPECT_EQ(r.status, 1) << s << ": " << r.output;
    EXPECT_NE(r.output.find("size"), std::string::npos) << r.output;
  }
  for (double s : {1e-9, 1.0, 1e11}) {
    put("s.obj", two_squares(s));
    const CliRun r = run("formfactors s.obj -o F.csv --quiet", 30);
    ASSERT_EQ(r.status, 0) << s << ": " << r.output;
    double f = 0;
    int i, j;
    ASSERT_EQ(std::sscanf(slurp(at("F.csv")).c_str(), "%d,%d,%lf", &i, &j, &f), 3);
    EXPECT_NEAR(f, 0.1998248957, 1e-9) << "scale " << s << " (catalogue value, 10 digits)";
  }
}

}  // namespace

namespace {

// Found by the fuzzer (tests/fuzz): a pentagon whose corner lies on another edge crashed --max-edge
// refinement (a constrained-triangulation vertex without an index). It is now rejected with its line.
TEST_F(Hostile, SelfTouchingPolygonIsRejectedNotCrashedWhenRefining) {
  put("touch.obj", slurp(fs::path(LAMBERT_SOURCE_DIR) / "tests/fuzz/corpus/regressions/obj_self_touching_polygon_refine_crash.obj"));
  const CliRun r = run("info touch.obj --max-edge 0.5", 30);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("touch.obj:"), std::string::npos) << r.output;
}

}  // namespace
