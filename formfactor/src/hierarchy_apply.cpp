// Hierarchical operator: y = F x by pull (cluster moments), gather (far links, first-order expansion of the
// kernel about both cluster centres), push (down to the patches) plus the exact leaf entries; rows streamed
// entry by entry; the memory limit.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <unistd.h>

#include "hierarchy_internal.hpp"

namespace lambert::formfactor {

using detail::HNode;
using detail::kPi;
using Mat3 = Eigen::Matrix3d;

HierarchicalOperator::HierarchicalOperator() : d_(std::make_unique<Impl>()) {}
HierarchicalOperator::~HierarchicalOperator() = default;
HierarchicalOperator::HierarchicalOperator(HierarchicalOperator&&) noexcept = default;
HierarchicalOperator& HierarchicalOperator::operator=(HierarchicalOperator&&) noexcept = default;

int HierarchicalOperator::size() const { return d_->n; }

double HierarchicalOperator::row_dot(int, const Eigen::Ref<const Eigen::VectorXd>&) const {
  LAMBERT_CHECK(false, "the hierarchical operator stores no rows (has_rows() is false): use a Krylov or Jacobi solve");
  return 0;
}

double HierarchicalOperator::row_sum(int i) const { return d_->row_sums.empty() ? 0.0 : d_->row_sums[size_t(i)]; }

namespace {

// Gather of one far link into the receiver's (g, J), given the source's moments (V, W) and u = c_B - c_A:
// sum_j K(u + b_j - a) A_j x_j n_j ~ K V + sum_k d_k K W(:, k) - J a, with K(u) = -u u^T / (pi |u|^4).
inline void gather(const Vec3& u, double vis, const Vec3& V, const Mat3& W, Vec3& g, Mat3& J) {
  const double r2 = u.squaredNorm(), i4 = 1 / (kPi * r2 * r2), i6 = i4 / r2;
  const double uV = u.dot(V);
  const Vec3 Wtu = W.transpose() * u;
  const double uWu = u.dot(W * u), tr = W.trace();
  g += vis * (-uV * i4 * u + (-Wtu - tr * u) * i4 + 4 * uWu * i6 * u);
  // J = -(u.V) I / (pi r^4) - u V^T / (pi r^4) + 4 (u.V) u u^T / (pi r^6)
  J += vis * (-uV * i4 * Mat3::Identity() - i4 * u * V.transpose() + 4 * uV * i6 * u * u.transpose());
}

}  // namespace

void HierarchicalOperator::apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const Impl& d = *d_;
  const int n = d.n, nn = int(d.nodes.size());
  if (n == 0) return;
  const mesh::PatchGeometry& g = *d.g;
  // Pull: per node V = sum A x n, W = sum A x n (c_p - c_node)^T (children after parents: reverse order).
  std::vector<Vec3> V(nn);
  std::vector<Mat3> W(nn);
  for (int k = nn - 1; k >= 0; --k) {
    const HNode& nd = d.nodes[k];
    if (nd.leaf()) {
      const int p = d.perm[nd.begin];
      V[k] = g.area[p] * x[p] * g.normal[p];
      W[k].setZero();
    } else {
      const int a = nd.left, b = nd.right;
      V[k] = V[a] + V[b];
      W[k] = W[a] + V[a] * (d.nodes[a].c - nd.c).transpose() + W[b] + V[b] * (d.nodes[b].c - nd.c).transpose();
    }
  }
  // Gather: each receiver node sums its own links in stored order (deterministic for any thread count).
  std::vector<Vec3> G(nn, Vec3::Zero());
  std::vector<Mat3> J(nn, Mat3::Zero());
  tbb::parallel_for(tbb::blocked_range<int>(0, nn, 256), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k < r.end(); ++k) {
      const std::int64_t e0 = d.far_off[k], e1 = d.far_off[k + 1];
      if (e0 == e1) continue;
      Vec3 gk = Vec3::Zero();
      Mat3 Jk = Mat3::Zero();
      const Vec3& ca = d.nodes[k].c;
      for (std::int64_t e = e0; e < e1; ++e) {
        const int b = d.far_src[e];
        gather(d.nodes[b].c - ca, double(d.far_vis[e]), V[b], W[b], gk, Jk);
      }
      G[k] = gk;
      J[k] = Jk;
    }
  });
  // Push: a child at offset a from its parent's centre receives g - J a and J.
  for (int k = 1; k < nn; ++k) {
    const HNode& nd = d.nodes[k];
    const int p = nd.parent;
    G[k] += G[p] - J[p] * (nd.c - d.nodes[p].c);
    J[k] += J[p];
  }
  // Leaves: n_i . g plus the exact entries.
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) {
      double s = g.normal[i].dot(G[d.leaf_of[i]]);
      for (std::int64_t e = d.leaf_off[i]; e < d.leaf_off[i + 1]; ++e) s += d.leaf_F[e] * x[d.leaf_src[e]];
      y[i] = s;
    }
  });
}

