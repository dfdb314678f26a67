// Shaft culling and the occluder tree (formfactor/src/shaft.hpp): the answer of OccluderTree::may_block must not
// depend on its occluder hint (the occluder found by the thread's previous query), or the form factors would depend
// on the thread count.
#include <gtest/gtest.h>

#include <random>
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

// For every patch pair, the shaft as the hierarchy's leaf pairs build it; may_block without a hint and with every
// occluder as the hint must agree exactly (a yes/no answer: no tolerance). Before the box test was made monotone
// under rounding (extreme corners instead of centre +- half extent), 19 of 27,029 such shafts differed.
TEST(OccluderTree, MayBlockDoesNotDependOnTheHint) {
  const mesh::PatchGeometry g = scene();
  const int n = g.size();
  std::vector<int> occ(static_cast<size_t>(n));
  for (int p = 0; p < n; ++p) occ[static_cast<size_t>(p)] = p;
  const fd::OccluderTree tree(g, occ);
  std::vector<fd::Box> box(static_cast<size_t>(n));
  for (int p = 0; p < n; ++p)
    for (const Vec3& v : g.polygon(p)) box[size_t(p)].add(v);
  long long shafts = 0, disagreements = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      fd::Shaft sh = fd::make_shaft(box[size_t(i)], box[size_t(j)]);
      sh.ni = g.normal[i];
      sh.oi = g.normal[i].dot(g.centroid[i]);
      sh.nj = g.normal[j];
      sh.oj = g.normal[j].dot(g.centroid[j]);
      sh.eps = 1e-10 * 4.6;
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

}  // namespace
}  // namespace lambert
