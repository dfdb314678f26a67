// The range of scene sizes lambert's form factors and visibility are verified at (prepare step 0).
#include <cmath>
#include <string>

#include "prepare_internal.hpp"

namespace lambert::mesh::detail {

void check_geometric_scale(const PolygonSoup& s) {
  Eigen::AlignedBox3d box;
  for (const auto& f : s.faces)
    for (int v : f.vertices) box.extend(s.positions[v]);
  if (box.isEmpty()) return;
  const double size = box.diagonal().norm();
  if (size == 0) return;  // a single point: the face checks report the degenerate faces
  // Measured (Cornell box scaled by powers of ten): row sums and the energy balance are exact to round-off
  // for sizes 9.6e-11 .. 2.9e12 m and wrong beyond (row sums 0.9997 at 9.6e-12 m, 0.985 at 9.6e-13 m, 0.995
  // at 9.6e12 m:
  // fixed absolute epsilons in the ray tracer's single-precision geometry). Refused outside a margin of that.
  if (size < kMinSceneSize || size > kMaxSceneSize)
    throw InputError(s.file + ": the scene's size (bounding-box diagonal " + num(size) + " m) is outside " + num(kMinSceneSize) +
                     " .. " + num(kMaxSceneSize) +
                     " m, the range where form factors and visibility are exact; coordinates are metres: rescale the model");
}

}  // namespace lambert::mesh::detail
