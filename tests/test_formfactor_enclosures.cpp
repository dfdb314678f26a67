// Closed surfaces and the cells they split space into (formfactor/src/enclosures.hpp), against scenes whose cells
// are known by construction: which patches' fronts face the same air. Cells are labels, so every check is exact
// (no numerical tolerance): the only tolerance is the contact distance eps = 1e-6 x the scene's bounding-box
// diagonal, as the hierarchy uses (kEnclosureEps), and every scene here meets exactly (shared corners are the same
// doubles) or misses by far more than eps.
#include <gtest/gtest.h>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "../formfactor/src/enclosures.hpp"
#include "lambert/formfactor/assemble.hpp"
#include "lambert/formfactor/hierarchy.hpp"
#include "lambert/io/readers.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/shapes.hpp"
#include "test_formfactor_util.hpp"
#include "test_hierarchy_util.hpp"

namespace lambert {
namespace {

using fftest::rect;
using mesh::shapes::Polygons;
namespace fd = formfactor::detail;

// Patches [begin, end) of a scene.
struct Range {
  int begin = 0, end = 0;
  bool has(int p) const { return begin <= p && p < end; }
};

struct SceneBuilder {
  Polygons polys;
  Range add(const Polygons& p) {
    Range r{int(polys.size()), 0};
    polys.insert(polys.end(), p.begin(), p.end());
    r.end = int(polys.size());
    return r;
  }
  Range add(const std::vector<Vec3>& p) { return add(Polygons{p}); }
};

// l + (h - l) i / n, with the ends exactly l and h (so that faces meeting at a corner share its doubles).
double at(double l, double h, int i, int n) { return i == 0 ? l : i == n ? h : l + (h - l) * i / n; }

// Face f of the box [lo, hi] (0..5: -x, +x, -y, +y, -z, +z, as shapes::box), in div[b] x div[c] rectangles along
// its in-plane axes b = (a + 1) % 3, c = (a + 2) % 3 (a = f / 2, div[a] unused). inward: fronts into the box.
Polygons face(const Vec3& lo, const Vec3& hi, int f, std::array<int, 3> div, bool inward) {
  const int a = f / 2, b = (a + 1) % 3, c = (a + 2) % 3;
  const bool high = f % 2 == 1;
  Polygons out;
  for (int i = 0; i < div[b]; ++i)
    for (int j = 0; j < div[c]; ++j)
      out.push_back(rect(a, high ? hi[a] : lo[a], at(lo[b], hi[b], i, div[b]), at(lo[b], hi[b], i + 1, div[b]),
                         at(lo[c], hi[c], j, div[c]), at(lo[c], hi[c], j + 1, div[c]), inward != high));
  return out;
}

// The six faces of [lo, hi] (without face `skip`, if in 0..5), face f split by div_of(f).
template <class DivOf>
Polygons room(const Vec3& lo, const Vec3& hi, bool inward, DivOf div_of, int skip = -1) {
  Polygons out;
  for (int f = 0; f < 6; ++f) {
    if (f == skip) continue;
    const Polygons p = face(lo, hi, f, div_of(f), inward);
    out.insert(out.end(), p.begin(), p.end());
  }
  return out;
}

double eps_of(const mesh::PatchGeometry& g) {
  Eigen::AlignedBox3d box;
  for (const Vec3& v : g.points) box.extend(v);
  return 1e-6 * box.diagonal().norm();
}

fd::Enclosures cells_of(const mesh::PatchGeometry& g) { return fd::find_enclosures(g, eps_of(g)); }

std::string describe(const mesh::PatchGeometry& g, const fd::Enclosures& e, int p) {
  std::ostringstream s;
  const Vec3 &c = g.centroid[p], &n = g.normal[p];
  s << "patch " << p << " (centroid " << c.x() << ", " << c.y() << ", " << c.z() << "; normal " << n.x() << ", "
    << n.y() << ", " << n.z() << ") has cell " << e.cell[p];
  return s.str();
}

std::string summary(const fd::Enclosures& e) {
  std::ostringstream s;
  s << "[" << e.surfaces << " surfaces, " << e.cells << " cells, " << e.unknown << " unknown, " << e.crossed
    << " crossed, " << e.surface_patches << " surface patches]";
  return s.str();
}

// All patches of r have one cell >= 0; returns it (-2 after a failure).
int common_cell(const mesh::PatchGeometry& g, const fd::Enclosures& e, Range r, const char* what) {
  const int c = e.cell[r.begin];
  bool ok = c >= 0;
  EXPECT_GE(c, 0) << what << ": " << describe(g, e, r.begin) << " " << summary(e);
  for (int p = r.begin + 1; p < r.end; ++p) {
    EXPECT_EQ(e.cell[p], c) << what << ": " << describe(g, e, p) << ", patch " << r.begin << " has " << c << " "
                            << summary(e);
    ok = ok && e.cell[p] == c;
  }
  return ok ? c : -2;
}

// Patches p and q may see each other: their cells must not refuse the pair (equal, or either -1).
void expect_not_separated(const mesh::PatchGeometry& g, const fd::Enclosures& e, int p, int q, const char* what) {
  EXPECT_TRUE(e.cell[p] < 0 || e.cell[q] < 0 || e.cell[p] == e.cell[q])
      << what << ": " << describe(g, e, p) << " but " << describe(g, e, q) << " and they see each other "
      << summary(e);
}

// The first patch whose centroid is c (exactly constructed scenes: within 1e-12).
int patch_at(const mesh::PatchGeometry& g, const Vec3& c) {
  for (int p = 0; p < g.size(); ++p)
    if ((g.centroid[p] - c).norm() < 1e-12) return p;
  ADD_FAILURE() << "no patch with centroid " << c.transpose();
  return 0;
}

// A panel outside every room, at y = -0.5 facing +y (towards the rooms' -y walls): the reference for "outside",
// so that a room that opened (its patches then outside too) cannot pass for a separate cell.
std::vector<Vec3> outside_panel() { return rect(1, -0.5, 0.2, 0.8, 0.2, 1.8, true); }

const auto uniform = [](int n) { return [n](int) { return std::array<int, 3>{n, n, n}; }; };

// 1. Two closed rooms 0.1 m apart: no segment joins their insides without crossing a wall. Also two rooms sharing
// a wall modelled two-sided (each room's wall patch, coincident and back to back, as mesh::prepare makes a
// two-sided face): the coincident faces around each edge must not join the two rooms' air. Both rooms also keep a
// cell apart from an outside panel (a room that opened would otherwise still differ from a closed one).
TEST(Enclosures, TwoClosedRoomsAreDifferentCells) {
  for (const double gap : {0.1, 0.0}) {
    SCOPED_TRACE(gap > 0 ? "rooms 0.1 m apart" : "rooms sharing a two-sided wall");
    SceneBuilder s;
    const Range a = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 2, true));
    const Range b = s.add(mesh::shapes::box(Vec3(1 + gap, 0, 0), Vec3(2 + gap, 1, 1), 2, true));
    const int out = s.add(outside_panel()).begin;
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
    const fd::Enclosures e = cells_of(g);
    const int ca = common_cell(g, e, a, "room A"), cb = common_cell(g, e, b, "room B");
    EXPECT_NE(ca, cb) << "both rooms in cell " << ca << " " << summary(e);
    EXPECT_GE(e.cell[out], 0) << describe(g, e, out);
    EXPECT_NE(ca, e.cell[out]) << "room A is open: " << describe(g, e, out) << " " << summary(e);
    EXPECT_NE(cb, e.cell[out]) << "room B is open: " << describe(g, e, out) << " " << summary(e);
    EXPECT_EQ(e.unknown, 0) << summary(e);
    EXPECT_EQ(e.surface_patches, b.end) << "every wall is on a closed surface, the panel on none " << summary(e);
  }
}

