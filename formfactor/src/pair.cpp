// One pair, scalar path: orientation culling, a-priori choice of the outer rule, or the adaptive contour.
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "batch.hpp"
#include "internal.hpp"
#include "lambert/formfactor/kernel.hpp"

namespace lambert::formfactor {
namespace detail {

const char* const kMethodNames[kMethodCount] = {"orientation_culled", "far_field", "centroid_hessian",
                                                "gauss4",  "gauss9",   "gauss16",   "gauss36", "gauss64", "contour"};

int tier_method(int t) { return kFarField + t; }

namespace {

bool convex_quad(std::span<const Vec3> q, const Vec3& n) {
  if (q.size() != 4) return false;
  for (int k = 0; k < 4; ++k) {
    const Vec3 e0 = q[(k + 1) % 4] - q[k], e1 = q[(k + 2) % 4] - q[(k + 1) % 4];
    if (!(e0.cross(e1).dot(n) > 0)) return false;
  }
  return true;
}

}  // namespace

void outer_rule(std::span<const Vec3> poly, std::span<const std::array<int, 3>> tris, int m,
                std::vector<std::array<double, 4>>& out) {
  const size_t first = out.size();
  Vec3 nn = mesh::newell_normal(poly);
  const Vec3 n = nn.normalized();
  if (m <= 1) {
    Vec3 c = Vec3::Zero();
    double A = 0;
    for (const auto& t : tris) {
      const double a = 0.5 * (poly[t[1]] - poly[t[0]]).cross(poly[t[2]] - poly[t[0]]).dot(n);
      c += a * (poly[t[0]] + poly[t[1]] + poly[t[2]]) / 3.0;
      A += a;
    }
    c /= A;
    out.push_back({c.x(), c.y(), c.z(), 1.0});
    return;
  }
  double total = 0;
  if (convex_quad(poly, n)) {
    const Rule2D& r = gauss_square(m);
    for (size_t k = 0; k < r.w.size(); ++k) {
      const double s = r.xi[k][0], t = r.xi[k][1];
      const Vec3 X = (1 - s) * (1 - t) * poly[0] + s * (1 - t) * poly[1] + s * t * poly[2] + (1 - s) * t * poly[3];
      const Vec3 ds = (1 - t) * (poly[1] - poly[0]) + t * (poly[2] - poly[3]);
      const Vec3 dt = (1 - s) * (poly[3] - poly[0]) + s * (poly[2] - poly[1]);
      const double J = ds.cross(dt).dot(n);
      out.push_back({X.x(), X.y(), X.z(), r.w[k] * J});
      total += r.w[k] * J;
    }
  } else {
    const Rule2D& r = gauss_triangle(m);
    for (const auto& t : tris) {
      const Vec3 &P0 = poly[t[0]], &P1 = poly[t[1]], &P2 = poly[t[2]];
      const double a = 0.5 * (P1 - P0).cross(P2 - P0).dot(n);
      for (size_t k = 0; k < r.w.size(); ++k) {
        const Vec3 X = P0 + r.xi[k][0] * (P1 - P0) + r.xi[k][1] * (P2 - P0);
        out.push_back({X.x(), X.y(), X.z(), r.w[k] * a});
        total += r.w[k] * a;
      }
    }
  }
  for (size_t k = first; k < out.size(); ++k) out[k][3] /= total;
}

std::unique_ptr<mesh::PatchGeometry> moved_to_origin(const mesh::PatchGeometry& g) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : g.points) box.extend(p);
  if (box.isEmpty()) return nullptr;
  const Vec3 centre = box.center();
  const bool far = centre.norm() > box.diagonal().norm();
  const Eigen::Matrix3d R = mesh::alignment(g);
  const bool turn = !R.isIdentity(0);
  if (!far && !turn) return nullptr;
  return std::make_unique<mesh::PatchGeometry>(mesh::moved_and_turned(g, centre, turn ? &R : nullptr));
}

