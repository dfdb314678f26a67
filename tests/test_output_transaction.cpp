// io::OutputSet: a run's outputs are all renamed or none changes; temporaries never survive a failure
// or SIGINT/SIGTERM; large polygons are triangulated validly (CGAL constrained Delaunay).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>

#include "lambert/io/atomic_file.hpp"
#include "lambert/mesh/geometry.hpp"

namespace fs = std::filesystem;
using namespace lambert;

namespace {

class Transaction : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir = fs::temp_directory_path() / ("lambert_tx_" + std::to_string(rd()));
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string at(const std::string& n) const { return (dir / n).string(); }
  void put(const std::string& n, const std::string& t) const { std::ofstream(at(n)) << t; }
  std::string get(const std::string& n) const {
    std::ifstream in(at(n));
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  int files() const { return static_cast<int>(std::distance(fs::directory_iterator(dir), fs::directory_iterator())); }
  fs::path dir;
};

// All written and committed: every target has its new content, no temporary remains.
TEST_F(Transaction, CommitRenamesEveryOutput) {
  put("a.txt", "old a");
  io::OutputSet out;
  out.add_output(at("a.txt"), "-o");
  out.add_output(at("b.txt"), "--stats");
  out.write(at("a.txt"), [](std::ostream& os) { os << "new a"; });
  out.write(at("b.txt"), [](std::ostream& os) { os << "new b"; });
  out.commit();
  EXPECT_EQ(get("a.txt"), "new a");
  EXPECT_EQ(get("b.txt"), "new b");
  EXPECT_EQ(files(), 2) << "a temporary or backup was left behind";
}

// The second output fails to write (a stream error, as on a full disk): the first keeps its old content
// and its temporary is removed when the set is destroyed.
TEST_F(Transaction, FailedWriteChangesNoOutput) {
  put("a.txt", "old a");
  put("b.txt", "old b");
  {
    io::OutputSet out;
    out.add_output(at("a.txt"), "-o");
    out.add_output(at("b.txt"), "--stats");
    out.write(at("a.txt"), [](std::ostream& os) { os << "new a"; });
    EXPECT_THROW(out.write(at("b.txt"), [](std::ostream& os) { os.setstate(std::ios::badbit); }), InputError);
  }
  EXPECT_EQ(get("a.txt"), "old a");
  EXPECT_EQ(get("b.txt"), "old b");
  EXPECT_EQ(files(), 2) << "a temporary was left behind";
}

// A rename that fails after an earlier one succeeded undoes the earlier one (from its hard-link backup).
TEST_F(Transaction, FailedRenameRestoresTheOutputsRenamedBefore) {
  put("a.txt", "old a");
  fs::create_directories(at("sub"));
  put("sub/b.txt", "old b");
  io::OutputSet out;
  out.add_output(at("a.txt"), "-o");
  out.add_output(at("sub/b.txt"), "--stats");
  out.write(at("a.txt"), [](std::ostream& os) { os << "new a"; });
  out.write(at("sub/b.txt"), [](std::ostream& os) { os << "new b"; });
  // Make the second rename fail: its target becomes a non-empty directory.
  fs::remove(at("sub/b.txt"));
  fs::create_directories(at("sub/b.txt/x"));
  EXPECT_THROW(out.commit(), InputError);
  EXPECT_EQ(get("a.txt"), "old a") << "the first output was renamed and not restored";
  int left = 0;
  for (auto& e : fs::recursive_directory_iterator(dir)) left += e.path().filename().string().find(".tmp-") != std::string::npos;
  EXPECT_EQ(left, 0) << "temporaries or backups left behind";
}

// SIGTERM (and SIGINT) while temporaries exist: the handler removes them, says so, and the process ends
// by that signal. Tested in a child process.
TEST_F(Transaction, SignalRemovesTemporaries) {
  for (int sig : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(sig);
    // A background job of a non-interactive shell starts with SIGINT ignored, and the handler keeps an inherited
    // ignore (as under nohup) by design: nothing to test for that signal in such a process.
    struct sigaction now{};
    if (::sigaction(sig, nullptr, &now) == 0 && now.sa_handler == SIG_IGN) {
      std::printf("signal %d is ignored in this process (started in the background?): not tested\n", sig);
      continue;
    }
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      io::OutputSet out;
      out.add_output(at("a.txt"), "-o");
      out.add_output(at("b.txt"), "--stats");
      out.write(at("a.txt"), [](std::ostream& os) { os << "complete a"; });
      out.write(at("b.txt"), [&](std::ostream& os) {
        os << "partial b";
        os.flush();
        ::raise(sig);  // interrupted mid-write: one complete temporary, one partial
      });
      _exit(0);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status;
    EXPECT_EQ(files(), 0) << "a temporary survived the signal";
  }
}

// Large polygons (above the ear-clipping size) get a valid triangulation: m - 2 triangles, each
// counter-clockwise about the normal, areas summing to the polygon's (relative 1e-12: round-off of m terms).
TEST(LargePolygon, TriangulationTilesTheStarPolygonCounterClockwise) {
  for (int m : {65, 1000, 20001}) {
    SCOPED_TRACE(m);
    std::vector<Vec3> poly;
    for (int k = 0; k < m; ++k) {  // a star: alternating radii, non-convex
      const double a = 2 * M_PI * k / m, r = k % 2 ? 0.5 : 1.0;
      poly.push_back({r * std::cos(a), 3.0, r * std::sin(a)});
    }
    const Vec3 n = mesh::newell_normal(poly);
    const auto tris = mesh::triangulate_polygon(poly, n.normalized());
    ASSERT_EQ(static_cast<int>(tris.size()), m - 2);
    double area = 0;
    for (size_t t = 0; t < tris.size(); ++t) {
      const auto& T = tris[t];
      const double a = 0.5 * (poly[T[1]] - poly[T[0]]).cross(poly[T[2]] - poly[T[0]]).dot(n.normalized());
      ASSERT_GT(a, 0) << "triangle " << t << " is not counter-clockwise";
      area += a;
    }
    EXPECT_NEAR(area, 0.5 * n.norm(), 1e-12 * 0.5 * n.norm());
  }
}

// A large self-intersecting polygon (a figure eight) or a clockwise one gives no triangulation, like ear
// clipping for small ones.
TEST(LargePolygon, SelfIntersectingOrClockwiseGivesNoTriangulation) {
  const int m = 200;
  std::vector<Vec3> eight;
  for (int k = 0; k < m; ++k) {
    const double t = 2 * M_PI * k / m;
    eight.push_back({std::sin(t), std::sin(t) * std::cos(t), 0});
  }
  EXPECT_TRUE(mesh::triangulate_polygon(eight, Vec3::UnitZ()).empty());
  std::vector<Vec3> circle;
  for (int k = 0; k < m; ++k) circle.push_back({std::cos(2 * M_PI * k / m), std::sin(2 * M_PI * k / m), 0});
  EXPECT_EQ(mesh::triangulate_polygon(circle, Vec3::UnitZ()).size(), size_t(m - 2));
  EXPECT_TRUE(mesh::triangulate_polygon(circle, -Vec3::UnitZ()).empty()) << "clockwise about the normal";
}

}  // namespace