// 2. An open room (no ceiling, or a door: a 3x3 wall with its middle quad missing) lets the outside in: its
// patches and an outside patch looking into it must not be refused. A closed room beside it keeps its own cell
// (else the test would pass with no separation at all).
TEST(Enclosures, RoomWithOpeningIsOneCellWithTheOutside) {
  for (const bool door : {false, true}) {
    SceneBuilder s;
    const Vec3 lo(0, 0, 0), hi(1, 1, 1);
    Range open;
    int outside = 0;
    if (!door) {
      open = s.add(room(lo, hi, true, uniform(2), /*skip +z*/ 5));
      outside = s.add(rect(2, 1.5, 0.2, 0.8, 0.2, 0.8, false)).begin;  // a sky panel over it, facing down
    } else {
      open = s.add(room(lo, hi, true, uniform(2), /*skip -y*/ 2));
      Polygons wall = face(lo, hi, 2, {3, 1, 3}, true);  // -y wall: 3 x 3 along z, x
      wall.erase(wall.begin() + 4);                       // the middle one: a door
      const Range w = s.add(wall);
      open.end = w.end;
      outside = s.add(rect(1, -0.5, 0.2, 0.8, 0.2, 0.8, true)).begin;  // in front of the door, facing +y
    }
    const Range closed = s.add(mesh::shapes::box(Vec3(1.1, 0, 0), Vec3(2.1, 1, 1), 2, true));
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
    const fd::Enclosures e = cells_of(g);
    SCOPED_TRACE(door ? "room with a door" : "room without ceiling");
    for (int p = open.begin; p < open.end; ++p) expect_not_separated(g, e, p, outside, "open room vs outside");
    const int cc = common_cell(g, e, closed, "closed room");
    EXPECT_NE(cc, e.cell[outside]) << "the closed room is not separated from the outside " << summary(e);
  }
}