namespace {
// PatchData::planar: null when every polygon is planar to 1e-8 of its circumradius. Not lower: a polygon projected
// onto its plane no longer meets its neighbours exactly along their shared edge, and F of touching patches moves by
// about (gap / size) ln(size / gap): the floor plan moved by 2e6 m and written with 10 decimals (corners 1e-10 m out
// of plane) had entries 2e-8 apart from the unmoved ones when its polygons were projected. Single precision leaves
// quads 1e-7 of their size out of plane and more.
std::shared_ptr<mesh::PatchGeometry> projected_if_not_planar(const mesh::PatchGeometry& g) {
  std::shared_ptr<mesh::PatchGeometry> out;
  for (int p = 0; p < g.size(); ++p) {
    const auto poly = g.polygon(p);
    if (poly.size() <= 3) continue;
    const Vec3 &c = g.centroid[size_t(p)], &n = g.normal[size_t(p)];
    double dev = 0, r = 0;
    for (const Vec3& v : poly) {
      dev = std::max(dev, std::abs(n.dot(v - c)));
      r = std::max(r, (v - c).norm());
    }
    if (!(dev > 1e-8 * r)) continue;
    if (!out) out = std::make_shared<mesh::PatchGeometry>(g);
    for (int k = g.offsets[size_t(p)]; k < g.offsets[size_t(p) + 1]; ++k) {
      Vec3& v = out->points[size_t(k)];
      v -= n.dot(v - c) * n;
    }
  }
  return out;
}
}  // namespace

PatchData prepare(const mesh::PatchGeometry& given, int max_tier) {
  PatchData P;
  P.planar = projected_if_not_planar(given);
  const mesh::PatchGeometry& g = P.planar ? *P.planar : given;
  const int n = g.size();
  P.n = n;
  P.g = &g;
  P.c = g.centroid;
  P.nrm = g.normal;
  P.area = g.area;
  P.radius.resize(n);
  P.rerr.resize(n);
  P.offset.resize(n);
  P.M.resize(n);
  P.M3.resize(n);
  P.kind.resize(n);
  // Relative to the scene's size (bounding-box diagonal), not to |coordinates|: translation invariant.
  Eigen::AlignedBox3d box;
  for (const Vec3& p : g.points) box.extend(p);
  const double scale = box.isEmpty() ? 0.0 : box.diagonal().norm();
  P.scene_eps = 1e-10 * std::max(scale, 1e-300);
  for (int t = 2; t <= std::min(max_tier, 4); ++t) P.rule_off[t].assign(1, 0);
  std::vector<std::array<int, 3>> local;
  for (int p = 0; p < n; ++p) {
    const auto poly = g.polygon(p);
    const Vec3& c = g.centroid[p];
    double r = 0;
    for (const Vec3& v : poly) r = std::max(r, (v - c).norm());
    P.radius[p] = r;
    P.offset[p] = g.normal[p].dot(c);
    local.clear();
    for (int t = g.triangle_offsets[p]; t < g.triangle_offsets[p + 1]; ++t) {
      const auto& T = g.triangles[t];
      local.push_back({T[0] - g.offsets[p], T[1] - g.offsets[p], T[2] - g.offsets[p]});
    }
    // Second moments about the centroid: per triangle (A/12)(sum v v^T + s s^T), s = sum of corners.
    std::array<double, 6> M{};
    for (const auto& t : local) {
      const Vec3 a = poly[t[0]] - c, b = poly[t[1]] - c, d = poly[t[2]] - c, s = a + b + d;
      const double At = 0.5 * (b - a).cross(d - a).dot(g.normal[p]);
      auto acc = [&](int i, int j) { return (a[i] * a[j] + b[i] * b[j] + d[i] * d[j] + s[i] * s[j]) * At / 12; };
      M[0] += acc(0, 0);
      M[1] += acc(1, 1);
      M[2] += acc(2, 2);
      M[3] += acc(0, 1);
      M[4] += acc(0, 2);
      M[5] += acc(1, 2);
    }
    for (double& v : M) v /= g.area[p];
    P.M[p] = M;
    // Third moments about the centroid: per triangle (A/60)(s_k s_l s_m + sum_v (v_k v_l s_m + v_k s_l v_m +
    // s_k v_l v_m + 2 v_k v_l v_m)) (the integrals of products of barycentric coordinates: A/10, A/30, A/60).
    std::array<double, 10> M3{};
    for (const auto& t : local) {
      const Vec3 v[3] = {poly[t[0]] - c, poly[t[1]] - c, poly[t[2]] - c};
      const Vec3 s = v[0] + v[1] + v[2];
      const double At = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).dot(g.normal[p]);
      for (int q = 0; q < 10; ++q) {
        const int i = kTriples[q][0], j = kTriples[q][1], k = kTriples[q][2];
        double sum = s[i] * s[j] * s[k];
        for (const Vec3& w : v)
          sum += w[i] * w[j] * s[k] + w[i] * s[j] * w[k] + s[i] * w[j] * w[k] + 2 * w[i] * w[j] * w[k];
        M3[size_t(q)] += sum * At / 60;
      }
    }
    for (double& v : M3) v /= g.area[p];
    P.M3[p] = M3;
    {
      Eigen::Matrix3d S;
      S << M[0], M[3], M[4], M[3], M[1], M[5], M[4], M[5], M[2];
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
      es.computeDirect(S, Eigen::EigenvaluesOnly);
      P.rerr[p] = std::max(r, std::sqrt(6 * std::max(0.0, es.eigenvalues().maxCoeff())));
    }
    if (poly.size() == 3) {
      P.kind[p] = 0;
    } else if (poly.size() == 4 && convex_quad(poly, g.normal[p])) {
      // A parallelogram to 1e-8 of its size: the corners of one given in decimals (a CAD box), or made by
      // refinement's midpoints, are that to the rounding of where the model sits (1.2e-10 m at 1e6 m; 1e-12 of a
      // 0.3 m block top was not, and the block top of CornellBox-Original.obj moved by (1e6, 2e6, 0) m was sampled
      // by triangles instead of its bilinear map: other ray samples; 1e-9 was not for the room's 0.15 m children
      // after a round of refinement there). The third moments the tiers then take as zero are 1e-8 of the patch's:
      // below 1.3e-9 F where a tier applies (r / d <= 0.5).
      const double sym = (poly[0] + poly[2] - poly[1] - poly[3]).norm();
      P.kind[p] = sym <= 1e-8 * std::max(r, 1e-300) ? 1 : 2;
    } else {
      P.kind[p] = 3;
    }
    for (int t = 2; t <= std::min(max_tier, 4); ++t) {
      outer_rule(poly, local, t, P.rule_pts[t]);
      P.rule_off[t].push_back(int(P.rule_pts[t].size()));
    }
  }
  for (auto& v : P.rule_pts) v.shrink_to_fit();  // ~0.9 kB per patch, up to twice that in doubling slack
  return P;
}

