// Shaft culling and the occluder tree (formfactor/src/shaft.hpp): the answer of OccluderTree::may_block must not
// depend on its occluder hint (the occluder found by the thread's previous query), or the form factors would depend
// on the thread count.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <span>
#include <vector>

#include "../formfactor/src/shaft.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/mesh/shapes.hpp"

namespace lambert {
namespace {

namespace fd = formfactor::detail;

// Two rooms side by side with a block in one: occluders touching the shafts' planes exactly (walls standing on
// floors, coplanar faces), where rounding decides.
mesh::PatchGeometry scene() {
  std::vector<std::vector<Vec3>> polys;
  for (auto part : {mesh::shapes::box(Vec3(0, 0, 0), Vec3(2, 2, 1), 4, true),
                    mesh::shapes::box(Vec3(0.4, 0.6, 0.0001), Vec3(1.0, 1.4, 0.4), 2, false),
                    mesh::shapes::box(Vec3(2.1, 0, 0), Vec3(4.1, 2, 1), 4, true)})
    polys.insert(polys.end(), part.begin(), part.end());
  return mesh::PatchGeometry::from_polygons(polys);
}

// The shaft as the hierarchy's leaf pairs build it.
fd::Shaft pair_shaft(const mesh::PatchGeometry& g, const std::vector<fd::Box>& box, int i, int j) {
  fd::Shaft sh = fd::make_shaft(box[size_t(i)], box[size_t(j)]);
  sh.ni = g.normal[i];
  sh.oi = g.normal[i].dot(g.centroid[i]);
  sh.nj = g.normal[j];
  sh.oj = g.normal[j].dot(g.centroid[j]);
  sh.eps = 1e-10 * 4.6;
  return sh;
}

// Every patch a potential occluder.
std::vector<int> every_patch(const mesh::PatchGeometry& g) {
  std::vector<int> occ(static_cast<size_t>(g.size()));
  for (int p = 0; p < g.size(); ++p) occ[size_t(p)] = p;
  return occ;
}

std::vector<fd::Box> boxes(const mesh::PatchGeometry& g) {
  std::vector<fd::Box> box(size_t(g.size()));
  for (int p = 0; p < g.size(); ++p)
    for (const Vec3& v : g.polygon(p)) box[size_t(p)].add(v);
  return box;
}

// For every patch pair, the shaft as the hierarchy's leaf pairs build it; may_block without a hint and with every
// occluder as the hint must agree exactly (a yes/no answer: no tolerance). Before the box test was made monotone
// under rounding (extreme corners instead of centre +- half extent), 19 of 27,029 such shafts differed.
TEST(OccluderTree, MayBlockDoesNotDependOnTheHint) {
  const mesh::PatchGeometry g = scene();
  const int n = g.size();
  const fd::OccluderTree tree(g, every_patch(g));
  const auto box = boxes(g);
  long long shafts = 0, disagreements = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      const fd::Shaft sh = pair_shaft(g, box, i, j);
      const bool plain = tree.may_block(sh, i, j);
      ++shafts;
      for (int h = 0; h < n; h += 7) {
        int hint = h;
        const bool hinted = tree.may_block(sh, i, j, &hint);
        if (hinted != plain) {
          ++disagreements;
          ADD_FAILURE() << "patches " << i << ", " << j << ": may_block " << plain << " without a hint, " << hinted
                        << " with hint " << h;
          if (disagreements > 5) return;
        }
      }
    }
  EXPECT_GT(shafts, 10000);
}


// A segment between the interiors of two patches of a convex room runs inside the room: no wall can block it. The
// walls next to a pair touch the pair's shaft only on its boundary (a face of the joint box, or a plane through
// the boxes' edges), where a segment between the two patches can only run if both lie in that plane (then they
// are coplanar and exchange nothing). So no pair of the empty box may need a ray. Before the shaft's tests were
// made strict (an occluder lying on the boundary counted as inside), 2,640 of the box's 3,072 pairs of patches
// on different walls did.
TEST(OccluderTree, WallsTouchingTheShaftOnlyOnItsBoundaryDoNotBlock) {
  const auto polys = mesh::shapes::box(Vec3(0, 0, 0), Vec3(2, 1.5, 1), 4, true);
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(polys);
  const int n = g.size();
  const fd::OccluderTree tree(g, every_patch(g));
  const auto box = boxes(g);
  int pairs = 0, flagged = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      if (std::abs(g.normal[i].dot(g.normal[j])) > 0.5) continue;  // same or opposite walls: not next to each other
      ++pairs;
      int hint = -1;
      if (tree.may_block(pair_shaft(g, box, i, j), i, j, &hint)) {
        if (++flagged <= 5)
          ADD_FAILURE() << "patches " << i << " and " << j << " (centroids " << g.centroid[i].transpose() << " / "
                        << g.centroid[j].transpose() << ") may be blocked by patch " << hint << " (centroid "
                        << g.centroid[hint].transpose() << ")";
      }
    }
  EXPECT_EQ(pairs, 3072);  // 12 pairs of neighbouring walls, 16 x 16 patch pairs each
  EXPECT_EQ(flagged, 0);
}

