// Patch factors back to input faces: area-weighted over the source face, summed over the target face.
#include <algorithm>
#include <string>

#include "lambert/formfactor/assemble.hpp"

namespace lambert::formfactor {

std::vector<FaceEntry> aggregate_to_faces(const DenseMatrixOperator& F, const mesh::PatchGeometry& g,
                                          const std::vector<int>& face_id, int input_faces) {
  const int n = F.size();
  LAMBERT_CHECK(int(face_id.size()) == n && g.size() == n,
                "aggregate_to_faces: face_id has " + std::to_string(face_id.size()) + " entries, geometry " +
                    std::to_string(g.size()) + " patches, matrix " + std::to_string(n));
  for (int p = 0; p < n; ++p)
    LAMBERT_CHECK(face_id[p] >= 0 && face_id[p] < input_faces,
                  "aggregate_to_faces: patch " + std::to_string(p) + " has face id " + std::to_string(face_id[p]) +
                      " outside [0, " + std::to_string(input_faces) + ")");
  const auto& M = F.matrix();
  std::vector<FaceEntry> out;
  // Identity map (one patch per face, in order): copy the nonzero entries directly.
  bool identity = n == input_faces;
  for (int p = 0; p < n && identity; ++p) identity = face_id[p] == p;
  if (identity) {
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        if (M(i, j) != 0) out.push_back({i, j, M(i, j)});
    return out;
  }
  std::vector<std::vector<int>> patches(input_faces);
  for (int p = 0; p < n; ++p) patches[face_id[p]].push_back(p);
  std::vector<double> row(input_faces);
  for (int I = 0; I < input_faces; ++I) {
    if (patches[I].empty()) continue;
    std::fill(row.begin(), row.end(), 0.0);
    double area = 0;
    for (int i : patches[I]) {
      area += g.area[i];
      for (int j = 0; j < n; ++j) row[face_id[j]] += g.area[i] * M(i, j);
    }
    for (int J = 0; J < input_faces; ++J)
      if (row[J] != 0) out.push_back({I, J, row[J] / area});
  }
  return out;
}

}  // namespace lambert::formfactor