// 3. Floor 3 x 3, walls and ceiling 2 x 2: the floor's edges end in the middle of the walls' edges and vice versa
// (T-junctions). Still closed: each piece of edge between the junctions has its two faces.
TEST(Enclosures, TJunctionsDoNotOpenARoom) {
  SceneBuilder s;
  const Range a = s.add(room(Vec3(0, 0, 0), Vec3(1, 1, 1), true, [](int f) {
    return f == 4 ? std::array<int, 3>{3, 3, 3} : std::array<int, 3>{2, 2, 2};
  }));
  const Range b = s.add(mesh::shapes::box(Vec3(1.1, 0, 0), Vec3(2.1, 1, 1), 2, true));
  const int out = s.add(outside_panel()).begin;
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  const int ca = common_cell(g, e, a, "room with T-junctions"), cb = common_cell(g, e, b, "plain room");
  EXPECT_NE(ca, cb) << summary(e);
  EXPECT_NE(ca, e.cell[out]) << "the T-junctions opened the room: " << describe(g, e, out) << " " << summary(e);
  EXPECT_NE(cb, e.cell[out]) << describe(g, e, out) << " " << summary(e);
  EXPECT_EQ(e.surface_patches, b.end) << "every wall of both rooms on a closed surface " << summary(e);
}

// The room of case 4: [0,1]^3 with its floor in 2k x k quads (a seam at x = 0.5, under the fin) and its other
// faces in 2k x 2k, a light panel facing down, a fin on the floor seam, and an outward closed box (furniture)
// floating inside.
struct FurnishedRoom {
  Range walls, light, fin, furniture;
  void build(SceneBuilder& s, const Vec3& o, int k = 1) {
    walls = s.add(room(o, o + Vec3(1, 1, 1), true, [k](int f) {
      return f == 4 ? std::array<int, 3>{2 * k, k, k} : std::array<int, 3>{2 * k, 2 * k, 2 * k};
    }));
    auto shifted = [&](std::vector<Vec3> p) {
      for (Vec3& v : p) v += o;
      return p;
    };
    light = s.add(shifted(rect(2, 0.9, 0.4, 0.6, 0.4, 0.6, false)));
    fin = s.add(shifted(rect(0, 0.5, 0.3, 0.7, 0.0, 0.4, true)));  // x = 0.5, y in [0.3, 0.7], z in [0, 0.4]
    Polygons box = mesh::shapes::box(o + Vec3(0.65, 0.1, 0.2), o + Vec3(0.9, 0.3, 0.5), 1, false);
    furniture = s.add(box);
  }
};

// 4. Junk inside a room (a light panel, a fin standing on a floor seam, a floating outward box) faces the room's
// air with its fronts: same cell as the walls. The room keeps a cell apart from an outside panel and from a second
// closed room, so the junk did not open it either.
TEST(Enclosures, LooseFacesInsideARoomShareItsCell) {
  SceneBuilder s;
  FurnishedRoom r;
  r.build(s, Vec3::Zero());
  const Range b = s.add(mesh::shapes::box(Vec3(1.1, 0, 0), Vec3(2.1, 1, 1), 2, true));
  const int out = s.add(outside_panel()).begin;
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  const int cw = common_cell(g, e, r.walls, "walls");
  EXPECT_NE(cw, e.cell[out]) << "the junk opened the room: " << describe(g, e, out) << " " << summary(e);
  for (Range x : {r.light, r.fin, r.furniture})
    for (int p = x.begin; p < x.end; ++p)
      EXPECT_EQ(e.cell[p], cw) << describe(g, e, p) << ", the walls have " << cw << " " << summary(e);
  EXPECT_NE(common_cell(g, e, b, "second room"), cw) << "the junk opened the room " << summary(e);
}

// 5. A one-sided partition at x = 1 spanning the room [0,2] x [0,1]^2 wall to wall and floor to ceiling, the
// floor, ceiling and side walls in two quads meeting at its edges: two cells; the partition's front shares the
// cell of the half it faces.
TEST(Enclosures, PartitionTouchingAllSidesSplitsTheRoom) {
  for (const bool faces_high : {false, true}) {
    SCOPED_TRACE(faces_high ? "partition facing +x" : "partition facing -x");
    // The shell: -x and +x walls whole, the other four faces in two quads along x (split at x = 1).
    const Polygons shell = room(Vec3(0, 0, 0), Vec3(2, 1, 1), true, [](int) { return std::array<int, 3>{2, 1, 1}; });
    Polygons lows, highs;
    for (const auto& q : shell) {
      double cx = 0;
      for (const Vec3& v : q) cx += v.x() / double(q.size());
      (cx < 1 ? lows : highs).push_back(q);
    }
    SceneBuilder s;
    const Range low = s.add(lows), high = s.add(highs);
    const int part = s.add(rect(0, 1.0, 0, 1, 0, 1, faces_high)).begin;
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
    const fd::Enclosures e = cells_of(g);
    const int cl = common_cell(g, e, low, "x < 1 half"), ch = common_cell(g, e, high, "x > 1 half");
    EXPECT_NE(cl, ch) << "the partition does not split the room " << summary(e);
    EXPECT_EQ(e.cell[part], faces_high ? ch : cl) << describe(g, e, part) << "; halves " << cl << ", " << ch << " "
                                                  << summary(e);
  }
}

