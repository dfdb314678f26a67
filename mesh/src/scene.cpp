#include "lambert/mesh/scene.hpp"
#include "triangulate_internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <OpenMesh/Core/System/omstream.hh>

namespace lambert::mesh {

void Report::warn(const std::string& key, long count, const std::string& message) {
  counts[key] += count;
  warnings.push_back(message);
}

namespace {

std::vector<char> used_materials(const Scene& s) {
  std::vector<char> used(s.materials.size(), 0);
  for (int m : s.material) used[m] = 1;
  return used;
}

}  // namespace

bool Scene::grey() const {
  // Only materials that some patch uses decide how many channels the solver needs.
  const auto used = used_materials(*this);
  for (size_t m = 0; m < materials.size(); ++m) {
    if (!used[m]) continue;
    const RGB& r = materials[m].reflectance;
    const RGB& e = materials[m].emission;
    if (r[0] != r[1] || r[0] != r[2] || e[0] != e[1] || e[0] != e[2]) return false;
  }
  return true;
}

RGB Scene::emitted_power() const {
  RGB sum = RGB::Zero();
  for (int p = 0; p < patches(); ++p) sum += geometry.area[p] * emission(p);
  return std::numbers::pi * sum;
}

ColorField Scene::reflectance_field() const {
  ColorField f(patches(), 3);
  for (int p = 0; p < patches(); ++p) f.row(p) = reflectance(p).matrix().transpose();
  return f;
}

ColorField Scene::emission_field() const {
  ColorField f(patches(), 3);
  for (int p = 0; p < patches(); ++p) f.row(p) = emission(p).matrix().transpose();
  return f;
}

namespace {

std::string num(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

std::string vec(const Eigen::Ref<const Eigen::Vector3d>& v) {
  std::string s = "(";  // appended, not "(" + ...: avoids a GCC 12 -Wrestrict false positive
  s += num(v[0]) + ", " + num(v[1]) + ", " + num(v[2]) + ")";
  return s;
}

// Input face index of soup face k (mesh::prepare may have split or dropped faces).
int input_face(const PolygonSoup& s, int k) { return s.faces[k].origin >= 0 ? s.faces[k].origin : k; }

// "scene.obj:12: face 5" (input face indices are 0-based, in file order).
std::string face_at(const PolygonSoup& s, int k) {
  return SourceLoc{s.file, s.faces[k].line}.str() + ": face " + std::to_string(input_face(s, k));
}

std::string vertex_at(const PolygonSoup& s, int v) {
  const int line = v < static_cast<int>(s.position_lines.size()) ? s.position_lines[v] : 0;
  return "vertex " + std::to_string(v) + (line > 0 ? " (" + SourceLoc{s.file, line}.str() + ")" : "");
}

[[noreturn]] void fail(const std::string& msg) { throw InputError(msg); }

double orient2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// c lies on segment [a, b], given that a, b, c are collinear within eps.
bool within(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return std::min(a.x(), b.x()) <= c.x() && c.x() <= std::max(a.x(), b.x()) &&
         std::min(a.y(), b.y()) <= c.y() && c.y() <= std::max(a.y(), b.y());
}

bool segments_touch(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2, const Eigen::Vector2d& p3,
                    const Eigen::Vector2d& p4, double eps) {
  const double d1 = orient2(p3, p4, p1), d2 = orient2(p3, p4, p2);
  const double d3 = orient2(p1, p2, p3), d4 = orient2(p1, p2, p4);
  if (((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps)) &&
      ((d3 > eps && d4 < -eps) || (d3 < -eps && d4 > eps)))
    return true;
  return (std::abs(d1) <= eps && within(p3, p4, p1)) || (std::abs(d2) <= eps && within(p3, p4, p2)) ||
         (std::abs(d3) <= eps && within(p1, p2, p3)) || (std::abs(d4) <= eps && within(p1, p2, p4));
}

// True when the polygon, projected on the plane with unit normal n, crosses or touches itself
// (non-adjacent edges meet, or an edge folds back onto the previous one). Zero-length edges
// (consecutive corners at the same position) are ignored: they do not change the shape.
bool self_intersecting(const std::vector<Vec3>& poly, const Vec3& n) {
  const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 v = n.cross(u);
  std::vector<Eigen::Vector2d> q;
  q.reserve(poly.size());
  for (size_t k = 0; k < poly.size(); ++k) {
    if (poly[k] == poly[(k + 1) % poly.size()]) continue;
    const Vec3 d = poly[k] - poly[0];
    q.emplace_back(d.dot(u), d.dot(v));
  }
  const int m = static_cast<int>(q.size());
  if (m < 3) return true;
  double scale = 0;
  for (auto& p : q) scale = std::max(scale, p.cwiseAbs().maxCoeff());
  const double eps = 1e-12 * scale * scale;
  for (int i = 0; i < m; ++i) {
    const auto &a = q[(i + m - 1) % m], &b = q[i], &c = q[(i + 1) % m];
    if (std::abs(orient2(a, b, c)) <= eps && (b - a).dot(c - b) < 0) return true;  // spike
  }
  if (m == 3) return false;
  // Large polygons: the pairwise edge test is O(m^2); CGAL's constrained triangulation (exact predicates,
  // O(m log m)) fails exactly when edges cross or touch.
  if (m > detail::kEarClippingMaxCorners) return detail::triangulate_cdt(q).empty();
  for (int i = 0; i < m; ++i)
    for (int j = i + 2; j < m; ++j) {
      if (i == 0 && j == m - 1) continue;  // adjacent through the wrap-around
      if (segments_touch(q[i], q[i + 1], q[j], q[(j + 1) % m], eps)) return true;
    }
  return false;
}

struct PatchSpec {
  std::vector<int> corners;  // position indices
  int face;
};

void check_material(const PolygonSoup& soup, int m, int first_face) {
  const Material& mat = soup.materials[m];
  const std::string who = "material '" + mat.name + "' (defined at " + mat.defined_at.str() + ", used by " +
                          face_at(soup, first_face) + ")";
  static const char* channel = "RGB";
  for (int c = 0; c < 3; ++c) {
    const double r = mat.reflectance[c];
    if (!(r >= 0 && r < 1)) {
      std::string why = "reflectance " + std::string(1, channel[c]) + " = " + num(r) + " is outside [0, 1)";
      if (r >= 1)
        why += ": a reflectance of 1 or more absorbs nothing, so a closed scene has no steady state";
      fail(who + ": " + why);
    }
    const double t = mat.transmittance[c];
    if (!(t >= 0 && t <= 1))
      fail(who + ": transmittance " + std::string(1, channel[c]) + " = " + num(t) + " is outside [0, 1]");
    if (!(r + t <= 1))
      fail(who + ": reflectance + transmittance " + std::string(1, channel[c]) + " = " + num(r + t) +
           " exceeds 1: the glazing would create light");
    const double e = mat.emission[c];
    if (!(e >= 0) || !std::isfinite(e))
      fail(who + ": emission " + std::string(1, channel[c]) + " = " + num(e) +
           " must be finite and >= 0 (W m^-2 sr^-1)");
  }
}

// Adds the face to the mesh if OpenMesh can keep the surface manifold there (its own add_face
// conditions: every vertex isolated or on the boundary, every existing halfedge still free).
bool can_add(const PolyMesh& mesh, const std::vector<PolyMesh::VertexHandle>& vh) {
  const size_t m = vh.size();
  for (size_t k = 0; k < m; ++k) {
    if (!mesh.is_boundary(vh[k])) return false;
    const auto h = mesh.find_halfedge(vh[k], vh[(k + 1) % m]);
    if (h.is_valid() && !mesh.is_boundary(h)) return false;
  }
  return true;
}

}  // namespace

Scene build_scene(const PolygonSoup& soup, const BuildOptions& options) {
  Scene scene;
  scene.source = soup.file;
  scene.materials = soup.materials;
  scene.groups = soup.groups;
  scene.input_faces = soup.input_faces >= 0 ? soup.input_faces : static_cast<int>(soup.faces.size());
  Report& report = scene.report;
  for (const auto& w : soup.warnings) report.warnings.push_back(w);

  const int nf = static_cast<int>(soup.faces.size());
  const int nv = static_cast<int>(soup.positions.size());
  const int nm = static_cast<int>(soup.materials.size());
  const int ng = static_cast<int>(soup.groups.size());
  if (nf == 0) fail(soup.file + ": no faces");

  // 1. Topology of each face; remember the first face using each material and position.
  std::vector<int> material_first(nm, -1), position_first(nv, -1);
  for (int k = 0; k < nf; ++k) {
    const SoupFace& f = soup.faces[k];
    const int m = static_cast<int>(f.vertices.size());
    if (m < 3)
      fail(face_at(soup, k) + " has " + std::to_string(m) + " corner" + (m == 1 ? "" : "s") +
           " (a polygon needs at least 3)");
    for (int c = 0; c < m; ++c) {
      const int v = f.vertices[c];
      if (v < 0 || v >= nv)
        fail(face_at(soup, k) + ": corner " + std::to_string(c) + " refers to vertex " + std::to_string(v) +
             ", out of range (the file has " + std::to_string(nv) + " vertices, 0-based)");
      if (position_first[v] < 0) position_first[v] = k;
    }
    std::vector<int> sorted = f.vertices;
    std::sort(sorted.begin(), sorted.end());
    const auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end())
      fail(face_at(soup, k) + " uses " + vertex_at(soup, *dup) + " twice (repeated corner)");
    if (f.material < 0 || f.material >= nm)
      fail(face_at(soup, k) + ": material index " + std::to_string(f.material) + " is out of range (" +
           std::to_string(nm) + " materials)");
    if (f.group < -1 || f.group >= ng)
      fail(face_at(soup, k) + ": group index " + std::to_string(f.group) + " is out of range (" +
           std::to_string(ng) + " groups)");
    if (material_first[f.material] < 0) material_first[f.material] = k;
  }

