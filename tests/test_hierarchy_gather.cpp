// The hierarchy's far-link kernel (formfactor/src/batch.hpp, gather_links): the third-order expansion of the point
// kernel about both cluster centres, evaluated 8 links at a time, against the point kernel summed directly.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "batch_kernels_util.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert {
namespace {

namespace fd = formfactor::detail;
constexpr double kPi = 3.14159265358979323846;
using fd::kPairMult;
using fd::kPairs;
using fd::kTripleMult;
using fd::kTriples;

// A source cluster: points c + b_j with normals n_j and weights w_j = A_j x_j.
struct Cluster {
  Vec3 c;
  std::vector<Vec3> b, n;
  std::vector<double> w;
};

Vec3 unit(std::mt19937& rng) {
  std::normal_distribution<double> N;
  Vec3 v(N(rng), N(rng), N(rng));
  return v.normalized();
}

Cluster random_cluster(std::mt19937& rng, const Vec3& c, double size, int count) {
  std::uniform_real_distribution<double> U(-1, 1), Uw(0.2, 1);
  Cluster k{c, {}, {}, {}};
  for (int j = 0; j < count; ++j) {
    k.b.push_back(size * Vec3(U(rng), U(rng), U(rng)));
    k.n.push_back(unit(rng));
    k.w.push_back(Uw(rng));
  }
  return k;
}

// The record gather_links reads: centre, V = sum w n, W = sum w n b^T, T(:, kl) = sum w n b_k b_l,
// U(:, klm) = sum w n b_k b_l b_m (column-major).
std::array<double, fd::kMomentRecord> record(const Cluster& k) {
  std::array<double, fd::kMomentRecord> r{};
  for (int i = 0; i < 3; ++i) r[size_t(i)] = k.c[i];
  for (size_t j = 0; j < k.b.size(); ++j) {
    const Vec3 v = k.w[j] * k.n[j];
    for (int i = 0; i < 3; ++i) {
      r[size_t(3 + i)] += v[i];
      for (int col = 0; col < 3; ++col) r[size_t(6 + 3 * col + i)] += v[i] * k.b[j][col];
      for (int kl = 0; kl < 6; ++kl) r[size_t(15 + 3 * kl + i)] += v[i] * k.b[j][kPairs[kl][0]] * k.b[j][kPairs[kl][1]];
      for (int q = 0; q < 10; ++q)
        r[size_t(33 + 3 * q + i)] += v[i] * k.b[j][kTriples[q][0]] * k.b[j][kTriples[q][1]] * k.b[j][kTriples[q][2]];
    }
  }
  return r;
}

// n . sum_j w_j K(p_j - x) n_j, K(u) = -u u^T / (pi |u|^4): the point kernel summed directly.
double direct(const std::vector<Cluster>& src, const std::vector<float>& vis, const Vec3& x, const Vec3& n) {
  double s = 0;
  for (size_t e = 0; e < src.size(); ++e)
    for (size_t j = 0; j < src[e].b.size(); ++j) {
      const Vec3 u = src[e].c + src[e].b[j] - x;
      const double r2 = u.squaredNorm();
      s += double(vis[e]) * src[e].w[j] * -(n.dot(u)) * (src[e].n[j].dot(u)) / (kPi * r2 * r2);
    }
  return s;
}

// n . (g - J a + H[a, a] / 2 - C[a, a, a] / 6) from gather_links' output about the receiver centre ca, at x = ca + a.
double expanded(const fd::BatchKernels& K, const std::vector<Cluster>& src, const std::vector<float>& vis,
                const Vec3& ca, const Vec3& a, const Vec3& n) {
  std::vector<double> rec;
  std::vector<int> idx;
  for (size_t e = 0; e < src.size(); ++e) {
    const auto r = record(src[e]);
    rec.insert(rec.end(), r.begin(), r.end());
    idx.push_back(int(e));
  }
  double out[fd::kLocalRecord] = {};
  K.gather_links(rec.data(), ca.data(), idx.data(), vis.data(), (long long)src.size(), out);
  Vec3 G(out[0], out[1], out[2]);
  for (int col = 0; col < 3; ++col)
    for (int row = 0; row < 3; ++row) G[row] -= out[3 + 3 * col + row] * a[col];
  for (int kl = 0; kl < 6; ++kl)
    for (int row = 0; row < 3; ++row)
      G[row] += 0.5 * kPairMult[kl] * a[kPairs[kl][0]] * a[kPairs[kl][1]] * out[12 + 3 * kl + row];
  for (int q = 0; q < 10; ++q)
    for (int row = 0; row < 3; ++row)
      G[row] -= kTripleMult[q] / 6 * a[kTriples[q][0]] * a[kTriples[q][1]] * a[kTriples[q][2]] * out[30 + 3 * q + row];
  return n.dot(G);
}

using batchtest::supported_kernels;

// The expansion is of third order in the source offsets b and the receiver offset a: its error relative to the
// directly summed kernel falls like (size / distance)^4. 13 links per call (one full step of 8 lanes and a padded
// one), sources spread round the receiver at distance 1, cluster sizes s = 0.04 and s / 2. Tolerance: the ratio
// of the two errors below 1/11 (1/16 in the limit, 1/8 for a wrong third-order term), and the error at s = 0.02
// below 2e-6 relative (fourth order: (0.02 * sqrt 3 * 2)^4 ~ 1.8e-5 times the expansion's small coefficients,
// summed over 13 links of either sign).
TEST(HierarchyGather, ExpansionErrorFallsWithTheFourthPowerOfTheClusterSize) {
  for (const fd::BatchKernels* K : supported_kernels()) {
    double err[2] = {0, 0}, scale = 0;
    for (int trial = 0; trial < 20; ++trial) {
      for (int h = 0; h < 2; ++h) {
        const double s = h == 0 ? 0.04 : 0.02;
        std::mt19937 rng(1000 + trial);  // the same configuration at both sizes
        const Vec3 ca(0.3, -0.2, 0.5);
        std::vector<Cluster> src;
        std::vector<float> vis;
        std::uniform_real_distribution<double> Uv(0.1, 1.0);
        for (int e = 0; e < 13; ++e) {
          src.push_back(random_cluster(rng, ca + unit(rng), s, 6));
          vis.push_back(float(Uv(rng)));
        }
        std::uniform_real_distribution<double> U(-1, 1);
        const Vec3 a = s * Vec3(U(rng), U(rng), U(rng));
        const Vec3 n = unit(rng);
        const double want = direct(src, vis, ca + a, n), got = expanded(*K, src, vis, ca, a, n);
        double mag = 0;  // the sum of the terms' magnitudes: the scale of the error
        for (size_t e = 0; e < src.size(); ++e)
          for (size_t j = 0; j < src[e].b.size(); ++j) mag += src[e].w[j] * vis[e] / kPi;
        err[h] += std::abs(got - want) / mag;
        if (h == 1) scale += mag;
        if (!(std::abs(got - want) / mag < 1e-3))
          ADD_FAILURE() << K->name << " trial " << trial << " size " << s << ": expansion " << got << " direct "
                        << want;
      }
    }
    const double ratio = err[1] / err[0];
    std::printf("%s: mean relative error %.3e at s = 0.04, %.3e at s = 0.02, ratio %.4f (1/16 = 0.0625)\n", K->name,
                err[0] / 20, err[1] / 20, ratio);
    EXPECT_LT(ratio, 1 / 11.0) << K->name << ": errors " << err[0] / 20 << " and " << err[1] / 20;
    EXPECT_LT(err[1] / 20, 2e-6) << K->name;
  }
}

// Every instruction set gives the generic kernel's sums to rounding (1e-12 relative to the largest output): the
// same expression compiled three times, FMA contraction the only difference. 1 to 40 links per call.
TEST(HierarchyGather, SameOnEveryInstructionSet) {
  const auto kernels = supported_kernels();
  std::mt19937 rng(5);
  std::vector<double> rec;
  std::vector<Vec3> centres;
  for (int b = 0; b < 50; ++b) {
    const Vec3 c = 3 * unit(rng);
    const auto r = record(random_cluster(rng, c, 0.2, 5));
    rec.insert(rec.end(), r.begin(), r.end());
  }
  std::uniform_int_distribution<int> Ub(0, 49);
  std::uniform_real_distribution<double> Uv(0, 1);
  for (int count = 1; count <= 40; ++count) {
    std::vector<int> src;
    std::vector<float> vis;
    for (int e = 0; e < count; ++e) src.push_back(Ub(rng)), vis.push_back(float(Uv(rng)));
    const Vec3 ca(0.05, -0.02, 0.01);
    double ref[fd::kLocalRecord] = {};
    kernels[0]->gather_links(rec.data(), ca.data(), src.data(), vis.data(), count, ref);
    double big = 0;
    for (double v : ref) big = std::max(big, std::abs(v));
    ASSERT_GT(big, 0) << "count " << count;
    for (size_t k = 1; k < kernels.size(); ++k) {
      double out[fd::kLocalRecord] = {};
      kernels[k]->gather_links(rec.data(), ca.data(), src.data(), vis.data(), count, out);
      for (int c = 0; c < fd::kLocalRecord; ++c)
        EXPECT_NEAR(out[c], ref[c], 1e-12 * big) << kernels[k]->name << " count " << count << " output " << c;
    }
  }
}

}  // namespace
}  // namespace lambert