// 6. A shut cupboard (inward closed box) floating in a room: its inside is its own cell (apart from the room's and
// from the outside's).
TEST(Enclosures, ShutBoxInsideARoomIsItsOwnCell) {
  SceneBuilder s;
  const Range walls = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 2, true));
  const Range cupboard = s.add(mesh::shapes::box(Vec3(0.3, 0.3, 0.2), Vec3(0.7, 0.6, 0.6), 1, true));
  const int out = s.add(outside_panel()).begin;
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  const int cw = common_cell(g, e, walls, "room"), cc = common_cell(g, e, cupboard, "cupboard");
  EXPECT_NE(cw, cc) << "the cupboard's inside shares the room's cell " << summary(e);
  EXPECT_NE(cw, e.cell[out]) << "the room is open: " << describe(g, e, out) << " " << summary(e);
  EXPECT_NE(cc, e.cell[out]) << "the cupboard is open: " << describe(g, e, out) << " " << summary(e);
}

// 7. A quad piercing the -x wall of a closed room (half inside, half outside), through the interior of the wall
// patch y, z in [0, 0.5]: its front lies on both sides, so it and the pierced wall patch get -1; the other walls
// keep their common cell.
TEST(Enclosures, CrossingPatchGetsNoCell) {
  SceneBuilder s;
  const Range walls = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 2, true));
  const int quad = s.add(rect(1, 0.25, 0.2, 0.3, -0.2, 0.2, true)).begin;  // y = 0.25, z in [0.2,0.3], x in [-0.2,0.2]
  const Range other = s.add(mesh::shapes::box(Vec3(-1.2, 0, 0), Vec3(-0.3, 1, 1), 1, true));  // a room outside
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  const int pierced = patch_at(g, Vec3(0, 0.25, 0.25));
  EXPECT_EQ(e.cell[quad], -1) << "crossing quad: " << describe(g, e, quad) << " " << summary(e);
  EXPECT_EQ(e.cell[pierced], -1) << "pierced wall: " << describe(g, e, pierced) << " " << summary(e);
  int c = -2;
  for (int p = walls.begin; p < walls.end; ++p) {
    if (p == pierced) continue;
    if (c == -2) c = e.cell[p];
    EXPECT_GE(e.cell[p], 0) << describe(g, e, p) << " " << summary(e);
    EXPECT_EQ(e.cell[p], c) << describe(g, e, p) << ", other walls " << c << " " << summary(e);
  }
  EXPECT_NE(common_cell(g, e, other, "room outside"), c) << summary(e);
  EXPECT_EQ(e.crossed, 2) << summary(e);
}

// The scene of cases 1 + 4 (walls 8 x 8: 736 patches, so that every parallel loop of find_enclosures has several
// chunks and the thread count can matter), shifted by o.
mesh::PatchGeometry furnished_pair(const Vec3& o) {
  SceneBuilder s;
  FurnishedRoom r;
  r.build(s, o, 4);
  s.add(mesh::shapes::box(o + Vec3(1.1, 0, 0), o + Vec3(2.1, 1, 1), 8, true));
  std::vector<Vec3> panel = outside_panel();
  for (Vec3& v : panel) v += o;
  s.add(panel);
  return mesh::PatchGeometry::from_polygons(s.polys);
}

// 8. Cells are labels numbered in patch order from the topology: far from the origin (float Embree coordinates are
// relative to the scene's centre) and for any thread count they are identical (exact comparison).
TEST(Enclosures, CellsDoNotDependOnPositionOrThreads) {
  const mesh::PatchGeometry g0 = furnished_pair(Vec3::Zero());
  const mesh::PatchGeometry g1 = furnished_pair(Vec3(1e6, -2e6, 3e5));
  const fd::Enclosures e0 = cells_of(g0), e1 = cells_of(g1);
  ASSERT_EQ(e0.cells, 3) << "room, second room, outside: the comparison must mean something " << summary(e0);
  ASSERT_EQ(e0.cell.size(), e1.cell.size());
  for (int p = 0; p < g0.size(); ++p)
    EXPECT_EQ(e0.cell[p], e1.cell[p]) << "shifted by (1e6, -2e6, 3e5): " << describe(g0, e0, p) << " vs "
                                      << describe(g1, e1, p) << " " << summary(e0) << summary(e1);
  std::vector<int> by_threads[2];
  for (int t = 0; t < 2; ++t) {
    const int threads = t == 0 ? 1 : 4;
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
    tbb::task_arena arena(threads);
    arena.execute([&] { by_threads[t] = cells_of(g0).cell; });
  }
  for (int p = 0; p < g0.size(); ++p) {
    EXPECT_EQ(by_threads[0][p], e0.cell[p]) << "1 thread vs default: patch " << p;
    EXPECT_EQ(by_threads[1][p], by_threads[0][p]) << "4 threads vs 1: patch " << p << " " << by_threads[1][p]
                                                  << " vs " << by_threads[0][p];
  }
}