namespace {

Moments<double> moments(const std::array<double, 6>& M) { return {M[0], M[1], M[2], M[3], M[4], M[5]}; }

}  // namespace

double tier_error(int t, double S, double r, double q, bool source_symmetric, bool target_symmetric) {
  const TierInput<double> in{S, r, q};
  if (t == 0) return tier0_error(in, source_symmetric, target_symmetric);
  double e[kTiers];
  tier_errors(in, source_symmetric, e);
  return e[t];
}

double hessian_correction(const Vec3& ci, const Vec3& ni, const std::array<double, 6>& M, const Vec3& cj,
                          const Vec3& nj, double Aj) {
  const Vec3 u = ci - cj;
  return centroid_hessian_correction(u.x(), u.y(), u.z(), ni.x(), ni.y(), ni.z(), nj.x(), nj.y(), nj.z(), moments(M), Aj);
}

double far_field(const Vec3& ci, const Vec3& ni, const std::array<double, 6>& Mi, const Vec3& cj, const Vec3& nj,
                 const std::array<double, 6>& Mj, double Aj) {
  const Vec3 u = ci - cj;
  return far_field_value(u.x(), u.y(), u.z(), ni.x(), ni.y(), ni.z(), nj.x(), nj.y(), nj.z(), moments(Mi), moments(Mj), Aj);
}

namespace {
// sum_k w_k F(x_k -> t) over rule points (x, y, z, w) with the normal of s: by the SIMD kernel when soa is given
// and t is a triangle or convex quad (its corners in the SoA), else one point at a time.
double rule_sum(const PatchData& P, const PointSoA* soa, int s, int t, std::span<const std::array<double, 4>> pts,
                std::span<const Vec3> Pt) {
  double F = 0;
  if (soa && P.kind[size_t(t)] <= 2) {
    thread_local std::vector<double> x, y, z, w, out;
    thread_local std::vector<int> si, ti;
    const size_t n = pts.size();
    x.resize(n), y.resize(n), z.resize(n), w.resize(n), out.resize(n);
    si.assign(n, s), ti.assign(n, t);
    for (size_t k = 0; k < n; ++k) x[k] = pts[k][0], y[k] = pts[k][1], z[k] = pts[k][2], w[k] = pts[k][3];
    batch_kernels().eval_points(soa->soa, x.data(), y.data(), z.data(), w.data(), si.data(), ti.data(), int(n),
                                out.data());
    for (size_t k = 0; k < n; ++k) F += out[k];
    return F;
  }
  for (const auto& X : pts) F += X[3] * contour_sum(Vec3(X[0], X[1], X[2]), P.nrm[s], Pt);
  return F;
}

PairEval pair_eval(const PatchData& P, const PointSoA* soa, int s, int t, double tol);
}  // namespace