void HierarchicalOperator::for_each_in_row(int i, const std::function<void(int j, double F)>& f) const {
  const Impl& d = *d_;
  for (std::int64_t e = d.leaf_off[i]; e < d.leaf_off[i + 1]; ++e) f(d.leaf_src[e], d.leaf_F[e]);
  const detail::PatchData& P = d.P;
  for (int k = d.leaf_of[i]; k >= 0; k = d.nodes[k].parent)
    for (std::int64_t e = d.far_off[k]; e < d.far_off[k + 1]; ++e) {
      const HNode& B = d.nodes[d.far_src[e]];
      const double vis = d.far_vis[e];
      for (int q = B.begin; q < B.end; ++q) {
        const int j = d.perm[q];
        f(j, vis * detail::far_field(P.c[i], P.nrm[i], P.M[i], P.c[j], P.nrm[j], P.M[j], P.area[j]));
      }
    }
}

void stream_faces(const HierarchicalOperator& F, const mesh::PatchGeometry& g, const std::vector<int>& face_id,
                  int input_faces, double min_factor, const std::function<void(int I, int J, double F)>& emit) {
  const int n = g.size();
  LAMBERT_CHECK(F.size() == n && face_id.size() == size_t(n), "stream_faces: sizes differ");
  std::vector<std::vector<int>> patches(size_t(std::max(input_faces, 0)));
  for (int p = 0; p < n; ++p) {
    LAMBERT_CHECK(face_id[p] >= 0 && face_id[p] < input_faces, "stream_faces: face id out of range");
    patches[size_t(face_id[p])].push_back(p);
  }
  std::vector<double> acc(size_t(std::max(input_faces, 0)), 0.0);
  std::vector<int> touched;
  for (int I = 0; I < input_faces; ++I) {
    double area = 0;
    for (int i : patches[I]) {
      area += g.area[i];
      const double Ai = g.area[i];
      F.for_each_in_row(i, [&](int j, double f) {
        const int J = face_id[j];
        if (acc[J] == 0 && f != 0) touched.push_back(J);
        acc[J] += Ai * f;
      });
    }
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    for (int J : touched) {
      const double v = acc[J] / area;
      acc[J] = 0;
      if (v != 0 && v >= min_factor) emit(I, J, v);
    }
    touched.clear();
  }
}

MemoryLimit system_memory_limit() {
  MemoryLimit m;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  m.bytes = pages > 0 && page > 0 ? std::size_t(double(pages) * double(page)) : (std::size_t(8) << 30);
  m.source = "physical memory";
  auto read_number = [](const char* path, std::size_t& out) {
    std::ifstream f(path);
    std::string s;
    if (!(f >> s) || s == "max") return false;
    try {
      out = std::stoull(s);
    } catch (...) {
      return false;
    }
    return true;
  };
  std::size_t limit = 0, usage = 0;
  if (read_number("/sys/fs/cgroup/memory.max", limit)) {
    read_number("/sys/fs/cgroup/memory.current", usage);
    const std::size_t free = limit > usage ? limit - usage : 0;
    if (free < m.bytes) m = {free, "cgroup memory.max minus memory.current"};
  } else if (read_number("/sys/fs/cgroup/memory/memory.limit_in_bytes", limit) && limit < (std::size_t(1) << 60)) {
    read_number("/sys/fs/cgroup/memory/memory.usage_in_bytes", usage);
    const std::size_t free = limit > usage ? limit - usage : 0;
    if (free < m.bytes) m = {free, "cgroup memory.limit_in_bytes minus usage"};
  }
  std::ifstream mi("/proc/meminfo");
  std::string key, unit;
  std::size_t kb = 0;
  while (mi >> key >> kb >> unit)
    if (key == "MemAvailable:") {
      if (kb * 1024 < m.bytes) m = {kb * 1024, "MemAvailable in /proc/meminfo"};
      break;
    }
  return m;
}

}  // namespace lambert::formfactor
