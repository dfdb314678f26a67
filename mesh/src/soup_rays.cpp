#include "soup_rays.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include "prepare_internal.hpp"

namespace lambert::mesh::detail {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangles = std::vector<K::Triangle_3>;
using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
K::Point_3 pt(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 vec(const K::Point_3& p) { return {p.x(), p.y(), p.z()}; }
}  // namespace

struct SoupRays::Impl {
  Triangles tris;
  std::vector<int> face;
  Tree tree;
};

SoupRays::SoupRays(const PolygonSoup& s, const std::vector<char>& include) : impl_(std::make_unique<Impl>()) {
  const int nf = static_cast<int>(s.faces.size());
  normal_.assign(nf, Vec3::Zero());
  tris_of_.resize(nf);
  cum_area_.resize(nf);
  for (int k = 0; k < nf; ++k) {
    if (!include[k]) continue;
    const auto poly = corners(s, k);
    const Vec3 nn = newell_normal(poly);
    if (!(nn.norm() > 0)) continue;
    normal_[k] = nn.normalized();
    double cum = 0;
    for (const auto& t : triangulate_polygon(poly, normal_[k])) {
      const std::array<Vec3, 3> tri{poly[t[0]], poly[t[1]], poly[t[2]]};
      const K::Triangle_3 kt(pt(tri[0]), pt(tri[1]), pt(tri[2]));
      if (kt.is_degenerate()) continue;
      impl_->tris.push_back(kt);
      impl_->face.push_back(k);
      tris_of_[k].push_back(tri);
      cum += 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).norm();
      cum_area_[k].push_back(cum);
    }
  }
  impl_->tree.insert(impl_->tris.begin(), impl_->tris.end());
  impl_->tree.build();
}

SoupRays::~SoupRays() = default;

SoupRays::Hit SoupRays::first(const Vec3& o, const Vec3& d, const std::function<bool(int)>& skip) const {
  Hit h;
  if (impl_->tris.empty()) return h;
  const K::Ray_3 ray(pt(o), K::Vector_3(d.x(), d.y(), d.z()));
  const auto* base = impl_->tris.data();
  const auto& faces = impl_->face;
  auto skip_id = [&](const Triangles::const_iterator& it) { return skip(faces[&*it - base]); };
  const auto x = impl_->tree.first_intersection(ray, skip_id);
  if (!x) return h;
  const int f = faces[&*x->second - base];
  Vec3 p;
  if (const auto* q = boost::get<K::Point_3>(&x->first)) {
    p = vec(*q);
  } else if (const auto* sg = boost::get<K::Segment_3>(&x->first)) {
    const Vec3 a = vec(sg->source()), b = vec(sg->target());
    p = (a - o).dot(d) < (b - o).dot(d) ? a : b;
  } else {
    return h;
  }
  h.face = f;
  h.t = std::max(0.0, (p - o).dot(d));
  h.front = d.dot(normal_[f]) < 0;
  return h;
}

Vec3 SoupRays::sample(int k, std::mt19937_64& rng) const {
  std::uniform_real_distribution<double> u(0, 1);
  const auto& cum = cum_area_[k];
  const double a = u(rng) * cum.back();
  const size_t i = std::min(cum.size() - 1, size_t(std::upper_bound(cum.begin(), cum.end(), a) - cum.begin()));
  double r1 = u(rng), r2 = u(rng);
  if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
  const auto& t = tris_of_[k][i];
  return t[0] + r1 * (t[1] - t[0]) + r2 * (t[2] - t[0]);
}

Vec3 cosine_direction(const Vec3& n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const double r = std::sqrt(u(rng)), phi = 2 * std::numbers::pi * u(rng);
  const Vec3 a = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 b = n.cross(a);
  return (r * std::cos(phi) * a + r * std::sin(phi) * b + std::sqrt(std::max(0.0, 1 - r * r)) * n).normalized();
}

}  // namespace lambert::mesh::detail