  // 2. Values: materials in use, positions in use.
  for (int m = 0; m < nm; ++m)
    if (material_first[m] >= 0) check_material(soup, m, material_first[m]);
  for (int v = 0; v < nv; ++v)
    if (position_first[v] >= 0 && !soup.positions[v].allFinite())
      fail(SourceLoc{soup.file, v < static_cast<int>(soup.position_lines.size()) ? soup.position_lines[v] : 0}.str() +
           ": vertex " + std::to_string(v) + " has a non-finite coordinate " + vec(soup.positions[v]) +
           " and is used by " + face_at(soup, position_first[v]));

  // 3. Geometry of each face: area, planarity, simplicity. Non-planar faces become triangles.
  std::vector<PatchSpec> specs;
  specs.reserve(nf);
  long nonplanar = 0;
  int worst_k = -1;  // soup face of the worst deviation
  std::vector<Vec3> poly;
  for (int k = 0; k < nf; ++k) {
    const auto& fv = soup.faces[k].vertices;
    const int m = static_cast<int>(fv.size());
    poly.resize(m);
    for (int c = 0; c < m; ++c) poly[c] = soup.positions[fv[c]];
    const Vec3 nn = newell_normal(poly);
    const double area = 0.5 * nn.norm();
    double longest = 0;
    for (int c = 0; c < m; ++c) longest = std::max(longest, (poly[(c + 1) % m] - poly[c]).norm());
    // Relative to the longest edge: round-off leaves ~1e-16 L^2 on a degenerate face.
    if (!(area > 0) || !std::isfinite(area) || area <= 1e-12 * longest * longest)
      fail(face_at(soup, k) + " has zero area (" + num(area) + " m^2, longest edge " + num(longest) +
           " m): its corners are collinear or coincide");
    const Vec3 n = nn / nn.norm();
    if (m == 3) {
      specs.push_back({fv, k});
      continue;
    }
    if (self_intersecting(poly, n))
      fail(face_at(soup, k) + " is self-intersecting (its edges cross or touch); it cannot be triangulated");
    const auto tris = triangulate_polygon(poly, n);
    if (tris.empty()) fail(face_at(soup, k) + " could not be triangulated (degenerate polygon)");
    const double dev = planarity_deviation(poly);
    if (dev > options.planarity_tolerance * std::sqrt(area)) {
      ++nonplanar;
      if (dev > report.worst_nonplanarity) {
        report.worst_nonplanarity = dev;
        report.worst_nonplanar_face = input_face(soup, k);
        worst_k = k;
      }
      // Each triangle's width (its altitude onto its longest edge): ear clipping takes a sliver between corners
      // nearly in a line where it comes first (a cut piece of a wall rounded to single precision: 0.4 m long,
      // 1e-7 m wide, whose form factors divided by its area left [0, 1]). Then the constrained Delaunay
      // triangulation, if its narrowest triangle is wider.
      auto narrowest = [&](const std::vector<std::array<int, 3>>& ts) {
        double w = INFINITY;
        for (const auto& t : ts) {
          const Vec3 &a = poly[t[0]], &b = poly[t[1]], &c = poly[t[2]];
          const double edge = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
          w = std::min(w, (b - a).cross(c - a).norm() / edge);
        }
        return w;
      };
      const std::vector<std::array<int, 3>>* use = &tris;
      std::vector<std::array<int, 3>> delaunay;
      if (narrowest(tris) <= 10 * dev) {
        delaunay = detail::triangulate_polygon_delaunay(poly, n);
        if (delaunay.size() == tris.size() && narrowest(delaunay) > narrowest(tris)) use = &delaunay;
      }
      for (const auto& t : *use) specs.push_back({{fv[t[0]], fv[t[1]], fv[t[2]]}, k});
    } else {
      specs.push_back({fv, k});
    }
  }
  if (nonplanar > 0)
    report.warn("nonplanar_faces_triangulated", nonplanar,
                std::to_string(nonplanar) + " non-planar face" + (nonplanar == 1 ? " was" : "s were") +
                    " split into triangles; worst deviation from the plane " + num(report.worst_nonplanarity) +
                    " m at " + face_at(soup, worst_k));