// The strict tests still see an occluder that reaches into the shaft by a hair: a floor patch and the ceiling patch
// above it, with a thin plate between them, or a wall patch moved 1e-9 m inward from the joint box's face.
TEST(OccluderTree, AnOccluderReachingIntoTheShaftByAHairMayBlock) {
  const std::vector<Vec3> floor = {Vec3(0, 0, 0), Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(1, 0, 0)};  // facing +y
  const std::vector<Vec3> ceiling = {Vec3(0, 2, 0), Vec3(1, 2, 0), Vec3(1, 2, 1), Vec3(0, 2, 1)};  // facing -y
  for (const double inset : {0.0, 1e-9}) {
    // A wall in the plane x = 1 - inset, facing -x, as tall as the room and 1 m deep.
    const double x = 1 - inset;
    const std::vector<Vec3> wall = {Vec3(x, 0, 0), Vec3(x, 2, 0), Vec3(x, 2, 1), Vec3(x, 0, 1)};
    const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons({floor, ceiling, wall});
    const fd::OccluderTree tree(g, {0, 1, 2});
    const bool blocked = tree.may_block(pair_shaft(g, boxes(g), 0, 1), 0, 1);
    EXPECT_EQ(blocked, inset > 0) << "wall at x = 1 - " << inset;
  }
}

// Independent check of the culling on the two rooms with a block: for every pair the tree clears, segments between
// random interior points of the two patches meet no other patch (brute force over every patch: plane crossing
// strictly between the ends, strictly inside the convex patch).
TEST(OccluderTree, ClearedPairsMeetNoPatch) {
  const mesh::PatchGeometry g = scene();
  const int n = g.size();
  const fd::OccluderTree tree(g, every_patch(g));
  const auto box = boxes(g);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.02, 1.0);
  auto interior = [&](int p) {  // a convex combination of the corners with every weight > 0
    const auto poly = g.polygon(p);
    Vec3 x = Vec3::Zero();
    double w = 0;
    for (const Vec3& v : poly) {
      const double a = u(rng);
      x += a * v;
      w += a;
    }
    return Vec3(x / w);
  };
  auto crosses = [&](const Vec3& a, const Vec3& b, int q) {
    const Vec3& nq = g.normal[q];
    const double da = nq.dot(a - g.centroid[q]), db = nq.dot(b - g.centroid[q]);
    if (!(da * db < 0)) return false;
    const Vec3 x = a + (b - a) * (da / (da - db));
    const auto poly = g.polygon(q);
    for (size_t k = 0; k < poly.size(); ++k) {
      const Vec3& p0 = poly[k];
      const Vec3& p1 = poly[(k + 1) % poly.size()];
      if (nq.dot((p1 - p0).cross(x - p0)) <= 0) return false;  // on or outside an edge (corners counter-clockwise)
    }
    return true;
  };
  long long cleared = 0, segments = 0, wrong = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      if (tree.may_block(pair_shaft(g, box, i, j), i, j)) continue;
      ++cleared;
      for (int r = 0; r < 4; ++r) {
        const Vec3 a = interior(i), b = interior(j);
        if (!(g.normal[i].dot(b - a) > 0 && g.normal[j].dot(a - b) > 0)) continue;  // carries no light
        ++segments;
        for (int q = 0; q < n; ++q)
          if (q != i && q != j && crosses(a, b, q)) {
            if (++wrong <= 5)
              ADD_FAILURE() << "pair " << i << ", " << j << " was cleared, but the segment " << a.transpose()
                            << " -> " << b.transpose() << " crosses patch " << q;
            break;
          }
      }
    }
  EXPECT_GT(cleared, 5000);
  EXPECT_GT(segments, 5000);
  EXPECT_EQ(wrong, 0) << "of " << segments << " segments";
}