// The hierarchical operator's options of tests 9-9c: a coarse tolerance (far links occur in small scenes), rays.
formfactor::HierarchyOptions coarse_with_rays() {
  formfactor::HierarchyOptions ho;
  ho.tolerance = 5e-2;
  ho.visibility = true;
  ho.visibility_method = formfactor::VisibilityMethod::Rays;
  return ho;
}

// Two closed rooms 2 x 2 x 1 m side by side (4 x 4 patches per wall), the first with a furniture box standing on its
// floor (tests 9 and 9c).
void two_rooms(SceneBuilder& s, Range& lit, Range& furniture, Range& dark) {
  lit = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(2, 2, 1), 4, true));
  furniture = s.add(mesh::shapes::box(Vec3(0.4, 0.6, 0.0001), Vec3(1.0, 1.4, 0.4), 1, false));
  dark = s.add(mesh::shapes::box(Vec3(2.1, 0, 0), Vec3(4.1, 2, 1), 4, true));
}

// 9. The hierarchical operator with enclosures on and off, two closed rooms 2 x 2 x 1 m side by side (the lit one
// with an emitting ceiling patch and a furniture box, the other dark), 4 x 4 patches per wall: far links, blocked
// links and leaf pairs all occur. The pairs the cells refuse carry no light (closed walls between them), so both
// operators approximate the same transport, each within its own admitted error (row_error: far links' expansion
// and blocked links' possible transmittance; row_visibility_sigma: the leaf pairs' ray estimates, taken at 3
// sigma). Hence per row |y_on - y_off| <= (row_error_on + row_error_off + 3 (sigma_on + sigma_off)) max x, plus
// 1e-12 max x for summation order. (Not "identical links": the tree splits differently when it keeps cells apart,
// so the two builds link same-cell pairs differently.)
// Where the refused pairs were blocked anyway the result is exact: the dark room receives exactly 0 from the lit
// room with enclosures on.
TEST(Enclosures, HierarchyWithCellsMatchesWithout) {
  SceneBuilder s;
  Range lit, furniture, dark;
  two_rooms(s, lit, furniture, dark);
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const int n = g.size();
  const int emitter = patch_at(g, Vec3(1.25, 0.75, 1));  // a ceiling patch of the lit room
  formfactor::HierarchyStats st[2];
  std::vector<formfactor::HierarchicalOperator> H;
  for (int on = 0; on < 2; ++on) {
    formfactor::HierarchyOptions ho = coarse_with_rays();
    ho.enclosures = on == 1;
    H.push_back(formfactor::build_hierarchy(g, ho, &st[on]));
  }
  for (int on = 0; on < 2; ++on)
    std::printf("enclosures %s: %d surfaces, %d cells, %lld pairs cell-culled, %lld far + %lld leaf links, %lld blocked, "
                "%lld rays, admitted row error max %.2e\n",
                on ? "on " : "off", st[on].enclosures, st[on].cells, st[on].pairs_cell_culled, st[on].far_links,
                st[on].leaf_links, st[on].links_blocked, st[on].rays_cast, st[on].row_error_max);
  EXPECT_GT(st[1].pairs_cell_culled, 0) << "nothing refused: the test exercises nothing";
  EXPECT_EQ(st[0].pairs_cell_culled, 0);
  EXPECT_EQ(st[1].cells, 2) << "lit room (with its furniture's fronts) and dark room";
  EXPECT_EQ(st[1].cell_unknown, 0);
  EXPECT_GT(st[0].far_links, 0) << "no far link: the comparison misses the cluster path";
  EXPECT_LT(st[1].links_blocked, st[0].links_blocked) << "the refused pairs were the off run's blocked links";

  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.1, 1);
  for (int trial = 0; trial < 4; ++trial) {
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    if (trial == 0) x[emitter] = 1;
    else if (trial == 1) x.setOnes();
    else
      for (int i = 0; i < n; ++i) x[i] = U(rng);
    const double worst =
        htest::expect_products_within_admitted(g, H, st, x, "trial " + std::to_string(trial) + ", enclosures on against off");
    std::printf("trial %d: worst |y_on - y_off| / admitted %.3f\n", trial, worst);
    // The dark room receives exactly nothing from the lit room and its furniture with enclosures on.
    Eigen::VectorXd xl = x, yl(n);
    for (int i = dark.begin; i < dark.end; ++i) xl[i] = 0;
    H[1].apply(xl, yl);
    for (int i = dark.begin; i < dark.end; ++i)
      EXPECT_EQ(yl[i], 0.0) << "dark room row " << i << " receives " << yl[i] << " from the lit room, trial " << trial;
    EXPECT_GT(yl.segment(lit.begin, lit.end - lit.begin).maxCoeff(), 0) << "the lit room receives nothing";
  }
  for (int i = dark.begin; i < dark.end; ++i)
    H[1].for_each_in_row(i, [&](int j, double F) {
      EXPECT_FALSE((lit.has(j) || furniture.has(j)) && F != 0) << "dark row " << i << " has F = " << F << " from " << j;
    });
}

