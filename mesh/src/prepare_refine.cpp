// mesh::prepare, refinement to a maximum edge length (method and reasons in prepare.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include "cdt_ties.hpp"
#include "prepare_internal.hpp"
#include "triangulate_internal.hpp"
#include "union_find.hpp"

namespace lambert::mesh::detail {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
using Fb = CGAL::Triangulation_face_base_with_info_2<int, K, CGAL::Constrained_triangulation_face_base_2<K>>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
  return lo << 32 | hi;
}

double orient2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// Orthonormal (u, v) with u x v = n, u along the first edge.
void plane_basis(const std::vector<Vec3>& poly, const Vec3& n, Vec3& u, Vec3& v) {
  u = poly[1] - poly[0];
  u -= u.dot(n) * n;
  if (!(u.norm() > 0)) u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n);
  u.normalize();
  v = n.cross(u);
}

enum class Kind { Skip, Tri, Quad, Poly, NonPlanar };

using detail::UnionFind;

// Longest-edge (Rivara LEPP) bisection of a planar triangle mesh until every edge is <= limit.
// Edges on the outer boundary must already be <= limit (they are never split).
class Bisection {
 public:
  Bisection(std::vector<Vec3>& pts, std::vector<std::array<int, 3>>& tris) : pts_(pts), tris_(tris) {
    for (int t = 0; t < static_cast<int>(tris_.size()); ++t) link(t);
  }

  // False if the refinement would have to split a boundary edge or runs away (should not happen).
  bool run(double limit, long max_splits) {
    const double limit2 = limit * limit;
    long splits = 0;
    for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
      while (len2(tris_[t], longest(t)) > limit2) {
        if (broken_ || ++splits > max_splits) return false;
        // Walk to the terminal edge: the longest edge of both triangles sharing it.
        int cur = t;
        for (;;) {
          const int k = longest(cur);
          const int a = tris_[cur][k], b = tris_[cur][(k + 1) % 3];
          const auto found = edges_.find(edge_key(a, b));
          if (found == edges_.end()) return false;
          const auto& side = found->second;
          const int nb = side[0] == cur ? side[1] : side[0];
          if (nb < 0) return false;
          const int kn = longest(nb);
          if (edge_key(tris_[nb][kn], tris_[nb][(kn + 1) % 3]) == edge_key(a, b)) {
            split(a, b, cur, nb);
            break;
          }
          cur = nb;
        }
      }
    }
    return !broken_;
  }

 private:
  double len2(const std::array<int, 3>& t, int k) const { return (pts_[t[(k + 1) % 3]] - pts_[t[k]]).squaredNorm(); }

  // Index k of the longest edge (t[k], t[k+1]); ties broken by vertex indices so that the
  // longest-edge relation is a strict order and the propagation path terminates.
  int longest(int t) const {
    const auto& tri = tris_[t];
    int best = 0;
    for (int k = 1; k < 3; ++k) {
      const double lk = len2(tri, k), lb = len2(tri, best);
      if (lk > lb || (lk == lb && edge_key(tri[k], tri[(k + 1) % 3]) > edge_key(tri[best], tri[(best + 1) % 3])))
        best = k;
    }
    return best;
  }

  void link(int t) {
    for (int k = 0; k < 3; ++k) {
      auto [it, fresh] = edges_.try_emplace(edge_key(tris_[t][k], tris_[t][(k + 1) % 3]), std::array<int, 2>{-1, -1});
      // A third triangle on an edge: not a manifold triangulation (a degenerate, self-touching input
      // polygon found by fuzzing); refinement gives up on this face instead of corrupting memory.
      if (it->second[0] >= 0 && it->second[1] >= 0) broken_ = true;
      (it->second[0] < 0 ? it->second[0] : it->second[1]) = t;
    }
  }
  void unlink(int t) {
    for (int k = 0; k < 3; ++k) {
      const auto it = edges_.find(edge_key(tris_[t][k], tris_[t][(k + 1) % 3]));
      if (it == edges_.end()) {
        broken_ = true;
        continue;
      }
      auto& side = it->second;
      if (side[0] == t) side[0] = side[1];
      side[1] = -1;
      if (side[0] < 0) edges_.erase(it);
    }
  }

  // Splits edge (a, b) at its midpoint in both triangles, keeping their winding.
  void split(int a, int b, int t1, int t2) {
    const int m = static_cast<int>(pts_.size());
    pts_.push_back(0.5 * (pts_[a] + pts_[b]));
    unlink(t1);
    unlink(t2);
    for (int t : {t1, t2}) {
      const auto tri = tris_[t];
      int k = 0;
      while (k < 3 && edge_key(tri[k], tri[(k + 1) % 3]) != edge_key(a, b)) ++k;
      if (k == 3) {
        broken_ = true;
        return;
      }
      const int p = tri[k], q = tri[(k + 1) % 3], r = tri[(k + 2) % 3];
      tris_[t] = {p, m, r};
      tris_.push_back({m, q, r});
      link(t);
      link(static_cast<int>(tris_.size()) - 1);
    }
  }

  std::vector<Vec3>& pts_;
  std::vector<std::array<int, 3>>& tris_;
  bool broken_ = false;
  std::unordered_map<std::uint64_t, std::array<int, 2>> edges_;
};

