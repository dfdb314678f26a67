// mesh::prepare, step 3: orientation. The file's winding is the truth: faces of one connected
// surface are made to agree (majority), and a whole surface is flipped only when rays show that
// the rest of the scene sees its back (cf. Takayama, Jacobson, Kavan, Sorkine-Hornung 2014,
// visibility-based mesh orientation). See prepare.hpp, step 3.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "prepare_internal.hpp"
#include "soup_rays.hpp"

namespace lambert::mesh {

Orientation parse_orientation(const std::string& name) {
  if (name == "file") return Orientation::file;
  if (name == "consistent") return Orientation::consistent;
  if (name == "visibility") return Orientation::visibility;
  throw InputError("unknown orientation mode '" + name + "' (expected file, consistent or visibility)");
}

namespace detail {

namespace {

constexpr int kRaysPerSide = 8;         // per face and side, at least ...
constexpr int kRaysPerSurface = 1024;   // ... and about this many per surface and side (at most 128 per face)
constexpr int kMinBackRays = 8;         // strong evidence: at least this many rays from the back ...
constexpr double kBackShare = 0.8;      // ... and this share of the area-weighted hits
constexpr double kNearGap = 0.1;        // an emitter's "near" surface: closer than this times sqrt(its area)

struct Components {
  std::vector<int> comp, parity;  // per face: component, flip relative to the component's first face
  std::vector<std::vector<int>> members;
  long non_orientable = 0;
};

// Two faces sharing an edge that lie in one plane on the same side of it (a duplicate face, a face
// folded back onto its neighbour) overlap: they are not one surface continuing across the edge,
// and their windings say nothing about each other (the public Cornell box repeats a side of each box
// as its "bottom").
bool folded(const PolygonSoup& s, int f, int g, std::uint64_t key) {
  const auto pf = corners(s, f), pg = corners(s, g);
  const Vec3 nf = newell_normal(pf), ng = newell_normal(pg);
  if (!(nf.norm() > 0) || !(ng.norm() > 0)) return false;
  if (nf.cross(ng).norm() > 1e-9 * nf.norm() * ng.norm()) return false;  // not coplanar
  const Vec3 a = s.positions[static_cast<int>(key >> 32)], b = s.positions[static_cast<int>(key & 0xffffffffu)];
  Vec3 cf = Vec3::Zero(), cg = Vec3::Zero();
  for (const Vec3& p : pf) cf += p / double(pf.size());
  for (const Vec3& p : pg) cg += p / double(pg.size());
  const Vec3 side = (b - a).cross(nf);
  return side.dot(cf - a) * side.dot(cg - a) > 0;
}

Components components(const PolygonSoup& s) {
  const int nf = static_cast<int>(s.faces.size());
  struct Use {
    std::uint64_t key;
    int face;
    int dir;
  };
  std::vector<Use> uses;
  for (int k = 0; k < nf; ++k) {
    const auto& fv = s.faces[k].vertices;
    for (size_t c = 0; c < fv.size(); ++c) {
      const int a = fv[c], b = fv[(c + 1) % fv.size()];
      uses.push_back({edge_key(a, b), k, a < b ? 1 : -1});
    }
  }
  std::sort(uses.begin(), uses.end(),
            [](const Use& x, const Use& y) { return x.key != y.key ? x.key < y.key : x.face < y.face; });
  // Adjacency across manifold edges (two faces): (neighbour, 1 if both run the edge the same way).
  std::vector<std::vector<std::pair<int, int>>> adj(nf);
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2 && uses[i].face != uses[i + 1].face && !folded(s, uses[i].face, uses[i + 1].face, uses[i].key)) {
      const int rel = uses[i].dir == uses[i + 1].dir ? 1 : 0;
      adj[uses[i].face].push_back({uses[i + 1].face, rel});
      adj[uses[i + 1].face].push_back({uses[i].face, rel});
    }
    i = j;
  }
  Components C;
  C.comp.assign(nf, -1);
  C.parity.assign(nf, 0);
  for (int k = 0; k < nf; ++k) {
    if (C.comp[k] >= 0) continue;
    const int c = static_cast<int>(C.members.size());
    C.members.emplace_back();
    bool conflict = false;
    std::vector<int> queue{k};
    C.comp[k] = c;
    for (size_t q = 0; q < queue.size(); ++q) {
      const int f = queue[q];
      C.members[c].push_back(f);
      for (auto [g, rel] : adj[f]) {
        if (C.comp[g] < 0) {
          C.comp[g] = c;
          C.parity[g] = C.parity[f] ^ rel;
          queue.push_back(g);
        } else if (C.parity[g] != (C.parity[f] ^ rel)) {
          conflict = true;
        }
      }
    }
    std::sort(C.members[c].begin(), C.members[c].end());
    if (conflict) ++C.non_orientable;
  }
  return C;
}

void flip_face(SoupFace& f) { std::reverse(f.vertices.begin() + 1, f.vertices.end()); }  // keeps the first corner

// A surface's open edges (used once within it: the open bottom of a block standing on a floor; of a bed, headboard
// and nightstands standing on it as one surface). A ray from the surface that ends on another surface in whose
// plane some of these edges lie, inside them, went through the opening and ended on what closes it. It never left
// the surface's inside; like a ray ending on the surface itself, it says nothing about which side the rest of the
// scene sees. Inside: an odd number of the edges on either side, in that plane; a chain of them that leaves the
// plane is followed along the open edges until it comes back, and that path counts as seen along the normal (a
// counter open at the bottom and at the back against two walls: the floor holds three sides of its footprint,
// the top's back edges along the walls close it).
struct Openings {
  std::vector<std::array<int, 2>> edges;  // vertex indices
  std::vector<std::pair<int, int>> at;    // (vertex, edge), sorted
  Eigen::AlignedBox3d box;                // the edges' box, grown by tol
  // x: where the ray ends, on a face with unit normal n.
  bool enclose(const PolygonSoup& s, const Vec3& x, const Vec3& n, double tol) const {
    if (edges.size() < 2 || !box.contains(x)) return false;
    auto in_plane = [&](int v) { return std::abs(n.dot(s.positions[v] - x)) <= tol; };
    thread_local std::vector<char> used;
    thread_local std::vector<int> path;  // edges counted
    used.assign(edges.size(), 0);
    path.clear();
    for (size_t e = 0; e < edges.size(); ++e)
      if (in_plane(edges[e][0]) && in_plane(edges[e][1])) used[e] = 1, path.push_back(static_cast<int>(e));
    if (path.size() < 2) return false;
    // The ends of chains in the plane (vertices on an odd number of its edges there; none when the edges in the plane
    // close, as a block's footprint does): from each, along open edges out of the plane until it comes back.
    thread_local std::vector<int> ends;
    ends.clear();
    for (int e : path) ends.insert(ends.end(), {edges[e][0], edges[e][1]});
    std::sort(ends.begin(), ends.end());
    for (size_t i = 0; i < ends.size();) {
      size_t j = i;
      while (j < ends.size() && ends[j] == ends[i]) ++j;
      if ((j - i) % 2 == 1) {
        int v = ends[i];
        for (;;) {
          int next = -1;
          for (auto it = std::lower_bound(at.begin(), at.end(), std::make_pair(v, -1)); it != at.end() && it->first == v; ++it)
            if (!used[it->second]) {
              next = it->second;
              break;
            }
          if (next < 0) break;
          used[next] = 1;
          path.push_back(next);
          v = edges[next][0] == v ? edges[next][1] : edges[next][0];
          if (in_plane(v)) break;
        }
      }
      i = j;
    }
    const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized(), w = n.cross(u);
    bool odd = false;  // crossings of the ray from x along u (half-open in w: a vertex on the ray counts once)
    for (int e : path) {
      const Vec3 a = s.positions[edges[e][0]] - x, b = s.positions[edges[e][1]] - x;
      const double ay = a.dot(w), by = b.dot(w);
      if ((ay > 0) != (by > 0) && 0 < a.dot(u) + (b.dot(u) - a.dot(u)) * (0 - ay) / (by - ay)) odd = !odd;
    }
    return odd;
  }
};

std::vector<Openings> openings(const PolygonSoup& s, const Components& C, double tol) {
  std::vector<Openings> out(C.members.size());
  struct Use {
    int comp;
    std::uint64_t key;
  };
  std::vector<Use> uses;
  for (int k = 0; k < static_cast<int>(s.faces.size()); ++k) {
    const auto& fv = s.faces[k].vertices;
    for (size_t c = 0; c < fv.size(); ++c) uses.push_back({C.comp[k], edge_key(fv[c], fv[(c + 1) % fv.size()])});
  }
  std::sort(uses.begin(), uses.end(),
            [](const Use& a, const Use& b) { return a.comp != b.comp ? a.comp < b.comp : a.key < b.key; });
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].comp == uses[i].comp && uses[j].key == uses[i].key) ++j;
    if (j - i == 1) {
      Openings& o = out[uses[i].comp];
      const int a = static_cast<int>(uses[i].key >> 32), b = static_cast<int>(uses[i].key & 0xffffffffu);
      o.edges.push_back({a, b});
      o.box.extend(s.positions[a]);
      o.box.extend(s.positions[b]);
    }
    i = j;
  }
  for (Openings& o : out)
    if (!o.edges.empty()) {
      o.box.min().array() -= tol;
      o.box.max().array() += tol;
      for (int e = 0; e < static_cast<int>(o.edges.size()); ++e) o.at.insert(o.at.end(), {{o.edges[e][0], e}, {o.edges[e][1], e}});
      std::sort(o.at.begin(), o.at.end());
    }
  return out;
}

}  // namespace