// 9b. A row of 32 empty closed rooms (inward unit boxes 0.1 m apart, 3 x 3 patches per wall), each its own cell.
// The tree splits between cells first, so every node above the rooms holds whole cells and meets no cell of a node
// outside it: each of the 31 node pairs that a split between rooms creates is refused at once, and no pair below it
// is visited (before, the refinement went on until both nodes held one room each: all 496 pairs of rooms, and in
// the million-polygon building 70 M node pairs). Expected: exactly 31 refusals; every row of a closed room summing
// to 1 within its admitted error (no same-room pair was refused); the other rooms receiving exactly nothing from
// the first; no ray (nothing hides anything inside a room).
TEST(Enclosures, CellsAreRefusedOnceWhereTheTreeSplitsThem) {
  constexpr int kRooms = 32;
  SceneBuilder s;
  std::vector<Range> rooms;
  for (int k = 0; k < kRooms; ++k)
    rooms.push_back(s.add(mesh::shapes::box(Vec3(1.1 * k, 0, 0), Vec3(1.1 * k + 1, 1, 1), 3, true)));
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const int n = g.size();
  formfactor::HierarchyOptions ho = coarse_with_rays();
  ho.portals = false;
  formfactor::HierarchyStats st;
  const formfactor::HierarchicalOperator H = formfactor::build_hierarchy(g, ho, &st);
  std::printf("%d patches, %d cells, %lld pairs cell-culled, %lld far + %lld leaf links, %lld blocked, %lld rays, "
              "admitted row error max %.2e\n",
              n, st.cells, st.pairs_cell_culled, st.far_links, st.leaf_links, st.links_blocked, st.rays_cast,
              st.row_error_max);
  ASSERT_EQ(st.cells, kRooms) << "one cell per room: the test must mean something";
  EXPECT_EQ(st.pairs_cell_culled, kRooms - 1) << "node pairs refused across cells: one per split between rooms";
  EXPECT_EQ(st.rays_cast, 0) << "rays cast, with nothing to hide anything in a room and no light between rooms";
  EXPECT_EQ(st.links_blocked, 0) << "blocked links between rooms that share no cell";
  Eigen::VectorXd ones = Eigen::VectorXd::Ones(n), y(n);
  H.apply(ones, y);
  ASSERT_EQ(int(st.row_error.size()), n);
  for (int i = 0; i < n; ++i)  // closed room: F 1 = 1, up to the admitted error (plus 1e-12 for round-off)
    EXPECT_LE(std::abs(y[i] - 1), st.row_error[i] + 1e-12)
        << "row " << i << " (room " << i / (n / kRooms) << ") sums to " << y[i] << ", admitted error " << st.row_error[i];
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  x.segment(rooms[0].begin, rooms[0].end - rooms[0].begin).setOnes();
  H.apply(x, y);
  for (int i = rooms[1].begin; i < n; ++i)
    EXPECT_EQ(y[i], 0.0) << "row " << i << " of a dark room receives " << y[i] << " from the first room";
}