PointSoA::PointSoA(const PatchData& P) {
  const mesh::PatchGeometry& g = *P.g;
  const size_t n = size_t(P.n), stride = n + kBatchPad;
  cols.assign(15 * stride, 0.0);
  double* c = cols.data();
  auto col = [&](int k) { return c + size_t(k) * stride; };
  for (size_t p = 0; p < n; ++p) {
    col(0)[p] = P.nrm[p].x(), col(1)[p] = P.nrm[p].y(), col(2)[p] = P.nrm[p].z();
    const auto poly = g.polygon(int(p));
    for (size_t k = 0; k < 4; ++k) {
      const Vec3& v = poly[std::min(k, poly.size() - 1)];  // triangles repeat corner 2 (batch.hpp)
      for (int a = 0; a < 3; ++a) col(3 + 3 * int(k) + a)[p] = v[a];
    }
  }
  soa.nx = col(0), soa.ny = col(1), soa.nz = col(2);
  for (int k = 0; k < 4; ++k) soa.qx[k] = col(3 + 3 * k), soa.qy[k] = col(4 + 3 * k), soa.qz[k] = col(5 + 3 * k);
  soa.eps = P.scene_eps;
}

PairEval pair_scalar(const PatchData& P, int s, int t, double tol) { return pair_eval(P, nullptr, s, t, tol); }
PairEval pair_scalar(const PatchData& P, const PointSoA& soa, int s, int t, double tol) {
  return pair_eval(P, &soa, s, t, tol);
}

namespace {
// An upper bound on A_s F_st for clipped polygons apart: A_s' A_t' / (pi d^2), d the gap between their bounding
// spheres (both cosines at most 1), or infinity. The double contour integral of a piece small against its distance
// cancels ln r of nearly equal values: a 3 um corner of a ceiling patch clipped to the front of a 2 cm triangle 5.5 m
// away (a model turned and rounded to single precision) gave A_s F_st = -1.8e-17 against an estimate of 1.1e-17,
// where this bound is 1.4e-17. Where the bound is within half the tolerance the pair is its midpoint, plus or minus
// half of it: a rigorous enclosure, without the integral.
double clipped_bound(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  auto sphere = [](const std::vector<Vec3>& p, Vec3& c, double& r) {
    c = Vec3::Zero();
    for (const Vec3& v : p) c += v;
    c /= double(p.size());
    r = 0;
    for (const Vec3& v : p) r = std::max(r, (v - c).norm());
  };
  Vec3 ca, cb;
  double ra, rb;
  sphere(a, ca, ra);
  sphere(b, cb, rb);
  const double d = (ca - cb).norm() - ra - rb;
  if (!(d > 0)) return INFINITY;
  return 0.5 * mesh::newell_normal(a).norm() * 0.5 * mesh::newell_normal(b).norm() / (kPi * d * d);
}

PairEval pair_eval(const PatchData& P, const PointSoA* soa, int s, int t, double tol) {
  PairEval out;
  const mesh::PatchGeometry& g = *P.g;
  const auto Ps = g.polygon(s), Pt = g.polygon(t);
  const double eps = P.scene_eps;
  const auto rt = plane_range(Pt, P.nrm[s], P.offset[s]);
  const auto rs = plane_range(Ps, P.nrm[t], P.offset[t]);
  if (!(rt[1] > eps) || !(rs[1] > eps)) {
    out.method = kCulled;
    return out;
  }
  const bool straddle = rt[0] < -eps || rs[0] < -eps;
  if (!straddle) {
    // The tier choice of tiers.hpp, as the SIMD classify: the first tier whose estimate is <= tol.
    const double D = (P.c[s] - P.c[t]).norm();
    const TierInput<double> in = tier_input(D, P.rerr[s], P.radius[t], P.area[t]);
    if (tier_eligible(D, P.radius[t], in)) {
      const bool sym = P.kind[s] == 1, symt = P.kind[t] == 1;
      double e[kTiers];
      e[0] = tier0_error(in, sym, symt);
      if (!(e[0] <= tol)) tier_errors(in, sym, e);
      for (int tier = 0; tier < kTiers; ++tier) {
        const double est = e[tier];
        if (!(est <= tol)) continue;
        const int m = kTierM[tier];
        double F = 0;
        if (tier == 0) {
          F = far_field(P.c[s], P.nrm[s], P.M[s], P.c[t], P.nrm[t], P.M[t], P.area[t]);
          out.evaluations = 1;
        } else if (tier == 1) {
          F = contour_sum(P.c[s], P.nrm[s], Pt) + hessian_correction(P.c[s], P.nrm[s], P.M[s], P.c[t], P.nrm[t], P.area[t]);
          out.evaluations = 1;
        } else if (m <= 4 && !P.rule_off[m].empty()) {  // rules prepared (prepare's max_tier)
          const int k0 = P.rule_off[m][s], k1 = P.rule_off[m][s + 1];
          F = rule_sum(P, soa, s, t, std::span(P.rule_pts[m]).subspan(size_t(k0), size_t(k1 - k0)), Pt);
          out.evaluations = P.rule_off[m][s + 1] - P.rule_off[m][s];
        } else {
          thread_local std::vector<std::array<double, 4>> pts;
          thread_local std::vector<std::array<int, 3>> local;
          pts.clear();
          local.clear();
          for (int k = g.triangle_offsets[s]; k < g.triangle_offsets[s + 1]; ++k)
            local.push_back({g.triangles[k][0] - g.offsets[s], g.triangles[k][1] - g.offsets[s], g.triangles[k][2] - g.offsets[s]});
          outer_rule(Ps, local, m, pts);
          F = rule_sum(P, soa, s, t, pts, Pt);
          out.evaluations = (long long)pts.size();
        }
        out.F = F;
        out.error = est;
        out.method = tier_method(tier);
        return out;
      }
    }
  }
  // Near pair: mutual clipping, then the adaptive double contour integral.
  thread_local std::vector<Vec3> cs, ct;
  clip_front(Ps, P.nrm[t], P.offset[t], eps, cs);
  clip_front(Pt, P.nrm[s], P.offset[s], eps, ct);
  out.method = kContour;
  if (cs.size() < 3 || ct.size() < 3) return out;
  if (const double B = clipped_bound(cs, ct); B <= 0.5 * tol * P.area[s]) {  // B: A_s F_st
    out.F = 0.5 * B / P.area[s];
    out.error = 0.5 * B / P.area[s];
    return out;
  }
  const ContourResult c = contour_pair(cs, ct, tol * P.area[s]);
  out.F = c.AF / P.area[s];
  out.error = c.error / P.area[s];
  out.evaluations = c.evaluations;
  return out;
}

}  // namespace

