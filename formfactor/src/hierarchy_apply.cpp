// Hierarchical operator: y = F x by pull (cluster moments), gather (far links, second-order expansion of the
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

#include "batch.hpp"
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

using Mat36 = Eigen::Matrix<double, 3, 6>;  // a vector per symmetric index pair kl: xx yy zz xy xz yz
constexpr int kK[6] = {0, 1, 2, 0, 0, 1}, kL[6] = {0, 1, 2, 1, 2, 2};
constexpr double kMult[6] = {1, 1, 1, 2, 2, 2};  // sum over k, l of a symmetric form = sum over kl of mult x

}  // namespace

void HierarchicalOperator::apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const Impl& d = *d_;
  const int n = d.n, nn = int(d.nodes.size());
  if (n == 0) return;
  const mesh::PatchGeometry& g = *d.g;
  const detail::PatchData& P = d.P;
  // Pull: per node V = sum A x n, W = sum A x n b^T, T(:,kl) = sum A x n b_k b_l, b = point - node centre (each
  // patch's own second moments included); children after parents: reverse order.
  struct Moments {
    Vec3 V;
    Mat3 W;
    Mat36 T;
  };
  std::vector<Moments> mom(static_cast<size_t>(nn));
  auto V = [&](int k) -> Vec3& { return mom[size_t(k)].V; };
  auto W = [&](int k) -> Mat3& { return mom[size_t(k)].W; };
  auto T = [&](int k) -> Mat36& { return mom[size_t(k)].T; };
  for (int k = nn - 1; k >= 0; --k) {
    const HNode& nd = d.nodes[k];
    if (nd.leaf()) {
      const int p = d.perm[nd.begin];
      V(k) = g.area[p] * x[p] * g.normal[p];
      W(k).setZero();
      for (int kl = 0; kl < 6; ++kl) T(k).col(kl) = V(k) * P.M[p][kl];
    } else {
      T(k).setZero();
      W(k).setZero();
      V(k).setZero();
      for (const int c : {nd.left, nd.right}) {
        const Vec3 dl = d.nodes[c].c - nd.c;
        V(k) += V(c);
        W(k) += W(c) + V(c) * dl.transpose();
        for (int kl = 0; kl < 6; ++kl) {
          const int a = kK[kl], b = kL[kl];
          T(k).col(kl) += T(c).col(kl) + W(c).col(a) * dl[b] + W(c).col(b) * dl[a] + V(c) * (dl[a] * dl[b]);
        }
      }
    }
  }
  // Gather (batch.hpp's gather_links, SIMD over a receiver's links): each receiver node sums its own links in
  // stored order (deterministic for any thread count). One record per node, the gather reads a source's centre
  // and moments at once.
  std::vector<double> rec(static_cast<size_t>(nn) * detail::kMomentRecord);
  for (int k = 0; k < nn; ++k) {
    double* r = rec.data() + static_cast<size_t>(k) * detail::kMomentRecord;
    std::copy_n(d.nodes[k].c.data(), 3, r);
    std::copy_n(V(k).data(), 3, r + 3);
    std::copy_n(W(k).data(), 9, r + 6);
    std::copy_n(T(k).data(), 18, r + 15);
  }
  std::vector<Vec3> G(nn, Vec3::Zero());
  std::vector<Mat3> J(nn, Mat3::Zero());
  std::vector<Mat36> H(nn, Mat36::Zero());
  const detail::BatchKernels& K = detail::batch_kernels();
  tbb::parallel_for(tbb::blocked_range<int>(0, nn, 256), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k < r.end(); ++k) {
      const std::int64_t e0 = d.far_off[k], e1 = d.far_off[k + 1];
      if (e0 == e1) continue;
      double out[30] = {};
      K.gather_links(rec.data(), d.nodes[k].c.data(), d.far_src.data() + e0, d.far_vis.data() + e0, e1 - e0, out);
      G[k] = Eigen::Map<const Vec3>(out);
      J[k] = Eigen::Map<const Mat3>(out + 3);
      H[k] = Eigen::Map<const Mat36>(out + 12);
    }
  });
  // Push: a child at offset a from its parent's centre receives g - J a + H[a,a]/2, J - H[a,.] and H.
  for (int k = 1; k < nn; ++k) {
    const HNode& nd = d.nodes[k];
    const int p = nd.parent;
    const Vec3 a = nd.c - d.nodes[p].c;
    Vec3 Haa = Vec3::Zero();
    Mat3 Ha = Mat3::Zero();  // column l: sum_k H_kl a_k
    for (int kl = 0; kl < 6; ++kl) {
      const int kk = kK[kl], ll = kL[kl];
      Haa += kMult[kl] * a[kk] * a[ll] * H[p].col(kl);
      Ha.col(ll) += a[kk] * H[p].col(kl);
      if (kk != ll) Ha.col(kk) += a[ll] * H[p].col(kl);
    }
    G[k] += G[p] - J[p] * a + 0.5 * Haa;
    J[k] += J[p] - Ha;
    H[k] += H[p];
  }
  // Leaves: n_i . (g + H : M_i / 2) (the patch's own extent) plus the exact entries.
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) {
      const int k = d.leaf_of[i];
      Vec3 gi = G[k];
      for (int kl = 0; kl < 6; ++kl) gi += 0.5 * kMult[kl] * P.M[i][kl] * H[k].col(kl);
      double s = g.normal[i].dot(gi);
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
