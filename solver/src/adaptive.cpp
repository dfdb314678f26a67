#include "lambert/solver/adaptive.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <numeric>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "lambert/formfactor/kernel.hpp"
#include "lambert/formfactor/visibility.hpp"

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

// A convex quad much longer than wide (opposite edges both > 2x the other two) is halved across its
// length instead of split 4 ways, which would keep its aspect ratio: 1 = cut edges 0 and 2 at their
// midpoints, 2 = edges 1 and 3, 0 = no such quad.
int long_quad(std::span<const Vec3> q) {
  if (q.size() != 4) return 0;
  double l[4];
  for (int i = 0; i < 4; ++i) l[i] = (q[(i + 1) % 4] - q[i]).norm();
  if (std::min(l[0], l[2]) > 2 * std::max(l[1], l[3])) return 1;
  if (std::min(l[1], l[3]) > 2 * std::max(l[0], l[2])) return 2;
  return 0;
}

// Children added by splitting a face (see the split in solve_adaptive).
int added_by_split(std::span<const Vec3> poly) {
  const int m = static_cast<int>(poly.size());
  return long_quad(poly) ? 1 : m == 3 ? 3 : m - 1;
}

// 3 points per triangle of patch p, at barycentric (2/3, 1/6, 1/6) and its permutations: strictly
// inside the patch even when it is not convex, and spread towards its corners.
void sample_points(const mesh::PatchGeometry& g, int p, std::vector<Vec3>& out) {
  out.clear();
  for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
    const Vec3 &a = g.points[g.triangles[t][0]], &b = g.points[g.triangles[t][1]], &c = g.points[g.triangles[t][2]];
    out.push_back((4 * a + b + c) / 6);
    out.push_back((a + 4 * b + c) / 6);
    out.push_back((a + b + 4 * c) / 6);
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

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

std::vector<double> direct_indicator(const mesh::Scene& scene, const ColorField& radiance,
                                     const formfactor::Visibility* caster) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  if (n == 0) return ind;
  const auto& g = scene.geometry;
  const ColorField Le = scene.emission_field();
  const double scale = (radiance - Le).maxCoeff();
  if (!(scale > 0)) return ind;
  std::vector<int> emitters;
  for (int e = 0; e < n; ++e)
    if (Le.row(e).maxCoeff() > 0) emitters.push_back(e);
  if (emitters.empty()) return ind;
  std::unique_ptr<formfactor::Visibility> own;
  if (!caster) {
    const std::vector<int> occ = formfactor::potential_occluders(g);
    if (!occ.empty()) own = formfactor::make_embree_visibility(g, occ);
    caster = own.get();  // null: nothing can block anything
  }
  std::vector<std::vector<Vec3>> targets(n);
  for (int e : emitters) sample_points(g, e, targets[e]);

  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& r) {
    std::vector<Vec3> xs, from;
    std::vector<std::uint8_t> hidden;
    for (int p = r.begin(); p < r.end(); ++p) {
      const RGB rho = scene.reflectance(p);
      if (!(rho.maxCoeff() > 0)) continue;
      sample_points(g, p, xs);
      RGB lo = RGB::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (const Vec3& x : xs) {
        RGB D = RGB::Zero();
        for (int e : emitters) {
          if (e == p) continue;
          const double F = formfactor::point_to_polygon(x, g.normal[p], g.polygon(e));
          if (!(F > 0)) continue;
          double visible = 1;
          if (caster) {
            const auto& to = targets[e];
            from.assign(to.size(), x);
            hidden.assign(to.size(), 0);
            caster->occluded(from, to, p, e, hidden);
            long blocked = 0;
            for (auto h : hidden) blocked += h;
            visible = 1 - static_cast<double>(blocked) / static_cast<double>(to.size());
          }
          D += F * visible * Le.row(e).transpose().array();
        }
        D *= rho;
        lo = lo.min(D);
        hi = hi.max(D);
      }
      ind[p] = (hi - lo).maxCoeff() / scale;
    }
  });
  return ind;
}

std::vector<double> gather_indicator(const mesh::Scene& scene, const formfactor::DenseMatrixOperator& F,
                                     const ColorField& radiance) {
  const int n = scene.patches();
  std::vector<double> ind(n, 0.0);
  if (n == 0 || F.size() != n) return ind;
  const auto& g = scene.geometry;
  const double scale = (radiance - scene.emission_field()).maxCoeff();
  if (!(scale > 0)) return ind;
  const auto& M = F.matrix();
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& r) {
    for (int p = r.begin(); p < r.end(); ++p) {
      const RGB rho = scene.reflectance(p);
      if (!(rho.maxCoeff() > 0)) continue;
      const auto poly = g.polygon(p);
      double diam = 0;
      for (size_t a = 0; a < poly.size(); ++a)
        for (size_t b = a + 1; b < poly.size(); ++b) diam = std::max(diam, (poly[a] - poly[b]).norm());
      RGB sum = RGB::Zero();
      for (int j = 0; j < n; ++j) {
        const double f = M(p, j);
        if (!(f > 0)) continue;
        const double d = (g.centroid[j] - g.centroid[p]).norm();
        const double variation = d > diam ? diam / d : 1.0;
        sum += f * variation * radiance.row(j).transpose().array();
      }
      ind[p] = (rho * sum).maxCoeff() / scale;
    }
  });
  return ind;
}