  // 4. Duplicate vertices: distinct used positions with identical coordinates (kept apart here).
  {
    // The back of a two-sided face has its own copies of the front's vertices: not duplicates.
    std::vector<char> back_only(nv, 0);
    for (const auto& f : soup.faces)
      if (f.side == 1)
        for (int v : f.vertices) back_only[v] = 1;
    for (const auto& f : soup.faces)
      if (f.side != 1)
        for (int v : f.vertices) back_only[v] = 0;
    std::vector<int> used;
    for (int v = 0; v < nv; ++v)
      if (position_first[v] >= 0 && !back_only[v]) used.push_back(v);
    auto less = [&](int a, int b) {
      const Vec3 &p = soup.positions[a], &q = soup.positions[b];
      if (p.x() != q.x()) return p.x() < q.x();
      if (p.y() != q.y()) return p.y() < q.y();
      if (p.z() != q.z()) return p.z() < q.z();
      return a < b;
    };
    std::sort(used.begin(), used.end(), less);
    long dups = 0;
    int ex_a = -1, ex_b = -1;
    for (size_t i = 1; i < used.size(); ++i)
      if (soup.positions[used[i]] == soup.positions[used[i - 1]]) {
        if (dups++ == 0) ex_a = used[i - 1], ex_b = used[i];
      }
    if (dups > 0)
      report.warn("duplicate_vertices", dups,
                  std::to_string(dups) + " vertices duplicate the coordinates of another vertex (e.g. " +
                      vertex_at(soup, ex_a) + " and " + vertex_at(soup, ex_b) + " at " +
                      vec(soup.positions[ex_a]) + "); kept apart: harmless where separate objects only touch, but " +
                      "faces meant to be connected there are not (mesh preparation welds them unless --no-repair)");
  }