// 9c. Dark cells (a solve's operator, HierarchyOptions::radiance_only with the patches' emission): two closed rooms
// 2 x 2 x 1 m side by side, each with a furniture box (so that pairs inside each room need rays), an emitting
// ceiling patch in the first only. The second room is a closed cell without an emitter: its radiance is 0 in any
// solution, so its pairs are refused without a link or a ray. Expected, against the same operator built without
// the emission (every pair linked): for any x, the product's rows of the lit room are identical (the same links:
// pairs across the cells are refused either way) and the dark room's rows are exactly 0; fewer rays; the dark rows
// flagged (HierarchyStats::row_dark) with an admitted error of at most 1; the radiance-relative error no larger.
TEST(Enclosures, DarkCellIsRefusedAndTheLitRowsAreUnchanged) {
  SceneBuilder s;
  Range lit, lit_box, dark;
  two_rooms(s, lit, lit_box, dark);
  const Range dark_box = s.add(mesh::shapes::box(Vec3(2.6, 0.6, 0.0001), Vec3(3.2, 1.4, 0.4), 1, false));
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const int n = g.size();
  const int emitter = patch_at(g, Vec3(1.25, 0.75, 1));
  auto in_lit = [&](int p) { return lit.has(p) || lit_box.has(p); };
  auto in_dark = [&](int p) { return dark.has(p) || dark_box.has(p); };
  formfactor::HierarchyStats st[2];
  std::vector<formfactor::HierarchicalOperator> H;
  for (int on = 0; on < 2; ++on) {
    formfactor::HierarchyOptions ho = coarse_with_rays();
    ho.brightness.assign(size_t(n), 1.0);  // the a-priori bound of a grey scene: every patch may be lit
    if (on) {
      ho.emission.assign(size_t(n), 0.0);
      ho.emission[size_t(emitter)] = 1.0;
      ho.radiance_only = true;
    }
    H.push_back(formfactor::build_hierarchy(g, ho, &st[on]));
    std::printf("emission %s: %lld dark cells, %lld dark patches, %lld dark pairs refused, %lld far + %lld leaf links, "
                "%lld rays, admitted row error max %.2e, radiance %.2e\n",
                on ? "given" : "not given", st[on].dark_cells, st[on].dark_patches, st[on].pairs_dark_culled,
                st[on].far_links, st[on].leaf_links, st[on].rays_cast, st[on].row_error_max, st[on].radiance_error_max);
  }
  ASSERT_EQ(st[1].cells, 2) << "lit room and dark room: the test must mean something";
  EXPECT_EQ(st[1].dark_cells, 1);
  EXPECT_EQ(st[1].dark_patches, dark_box.end - dark.begin) << "the dark room and its box, nothing else";
  EXPECT_GT(st[1].pairs_dark_culled, 0);
  EXPECT_EQ(st[0].pairs_dark_culled, 0);
  EXPECT_LT(st[1].rays_cast, st[0].rays_cast) << "the dark room's rays were not saved";
  EXPECT_GT(st[1].rays_cast, 0) << "the lit room's pairs need rays (its box)";
  EXPECT_LE(st[1].radiance_error_max, st[0].radiance_error_max) << "the dark rows' error, weighed by 0, counted";
  ASSERT_EQ(int(st[1].row_dark.size()), n);
  for (int p = 0; p < n; ++p) {
    EXPECT_EQ(int(st[1].row_dark[size_t(p)]), in_dark(p) ? 1 : 0) << "patch " << p;
    if (in_dark(p)) {
      EXPECT_LE(st[1].row_error[size_t(p)], 1.0) << "dark row " << p;
    }
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0.1, 1);
  for (int trial = 0; trial < 3; ++trial) {
    Eigen::VectorXd x(n), y[2];
    for (int i = 0; i < n; ++i) x[i] = trial == 0 ? 1.0 : U(rng);
    for (int on = 0; on < 2; ++on) {
      y[on].resize(n);
      H[size_t(on)].apply(x, y[on]);
    }
    for (int i = 0; i < n; ++i) {
      if (in_lit(i)) {
        EXPECT_EQ(y[1][i], y[0][i]) << "lit row " << i << ", trial " << trial;
      } else if (in_dark(i)) {
        EXPECT_EQ(y[1][i], 0.0) << "dark row " << i << " receives " << y[1][i] << ", trial " << trial;
      }
    }
  }
}

// 10. Open scenes: a ground quad [-1,1]^2 with an outward box [-0.5,0.5]^2 x [0,1] standing on it, no bottom (its
// bottom edges lie inside the ground quad: not a closed surface). Mutually visible patches (box sides and top vs
// ground) are never refused. The ground's sample point (the centroid of its largest triangle, (1/3, -1/3)) lies
// under the box, so a box wrongly taken as closed would put the ground inside it. An empty scene and a single
// patch give the trivial answer.
TEST(Enclosures, EmptyAndOpenScenesGiveOneCell) {
  {
    const fd::Enclosures e = fd::find_enclosures(mesh::PatchGeometry::from_polygons({}), 1e-6);
    EXPECT_TRUE(e.cell.empty());
    EXPECT_EQ(e.surfaces, 0);
    EXPECT_EQ(e.cells, 0);
  }
  {
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons({rect(2, 0, -1, 1, -1, 1, true)});
    const fd::Enclosures e = cells_of(g);
    ASSERT_EQ(e.cell.size(), 1u);
    EXPECT_EQ(e.cell[0], 0) << summary(e);
  }
  SceneBuilder s;
  const int ground = s.add(rect(2, 0, -1, 1, -1, 1, true)).begin;
  const Range box = s.add(room(Vec3(-0.5, -0.5, 0), Vec3(0.5, 0.5, 1), false, uniform(2), /*skip -z*/ 4));
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  for (int p = box.begin; p < box.end; ++p) expect_not_separated(g, e, p, ground, "open box vs ground");
  EXPECT_EQ(e.surfaces, 0) << summary(e);
}