class Refiner {
 public:
  Refiner(PolygonSoup& s, double max_edge, long long max_patches) : s_(s), L_(max_edge), max_patches_(max_patches) {}

  void run(Report& report) {
    const int nf = static_cast<int>(s_.faces.size());
    classify();
    // Pieces per edge class: ceil(length / L), ignoring excess below 1e-13 relative (2.7 / 0.3). In
    // double first: the count can exceed an int (1e-9 m pieces of a 10 m edge), which the estimate refuses.
    std::vector<double> count(uf_.parent.size(), 1);
    for (int e = 0; e < static_cast<int>(ends_.size()); ++e) {
      const double len = (s_.positions[ends_[e][1]] - s_.positions[ends_[e][0]]).norm();
      const double n = std::max(1.0, std::ceil(len / L_ * (1 - 1e-13)));
      count[uf_.find(e)] = std::max(count[uf_.find(e)], n);
    }
    std::vector<double> split(ends_.size());
    for (int e = 0; e < static_cast<int>(ends_.size()); ++e) split[e] = count[uf_.find(e)];
    std::vector<char> refined(nf, 0);
    for (int k = 0; k < nf; ++k) {
      if (kind_[k] == Kind::Skip) continue;
      for (int e : face_edges_[k]) refined[k] |= split[e] > 1;
      if (s_.faces[k].vertices.size() >= 5) refined[k] |= diameter(k) > 2 * L_;
    }
    check_estimate(estimate(split, refined));
    pieces_.assign(split.begin(), split.end());
    // Edge points, shared by all faces on the edge (vertex indices from the lower to the higher end).
    points_.resize(ends_.size());
    for (int e = 0; e < static_cast<int>(ends_.size()); ++e) {
      const int a = ends_[e][0], b = ends_[e][1], n = pieces_[e];
      points_[e].push_back(a);
      for (int i = 1; i < n; ++i)
        points_[e].push_back(add_point(s_.positions[a] + (double(i) / n) * (s_.positions[b] - s_.positions[a])));
      points_[e].push_back(b);
    }

    std::vector<SoupFace> out;
    out.reserve(s_.faces.size());
    std::vector<int> refined_ids, failed_ids;
    long refined_faces = 0;
    for (int k = 0; k < nf; ++k) {
      const SoupFace& f = s_.faces[k];
      if (!refined[k]) {
        out.push_back(f);
        continue;
      }
      std::vector<std::vector<int>> pieces;
      bool ok = true;
      const auto& c = f.vertices;
      switch (kind_[k]) {
        case Kind::Quad: grid(c, pieces); break;
        case Kind::Tri: ok = triangle(c, pieces); break;
        case Kind::Poly: ok = general(boundary(c), pieces); break;
        case Kind::NonPlanar:
          for (const auto& t : tris_[k]) ok = ok && triangle({c[t[0]], c[t[1]], c[t[2]]}, pieces);
          break;
        case Kind::Skip: break;
      }
      if (!ok) {
        failed_ids.push_back(origin_of(s_, k));
        out.push_back(f);
        continue;
      }
      ++refined_faces;
      refined_ids.push_back(origin_of(s_, k));
      for (auto& p : pieces) {
        SoupFace piece = f;
        piece.vertices = std::move(p);
        out.push_back(std::move(piece));
      }
    }
    const long added = static_cast<long>(out.size()) - nf;
    s_.faces = std::move(out);
    report.counts["faces_refined"] += 0;
    report.counts["patches_added"] += 0;
    if (refined_faces > 0) {
      report.counts["patches_added"] += added;
      report.warn("faces_refined", refined_faces,
                  std::to_string(refined_faces) + " face" + (refined_faces == 1 ? " was" : "s were") +
                      " refined to edges of at most " + num(L_) + " m (" + std::to_string(added) +
                      " patches added): input face" + (refined_ids.size() == 1 ? " " : "s ") + id_list(refined_ids));
    }
    if (!failed_ids.empty())
      report.warn("faces_not_refined", static_cast<long>(failed_ids.size()),
                  std::to_string(failed_ids.size()) + " face" + (failed_ids.size() == 1 ? "" : "s") +
                      " could not be refined and keep their size: input face" +
                      (failed_ids.size() == 1 ? " " : "s ") + id_list(failed_ids));
  }

