#include "lambert/solver/adaptive.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <utility>

namespace lambert::solver {
namespace {

struct Box {
  Vec3 lo, hi;
};

Box box_of(std::span<const Vec3> poly) {
  Box b{poly[0], poly[0]};
  for (const Vec3& v : poly) {
    b.lo = b.lo.cwiseMin(v);
    b.hi = b.hi.cwiseMax(v);
  }
  return b;
}

// Do some edge of a and some edge of b lie on one line and overlap by more than eps?
bool share_edge_segment(std::span<const Vec3> a, std::span<const Vec3> b, double eps) {
  const size_t na = a.size(), nb = b.size();
  for (size_t i = 0; i < na; ++i) {
    const Vec3& p0 = a[i];
    const Vec3 d = a[(i + 1) % na] - p0;
    const double len = d.norm();
    if (!(len > eps)) continue;
    const Vec3 u = d / len;
    for (size_t j = 0; j < nb; ++j) {
      const Vec3 q0 = b[j] - p0, q1 = b[(j + 1) % nb] - p0;
      const double t0 = q0.dot(u), t1 = q1.dot(u);
      if ((q0 - t0 * u).norm() > eps || (q1 - t1 * u).norm() > eps) continue;  // not on a's line
      const double overlap = std::min(len, std::max(t0, t1)) - std::max(0.0, std::min(t0, t1));
      if (overlap > eps) return true;
    }
  }
  return false;
}

bool convex(std::span<const Vec3> poly, const Vec3& n) {
  const size_t m = poly.size();
  for (size_t i = 0; i < m; ++i) {
    const Vec3 e0 = poly[i] - poly[(i + m - 1) % m], e1 = poly[(i + 1) % m] - poly[i];
    if (e0.cross(e1).dot(n) < -1e-12 * e0.norm() * e1.norm()) return false;
  }
  return true;
}

// One soup face per scene patch, corners welded by exact position; used when build_scene did not keep
// faces one to one (it triangulates non-planar polygons), so that patches can be mapped to faces.
mesh::PolygonSoup soup_from_scene(const mesh::PolygonSoup& in, const mesh::Scene& scene) {
  mesh::PolygonSoup s = in;
  s.positions.clear();
  s.position_lines.clear();
  s.faces.clear();
  std::map<std::array<double, 3>, int> index;
  const auto& g = scene.geometry;
  for (int p = 0; p < scene.patches(); ++p) {
    mesh::SoupFace f;
    for (const Vec3& v : g.polygon(p)) {
      auto [it, added] = index.try_emplace({v.x(), v.y(), v.z()}, static_cast<int>(s.positions.size()));
      if (added) {
        s.positions.push_back(v);
        s.position_lines.push_back(0);
      }
      f.vertices.push_back(it->second);
    }
    f.material = scene.material[p];
    f.group = scene.group[p];
    f.origin = scene.face_id[p];
    s.faces.push_back(std::move(f));
  }
  return s;
}

// Children added by splitting a face with m corners (see split_face).
int added_by_split(int m) { return m == 3 ? 3 : m - 1; }

}  // namespace

std::vector<double> jump_indicator(const mesh::Scene& scene, const ColorField& radiance) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  if (n == 0) return ind;
  const auto& g = scene.geometry;
  const ColorField Le = scene.emission_field();
  const double scale = (radiance - Le).maxCoeff();
  if (!(scale > 0)) return ind;  // nothing reflected: no resolution error to find

  std::vector<Box> boxes(n);
  Box all = box_of(g.polygon(0));
  for (int p = 0; p < n; ++p) {
    boxes[p] = box_of(g.polygon(p));
    all.lo = all.lo.cwiseMin(boxes[p].lo);
    all.hi = all.hi.cwiseMax(boxes[p].hi);
  }
  const double eps = 1e-9 * std::max((all.hi - all.lo).norm(), 1e-300);
  // Same smooth surface: normals within 30 degrees (VertexSplit's default crease), so that the jump
  // across a room's corner (orientation, not resolution) does not count.
  const double cos_crease = std::cos(mesh::VertexSplit::kDefaultCreaseDeg * std::numbers::pi / 180.0);

  // Sweep along x over boxes sorted by their low x.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return boxes[a].lo.x() < boxes[b].lo.x(); });
  for (int ia = 0; ia < n; ++ia) {
    const int p = order[ia];
    for (int ib = ia + 1; ib < n; ++ib) {
      const int q = order[ib];
      if (boxes[q].lo.x() > boxes[p].hi.x() + eps) break;
      if ((boxes[q].lo.array() > boxes[p].hi.array() + eps).any() ||
          (boxes[p].lo.array() > boxes[q].hi.array() + eps).any())
        continue;
      if (scene.material[p] != scene.material[q]) continue;
      if (g.normal[p].dot(g.normal[q]) < cos_crease) continue;
      if (!share_edge_segment(g.polygon(p), g.polygon(q), eps)) continue;
      const double jump = (radiance.row(p) - radiance.row(q)).cwiseAbs().maxCoeff() / scale;
      ind[p] = std::max(ind[p], jump);
      ind[q] = std::max(ind[q], jump);
    }
  }
  return ind;
}