// The dense assembly with cells: pairs of patches facing different cells are exactly 0 without rays, and every
// other entry is bit-identical to the assembly without cells (the ray estimates are seeded per pair, so the same
// pairs get the same rays). The cross-cell entries are 0 in the assembly without cells too: there rays find every
// segment between the two rooms blocked (no tolerance: an exact comparison).
TEST(Enclosures, DenseWithCellsMatchesWithout) {
  SceneBuilder s;
  const Range lit = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(2, 2, 1), 3, true));
  s.add(mesh::shapes::box(Vec3(0.4, 0.6, 0.0001), Vec3(1.0, 1.4, 0.4), 1, false));
  const Range dark = s.add(mesh::shapes::box(Vec3(2.1, 0, 0), Vec3(4.1, 2, 1), 3, true));
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  formfactor::Stats st[2];
  std::vector<formfactor::DenseMatrixOperator> F;
  for (int on = 0; on < 2; ++on) {
    formfactor::Options o;
    o.visibility = true;
    o.visibility_method = formfactor::VisibilityMethod::Rays;
    o.enclosures = on == 1;
    F.push_back(formfactor::assemble(g, o, &st[on]));
  }
  EXPECT_EQ(st[0].pairs_cell_hidden, 0);
  EXPECT_GT(st[1].pairs_cell_hidden, 0) << "nothing refused: the test exercises nothing";
  EXPECT_EQ(st[1].cells, 2) << st[1].enclosures << " closed surfaces";
  EXPECT_LT(st[1].pairs_ray_tested, st[0].pairs_ray_tested);
  const int n = g.size();
  auto in = [](const Range& r, int p) { return p >= r.begin && p < r.end; };
  int mismatches = 0;
  for (int i = 0; i < n && mismatches < 5; ++i)
    for (int j = 0; j < n && mismatches < 5; ++j) {
      const double a = F[0].matrix()(i, j), b = F[1].matrix()(i, j);
      const bool across = (in(lit, i) && in(dark, j)) || (in(dark, i) && in(lit, j));
      if (a != b || (across && b != 0)) {
        ++mismatches;
        ADD_FAILURE() << "F(" << i << ", " << j << "): " << a << " without cells, " << b << " with"
                      << (across ? " (across the rooms: must be 0)" : "");
      }
    }
}

// Inputs without mesh::prepare's imprinting (--no-repair, or geometry given to build_hierarchy directly), which the
// header promises to handle ("a model that was not repaired"). Both failed before the contact probes and the seam
// rule of enclosures.cpp's step 5.

// A closed outward box standing on a single floor quad (its bottom face coplanar with the floor): the point just
// in front of the floor (the centroid of its largest triangle + 4 eps) lies inside the box, so the floor gets the
// box's inside as its cell, different from the walls it sees; the hierarchy then refuses floor <-> walls and
// ceiling (the floor would gather F = 0 from the ceiling instead of 0.058) unless the contact marks the floor -1.
TEST(Enclosures, ClosedBoxStandingOnAPatchDoesNotSeparateItFromTheRoom) {
  SceneBuilder s;
  const Range walls = s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 1, true));
  const Range box = s.add(mesh::shapes::box(Vec3(0.2, 0.2, 0), Vec3(0.8, 0.8, 0.4), 1, false));
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  const int floor = patch_at(g, Vec3(0.5, 0.5, 0));
  for (int p = walls.begin; p < walls.end; ++p) expect_not_separated(g, e, floor, p, "floor vs walls");
  for (int p = box.begin; p < box.end; ++p)
    if (g.normal[p].z() > -0.5) expect_not_separated(g, e, floor, p, "floor vs box sides and top");
}

// A quad crossing the -x wall of a closed room exactly along the seam y = 0.5 between two wall patches: its
// edges cross the wall plane on the patches' common edge and the seam lies in the quad's plane; unless a crossing
// through a boundary counts, the quad takes the room's cell, yet its outside half sees an outside panel.
TEST(Enclosures, PatchCrossingAlongASeamGetsNoCell) {
  SceneBuilder s;
  s.add(mesh::shapes::box(Vec3(0, 0, 0), Vec3(1, 1, 1), 2, true));
  const int quad = s.add(rect(1, 0.5, 0.2, 0.3, -0.1, 0.3, true)).begin;       // y = 0.5, x in [-0.1, 0.3]
  const int outside = s.add(rect(1, 0.8, 0.0, 0.5, -0.5, -0.1, false)).begin;  // x < 0, facing -y
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(s.polys);
  const fd::Enclosures e = cells_of(g);
  expect_not_separated(g, e, quad, outside, "seam-crossing quad vs outside panel");
  EXPECT_EQ(e.cell[quad], -1) << describe(g, e, quad) << " " << summary(e);
}

// A door opening of the floor plan: the floor's edge along the wall's base passes the corner of the door jamb that
// stands on the floor, two patches of one closed surface meeting at a point. Nothing crosses anything there: every
// patch of examples/floorplan.obj, prepared as `lambert solve` prepares it, gets a cell (10 jamb and floor patches
// got none while a crossing through a patch's boundary counted against patches of the same surface). Exact counts.
TEST(Enclosures, DoorJambsStandingOnTheFloorKeepTheirCells) {
  mesh::PolygonSoup soup = io::read_soup(std::string(LAMBERT_SOURCE_DIR) + "/examples/floorplan.obj");
  const mesh::Scene scene = mesh::prepare_and_build(soup, {});
  const mesh::PatchGeometry& g = scene.geometry;
  const fd::Enclosures e = cells_of(g);
  EXPECT_EQ(e.surfaces, 4) << summary(e);
  EXPECT_EQ(e.crossed, 0) << summary(e);
  for (int p = 0; p < g.size(); ++p)
    if (e.cell[p] < 0) {
      ADD_FAILURE() << "patch without a cell: " << describe(g, e, p) << " " << summary(e);
      break;
    }
}

}  // namespace
}  // namespace lambert
