// Adaptive refinement (refine/adaptive.hpp) against a case with a known continuous answer.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "lambert/formfactor/kernel.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/refine/adaptive.hpp"
#include "lambert/refine/indicators.hpp"

using namespace lambert;

namespace {

constexpr double kRho = 0.5;  // floor reflectance
constexpr double kLe = 1.0;   // emitter radiance, W m^-2 sr^-1

// Small square emitter above the floor's (0, 0) corner, facing down (-z).
std::vector<Vec3> emitter() {
  const double a = 0.05, b = 0.2, h = 0.15;
  return {{a, a, h}, {a, b, h}, {b, b, h}, {b, a, h}};
}

// Unit floor [0,1]^2 at z = 0 (normal +z, rho = 0.5) in n x n quads, plus the emitter (rho = 0).
// Corners welded by position so that neighbours share vertex indices.
mesh::PolygonSoup floor_scene(int n) {
  mesh::PolygonSoup s = mesh::make_empty_soup("floor.test");
  mesh::Material fl{"floor", RGB::Constant(kRho), RGB::Zero(), false, {}};
  mesh::Material em{"emitter", RGB::Zero(), RGB::Constant(kLe), false, {}};
  s.materials = {s.materials[0], fl, em};
  std::map<std::array<double, 3>, int> index;
  auto add = [&](const std::vector<Vec3>& poly, int material) {
    mesh::SoupFace f;
    for (const Vec3& v : poly) {
      auto [it, added] = index.try_emplace({v.x(), v.y(), v.z()}, static_cast<int>(s.positions.size()));
      if (added) {
        s.positions.push_back(v);
        s.position_lines.push_back(0);
      }
      f.vertices.push_back(it->second);
    }
    f.material = material;
    f.line = static_cast<int>(s.faces.size()) + 1;
    s.faces.push_back(f);
  };
  for (const auto& q : mesh::shapes::grid(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), n, n)) add(q, 1);
  add(emitter(), 2);
  return s;
}

// Exact floor radiance at x: no interreflection (the floor is flat, the emitter black), so
// L(x) = rho * Le * F(dA_x -> emitter), Lambert's contour formula.
double exact_radiance(const Vec3& x) {
  const auto e = emitter();
  return kRho * kLe * formfactor::point_to_polygon(x, Vec3::UnitZ(), e);
}

