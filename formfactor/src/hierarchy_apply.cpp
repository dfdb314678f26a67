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

using Mat36 = Eigen::Matrix<double, 3, 6>;  // a vector per symmetric index pair kl: xx yy zz xy xz yz
constexpr int kKL[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
constexpr int kK[6] = {0, 1, 2, 0, 0, 1}, kL[6] = {0, 1, 2, 1, 2, 2};
constexpr double kMult[6] = {1, 1, 1, 2, 2, 2};  // sum over k, l of a symmetric form = sum over kl of mult x

// Gather of one far link into the receiver's (g, J, H), given the source's moments about its centre
// (V = sum A x n, W = sum A x n b^T, T(:, kl) = sum A x n b_k b_l) and u = c_B - c_A: the second-order Taylor
// expansion of sum_j K(u + b_j - a) A_j x_j n_j in b and a, K(u) = -u u^T / (pi |u|^4):
//   g = K V + sum_k d_k K W(:,k) + 1/2 sum_kl d_k d_l K T(:,kl),   (a-independent part)
//   G(a) = g - J a + 1/2 H[a, a],  J(:,l) = d_l K V + sum_k d_k d_l K W(:,k),  H_kl = d_k d_l K V.
// With phi = 1/(pi r^4), dphi = -4 phi u / r^2 and S_kl = d_k d_l phi = -4 phi (delta_kl / r^2 - 6 u_k u_l / r^4):
//   d_k (K v) = -dphi_k (u.v) u - phi (v_k u + (u.v) e_k)
//   d_k d_l (K v) = -S_kl (u.v) u - dphi_k (v_l u + (u.v) e_l) - dphi_l (v_k u + (u.v) e_k) - phi (v_k e_l + v_l e_k).
inline void gather(const Vec3& u, double vis, const Vec3& V, const Mat3& W, const Mat36& T, Vec3& g, Mat3& J,
                   Mat36& H) {
  // Written out (no Eigen temporaries): this is the inner loop of every product F x.
  const double r2 = u.squaredNorm(), phi = 1 / (kPi * r2 * r2), c4 = -4 * phi / r2, c24 = 24 * phi / (r2 * r2);
  const Vec3 dphi = c4 * u;  // grad phi
  const double uV = u.dot(V);
  const Vec3 Wtu = W.transpose() * u;
  const Vec3 Wdphi = W * dphi;
  const double tr = W.trace();
  // P_kl = u . T(:,kl) (symmetric), q_l = sum_k T(k, kl).
  double Pv[6];
  for (int kl = 0; kl < 6; ++kl) Pv[kl] = u.dot(T.col(kl));
  const Vec3 q(T(0, 0) + T(1, 3) + T(2, 4), T(0, 3) + T(1, 1) + T(2, 5), T(0, 4) + T(1, 5) + T(2, 2));
  const Vec3 Pu(Pv[0] * u[0] + Pv[3] * u[1] + Pv[4] * u[2], Pv[3] * u[0] + Pv[1] * u[1] + Pv[5] * u[2],
                Pv[4] * u[0] + Pv[5] * u[1] + Pv[2] * u[2]);
  const double trP = Pv[0] + Pv[1] + Pv[2], uPu = u.dot(Pu);
  const double SP = c4 * trP + c24 * uPu;  // S : P, S = c4 I + c24 u u^T
  // g = K V + sum_k d_k K W(:,k) + 1/2 sum_kl d_k d_l K T(:,kl)
  //   = u (-phi uV - dphi.Wtu - phi tr - SP/2 - dphi.q) - phi Wtu - P dphi - phi q,  P dphi = c4 P u.
  const double cu = -phi * uV - dphi.dot(Wtu) - phi * tr - 0.5 * SP - dphi.dot(q);
  g += vis * (cu * u - phi * Wtu - c4 * Pu - phi * q);
  // J = u a^T - Wtu dphi^T + c I - phi W^T with
  //   a = -(S Wtu) - W dphi - tr dphi - uV dphi - phi V,  S Wtu = c4 Wtu + c24 u (u.Wtu),
  //   c = -u.(W dphi) - phi tr - phi uV.
  const Vec3 a = -(c4 * Wtu + (c24 * u.dot(Wtu)) * u) - Wdphi - (tr + uV) * dphi - phi * V;
  const double c = -u.dot(Wdphi) - phi * (tr + uV);
  for (int col = 0; col < 3; ++col)
    for (int row = 0; row < 3; ++row)
      J(row, col) += vis * (u[row] * a[col] - Wtu[row] * dphi[col] - phi * W(col, row) + (row == col ? c : 0.0));
  // H_kl = d_k d_l K V = u alpha_kl + e_l w_k + e_k w_l, alpha_kl = -S_kl uV - dphi_k V_l - dphi_l V_k,
  // w = -phi V - uV dphi.
  const Vec3 w = -phi * V - uV * dphi;
  for (int kl = 0; kl < 6; ++kl) {
    const int k = kK[kl], l = kL[kl];
    const double S_kl = (k == l ? c4 : 0.0) + c24 * u[k] * u[l];
    const double alpha = -S_kl * uV - dphi[k] * V[l] - dphi[l] * V[k];
    for (int row = 0; row < 3; ++row) H(row, kl) += vis * alpha * u[row];
    H(l, kl) += vis * w[k];
    H(k, kl) += vis * w[l];
  }
}

}  // namespace

void HierarchicalOperator::apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const Impl& d = *d_;
  const int n = d.n, nn = int(d.nodes.size());
  if (n == 0) return;
  const mesh::PatchGeometry& g = *d.g;
  const detail::PatchData& P = d.P;
  // Pull: per node V = sum A x n, W = sum A x n b^T, T(:,kl) = sum A x n b_k b_l, b = point - node centre (each
  // patch's own second moments included); children after parents: reverse order.
  // One record per node: the gather reads all three of a source at once (one cache miss instead of three).
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
  // Gather: each receiver node sums its own links in stored order (deterministic for any thread count).
  std::vector<Vec3> G(nn, Vec3::Zero());
  std::vector<Mat3> J(nn, Mat3::Zero());
  std::vector<Mat36> H(nn, Mat36::Zero());
  tbb::parallel_for(tbb::blocked_range<int>(0, nn, 256), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k < r.end(); ++k) {
      const std::int64_t e0 = d.far_off[k], e1 = d.far_off[k + 1];
      if (e0 == e1) continue;
      Vec3 gk = Vec3::Zero();
      Mat3 Jk = Mat3::Zero();
      Mat36 Hk = Mat36::Zero();
      const Vec3& ca = d.nodes[k].c;
      for (std::int64_t e = e0; e < e1; ++e) {
        const int b = d.far_src[e];
        const Moments& m = mom[size_t(b)];
        gather(d.nodes[b].c - ca, double(d.far_vis[e]), m.V, m.W, m.T, gk, Jk, Hk);
      }
      G[k] = gk;
      J[k] = Jk;
      H[k] = Hk;
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
