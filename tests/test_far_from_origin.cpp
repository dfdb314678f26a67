// A model in GIS coordinates: the bundled room moved by (1e6, 0, -2e6) m solves, passes every check and gives
// the energies and the form factors of the room at the origin. Before the assembly moved far scenes to the origin,
// the near pairs' integrals lost digits there and the reciprocity check refused the result (9x its bound, exit 3).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <utility>

#include "cli_util.hpp"

namespace lambert {
namespace {

struct FarFromOrigin : test::Cli {
  std::string moved_room() const;
};

// examples/room.obj moved by (1e6, 0, -2e6) m, written with 10 decimals (1e-10 m, as a GIS export might).
std::string FarFromOrigin::moved_room() const {
  const std::string examples = std::string(LAMBERT_SOURCE_DIR) + "/examples/";
  std::ifstream in(examples + "room.obj");
  std::stringstream moved;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) {
      std::istringstream ss(line.substr(2));
      double x, y, z;
      ss >> x >> y >> z;
      char buf[128];
      std::snprintf(buf, sizeof buf, "v %.10f %.10f %.10f", x + 1e6, y, z - 2e6);
      moved << buf << '\n';
    } else if (line.rfind("mtllib ", 0) == 0) {
      moved << "mtllib " << examples << line.substr(7) << '\n';
    } else {
      moved << line << '\n';
    }
  }
  return write("room_far.obj", moved.str());
}

TEST_F(FarFromOrigin, RoomMovedByAMillionMetresSolvesWithTheSameEnergies) {
  const std::string examples = std::string(LAMBERT_SOURCE_DIR) + "/examples/";
  const std::string far = moved_room();
  const auto a = test::run("solve " + examples + "room.obj -o " + path("a.vtu") + " --stats " + path("a.json") + " --quiet");
  const auto b = test::run("solve " + far + " -o " + path("b.vtu") + " --stats " + path("b.json") + " --quiet");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  nlohmann::json ja, jb;
  std::ifstream(path("a.json")) >> ja;
  std::ifstream(path("b.json")) >> jb;
  // Absorbed power per channel: 1e-7 relative. The same patches and the same ray samples relative to each patch
  // (the next test), so what is left is the form factors' round-off (~1e-9 per entry). Before the source of a pair
  // of equal areas was decided with a margin, this was 16-ray noise (1e-4).
  for (int c = 0; c < 3; ++c) {
    const double pa = ja["energy"]["absorbed_W"][c], pb = jb["energy"]["absorbed_W"][c];
    EXPECT_NEAR(pb, pa, 1e-7 * pa) << "channel " << c;
  }
}

// The same room's form factors, entry by entry: the same nonzero entries, each within 1e-8 (the per-entry tolerance
// of the unoccluded integral; the two runs' integrals differ by round-off, and their rays are the same rays). Moved,
// pairs of patches with equal areas (floor and ceiling patches over each other) took the other patch as source by
// rounding, so other ray samples: entries 1.4e-3 apart, and 20 more nonzero entries.
TEST_F(FarFromOrigin, RoomMovedByAMillionMetresHasTheSameFormFactors) {
  const std::string examples = std::string(LAMBERT_SOURCE_DIR) + "/examples/";
  const std::string far = moved_room();
  const auto a = test::run("formfactors " + examples + "room.obj -o " + path("a.csv") + " --quiet");
  const auto b = test::run("formfactors " + far + " -o " + path("b.csv") + " --quiet");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  auto load = [](const std::string& file) {
    std::map<std::pair<int, int>, double> m;
    std::ifstream in(file);
    std::string line;
    while (std::getline(in, line)) {
      int i = 0, j = 0;
      double f = 0;
      if (std::sscanf(line.c_str(), "%d,%d,%lf", &i, &j, &f) == 3) m[{i, j}] = f;
    }
    return m;
  };
  const auto fa = load(path("a.csv")), fb = load(path("b.csv"));
  ASSERT_GT(fa.size(), 100000u) << "the room's form factors";
  EXPECT_EQ(fa.size(), fb.size());
  int reported = 0;
  for (const auto& [ij, f] : fa) {
    const auto it = fb.find(ij);
    const double g = it == fb.end() ? 0.0 : it->second;
    if (std::abs(f - g) > 1e-8 && reported++ < 10)
      ADD_FAILURE() << "F(" << ij.first << ", " << ij.second << "): " << f << " at the origin, " << g << " moved";
  }
  EXPECT_EQ(reported, 0) << "entries more than 1e-8 apart";
}

}  // namespace
}  // namespace lambert