// Integrates f over the parallelogram quad (corners q0..q3) with 3 x 3 Gauss points on cells no
// wider than h: L(x) varies on the scale of the emitter height (0.15 m), so h = 1/128 m resolves it.
template <class Fn>
double integrate_quad(std::span<const Vec3> q, Fn f, double h = 1.0 / 128) {
  const Vec3 u = q[1] - q[0], v = q[3] - q[0];
  const int nu = std::max(1, static_cast<int>(std::ceil(u.norm() / h - 1e-9)));
  const int nv = std::max(1, static_cast<int>(std::ceil(v.norm() / h - 1e-9)));
  const double gx[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
  const double gw[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  const double cell = u.cross(v).norm() / (nu * nv);
  double sum = 0;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          sum += gw[a] * gw[b] * cell * f(q[0] + (i + gx[a]) / nu * u + (j + gx[b]) / nv * v);
  return sum;
}

struct Errors {
  double l2 = 0;          // relative L2 error of the piecewise-constant floor radiance vs L(x)
  double patch_avg = 0;   // max |L_p - exact patch average| / max L_p (checks the reference itself)
  int floor_patches = 0;
};

Errors floor_errors(const mesh::Scene& scene, const ColorField& L) {
  Errors e;
  double err2 = 0, norm2 = 0, lmax = 0;
  for (int p = 0; p < scene.patches(); ++p) {
    if (scene.materials[scene.material[p]].name != "floor") continue;
    const auto q = scene.geometry.polygon(p);
    EXPECT_EQ(q.size(), 4u) << "patch " << p;
    const double Lp = L(p, 0);
    err2 += integrate_quad(q, [&](const Vec3& x) { return std::pow(Lp - exact_radiance(x), 2); });
    norm2 += integrate_quad(q, [&](const Vec3& x) { return std::pow(exact_radiance(x), 2); });
    const double avg = integrate_quad(q, exact_radiance) / scene.geometry.area[p];
    e.patch_avg = std::max(e.patch_avg, std::abs(Lp - avg));
    lmax = std::max(lmax, Lp);
    ++e.floor_patches;
  }
  e.l2 = std::sqrt(err2 / norm2);
  e.patch_avg /= lmax;
  return e;
}

struct Uniform {
  mesh::Scene scene;
  solver::Solution solution;
  double seconds;
};

Uniform solve_uniform(int n) {
  const auto t0 = std::chrono::steady_clock::now();
  Uniform u{mesh::build_scene(floor_scene(n)), {}, 0};
  const auto F = formfactor::assemble(u.scene.geometry);
  u.solution = solver::solve(F, u.scene.geometry.area, u.scene.reflectance_field(), u.scene.emission_field());
  u.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return u;
}

}  // namespace

// The L2 error of the piecewise-constant radiance against the exact L(x) = rho Le F(x -> emitter),
// adaptive (from a 4 x 4 floor, budget = patches of the uniform n x n floor) vs uniform n x n.
TEST(Adaptive, BeatsUniformRefinementAtEqualPatchCount) {
  for (int n : {8, 16, 32}) {
  SCOPED_TRACE("uniform " + std::to_string(n) + " x " + std::to_string(n));
  const Uniform uni = solve_uniform(n);
  const Errors eu = floor_errors(uni.scene, uni.solution.radiance);

  refine::AdaptiveOptions o;
  o.max_patches = uni.scene.patches();  // n^2 + 1
  o.tolerance = 0.01;                   // small enough that the budget, not the tolerance, stops it
  o.max_rounds = 16;
  const refine::AdaptiveResult r = refine::solve_adaptive(floor_scene(4), o);
  const Errors ea = floor_errors(r.scene, r.solution.radiance);

  std::string rounds;
  for (size_t k = 0; k < r.patches_per_round.size(); ++k)
    rounds += std::to_string(r.patches_per_round[k]) + " (max indicator " + std::to_string(r.max_indicator[k]) + ") ";
  std::printf("uniform : %d patches, L2 error %.4f, %.2f s\n", uni.scene.patches(), eu.l2, uni.seconds);
  std::printf("adaptive: %d patches, L2 error %.4f, %.2f s, stop %s, rounds: %s\n", r.scene.patches(), ea.l2,
              r.seconds, r.stop.c_str(), rounds.c_str());

  // The reference is right: each solved patch equals the exact patch average of L(x) up to the
  // form-factor tolerance (1e-8 absolute on F) and the 3x3 Gauss cells (smooth integrand), 1e-5 relative.
  EXPECT_LT(eu.patch_avg, 1e-5);
  EXPECT_LT(ea.patch_avg, 1e-5);
  EXPECT_LE(r.scene.patches(), uni.scene.patches());
  // Adaptive must be clearly better, not just by noise: at most 0.8 x the uniform error.
  EXPECT_LT(ea.l2, 0.8 * eu.l2) << "adaptive " << ea.l2 << " uniform " << eu.l2;
  }
}

// Nothing above tolerance: one solve, no refinement, and the result is the plain solve.
TEST(Adaptive, StopsWithoutRefiningWhenTheEstimateIsBelowTolerance) {
  refine::AdaptiveOptions o;
  o.max_patches = 1000;
  o.tolerance = 1e9;  // far above any estimate
  const auto first = refine::solve_adaptive(floor_scene(4), o);
  ASSERT_EQ(first.patches_per_round.size(), 1u);
  EXPECT_EQ(first.patches_per_round[0], 17);
  EXPECT_EQ(first.stop, "converged");
  // Local indicators are ranges of radiance relative to the largest reflected one: in (0, 1] here.
  EXPECT_LE(first.max_indicator[0], 1.0);
  EXPECT_GT(first.max_indicator[0], 0.0);
  // Just above the coarse estimate: still no refinement; just below: refinement.
  const double E = first.error_estimate[0];
  ASSERT_GT(E, 0.0);
  o.tolerance = 1.001 * E;
  EXPECT_EQ(refine::solve_adaptive(floor_scene(4), o).patches_per_round.size(), 1u);
  o.tolerance = 0.999 * E;
  o.max_rounds = 1;
  EXPECT_EQ(refine::solve_adaptive(floor_scene(4), o).patches_per_round.size(), 2u);
}

// Budget respected, total area kept, faces keep their input origin, and the final radiance (solved
// from the previous round's guess) equals a fresh solve of the final scene.
TEST(Adaptive, RespectsBudgetKeepsAreaAndReuseDoesNotBiasTheSolution) {
  refine::AdaptiveOptions o;
  o.max_patches = 100;
  o.tolerance = 0.01;
  o.max_rounds = 10;
  const auto r = refine::solve_adaptive(floor_scene(4), o);
  EXPECT_LE(r.scene.patches(), 100);
  EXPECT_GT(r.scene.patches(), 17);
  EXPECT_EQ(r.stop, "budget");
  double floor_area = 0;
  for (int p = 0; p < r.scene.patches(); ++p) {
    if (r.scene.materials[r.scene.material[p]].name == "floor") floor_area += r.scene.geometry.area[p];
    EXPECT_GE(r.scene.face_id[p], 0);
    EXPECT_LT(r.scene.face_id[p], 17) << "patch " << p;
  }
  EXPECT_NEAR(floor_area, 1.0, 1e-12);  // midpoint splits of squares: exact up to round-off
  const auto F = formfactor::assemble(r.scene.geometry);
  const auto fresh =
      solver::solve(F, r.scene.geometry.area, r.scene.reflectance_field(), r.scene.emission_field());
  // Both solves converge to 1e-8 relative residual; the operator is the same.
  EXPECT_LT((fresh.radiance - r.solution.radiance).cwiseAbs().maxCoeff(), 1e-7);
}

// Triangles split into 4 by edge midpoints; a hanging node still makes neighbours (indicator > 0 on
// both sides of a split edge).
TEST(Adaptive, SplitsTrianglesAndFindsNeighboursAcrossHangingNodes) {
  mesh::PolygonSoup s = floor_scene(2);
  // Replace each floor quad by two triangles.
  std::vector<mesh::SoupFace> faces;
  for (const auto& f : s.faces) {
    if (f.material != 1) {
      faces.push_back(f);
      continue;
    }
    mesh::SoupFace a = f, b = f;
    a.vertices = {f.vertices[0], f.vertices[1], f.vertices[2]};
    b.vertices = {f.vertices[0], f.vertices[2], f.vertices[3]};
    faces.push_back(a);
    faces.push_back(b);
  }
  s.faces = faces;
  refine::AdaptiveOptions o;
  o.max_patches = 60;
  o.tolerance = 0.01;
  o.max_rounds = 3;
  const auto r = refine::solve_adaptive(s, o);
  ASSERT_GE(r.patches_per_round.size(), 2u);
  EXPECT_EQ(r.patches_per_round[0], 9);
  EXPECT_GT(r.scene.patches(), 9);
  double floor_area = 0;
  for (int p = 0; p < r.scene.patches(); ++p) {
    if (r.scene.material[p] == 1) {
      EXPECT_EQ(r.scene.geometry.polygon(p).size(), 3u) << "patch " << p;
      floor_area += r.scene.geometry.area[p];
    }
  }
  EXPECT_NEAR(floor_area, 1.0, 1e-12);
  // Every floor patch touches another floor patch along an edge, so with a non-uniform L every one
  // has a neighbour; an indicator of 0 would mean a missed neighbour (L differs between any two).
  const auto ind = refine::jump_indicator(r.scene, r.solution.radiance);
  for (int p = 0; p < r.scene.patches(); ++p) {
    if (r.scene.material[p] == 1) {
      EXPECT_GT(ind[p], 0.0) << "patch " << p;
    }
  }
}

// Soup from polygons with one material per polygon (corners welded by position).
mesh::PolygonSoup soup_of(const std::vector<std::vector<Vec3>>& polys, const std::vector<int>& material,
                          std::vector<mesh::Material> materials) {
  mesh::PolygonSoup s = mesh::make_empty_soup("shapes.test");
  s.materials.insert(s.materials.end(), materials.begin(), materials.end());
  std::map<std::array<double, 3>, int> index;
  for (size_t k = 0; k < polys.size(); ++k) {
    mesh::SoupFace f;
    for (const Vec3& v : polys[k]) {
      auto [it, added] = index.try_emplace({v.x(), v.y(), v.z()}, static_cast<int>(s.positions.size()));
      if (added) {
        s.positions.push_back(v);
        s.position_lines.push_back(0);
      }
      f.vertices.push_back(it->second);
    }
    f.material = material[k];
    f.line = static_cast<int>(k) + 1;
    s.faces.push_back(f);
  }
  return s;
}

// A closed unit room (3 x 3 quads per wall, rho = 0.6) with a floating block, lit by the ceiling's
// centre quad: interreflection and occlusion, so reused pairs include ray-tested ones.
mesh::PolygonSoup lit_room_with_block() {
  const auto polys = mesh::shapes::room_with_block(3, 1);
  std::vector<int> material(polys.size(), 1);
  int lamps = 0;
  for (size_t k = 0; k < polys.size(); ++k) {
    Vec3 c = Vec3::Zero();
    for (const Vec3& v : polys[k]) c += v / static_cast<double>(polys[k].size());
    if ((c - Vec3(0.5, 0.5, 1.0)).norm() < 1e-9) material[k] = 2, ++lamps;
  }
  EXPECT_EQ(lamps, 1);
  return soup_of(polys, material,
                 {{"white", RGB::Constant(0.6), RGB::Zero(), false, {}}, {"lamp", RGB::Zero(), RGB::Constant(1.0), false, {}}});
}

// Reusing the previous round's form factors changes nothing but the work: every pair of two unsplit
// patches is copied, and the final radiance is what a fresh assembly of the final scene gives.
TEST(Adaptive, ReusedFormFactorsGiveTheSameSolution) {
  for (bool visibility : {false, true}) {
    SCOPED_TRACE(visibility ? "with visibility" : "without visibility");
    refine::AdaptiveOptions o;
    o.max_patches = 400;
    o.tolerance = 0.02;
    o.max_rounds = 3;
    o.ff.visibility = visibility;
    o.ff.rays_per_pair = 64;  // less ray noise between reused and fresh entries (see the bound below)
    const auto r = refine::solve_adaptive(lit_room_with_block(), o);
    ASSERT_EQ(r.rounds.size(), 4u);
    EXPECT_EQ(r.rounds[0].pairs_reused, 0);
    for (size_t k = 1; k < r.rounds.size(); ++k) {
      // Patches kept from round k-1 = patches of k-1 minus those split there.
      const long long kept = r.rounds[k - 1].patches - r.rounds[k - 1].split;
      EXPECT_EQ(r.rounds[k].pairs_reused, kept * (kept - 1) / 2) << "round " << k;
      std::printf("round %zu: %d patches, %lld of %lld pairs reused, form factors %.3f s\n", k, r.rounds[k].patches,
                  r.rounds[k].pairs_reused, r.rounds[k].pairs_total, r.rounds[k].assemble_seconds);
    }
    const auto F = formfactor::assemble(r.scene.geometry, o.ff);
    const auto fresh = solver::solve(F, r.scene.geometry.area, r.scene.reflectance_field(), r.scene.emission_field());
    const ColorField diff = (r.solution.radiance - fresh.radiance).cwiseAbs();
    double mean = 0, norm = 0;  // area-weighted mean |difference| / mean radiance
    for (int p = 0; p < r.scene.patches(); ++p) {
      mean += r.scene.geometry.area[p] * diff.row(p).sum();
      norm += r.scene.geometry.area[p] * fresh.radiance.row(p).sum();
    }
    mean /= norm;
    const double largest = diff.maxCoeff() / fresh.radiance.maxCoeff();
    std::printf("radiance difference, reuse vs fresh: largest %.3g of the maximum, mean %.3g\n", largest, mean);
    if (!visibility) {
      // Both matrices agree to the form-factor tolerance (1e-8 per entry); both solves stop at 1e-8.
      EXPECT_LT(largest, 1e-6);
    } else {
      // Visible fractions are 64-ray estimates whose samples are seeded by patch index, which shifts when
      // patches split, so a fresh pair gets other samples than the copied one: differences at the level
      // of ray noise (measured: largest 0.06% of the maximum, mean 0.1%). A wrong pair copied would be off
      // by the size of a form factor.
      EXPECT_LT(largest, 1e-2);
      EXPECT_LT(mean, 1e-2);
    }
  }
}

// A black block (the shadow caster) between a small emitter high above and a floor in 5 x 5 quads: the
// block's top [0.4,0.6]^2 at z = 1 and the emitter at z = 2 put the shadow edge on the floor along
// x, y = 0.3 and 0.7, through the middles of the ring of 8 quads around the centre one. The direct
// indicator must mark exactly those: the centre quad is in full shadow (direct radiance 0 everywhere),
// the outer 16 are fully lit, where the direct radiance varies by less than 10% of its maximum (a
// point-like source 2 m above, cos^4 falloff over 0.2 m cells).
TEST(Adaptive, DirectIndicatorMarksPatchesStraddlingAShadowEdge) {
  std::vector<std::vector<Vec3>> polys = mesh::shapes::grid(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), 5, 5);
  std::vector<int> material(polys.size(), 1);
  for (const auto& q : mesh::shapes::box({0.4, 0.4, 0.9}, {0.6, 0.6, 1.0}, 1, false)) {
    polys.push_back(q);
    material.push_back(2);
  }
  const double a = 0.49, b = 0.51;  // 2 cm emitter facing down: penumbra ~1 cm wide
  polys.push_back({{a, a, 2}, {a, b, 2}, {b, b, 2}, {b, a, 2}});
  material.push_back(3);
  const auto soup = soup_of(polys, material,
                            {{"floor", RGB::Constant(0.5), RGB::Zero(), false, {}},
                             {"block", RGB::Zero(), RGB::Zero(), false, {}},
                             {"lamp", RGB::Zero(), RGB::Constant(1.0), false, {}}});
  const mesh::Scene scene = mesh::build_scene(soup);
  const auto F = formfactor::assemble(scene.geometry);
  const auto sol = solver::solve(F, scene.geometry.area, scene.reflectance_field(), scene.emission_field());
  const auto ind = refine::direct_indicator(scene, sol.radiance);
  for (int p = 0; p < 25; ++p) {
    const int i = p / 5, j = p % 5;  // grid order: row by row
    const bool centre = i == 2 && j == 2, ring = !centre && i >= 1 && i <= 3 && j >= 1 && j <= 3;
    SCOPED_TRACE("floor quad " + std::to_string(p) + " centroid " + std::to_string(scene.geometry.centroid[p].x()) +
                 ", " + std::to_string(scene.geometry.centroid[p].y()));
    if (ring) {
      EXPECT_GT(ind[p], 0.5);  // lit and shadowed sample points: an oscillation near the full value
    } else if (centre) {
      EXPECT_EQ(ind[p], 0.0);
    } else {
      EXPECT_LT(ind[p], 0.1);
    }
  }
  for (int p = 25; p < scene.patches(); ++p) EXPECT_EQ(ind[p], 0.0) << "patch " << p << " (rho = 0)";
}