ReverseIntegral reverse_integral(const PatchData& P, int s, int t, double tol, double entry_tol) {
  const mesh::PatchGeometry& g = *P.g;
  std::vector<Vec3> cs, ct;
  clip_front(g.polygon(s), P.nrm[t], P.offset[t], P.scene_eps, cs);
  clip_front(g.polygon(t), P.nrm[s], P.offset[s], P.scene_eps, ct);
  ReverseIntegral r;
  if (cs.size() < 3 || ct.size() < 3) return r;
  if (const double B = clipped_bound(cs, ct); B <= 0.5 * entry_tol * P.area[s]) {  // as pair_eval
    r.AF = 0.5 * B;
    r.error = 0.5 * B;
    return r;
  }
  const ContourResult c = contour_pair(ct, cs, tol * P.area[s]);
  r.AF = c.AF;
  r.error = c.error;
  return r;
}

}  // namespace detail

PairResult polygon_to_polygon(std::span<const Vec3> Pi, std::span<const Vec3> Pj, double tolerance) {
  const mesh::PatchGeometry g = mesh::PatchGeometry::from_polygons(
      {std::vector<Vec3>(Pi.begin(), Pi.end()), std::vector<Vec3>(Pj.begin(), Pj.end())});
  const detail::PatchData P = detail::prepare(g);
  // Integrate from the smaller patch: F of the other direction then inherits an error scaled by A_s/A_t <= 1.
  const bool swap = detail::source_is_j(g.area[0], g.area[1]);
  const int s = swap ? 1 : 0, t = 1 - s;
  const detail::PairEval e = detail::pair_scalar(P, s, t, tolerance);
  PairResult r;
  r.method = detail::kMethodNames[e.method];
  const double Fst = e.F, Fts = e.F * g.area[s] / g.area[t];
  r.F = swap ? Fts : Fst;
  r.F_reverse = swap ? Fst : Fts;
  r.error_estimate = swap ? e.error * g.area[s] / g.area[t] : e.error;
  return r;
}

}  // namespace lambert::formfactor