  // 5. Orientation: an edge traversed in the same direction by two faces.
  {
    struct Dir {
      std::uint64_t key;
      int face;
    };
    std::vector<Dir> dirs;
    for (int k = 0; k < nf; ++k) {
      const auto& fv = soup.faces[k].vertices;
      for (size_t c = 0; c < fv.size(); ++c) {
        const auto a = static_cast<std::uint64_t>(fv[c]), b = static_cast<std::uint64_t>(fv[(c + 1) % fv.size()]);
        dirs.push_back({a << 32 | b, k});
      }
    }
    std::sort(dirs.begin(), dirs.end(), [](const Dir& x, const Dir& y) {
      return x.key != y.key ? x.key < y.key : x.face < y.face;
    });
    // Only edges that exactly two faces share: where three or more faces meet (a wall standing on a
    // floor line, a partition against a wall, after imprinting) some always run the same way.
    std::map<std::uint64_t, int> uses;
    for (const auto& d : dirs) {
      const std::uint64_t a = d.key >> 32, b = d.key & 0xffffffffu;
      uses[std::min(a, b) << 32 | std::max(a, b)]++;
    }
    auto manifold = [&](std::uint64_t key) {
      const std::uint64_t a = key >> 32, b = key & 0xffffffffu;
      return uses[std::min(a, b) << 32 | std::max(a, b)] == 2;
    };
    std::vector<std::uint64_t> bad;  // undirected keys
    size_t ex = dirs.size();
    for (size_t i = 1; i < dirs.size(); ++i)
      if (dirs[i].key == dirs[i - 1].key && manifold(dirs[i].key)) {
        const std::uint64_t a = dirs[i].key >> 32, b = dirs[i].key & 0xffffffffu;
        bad.push_back(std::min(a, b) << 32 | std::max(a, b));
        if (ex == dirs.size()) ex = i;
      }
    std::sort(bad.begin(), bad.end());
    const long count = std::unique(bad.begin(), bad.end()) - bad.begin();
    if (count > 0) {
      const int a = static_cast<int>(dirs[ex].key >> 32), b = static_cast<int>(dirs[ex].key & 0xffffffffu);
      report.warn("inconsistent_orientation_edges", count,
                  std::to_string(count) + " edge" + (count == 1 ? " is" : "s are") +
                      " traversed in the same direction by two faces (inconsistent orientation), e.g. vertex " +
                      std::to_string(a) + " -> " + std::to_string(b) + " in " + face_at(soup, dirs[ex - 1].face) +
                      " and " + face_at(soup, dirs[ex].face));
    }
  }