// The hierarchy's pairs below a pair of clusters walk the occluder tree from the clusters' shaft's frontier
// (OccluderTree::frontier) instead of its root. On the two rooms with a block, for groups of 6 neighbouring patches
// (as the hierarchy's small clusters: their joint boxes grown by 1e-9 of the scene) and every pair of patches
// between two groups, the walk from the frontier must find the same occluders in the same order as the walk from
// the root, and may_block must agree with and without its hint (yes/no and lists: no tolerance), for frontiers of
// nodes of up to 1, 4 and 32 occluders; and each frontier found from a coarser frontier (OccluderTree::frontier_from)
// must be the one found from the root.
TEST(OccluderTree, WalksFromAFrontierFindWhatWalksFromTheRootFind) {
  const mesh::PatchGeometry g = scene();
  const int n = g.size();
  const fd::OccluderTree tree(g, every_patch(g));
  const auto box = boxes(g);
  constexpr int kGroup = 6;
  const double pad = 1e-9 * 4.6;
  long long pairs = 0, blocked = 0, differ = 0, frontier_nodes = 0;
  size_t largest = 0;  // frontiers of more than 64 nodes are walked from the frontier too (once from the root)
  std::vector<int> front, from_root, from_front;
  for (int items : {1, 4, 32})
    for (int ga = 0; ga + kGroup <= n; ga += kGroup)
      for (int gb = ga + kGroup; gb + kGroup <= n; gb += kGroup) {
        fd::Box ba, bb;
        for (int k = 0; k < kGroup; ++k) {
          ba.add(box[size_t(ga + k)]);
          bb.add(box[size_t(gb + k)]);
        }
        front.clear();
        tree.frontier(fd::grown_box_shaft(ba, bb, pad, 1e-10 * 4.6), items, front);
        frontier_nodes += static_cast<long long>(front.size());
        // The same frontier from a coarse one (nodes of up to 64 occluders) of a pair of larger groups holding these,
        // grown by twice the margin (as the hierarchy's two levels): the same nodes in the same order.
        {
          fd::Box ca = ba, cb = bb;
          for (int k = kGroup; k < 3 * kGroup; ++k) {
            if (ga + k < n) ca.add(box[size_t(ga + k)]);
            if (gb + k < n) cb.add(box[size_t(gb + k)]);
          }
          std::vector<int> coarse, nested;
          tree.frontier(fd::grown_box_shaft(ca, cb, 2 * pad, 1e-10 * 4.6), 64, coarse);
          tree.frontier_from(fd::grown_box_shaft(ba, bb, pad, 1e-10 * 4.6), items, coarse, nested);
          if (nested != front && ++differ <= 5)
            ADD_FAILURE() << "groups " << ga << ", " << gb << ": frontier of " << front.size() << " nodes from the root, "
                          << nested.size() << " from a coarse frontier of " << coarse.size();
        }
        largest = std::max(largest, front.size());
        for (int i = ga; i < ga + kGroup; ++i)
          for (int j = gb; j < gb + kGroup; ++j) {
            const fd::Shaft sh = pair_shaft(g, box, i, j);
            from_root.clear();
            from_front.clear();
            tree.collect(sh, i, j, from_root);
            tree.collect_from(sh, i, j, front, from_front);
            int hint = from_root.empty() ? -1 : from_root.back();
            const bool mb = tree.may_block(sh, i, j), mb_front = tree.may_block_from(sh, i, j, front, &hint);
            ++pairs;
            blocked += mb;
            if ((from_root != from_front || mb != mb_front || mb != !from_root.empty()) && ++differ <= 5)
              ADD_FAILURE() << "pair " << i << ", " << j << " (frontier of nodes <= " << items << " occluders, "
                            << front.size() << " nodes): " << from_root.size() << " occluders from the root, "
                            << from_front.size() << " from the frontier; may_block " << mb << " / " << mb_front;
          }
      }
  EXPECT_GT(pairs, 30000);
  EXPECT_GT(blocked, 1000);
  EXPECT_GT(pairs - blocked, 1000);
  EXPECT_GT(frontier_nodes, 0);
  EXPECT_GT(largest, 64u) << "no frontier of more than 64 nodes";
  EXPECT_EQ(differ, 0) << "of " << pairs << " pairs";
}