 private:
  int edge(int a, int b) {
    const auto [it, fresh] = edge_id_.try_emplace(edge_key(a, b), static_cast<int>(ends_.size()));
    if (fresh) {
      ends_.push_back({std::min(a, b), std::max(a, b)});
      uf_.add();
    }
    return it->second;
  }

  // Vertex indices along edge (a, b), from a to b inclusive.
  std::vector<int> path(int a, int b) const {
    std::vector<int> p = points_[edge_id_.at(edge_key(a, b))];
    if (a > b) std::reverse(p.begin(), p.end());
    return p;
  }

  int add_point(const Vec3& p) {
    if (s_.position_lines.size() == s_.positions.size()) s_.position_lines.push_back(0);
    s_.positions.push_back(p);
    return static_cast<int>(s_.positions.size()) - 1;
  }

  double diameter(int k) const {
    const auto& fv = s_.faces[k].vertices;
    double d2 = 0;
    for (size_t i = 0; i < fv.size(); ++i)
      for (size_t j = i + 1; j < fv.size(); ++j)
        d2 = std::max(d2, (s_.positions[fv[i]] - s_.positions[fv[j]]).squaredNorm());
    return std::sqrt(d2);
  }

  // Patches after refinement: exact for quad grids (n x m) and uniformly split triangles (n^2); other
  // faces from their area (the lattice of spacing L has ~2 / (sqrt(3) / 2 L^2) triangles per unit area,
  // bisection adds some) plus their boundary pieces.
  double estimate(const std::vector<double>& pieces, const std::vector<char>& refined) const {
    double total = 0;
    for (int k = 0; k < static_cast<int>(s_.faces.size()); ++k) {
      if (!refined[k]) {
        total += 1;
        continue;
      }
      const auto& fe = face_edges_[k];
      if (kind_[k] == Kind::Quad) {
        total += pieces[fe[0]] * pieces[fe[1]];
      } else if (kind_[k] == Kind::Tri && pieces[fe[0]] == pieces[fe[1]] && pieces[fe[1]] == pieces[fe[2]]) {
        total += pieces[fe[0]] * pieces[fe[0]];
      } else {
        const double area = 0.5 * newell_normal(corners(s_, k)).norm();
        double boundary = 0;
        for (size_t i = 0; i < s_.faces[k].vertices.size() && i < fe.size(); ++i) boundary += pieces[fe[i]];
        total += 2.0 * area / (std::sqrt(3.0) / 2 * L_ * L_) + boundary;
      }
    }
    return total;
  }

  void check_estimate(double patches) const {
    const double int_max = double(std::numeric_limits<int>::max());
    const double limit = max_patches_ > 0 ? std::min(double(max_patches_), int_max) : int_max;
    if (patches <= limit) return;
    // Patches scale as 1 / L^2 (area-dominated): the L that would give the limit.
    const double fits = L_ * std::sqrt(patches / limit);
    throw InputError("refinement to edges of at most " + num(L_) + " m (--max-edge) would make about " + num(patches) +
                     " patches, more than the " + num(limit) +
                     (max_patches_ > 0 ? " whose form factors fit in memory" : " a patch index can count") +
                     "; refused before refining: use a larger --max-edge (about " + num(fits) + " m or more)");
  }