  // 6. Patches, geometry and the OpenMesh mesh (face p == patch p).
  const int np = static_cast<int>(specs.size());
  std::vector<std::vector<Vec3>> polys(np);
  scene.face_id.resize(np);
  scene.material.resize(np);
  scene.group.resize(np);
  scene.side.resize(np);
  for (int p = 0; p < np; ++p) {
    const SoupFace& f = soup.faces[specs[p].face];
    scene.side[p] = f.side;
    scene.face_id[p] = input_face(soup, specs[p].face);
    scene.material[p] = f.material;
    scene.group[p] = f.group;
    for (int v : specs[p].corners) polys[p].push_back(soup.positions[v]);
  }
  try {
    scene.geometry = PatchGeometry::from_polygons(polys);
  } catch (const InputError& e) {
    // The checks above should have caught it; still name the input face, not the patch.
    for (int p = 0; p < np; ++p) {
      try {
        PatchGeometry::from_polygons({polys[p]});
      } catch (const InputError& one) {
        fail(face_at(soup, specs[p].face) + ": " + one.what());
      }
    }
    fail(soup.file + ": " + e.what());
  }

  PolyMesh& mesh = scene.mesh;
  std::vector<PolyMesh::VertexHandle> vhandle(nv);
  for (int v = 0; v < nv; ++v)
    if (position_first[v] >= 0) {
      const Vec3& x = soup.positions[v];
      vhandle[v] = mesh.add_vertex(PolyMesh::Point(x.x(), x.y(), x.z()));
    }
  long detached = 0;
  int ex_detached = -1;
  std::vector<PolyMesh::VertexHandle> fh;
  // OpenMesh reports failed add_face on omerr (std::cerr): our own check comes first, and the
  // stream is silenced in case OpenMesh rejects a configuration the check does not foresee.
  auto& err = ::omerr();
  const bool was_enabled = err.is_enabled();
  err.disable();
  for (int p = 0; p < np; ++p) {
    fh.clear();
    for (int v : specs[p].corners) fh.push_back(vhandle[v]);
    PolyMesh::FaceHandle f;
    if (can_add(mesh, fh)) f = mesh.add_face(fh);
    if (!f.is_valid()) {
      for (auto& h : fh) {
        const PolyMesh::Point x = mesh.point(h);  // copy: add_vertex may reallocate the points
        h = mesh.add_vertex(x);
      }
      f = mesh.add_face(fh);
      ++detached;
      if (ex_detached < 0) ex_detached = specs[p].face;
    }
    if (f.idx() != p) {
      if (was_enabled) err.enable();
      throw std::logic_error("build_scene: mesh face " + std::to_string(f.idx()) + " != patch " +
                             std::to_string(p));
    }
  }
  if (was_enabled) err.enable();
  if (detached > 0)
    report.warn("nonmanifold_faces_detached", detached,
                std::to_string(detached) + " face" + (detached == 1 ? "" : "s") +
                    " could not be joined to the half-edge mesh, because an edge is shared by more than two faces "
                    "(a non-manifold edge, valid where a wall stands on a slab) or a neighbour is wound against it; "
                    "they got private copies of their vertices, so point-data radiance is not averaged across those "
                    "edges (cell data and form factors are unaffected), e.g. " +
                    face_at(soup, ex_detached));
  if (static_cast<int>(mesh.n_faces()) != np || scene.geometry.size() != np)
    throw std::logic_error("build_scene: " + std::to_string(mesh.n_faces()) + " mesh faces, " +
                           std::to_string(scene.geometry.size()) + " geometry patches, " + std::to_string(np) +
                           " patches expected");

  // 7. Scene-level warnings.
  bool emitter = false;
  for (int p = 0; p < np && !emitter; ++p) emitter = (scene.emission(p) > 0).any();
  if (!emitter && options.warn_no_emitter) report.warn("no_emitter", 1, "no emitter: the solution will be zero");
  if (soup.faces_without_material > 0)
    report.warn("faces_without_material", soup.faces_without_material,
                std::to_string(soup.faces_without_material) + " face" +
                    (soup.faces_without_material == 1 ? " has" : "s have") + " no material and got '" +
                    soup.materials[0].name + "'");
  return scene;
}

}  // namespace lambert::mesh