AdaptiveResult solve_adaptive(const mesh::PolygonSoup& input, const AdaptiveOptions& options) {
  if (options.max_patches < 1)
    throw InputError("adaptive refinement: max_patches must be >= 1, got " + std::to_string(options.max_patches));
  if (!(options.tolerance > 0) || !std::isfinite(options.tolerance))
    throw InputError("adaptive refinement: tolerance must be finite and > 0, got " +
                     std::to_string(options.tolerance));
  if (options.max_rounds < 0)
    throw InputError("adaptive refinement: max_rounds must be >= 0, got " + std::to_string(options.max_rounds));
  const auto start = std::chrono::steady_clock::now();

  AdaptiveResult result;
  mesh::PolygonSoup soup = input;
  // Children take their face's place, so indices shift: pin each face's input index in origin.
  if (soup.input_faces < 0) soup.input_faces = static_cast<int>(soup.faces.size());
  for (size_t k = 0; k < soup.faces.size(); ++k)
    if (soup.faces[k].origin < 0) soup.faces[k].origin = static_cast<int>(k);

  ColorField guess;  // previous radiance mapped to the current patches
  for (int round = 0;; ++round) {
    mesh::Scene scene = mesh::build_scene(soup);
    if (scene.patches() != static_cast<int>(soup.faces.size())) {
      soup = soup_from_scene(soup, scene);
      scene = mesh::build_scene(soup);
    }
    const int n = scene.patches();
    if (round == 0 && n > options.max_patches)
      throw InputError(input.file + ": " + std::to_string(n) + " patches before refinement, above max_patches = " +
                       std::to_string(options.max_patches));
    result.patches_per_round.push_back(n);

    const formfactor::DenseMatrixOperator F = formfactor::assemble(scene.geometry, options.ff);
    Options so = options.solve;
    so.initial_guess = guess.rows() == n ? guess : ColorField();
    Solution sol = solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field(), so);

    const std::vector<double> ind = jump_indicator(scene, sol.radiance);
    result.max_indicator.push_back(ind.empty() ? 0.0 : *std::max_element(ind.begin(), ind.end()));

    std::vector<int> above;
    for (int p = 0; p < n; ++p)
      if (ind[p] > options.tolerance) above.push_back(p);
    std::stable_sort(above.begin(), above.end(), [&](int a, int b) { return ind[a] > ind[b]; });

    std::vector<char> split(n, 0);
    int count = n, chosen = 0;
    long not_splittable = 0;
    for (int p : above) {
      const auto poly = scene.geometry.polygon(p);
      const int m = static_cast<int>(poly.size());
      if (m > 3 && !convex(poly, scene.geometry.normal[p])) {
        ++not_splittable;
        continue;
      }
      if (count + added_by_split(m) > options.max_patches) continue;
      count += added_by_split(m);
      split[p] = 1;
      ++chosen;
    }
    result.not_splittable = not_splittable;

    const bool last = above.empty() || chosen == 0 || round == options.max_rounds;
    if (last) {
      result.stop = above.empty() ? "converged" : chosen == 0 ? "budget" : "max_rounds";
      result.soup = std::move(soup);
      result.scene = std::move(scene);
      result.solution = std::move(sol);
      break;
    }

    // Split the marked faces; children take their parent's place and its radiance as a start.
    mesh::PolygonSoup next = soup;
    next.faces.clear();
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
      auto [it, added] = midpoint.try_emplace(key, static_cast<int>(next.positions.size()));
      if (added) {
        next.positions.push_back(0.5 * (next.positions[a] + next.positions[b]));
        next.position_lines.push_back(0);
      }
      return it->second;
    };
    next.position_lines.resize(next.positions.size(), 0);
    std::vector<int> parent;
    for (int p = 0; p < n; ++p) {
      const mesh::SoupFace& f = soup.faces[p];
      if (!split[p]) {
        next.faces.push_back(f);
        parent.push_back(p);
        continue;
      }
      const std::vector<int>& v = f.vertices;
      const int m = static_cast<int>(v.size());
      std::vector<int> e(m);  // e[i]: midpoint of edge (i, i+1)
      for (int i = 0; i < m; ++i) e[i] = mid(v[i], v[(i + 1) % m]);
      std::vector<std::vector<int>> children;
      if (m == 3) {
        children = {{v[0], e[0], e[2]}, {e[0], v[1], e[1]}, {e[2], e[1], v[2]}, {e[0], e[1], e[2]}};
      } else {
        Vec3 c = Vec3::Zero();
        for (int i : v) c += next.positions[i];
        const int ci = static_cast<int>(next.positions.size());
        next.positions.push_back(c / m);
        next.position_lines.push_back(0);
        for (int i = 0; i < m; ++i) children.push_back({v[i], e[i], ci, e[(i + m - 1) % m]});
      }
      for (auto& cv : children) {
        mesh::SoupFace child = f;
        child.vertices = std::move(cv);
        next.faces.push_back(std::move(child));
        parent.push_back(p);
      }
    }
    guess.resize(static_cast<Eigen::Index>(parent.size()), 3);
    for (size_t k = 0; k < parent.size(); ++k) guess.row(static_cast<Eigen::Index>(k)) = sol.radiance.row(parent[k]);
    soup = std::move(next);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lambert::solver