void orient(PolygonSoup& s, Orientation mode, double tol, Report& report) {
  const int nf = static_cast<int>(s.faces.size());
  const Components C = components(s);
  const std::vector<Openings> open = mode == Orientation::visibility ? openings(s, C, tol) : std::vector<Openings>{};
  const int nc = static_cast<int>(C.members.size());
  report.counts["faces_reoriented"] += 0;
  report.counts["non_orientable_components"] += 0;
  if (C.non_orientable > 0)
    report.warn("non_orientable_components", C.non_orientable,
                plural(C.non_orientable, "connected surface is", "connected surfaces are") +
                    " not orientable (like a Moebius strip); some neighbours keep opposite orientations");

  // flip[k]: the face ends up reversed. Majority per component (consistent, visibility).
  std::vector<int> flip(nf, 0);
  if (mode != Orientation::file) {
    for (int c = 0; c < nc; ++c) {
      long ones = 0;
      for (int f : C.members[c]) ones += C.parity[f];
      const int flip_all = 2 * ones > static_cast<long>(C.members[c].size());  // ties keep the first face
      for (int f : C.members[c]) {
        flip[f] = C.parity[f] ^ flip_all;
      }
    }
  }

  // Rays from both sides of every usable face: which side reaches other surfaces (evidence), and
  // which side reaches front sides (the hint). Directions are drawn around the face's file normal;
  // "side" below is relative to the orientation after the majority step.
  std::vector<char> usable(nf);
  for (int k = 0; k < nf; ++k) usable[k] = usable_face(s, k);
  std::vector<double> face_area(nf);  // m^2, one Newell normal per face (the rays' weights, the emitters' size)
  for (int k = 0; k < nf; ++k) face_area[k] = 0.5 * newell_normal(corners(s, k)).norm();
  const SoupRays rays(s, usable);
  std::vector<double> evidence_front(nc, 0), evidence_back(nc, 0);
  std::vector<long> front_rays(nc, 0), back_rays(nc, 0);
  struct Ray {
    int face, hit;
    bool from_front;  // leaves the face's current front side
    bool hit_front;   // arrives at the hit face's file front side
  };
  const bool several = nc > 1;
  std::vector<int> rays_per_side(nf, kRaysPerSide);
  for (int k = 0; k < nf; ++k) {
    const long m = static_cast<long>(C.members[C.comp[k]].size());
    rays_per_side[k] = static_cast<int>(std::clamp<long>((kRaysPerSurface + m - 1) / m, kRaysPerSide, 128));
  }
  // Faces in parallel (each draws from its own seeded generator), read in face order: the same result for any
  // thread count. Per face: its rays (kept per face, not copied into one list: a million faces cast ~1e8), and how
  // many leaving each side reached another surface (evidence).
  struct FaceRays {
    std::vector<Ray> cast;
    int evidence[2] = {0, 0};
    int traced[2] = {0, 0}, near[2] = {0, 0};  // emitters: rays per side, and those ending within kNearGap of it
  };
  std::vector<FaceRays> per_face(static_cast<size_t>(nf));
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, 64), [&](const tbb::blocked_range<int>& range) {
    for (int k = range.begin(); k < range.end(); ++k) {
      if (!rays.has(k)) continue;
      FaceRays& out = per_face[static_cast<size_t>(k)];
      std::mt19937_64 rng(0x9E3779B97F4A7C15ull ^ std::uint64_t(k) * 0xBF58476D1CE4E5B9ull);
      const Vec3 n = rays.normal(k) * (flip[k] ? -1.0 : 1.0);
      const bool emitter = !s.materials[s.faces[k].material].two_sided && s.materials[s.faces[k].material].emission.maxCoeff() > 0;
      const double near_gap = emitter ? kNearGap * std::sqrt(face_area[k]) : 0.0;
      for (int r = 0; r < rays_per_side[k]; ++r) {
        const Vec3 o = rays.sample(k, rng);
        const Vec3 d = cosine_direction(n, rng);
        for (int side = 0; side < 2; ++side) {
          const Vec3 dir = side == 0 ? d : Vec3(-d);
          auto h = rays.first(o, dir, [k](int f) { return f == k; });
          if (emitter) {
            ++out.traced[side];
            out.near[side] += h.face >= 0 && h.t * std::abs(dir.dot(n)) < near_gap;  // the hit's height over the face
          }
          if (h.face < 0) continue;
          if (C.comp[h.face] != C.comp[k]) {
            // A face of its own surface at the same distance (a block's bottom on the floor) is hit first:
            // the ray ends inside its own surface, it is no evidence.
            const int c = C.comp[k];
            const auto own = rays.first(o, dir, [&](int f) { return f == k || C.comp[f] != c; }, h.t * (1 + 1e-9) + 1e-12);
            if (own.face >= 0) h = own;
            // Through an opening of its own surface onto what closes it (a block's open bottom on the floor).
            if (own.face < 0 && !open.empty() && open[c].enclose(s, o + h.t * dir, rays.normal(h.face), tol)) continue;
          }
          out.cast.push_back({k, h.face, side == 0, h.front});
          if (several && C.comp[h.face] != C.comp[k]) ++out.evidence[side];
        }
      }
    }
  });
  for (int k = 0; k < nf; ++k) {
    const FaceRays& fr = per_face[static_cast<size_t>(k)];
    if (fr.cast.empty()) continue;
    const int c = C.comp[k];
    const double area = face_area[k] / rays_per_side[k];
    evidence_front[c] += area * fr.evidence[0];
    evidence_back[c] += area * fr.evidence[1];
    front_rays[c] += fr.evidence[0];
    back_rays[c] += fr.evidence[1];
  }

  std::vector<int> surface_flip(nc, 0);
  std::vector<std::string> named;
  long surfaces = 0, surface_faces = 0;
  if (mode == Orientation::visibility) {
    for (int c = 0; c < nc; ++c) {
      const double total = evidence_front[c] + evidence_back[c];
      if (back_rays[c] >= kMinBackRays && evidence_back[c] >= kBackShare * total) {
        surface_flip[c] = 1;
        ++surfaces;
        surface_faces += static_cast<long>(C.members[c].size());
        if (named.size() < 3) {
          std::vector<int> ids;
          for (int f : C.members[c]) ids.push_back(origin_of(s, f));
          named.push_back("the surface of input face" + std::string(ids.size() == 1 ? " " : "s ") + id_list(ids, 4) +
                          " (its back side gets " + std::to_string(int(std::lround(100 * evidence_back[c] / total))) +
                          " % of the rays that reach other surfaces)");
        }
      }
    }
  }

  // Second step: surfaces the rays leave undecided (both sides see the scene: a wall face meshed on its own, whose
  // back faces the other face of a thin wall; a furniture face whose back sees the other faces of its box) take
  // their side from the decided surfaces they see. A ray between two surfaces is consistent when it leaves a front
  // and arrives at a front, or leaves a back and arrives at a back. An undecided surface whose rays to and from
  // decided surfaces are inconsistent with 80 % of their weight (at least 8 rays) is turned round; consistent with
  // 80 %, it is kept; either way it is decided from the next round on (rounds until nothing changes: the same
  // result in any order). In a valid model the rays are consistent and nothing turns; a surface with a side that
  // sees decided surfaces mostly consistently (a light panel whose back faces the ceiling: its front sees the room)
  // keeps the file's winding. A model inside out (a mirrored export, walls and furniture meshed face by face) turns
  // from the surfaces whose side the first step decided.
  std::vector<int> coupled_flip(nc, 0);
  long coupled = 0, coupled_faces = 0;
  std::vector<int> coupled_ids;
  if (mode == Orientation::visibility && several) {
    std::vector<char> decided(nc, 0);
    for (int c = 0; c < nc; ++c) {
      const double total = evidence_front[c] + evidence_back[c];
      decided[c] = surface_flip[c] || (front_rays[c] >= kMinBackRays && evidence_front[c] >= kBackShare * total);
    }
    // The rays between two different one-sided surfaces, each with its weight (the area it stands for).
    struct Link {
      int from, to;       // surfaces
      double weight;
      bool leaves_front, arrives_front;  // as oriented after the first step
    };
    std::vector<Link> links;
    for (int k = 0; k < nf; ++k) {
      const int c = C.comp[k];
      if (s.materials[s.faces[k].material].two_sided) continue;
      const double area = face_area[k] / rays_per_side[k];
      for (const Ray& r : per_face[static_cast<size_t>(k)].cast) {
        const int d = C.comp[r.hit];
        if (d == c || (decided[c] && decided[d]) || s.materials[s.faces[r.hit].material].two_sided) continue;
        links.push_back({c, d, area, r.from_front != bool(surface_flip[c]), r.hit_front != bool(flip[r.hit] ^ surface_flip[d])});
      }
    }
    for (bool changed = true; changed;) {
      changed = false;
      // Per undecided surface and side (0 front, 1 back): weight of consistent and inconsistent links to decided
      // surfaces, and their rays.
      std::vector<std::array<double, 2>> agree(nc, {0, 0}), disagree(nc, {0, 0});
      std::vector<std::array<int, 2>> agreeing(nc, {0, 0});
      std::vector<int> count(nc, 0);
      for (const Link& l : links) {
        if (decided[l.from] == decided[l.to]) continue;
        const bool out = !decided[l.from];
        const int u = out ? l.from : l.to, d = out ? l.to : l.from;
        const bool d_front = (out ? l.arrives_front : l.leaves_front) != bool(coupled_flip[d]);
        const bool u_front = out ? l.leaves_front : l.arrives_front;
        const int side = u_front ? 0 : 1;
        if (u_front == d_front) {
          agree[u][side] += l.weight;
          ++agreeing[u][side];
        } else {
          disagree[u][side] += l.weight;
        }
        ++count[u];
      }
      for (int c = 0; c < nc; ++c) {
        if (decided[c] || count[c] < kMinBackRays) continue;
        const double yes = agree[c][0] + agree[c][1], no = disagree[c][0] + disagree[c][1];
        // A side whose links to decided surfaces are mostly consistent vouches for the file's winding (a block
        // wound inward around an object seen from its front; a light panel whose front sees the room).
        bool vouched = false;
        for (int side = 0; side < 2; ++side)
          vouched = vouched || (agreeing[c][side] >= kMinBackRays && agree[c][side] > disagree[c][side]);
        if (no >= kBackShare * (yes + no) && !vouched) {
          coupled_flip[c] = 1;
          ++coupled;
          coupled_faces += static_cast<long>(C.members[c].size());
          for (int f : C.members[c]) coupled_ids.push_back(origin_of(s, f));
        } else if (yes < kBackShare * (yes + no)) {
          continue;  // undecided still
        }
        decided[c] = 1;  // counts from the next round on (this round's votes are in)
        changed = true;
      }
    }
    for (int c = 0; c < nc; ++c) surface_flip[c] ^= coupled_flip[c];
  }

  // Apply: every flipped face counted and named.
  long flipped = 0;
  std::vector<int> flipped_ids;
  double area_all = 0, area_flipped = 0;
  for (int k = 0; k < nf; ++k) {
    const int final_flip = flip[k] ^ surface_flip[C.comp[k]];
    const double area = face_area[k];
    area_all += area;
    if (final_flip) {
      flip_face(s.faces[k]);
      ++flipped;
      flipped_ids.push_back(origin_of(s, k));
      area_flipped += area;
    }
  }
  report.counts["surfaces_flipped"] += 0;
  if (flipped > 0) {
    report.counts["faces_reoriented"] += flipped;
    // Most of the area turned: the model came inside out as a whole (a mirrored export). Reversing it as read turns
    // what no ray can tell as well (a light facing a ceiling close by).
    const auto asked = report.counts.find("faces_reversed_as_asked");
    const bool reversed = asked != report.counts.end() && asked->second > 0;
    const std::string whole =
        !(area_flipped > 0.5 * area_all) ? ""
        : reversed ? " (most of the model's area was turned back after --reverse-winding reversed it: was the file's "
                     "winding right?)"
                   : " (most of the model's area was inside out, as a mirrored export leaves it: --reverse-winding "
                     "reverses every face as read, lights facing a ceiling too)";
    report.warnings.push_back(
        plural(flipped, "face was", "faces were") + " reoriented (to agree with the majority of their connected "
        "surface" + std::string(surfaces + coupled > 0 ? ", or with their whole surface" : "") + "): input face" +
        (flipped_ids.size() == 1 ? " " : "s ") + id_list(flipped_ids) + whole);
  }
  if (surfaces > 0) {
    std::string list;
    for (size_t i = 0; i < named.size(); ++i) list += (i ? "; " : "") + named[i];
    if (surfaces > static_cast<long>(named.size())) list += "; and " + std::to_string(surfaces - long(named.size())) + " more";
    report.warn("surfaces_flipped", surfaces,
                plural(surfaces, "surface was", "surfaces were") + " turned round (" + plural(surface_faces, "face", "faces") +
                    ") because the rest of the scene sees its back (--orient consistent or file keeps the file's "
                    "winding): " + list);
  }

  if (coupled > 0)
    report.warn("surfaces_flipped", coupled,
                plural(coupled, "surface was", "surfaces were") + " turned round (" + plural(coupled_faces, "face", "faces") +
                    ") because the surfaces around, whose side the rays made clear, see their backs and are seen from "
                    "behind by them (--orient consistent or file keeps the file's winding): input face" +
                    (coupled_ids.size() == 1 ? " " : "s ") + id_list(coupled_ids));

  // Hint: one-sided faces whose back reaches front sides more often than their front does.
  std::vector<int> front_lit(nf, 0), back_lit(nf, 0);
  for (const FaceRays& fr : per_face)
    for (const Ray& r : fr.cast) {
      const int fh = flip[r.hit] ^ surface_flip[C.comp[r.hit]];
      // r.from_front is relative to the majority orientation; a surface flip swaps it.
      const bool from_front = r.from_front != bool(surface_flip[C.comp[r.face]]);
      const bool lit = s.materials[s.faces[r.hit].material].two_sided || (r.hit_front != bool(fh));
      if (!lit) continue;
      (from_front ? front_lit : back_lit)[r.face]++;
    }
  std::vector<int> behind;
  for (int k = 0; k < nf; ++k)
    if (!s.materials[s.faces[k].material].two_sided && back_lit[k] > 2 * front_lit[k] &&
        back_lit[k] >= rays_per_side[k] / 2)
      behind.push_back(origin_of(s, k));
  report.counts["faces_seen_from_behind"] += 0;
  if (!behind.empty())
    report.warn("faces_seen_from_behind", static_cast<long>(behind.size()),
                plural(static_cast<long>(behind.size()), "one-sided face is", "one-sided faces are") +
                    " seen by the scene mostly from behind (they stay black there; mark them two-sided if they "
                    "are thin surfaces meant to reflect on both sides): input face" +
                    (behind.size() == 1 ? " " : "s ") + id_list(behind));

  // Hint: emitters whose front is covered at close range (>= 90 % of its rays end at a height over the face below a
  // tenth of its size) while their back is not (<= 10 %): a light below a ceiling facing it, its light kept in the
  // gap. No ray tells that from a valid cove light (both sides see the scene), so it is said, not turned.
  std::vector<int> facing_near;
  for (int k = 0; k < nf; ++k) {
    const FaceRays& fr = per_face[static_cast<size_t>(k)];
    const int front = surface_flip[C.comp[k]] ? 1 : 0, back = 1 - front;  // sides as finally oriented
    if (fr.traced[front] >= kMinBackRays && fr.traced[back] >= kMinBackRays && fr.near[front] >= 0.9 * fr.traced[front] &&
        fr.near[back] <= 0.1 * fr.traced[back])
      facing_near.push_back(origin_of(s, k));
  }
  report.counts["emitters_facing_a_near_surface"] += 0;
  if (!facing_near.empty())
    report.warn("emitters_facing_a_near_surface", static_cast<long>(facing_near.size()),
                plural(static_cast<long>(facing_near.size()),
                       "emitting face faces a surface closer than a tenth of its size while its back sees the scene: its",
                       "emitting faces face a surface closer than a tenth of their size while their backs see the scene: "
                       "their") +
                    " light stays in the gap (a light below a ceiling wound to face it? reverse it in the file): input "
                    "face" +
                    (facing_near.size() == 1 ? " " : "s ") + id_list(facing_near));
}

}  // namespace detail
}  // namespace lambert::mesh
