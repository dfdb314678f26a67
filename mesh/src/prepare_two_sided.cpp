// mesh::prepare, last step: two-sided faces become two patches, front and back (see prepare.hpp).
#include <vector>

#include "prepare_internal.hpp"

namespace lambert::mesh::detail {

void duplicate_two_sided(PolygonSoup& s, Report& report) {
  long n = 0;
  for (const auto& f : s.faces) n += s.materials.at(f.material).two_sided && f.side == 0;
  report.counts["two_sided_faces"] += n;
  if (n == 0) return;
  if (s.input_faces < 0) s.input_faces = static_cast<int>(s.faces.size());
  std::vector<SoupFace> out;
  out.reserve(s.faces.size() + n);
  for (int k = 0; k < static_cast<int>(s.faces.size()); ++k) {
    SoupFace f = s.faces[k];
    f.origin = origin_of(s, k);
    out.push_back(f);
    if (!s.materials[f.material].two_sided || f.side != 0) continue;
    // The back: the same corners in reverse order (first corner kept), on its own copies of the
    // vertices, so that it is a separate surface and the front's neighbours stay its neighbours.
    SoupFace back = f;
    back.side = 1;
    back.vertices.clear();
    for (size_t c = 0; c < f.vertices.size(); ++c) {
      const int v = f.vertices[(f.vertices.size() - c) % f.vertices.size()];
      back.vertices.push_back(static_cast<int>(s.positions.size()));
      s.positions.push_back(s.positions[v]);
      s.position_lines.push_back(v < static_cast<int>(s.position_lines.size()) ? s.position_lines[v] : 0);
    }
    out.push_back(std::move(back));
  }
  s.faces = std::move(out);
}

}  // namespace lambert::mesh::detail
