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

// count points within size of c; flat: in the plane through c normal to `normal`, all with that normal.
Cluster random_cluster(std::mt19937& rng, const Vec3& c, double size, int count, const Vec3* normal = nullptr) {
  std::uniform_real_distribution<double> U(-1, 1), Uw(0.2, 1);
  Cluster k{c, {}, {}, {}};
  for (int j = 0; j < count; ++j) {
    Vec3 b = size * Vec3(U(rng), U(rng), U(rng));
    if (normal) b -= normal->dot(b) * *normal;
    k.b.push_back(b);
    k.n.push_back(normal ? *normal : unit(rng));
    k.w.push_back(Uw(rng));
  }
  return k;
}

// The records the kernels read: gather_links centre, V = sum w n, W = sum w n b^T, T(:, kl) = sum w n b_k b_l,
// U(:, klm) = sum w n b_k b_l b_m (column-major); gather_links_flat the centre, the first point's normal as the
// axis and the scalar moments sum w b^t.
struct Records {
  std::array<double, fd::kVectorRecord> v{};
  std::array<double, fd::kScalarRecord> s{};
};
Records record(const Cluster& k) {
  Records rr;
  auto& r = rr.v;
  for (int i = 0; i < 3; ++i) r[size_t(i)] = rr.s[size_t(i)] = k.c[i];
  for (int i = 0; i < 3; ++i) rr.s[size_t(3 + i)] = k.n[0][i];
  for (size_t j = 0; j < k.b.size(); ++j) {
    const Vec3 v = k.w[j] * k.n[j];
    for (int i = 0; i < 3; ++i) {
      r[size_t(3 + i)] += v[i];
      for (int col = 0; col < 3; ++col) r[size_t(6 + 3 * col + i)] += v[i] * k.b[j][col];
      for (int kl = 0; kl < 6; ++kl) r[size_t(15 + 3 * kl + i)] += v[i] * k.b[j][kPairs[kl][0]] * k.b[j][kPairs[kl][1]];
      for (int q = 0; q < 10; ++q)
        r[size_t(33 + 3 * q + i)] += v[i] * k.b[j][kTriples[q][0]] * k.b[j][kTriples[q][1]] * k.b[j][kTriples[q][2]];
    }
    double* sm = rr.s.data() + 6;
    sm[0] += k.w[j];
    for (int i = 0; i < 3; ++i) sm[1 + i] += k.w[j] * k.b[j][i];
    for (int kl = 0; kl < 6; ++kl) sm[4 + kl] += k.w[j] * k.b[j][kPairs[kl][0]] * k.b[j][kPairs[kl][1]];
    for (int q = 0; q < 10; ++q)
      sm[10 + q] += k.w[j] * k.b[j][kTriples[q][0]] * k.b[j][kTriples[q][1]] * k.b[j][kTriples[q][2]];
  }
  return rr;
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

// n . (g - J a + H[a, a] / 2 - C[a, a, a] / 6) from gather_links' output about the receiver centre ca, at x = ca + a
// (flat: the same from gather_links_flat's scalar record, with n as the receiver's axis).
double expanded(const fd::BatchKernels& K, const std::vector<Cluster>& src, const std::vector<float>& vis,
                const Vec3& ca, const Vec3& a, const Vec3& n, bool flat = false) {
  std::vector<double> rv, rs;
  std::vector<int> idx;
  for (size_t e = 0; e < src.size(); ++e) {
    const Records r = record(src[e]);
    rv.insert(rv.end(), r.v.begin(), r.v.end());
    rs.insert(rs.end(), r.s.begin(), r.s.end());
    idx.push_back(int(e));
  }
  const int R = flat ? 1 : 3;  // rows per index tuple
  double out[fd::kLocalRecord] = {};
  if (flat)
    K.gather_links_flat(rs.data(), ca.data(), n.data(), idx.data(), vis.data(), (long long)src.size(), out);
  else
    K.gather_links(rv.data(), ca.data(), idx.data(), vis.data(), (long long)src.size(), out);
  Eigen::Vector3d G = Eigen::Vector3d::Zero();
  for (int row = 0; row < R; ++row) {
    G[row] = out[row];
    for (int col = 0; col < 3; ++col) G[row] -= out[R * (1 + col) + row] * a[col];
    for (int kl = 0; kl < 6; ++kl)
      G[row] += 0.5 * kPairMult[kl] * a[kPairs[kl][0]] * a[kPairs[kl][1]] * out[R * (4 + kl) + row];
    for (int q = 0; q < 10; ++q)
      G[row] -= kTripleMult[q] / 6 * a[kTriples[q][0]] * a[kTriples[q][1]] * a[kTriples[q][2]] * out[R * (10 + q) + row];
  }
  return flat ? G[0] : n.dot(G);
}

using batchtest::supported_kernels;

// The expansion is of third order in the source offsets b and the receiver offset a: its error relative to the
// directly summed kernel falls like (size / distance)^4. 13 links per call (one full step of 8 lanes and a padded
// one), sources spread round the receiver at distance 1, cluster sizes s = 0.04 and s / 2. Tolerance: the ratio
// of the two errors below 1/11 (1/16 in the limit, 1/8 for a wrong third-order term), and the error at s = 0.02
// below 2e-6 relative (fourth order: (0.02 * sqrt 3 * 2)^4 ~ 1.8e-5 times the expansion's small coefficients,
// summed over 13 links of either sign).
// Both kernels: any clusters (gather_links) and flat ones (gather_links_flat: points in a plane, one normal; the
// receiver point in its plane).
TEST(HierarchyGather, ExpansionErrorFallsWithTheFourthPowerOfTheClusterSize) {
  for (const fd::BatchKernels* K : supported_kernels())
    for (const bool flat : {false, true}) {
      double err[2] = {0, 0};
      for (int trial = 0; trial < 20; ++trial) {
        for (int h = 0; h < 2; ++h) {
          const double s = h == 0 ? 0.04 : 0.02;
          std::mt19937 rng(1000 + trial);  // the same configuration at both sizes
          const Vec3 ca(0.3, -0.2, 0.5);
          const Vec3 n = unit(rng);
          std::vector<Cluster> src;
          std::vector<float> vis;
          std::uniform_real_distribution<double> Uv(0.1, 1.0);
          for (int e = 0; e < 13; ++e) {
            const Vec3 dir = unit(rng), w = unit(rng);
            src.push_back(random_cluster(rng, ca + dir, s, 6, flat ? &w : nullptr));
            vis.push_back(float(Uv(rng)));
          }
          std::uniform_real_distribution<double> U(-1, 1);
          Vec3 a = s * Vec3(U(rng), U(rng), U(rng));
          if (flat) a -= n.dot(a) * n;
          const double want = direct(src, vis, ca + a, n), got = expanded(*K, src, vis, ca, a, n, flat);
          double mag = 0;  // the sum of the terms' magnitudes: the scale of the error
          for (size_t e = 0; e < src.size(); ++e)
            for (size_t j = 0; j < src[e].b.size(); ++j) mag += src[e].w[j] * vis[e] / kPi;
          err[h] += std::abs(got - want) / mag;
          if (!(std::abs(got - want) / mag < 1e-3))
            ADD_FAILURE() << K->name << (flat ? " flat" : "") << " trial " << trial << " size " << s
                          << ": expansion " << got << " direct " << want;
        }
      }
      const double ratio = err[1] / err[0];
      std::printf("%s%s: mean relative error %.3e at s = 0.04, %.3e at s = 0.02, ratio %.4f (1/16 = 0.0625)\n",
                  K->name, flat ? " flat" : "", err[0] / 20, err[1] / 20, ratio);
      EXPECT_LT(ratio, 1 / 11.0) << K->name << (flat ? " flat" : "") << ": errors " << err[0] / 20 << " and "
                                 << err[1] / 20;
      EXPECT_LT(err[1] / 20, 2e-6) << K->name << (flat ? " flat" : "");
    }
}

// Every instruction set gives the generic kernel's sums to rounding (1e-12 relative to the largest output): the
// same expression compiled three times, FMA contraction the only difference. 1 to 40 links per call, both kernels.
TEST(HierarchyGather, SameOnEveryInstructionSet) {
  const auto kernels = supported_kernels();
  std::mt19937 rng(5);
  std::vector<double> rv, rs;
  for (int b = 0; b < 50; ++b) {
    const Vec3 c = 3 * unit(rng);
    const Records r = record(random_cluster(rng, c, 0.2, 5));
    rv.insert(rv.end(), r.v.begin(), r.v.end());
    rs.insert(rs.end(), r.s.begin(), r.s.end());
  }
  std::uniform_int_distribution<int> Ub(0, 49);
  std::uniform_real_distribution<double> Uv(0, 1);
  for (int count = 1; count <= 40; ++count) {
    std::vector<int> src;
    std::vector<float> vis;
    for (int e = 0; e < count; ++e) src.push_back(Ub(rng)), vis.push_back(float(Uv(rng)));
    const Vec3 ca(0.05, -0.02, 0.01), na = Vec3(0.3, -0.5, 0.8).normalized();
    for (const bool flat : {false, true}) {  // (flat: the records' axes and scalar moments as if flat)
      auto run = [&](const fd::BatchKernels& K, double* out) {
        if (flat)
          K.gather_links_flat(rs.data(), ca.data(), na.data(), src.data(), vis.data(), count, out);
        else
          K.gather_links(rv.data(), ca.data(), src.data(), vis.data(), count, out);
      };
      const int outputs = flat ? fd::kTuples : fd::kLocalRecord;
      double ref[fd::kLocalRecord] = {};
      run(*kernels[0], ref);
      double big = 0;
      for (double v : ref) big = std::max(big, std::abs(v));
      ASSERT_GT(big, 0) << "count " << count;
      for (size_t k = 1; k < kernels.size(); ++k) {
        double out[fd::kLocalRecord] = {};
        run(*kernels[k], out);
        for (int c = 0; c < outputs; ++c)
          EXPECT_NEAR(out[c], ref[c], 1e-12 * big)
              << kernels[k]->name << (flat ? " flat" : "") << " count " << count << " output " << c;
      }
    }
  }
}

}  // namespace
}  // namespace lambert