// The exact path collects a merged polygon's members once (OccluderTree::collect_grouped_from): on the two rooms with
// a block, with the patches of each wall, floor and block face as one group (their plane's patches; some patches of
// each left alone, or none) and an `accept` that refuses a patch in three, for pairs of patches: the patches outside
// groups must come in collect_from's order, filtered by accept, and each group must be listed once exactly when
// collect_from lists an accepted member of it (lists and sets: no tolerance). Also from a frontier.
TEST(OccluderTree, GroupedCollectListsEachGroupOnceAndTheRestInOrder) {
  const mesh::PatchGeometry g = scene();
  const int n = g.size();
  fd::OccluderTree tree(g, every_patch(g));
  const auto box = boxes(g);
  long long pairs = 0, grouped = 0, differ = 0;
  // Groups: patches whose planes agree (normal and offset to 1e-9); all of them, then all but every fifth patch.
  for (int alone : {0, 5}) {
    std::vector<int> group(size_t(n), -1);
    std::vector<std::pair<Vec3, double>> planes;
    for (int p = 0; p < n; ++p) {
      if (alone > 0 && p % alone == 0) continue;
      const Vec3 nn = g.normal[p];
      const double o = nn.dot(g.centroid[p]);
      int id = -1;
      for (size_t k = 0; k < planes.size() && id < 0; ++k)
        if ((planes[k].first - nn).norm() < 1e-9 && std::abs(planes[k].second - o) < 1e-9) id = int(k);
      if (id < 0) id = int(planes.size()), planes.push_back({nn, o});
      group[size_t(p)] = id;
    }
    tree.set_groups(group);
    auto accept = [](int p) { return p % 3 != 1; };
    std::vector<int> all, got, seen, front;
    for (int i = 0; i < n; i += 3)
      for (int j = i + 1; j < n; j += 2) {
        const fd::Shaft sh = pair_shaft(g, box, i, j);
        all.clear();
        tree.collect(sh, i, j, all);
        std::vector<int> want_rest;
        std::vector<int> want_groups;
        for (int p : all) {
          if (!accept(p)) continue;
          if (group[size_t(p)] < 0) want_rest.push_back(p);
          else want_groups.push_back(group[size_t(p)]);
        }
        std::sort(want_groups.begin(), want_groups.end());
        want_groups.erase(std::unique(want_groups.begin(), want_groups.end()), want_groups.end());
        for (int from_frontier = 0; from_frontier < 2; ++from_frontier) {
          front.clear();
          if (from_frontier)
            tree.frontier(fd::grown_box_shaft(box[size_t(i)], box[size_t(j)], 1e-9 * 4.6, 1e-10 * 4.6), 4, front);
          got.clear();
          tree.collect_grouped_from(sh, i, j, from_frontier ? std::span<const int>(front) : fd::OccluderTree::root(),
                                    accept, got, seen);
          std::vector<int> rest, groups;
          for (int p : got) {
            if (group[size_t(p)] < 0) rest.push_back(p);
            else groups.push_back(group[size_t(p)]);
          }
          const size_t listed = groups.size();
          std::sort(groups.begin(), groups.end());
          const bool once = std::unique(groups.begin(), groups.end()) == groups.end();
          ++pairs;
          grouped += static_cast<long long>(listed);
          if ((rest != want_rest || groups != want_groups || !once || listed != want_groups.size()) && ++differ <= 5)
            ADD_FAILURE() << "pair " << i << ", " << j << (from_frontier ? " (from a frontier)" : "") << ": "
                          << rest.size() << " ungrouped occluders (want " << want_rest.size() << "), " << listed
                          << " group entries (want " << want_groups.size() << " groups), every " << alone
                          << "th patch alone";
        }
      }
  }
  EXPECT_GT(pairs, 10000);
  EXPECT_GT(grouped, 1000);
  EXPECT_EQ(differ, 0) << "of " << pairs << " walks";
}

}  // namespace
}  // namespace lambert