  void classify() {
    const int nf = static_cast<int>(s_.faces.size());
    const double planarity = BuildOptions{}.planarity_tolerance;
    kind_.assign(nf, Kind::Skip);
    tris_.assign(nf, {});
    face_edges_.assign(nf, {});
    for (int k = 0; k < nf; ++k) {
      if (!usable_face(s_, k)) continue;
      const auto& c = s_.faces[k].vertices;
      const int m = static_cast<int>(c.size());
      const auto poly = corners(s_, k);
      const Vec3 nn = newell_normal(poly);
      for (int i = 0; i < m; ++i) face_edges_[k].push_back(edge(c[i], c[(i + 1) % m]));
      if (m == 3) {
        kind_[k] = Kind::Tri;
        continue;
      }
      if (planarity_deviation(poly) > planarity * std::sqrt(0.5 * nn.norm())) {
        // As build_scene would: its triangles, whose diagonals become edges too.
        kind_[k] = Kind::NonPlanar;
        tris_[k] = triangulate_polygon(poly, nn.normalized());
        for (const auto& t : tris_[k])
          for (int i = 0; i < 3; ++i) face_edges_[k].push_back(edge(c[t[i]], c[t[(i + 1) % 3]]));
        continue;
      }
      kind_[k] = Kind::Poly;
      if (m == 4) {
        Vec3 u, v;
        plane_basis(poly, nn.normalized(), u, v);
        std::array<Eigen::Vector2d, 4> q;
        double scale = 0;
        for (int i = 0; i < 4; ++i) {
          q[i] = {(poly[i] - poly[0]).dot(u), (poly[i] - poly[0]).dot(v)};
          scale = std::max(scale, q[i].cwiseAbs().maxCoeff());
        }
        bool convex = true;
        for (int i = 0; i < 4; ++i) convex = convex && orient2(q[i], q[(i + 1) % 4], q[(i + 2) % 4]) > 1e-9 * scale * scale;
        if (convex) {
          kind_[k] = Kind::Quad;
          uf_.unite(face_edges_[k][0], face_edges_[k][2]);  // opposite edges: same number of pieces
          uf_.unite(face_edges_[k][1], face_edges_[k][3]);
        }
      }
    }
  }

  // Split boundary of a polygon: its corners and every edge point, in winding order.
  std::vector<int> boundary(const std::vector<int>& c) const {
    std::vector<int> loop;
    for (size_t i = 0; i < c.size(); ++i) {
      const auto p = path(c[i], c[(i + 1) % c.size()]);
      loop.insert(loop.end(), p.begin(), p.end() - 1);
    }
    return loop;
  }