// Split midpoints are welded: after several rounds no two vertices of the soup share a position (so
// build_scene reports no duplicate vertices), and faces split on both sides of an edge share its midpoint.
TEST(Adaptive, SplitCornersAreWelded) {
  refine::AdaptiveOptions o;
  o.max_patches = 300;
  o.tolerance = 0.01;
  o.max_rounds = 5;
  const auto r = refine::solve_adaptive(lit_room_with_block(), o);
  ASSERT_GT(r.patches_per_round.size(), 2u);
  std::map<std::array<double, 3>, int> seen;
  for (size_t v = 0; v < r.soup.positions.size(); ++v) {
    const Vec3& x = r.soup.positions[v];
    const auto [it, added] = seen.try_emplace({x.x(), x.y(), x.z()}, static_cast<int>(v));
    EXPECT_TRUE(added) << "vertices " << it->second << " and " << v << " at " << x.transpose();
  }
  EXPECT_EQ(r.scene.report.counts.count("duplicate_vertices"), 0u);
}

TEST(Adaptive, RejectsInvalidOptions) {
  const auto s = floor_scene(2);
  refine::AdaptiveOptions o;
  o.tolerance = 0;
  EXPECT_THROW(refine::solve_adaptive(s, o), InputError);
  o.tolerance = 0.1;
  o.max_rounds = -1;
  EXPECT_THROW(refine::solve_adaptive(s, o), InputError);
  o.max_rounds = 2;
  o.max_patches = 3;  // the input already has 5 patches
  EXPECT_THROW(refine::solve_adaptive(s, o), InputError);
}