AdaptiveResult solve_adaptive(const mesh::PolygonSoup& input, const AdaptiveOptions& options) {
  if (options.max_patches < 1)
    throw InputError("adaptive refinement: max_patches must be >= 1, got " + std::to_string(options.max_patches));
  if (!(options.mark_fraction > 0 && options.mark_fraction <= 1))
    throw InputError("adaptive refinement: mark_fraction must be in (0, 1], got " +
                     std::to_string(options.mark_fraction));
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

  // New corners are welded by exact position to any vertex already there (the input's first copy).
  std::map<std::array<double, 3>, int> vertex_at;
  auto add_vertex = [&](mesh::PolygonSoup& s, const Vec3& x) {
    auto [it, added] = vertex_at.try_emplace({x.x(), x.y(), x.z()}, static_cast<int>(s.positions.size()));
    if (added) {
      s.positions.push_back(x);
      s.position_lines.push_back(0);
    }
    return it->second;
  };

  ColorField guess;                       // previous radiance mapped to the current patches
  formfactor::DenseMatrixOperator F_old;  // previous round's matrix
  mesh::PatchGeometry g_old;
  std::vector<int> kept_from;             // per face of `soup`: its face in the previous round, -1 if new
  for (int round = 0;; ++round) {
    mesh::Scene scene = mesh::build_scene(soup);
    if (scene.patches() != static_cast<int>(soup.faces.size())) {
      // build_scene triangulated non-planar faces: continue on its patches (only in round 0, since
      // splits of planar faces are planar).
      soup = soup_from_scene(soup, scene);
      scene = mesh::build_scene(soup);
      kept_from.clear();
      vertex_at.clear();
    }
    const int n = scene.patches();
    if (round == 0) {
      if (n > options.max_patches)
        throw InputError(input.file + ": " + std::to_string(n) + " patches before refinement, above max_patches = " +
                         std::to_string(options.max_patches));
    }
    if (vertex_at.empty())
      for (size_t v = 0; v < soup.positions.size(); ++v)
        vertex_at.try_emplace({soup.positions[v].x(), soup.positions[v].y(), soup.positions[v].z()},
                              static_cast<int>(v));
    result.patches_per_round.push_back(n);
    AdaptiveRound info;
    info.patches = n;
    info.pairs_total = static_cast<long long>(n) * (n - 1) / 2;

    // Reuse: a kept face's patch must have exactly its old polygon (checked, not assumed).
    formfactor::Options ffo = options.ff;
    formfactor::Reuse reuse;
    if (options.reuse && static_cast<int>(kept_from.size()) == n && F_old.size() == g_old.size()) {
      reuse.previous = &F_old;
      reuse.previous_index.assign(n, -1);
      for (int p = 0; p < n; ++p) {
        const int q = kept_from[p];
        if (q < 0) continue;
        const auto a = scene.geometry.polygon(p), b = g_old.polygon(q);
        if (a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin())) reuse.previous_index[p] = q;
      }
      ffo.reuse = &reuse;
    } else {
      ffo.reuse = nullptr;
    }
    auto t0 = std::chrono::steady_clock::now();
    formfactor::Stats st;
    formfactor::DenseMatrixOperator F = formfactor::assemble(scene.geometry, ffo, &st);
    info.assemble_seconds = seconds_since(t0);
    info.pairs_reused = st.pairs_reused;
    F_old = formfactor::DenseMatrixOperator();  // free it before the solve

    t0 = std::chrono::steady_clock::now();
    Options so = options.solve;
    so.initial_guess = guess.rows() == n ? guess : ColorField();
    if (so.initial_guess.rows() == n) {
      // A patch that sees nothing (e.g. floor under a block) has L = Le exactly; a parent's value as its
      // start would leave round-off (tiny negative radiances) there.
      const ColorField Le = scene.emission_field();
      for (int p = 0; p < n; ++p)
        if (F.row_sum(p) == 0) so.initial_guess.row(p) = Le.row(p);
    }
    Solution sol = solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field(), so);
    info.solve_seconds = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    std::vector<double> ind = jump_indicator(scene, sol.radiance);
    if (!ind.empty()) info.max_jump = *std::max_element(ind.begin(), ind.end());
    if (options.gather_indicator) {
      const std::vector<double> d = gather_indicator(scene, F, sol.radiance);
      for (int p = 0; p < n; ++p) {
        info.max_gather = std::max(info.max_gather, d[p]);
        ind[p] = std::max(ind[p], d[p]);
      }
    }
    if (options.direct_indicator) {
      const std::vector<double> d = direct_indicator(scene, sol.radiance);
      for (int p = 0; p < n; ++p) {
        info.max_direct = std::max(info.max_direct, d[p]);
        ind[p] = std::max(ind[p], d[p]);
      }
    }
    info.indicator_seconds = seconds_since(t0);
    result.max_indicator.push_back(std::max({info.max_jump, info.max_direct, info.max_gather}));

    // Global estimate: the area-weighted L2 size of the local indicators against that of the reflected
    // radiance (both relative to its maximum, so the scale cancels).
    const ColorField R = sol.radiance - scene.emission_field();
    const double rscale = R.maxCoeff();
    std::vector<double> weight(n, 0.0);  // A_p eta_p^2: patch p's share of the estimated squared error
    double total = 0, norm = 0;
    for (int p = 0; p < n; ++p) {
      const double a = scene.geometry.area[p];
      weight[p] = a * ind[p] * ind[p];
      total += weight[p];
      if (rscale > 0) norm += a * std::pow(std::max(0.0, R.row(p).maxCoeff()) / rscale, 2);
    }
    info.error_estimate = norm > 0 ? std::sqrt(total / norm) : 0.0;
    result.error_estimate.push_back(info.error_estimate);
    const bool converged = !(info.error_estimate > options.tolerance);

    // Doerfler marking: the patches with the largest shares until they carry `mark_fraction` of the total.
    std::vector<int> order;
    for (int p = 0; p < n; ++p)
      if (weight[p] > 0) order.push_back(p);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return weight[a] > weight[b]; });
    std::vector<char> split(n, 0);
    int count = n, chosen = 0, marked = 0;
    long not_splittable = 0;
    double covered = 0;
    for (int p : order) {
      if (converged || covered >= options.mark_fraction * total) break;
      ++marked;
      const auto poly = scene.geometry.polygon(p);
      const int m = static_cast<int>(poly.size());
      if (m > 3 && !convex(poly, scene.geometry.normal[p])) {
        ++not_splittable;
        continue;
      }
      if (count + added_by_split(poly) > options.max_patches) continue;
      count += added_by_split(poly);
      split[p] = 1;
      covered += weight[p];
      ++chosen;
    }
    result.not_splittable = not_splittable;
    info.marked = marked;
    info.split = chosen;
    result.rounds.push_back(info);

    const bool last = converged || chosen == 0 || round == options.max_rounds;
    if (last) {
      result.stop = converged ? "converged" : chosen == 0 ? "budget" : "max_rounds";
      result.soup = std::move(soup);
      result.scene = std::move(scene);
      result.solution = std::move(sol);
      break;
    }

    // Split the marked faces; children take their parent's place and its radiance as a start.
    mesh::PolygonSoup next = soup;
    next.faces.clear();
    next.position_lines.resize(next.positions.size(), 0);
    // 0.5 (a + b) is symmetric in a and b, so both faces of an edge compute the same point.
    auto mid = [&](int a, int b) { return add_vertex(next, 0.5 * (next.positions[a] + next.positions[b])); };
    std::vector<int> parent;
    kept_from.clear();
    for (int p = 0; p < n; ++p) {
      const mesh::SoupFace& f = soup.faces[p];
      if (!split[p]) {
        next.faces.push_back(f);
        parent.push_back(p);
        kept_from.push_back(p);
        continue;
      }
      const std::vector<int>& v = f.vertices;
      const int m = static_cast<int>(v.size());
      std::vector<int> e(m, -1);  // e[i]: midpoint of edge (i, i+1), where used
      const int halve = long_quad(scene.geometry.polygon(p));
      for (int i = 0; i < m; ++i)
        if (halve == 0 || (halve == 1) == (i % 2 == 0)) e[i] = mid(v[i], v[(i + 1) % m]);
      std::vector<std::vector<int>> children;
      if (halve == 1) {
        children = {{v[0], e[0], e[2], v[3]}, {e[0], v[1], v[2], e[2]}};
      } else if (halve == 2) {
        children = {{v[0], v[1], e[1], e[3]}, {e[3], e[1], v[2], v[3]}};
      } else if (m == 3) {
        children = {{v[0], e[0], e[2]}, {e[0], v[1], e[1]}, {e[2], e[1], v[2]}, {e[0], e[1], e[2]}};
      } else {
        Vec3 c = Vec3::Zero();
        for (int i : v) c += next.positions[i];
        const int ci = add_vertex(next, c / m);
        for (int i = 0; i < m; ++i) children.push_back({v[i], e[i], ci, e[(i + m - 1) % m]});
      }
      for (auto& cv : children) {
        mesh::SoupFace child = f;
        child.vertices = std::move(cv);
        next.faces.push_back(std::move(child));
        parent.push_back(p);
        kept_from.push_back(-1);
      }
    }
    guess.resize(static_cast<Eigen::Index>(parent.size()), 3);
    for (size_t k = 0; k < parent.size(); ++k) guess.row(static_cast<Eigen::Index>(k)) = sol.radiance.row(parent[k]);
    if (options.reuse) {
      F_old = std::move(F);
      g_old = scene.geometry;
    }
    soup = std::move(next);
  }
  result.seconds = seconds_since(start);
  return result;
}

}  // namespace lambert::solver