  // Bilinear n x m grid of a planar convex quad: straight grid lines, so the cells tile it exactly.
  void grid(const std::vector<int>& c, std::vector<std::vector<int>>& pieces) {
    const auto bottom = path(c[0], c[1]), top = path(c[3], c[2]), left = path(c[0], c[3]), right = path(c[1], c[2]);
    const int n = static_cast<int>(bottom.size()) - 1, m = static_cast<int>(left.size()) - 1;
    // Copies: add_point reallocates the positions.
    const Vec3 p0 = s_.positions[c[0]], p1 = s_.positions[c[1]], p2 = s_.positions[c[2]], p3 = s_.positions[c[3]];
    std::vector<std::vector<int>> g(n + 1, std::vector<int>(m + 1));
    for (int j = 0; j <= m; ++j)
      for (int i = 0; i <= n; ++i) {
        if (j == 0) g[i][j] = bottom[i];
        else if (j == m) g[i][j] = top[i];
        else if (i == 0) g[i][j] = left[j];
        else if (i == n) g[i][j] = right[j];
        else {
          const double x = double(i) / n, y = double(j) / m;
          g[i][j] = add_point((1 - x) * (1 - y) * p0 + x * (1 - y) * p1 + x * y * p2 + (1 - x) * y * p3);
        }
      }
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < n; ++i) pieces.push_back({g[i][j], g[i + 1][j], g[i + 1][j + 1], g[i][j + 1]});
  }

  // A triangle: uniform k^2 split when its three edges have k pieces each, else the general mesher.
  bool triangle(const std::vector<int>& c, std::vector<std::vector<int>>& pieces) {
    const auto ab = path(c[0], c[1]), ac = path(c[0], c[2]), bc = path(c[1], c[2]);
    const int k = static_cast<int>(ab.size()) - 1;
    if (static_cast<int>(ac.size()) - 1 != k || static_cast<int>(bc.size()) - 1 != k) return general(boundary(c), pieces);
    const Vec3 A = s_.positions[c[0]], B = s_.positions[c[1]], C = s_.positions[c[2]];  // copies, as in grid()
    std::vector<std::vector<int>> P(k + 1);
    for (int i = 0; i <= k; ++i) {
      P[i].resize(k + 1 - i);
      for (int j = 0; i + j <= k; ++j) {
        if (j == 0) P[i][j] = ab[i];
        else if (i == 0) P[i][j] = ac[j];
        else if (i + j == k) P[i][j] = bc[j];
        else P[i][j] = add_point(A + (double(i) / k) * (B - A) + (double(j) / k) * (C - A));
      }
    }
    for (int j = 0; j < k; ++j)
      for (int i = 0; i + j < k; ++i) {
        pieces.push_back({P[i][j], P[i + 1][j], P[i][j + 1]});
        if (i + j + 1 < k) pieces.push_back({P[i + 1][j], P[i + 1][j + 1], P[i][j + 1]});
      }
    return true;
  }

  // Planar simple polygon given by its split boundary (every segment <= L): boundary plus an
  // equilateral lattice of spacing ~L kept >= L/2 from the boundary, constrained Delaunay, then
  // longest-edge bisection of interior edges longer than L. False if a check fails.
  bool general(const std::vector<int>& loop, std::vector<std::vector<int>>& pieces) {
    const int nb = static_cast<int>(loop.size());
    std::vector<Vec3> pts;
    for (int v : loop) pts.push_back(s_.positions[v]);
    const Vec3 nn = newell_normal(pts);
    const Vec3 n = nn.normalized();
    Vec3 u, v;
    plane_basis(pts, n, u, v);
    const Vec3 o = pts[0];
    std::vector<Eigen::Vector2d> q(nb);
    Eigen::AlignedBox2d box;
    for (int i = 0; i < nb; ++i) {
      q[i] = {(pts[i] - o).dot(u), (pts[i] - o).dot(v)};
      box.extend(q[i]);
    }
    // Lattice strictly inside, by scanline crossings; boundary segments bucketed for the margin test.
    const double h = L_ * (1 - 1e-9), margin = 0.5 * h, dy = h * std::sqrt(3.0) / 2;
    std::unordered_map<std::uint64_t, std::vector<int>> buckets;
    auto cell_key = [&](long ix, long iy) {
      return static_cast<std::uint64_t>(ix + (1L << 30)) << 32 | static_cast<std::uint64_t>(iy + (1L << 30));
    };
    auto cell_of = [&](double x) { return static_cast<long>(std::floor(x / h)); };
    for (int i = 0; i < nb; ++i) {
      const auto &a = q[i], &b = q[(i + 1) % nb];
      for (long ix = cell_of(std::min(a.x(), b.x()) - margin); ix <= cell_of(std::max(a.x(), b.x()) + margin); ++ix)
        for (long iy = cell_of(std::min(a.y(), b.y()) - margin); iy <= cell_of(std::max(a.y(), b.y()) + margin); ++iy)
          buckets[cell_key(ix, iy)].push_back(i);
    }
    auto near_boundary = [&](const Eigen::Vector2d& p) {
      const auto it = buckets.find(cell_key(cell_of(p.x()), cell_of(p.y())));
      if (it == buckets.end()) return false;
      for (int i : it->second) {
        const Eigen::Vector2d a = q[i], d = q[(i + 1) % nb] - a;
        const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
        if ((a + t * d - p).norm() < margin) return true;
      }
      return false;
    };
    std::vector<Eigen::Vector2d> lattice;
    std::vector<double> xs;
    for (long j = static_cast<long>(std::floor(box.min().y() / dy)); j * dy <= box.max().y(); ++j) {
      const double y = j * dy, x0 = (j & 1) ? 0.5 * h : 0.0;
      xs.clear();
      for (int i = 0; i < nb; ++i) {
        const auto &a = q[i], &b = q[(i + 1) % nb];
        if ((a.y() > y) != (b.y() > y)) xs.push_back(a.x() + (y - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
      }
      std::sort(xs.begin(), xs.end());
      for (size_t t = 0; t + 1 < xs.size(); t += 2)
        for (long i = static_cast<long>(std::ceil((xs[t] - x0) / h)); x0 + i * h < xs[t + 1]; ++i) {
          const Eigen::Vector2d p(x0 + i * h, y);
          if (!near_boundary(p)) lattice.push_back(p);
        }
    }
    // Constrained Delaunay triangulation; info = local point index (boundary first).
    CDT cdt;
    std::vector<CDT::Vertex_handle> vh(nb);
    for (int i = 0; i < nb; ++i) {
      vh[i] = cdt.insert(K::Point_2(q[i].x(), q[i].y()));
      vh[i]->info() = i;
    }
    CDT::Face_handle hint;
    for (size_t i = 0; i < lattice.size(); ++i) {
      const auto w = cdt.insert(K::Point_2(lattice[i].x(), lattice[i].y()), hint);
      w->info() = nb + static_cast<int>(i);
      hint = w->face();
    }
    for (int i = 0; i < nb; ++i) cdt.insert_constraint(vh[i], vh[(i + 1) % nb]);
    if (cdt.number_of_vertices() != static_cast<size_t>(nb) + lattice.size()) return false;
    // Every vertex must be one inserted above (a self-touching boundary can merge one point and add an
    // intersection point, keeping the count): its index in range and its point the one inserted there.
    for (auto w : cdt.finite_vertex_handles()) {
      const int i = w->info();
      if (i < 0 || i >= nb + static_cast<int>(lattice.size())) return false;
      const Eigen::Vector2d& at = i < nb ? q[i] : lattice[size_t(i - nb)];
      if (w->point() != K::Point_2(at.x(), at.y())) return false;
    }
    settle_cocircular_ties(cdt);  // near-ties decided as exact ties (cdt_ties.hpp)
    // Inside = odd number of constraints crossed from the infinite face.
    mark_nesting_levels(cdt);
    std::vector<std::array<int, 3>> tris;
    for (auto f : cdt.finite_face_handles())
      if (f->info() % 2 == 1) tris.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
    tris = canonical_triangles(std::move(tris));
    for (const auto& p : lattice) pts.push_back(o + p.x() * u + p.y() * v);
    Bisection bisect(pts, tris);
    const double area = 0.5 * nn.norm();
    if (!bisect.run(L_ * (1 + 1e-12), 20 * static_cast<long>(tris.size() + area / (L_ * L_)) + 1000)) return false;
    // The pieces must tile the polygon (checks the inside marking and the bisection).
    double sum = 0;
    for (const auto& t : tris) sum += 0.5 * (pts[t[1]] - pts[t[0]]).cross(pts[t[2]] - pts[t[0]]).dot(n);
    if (!(std::abs(sum - area) <= 1e-9 * area)) return false;
    std::vector<int> global(pts.size());
    for (int i = 0; i < nb; ++i) global[i] = loop[i];
    for (size_t i = nb; i < pts.size(); ++i) global[i] = add_point(pts[i]);
    for (const auto& t : tris) pieces.push_back({global[t[0]], global[t[1]], global[t[2]]});
    return true;
  }

  PolygonSoup& s_;
  double L_;
  long long max_patches_;
  std::vector<Kind> kind_;
  std::vector<std::vector<std::array<int, 3>>> tris_;  // NonPlanar: triangulation (corner indices)
  std::vector<std::vector<int>> face_edges_;           // edge ids of each face (and its diagonals)
  std::unordered_map<std::uint64_t, int> edge_id_;
  std::vector<std::array<int, 2>> ends_;  // edge id -> (lower, higher) vertex
  UnionFind uf_;                          // edge classes that must get the same number of pieces
  std::vector<int> pieces_;
  std::vector<std::vector<int>> points_;  // edge id -> vertex indices from lower to higher end
};

}  // namespace

void refine(PolygonSoup& soup, double max_edge, Report& report, long long max_patches) {
  Refiner(soup, max_edge, max_patches).run(report);
}

}  // namespace lambert::mesh::detail
