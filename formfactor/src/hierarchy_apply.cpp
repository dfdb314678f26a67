// Hierarchical operator: y = F x by pull (cluster moments), gather (far links, third-order expansion of the
// kernel about both cluster centres), push (down to the patches) plus the exact leaf entries; rows streamed
// entry by entry; the memory limit.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <memory>
#include <mutex>
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

using Mat36 = Eigen::Matrix<double, 3, 6>;    // a vector per symmetric index pair (detail::kPairs)
using Mat310 = Eigen::Matrix<double, 3, 10>;  // a vector per symmetric index triple (detail::kTriples)
using detail::kPairMult;
using detail::kPairs;
using detail::kTripleMult;
using detail::kTriples;

constexpr int kRec = detail::kMomentRecord;  // per node: centre, V, W, T, U (batch.hpp)
constexpr int kAcc = detail::kLocalRecord;   // per node: g, J, H, C of the expansion about its centre
constexpr int kParallelPatches = 8192;       // subtrees at least this large are pulled / pushed as parallel tasks

// The index of a sorted pair / triple in kPairs / kTriples.
constexpr int pair_index(int i, int j) {
  const int a = i < j ? i : j, b = i < j ? j : i;
  return a == b ? a : (a == 0 ? (b == 1 ? 3 : 4) : 5);
}
constexpr int triple_index(int i, int j, int k) {
  for (int q = 0; q < 10; ++q) {
    const int a = kTriples[q][0], b = kTriples[q][1], c = kTriples[q][2];
    if ((a == i && b == j && c == k) || (a == i && b == k && c == j) || (a == j && b == i && c == k) ||
        (a == j && b == k && c == i) || (a == k && b == i && c == j) || (a == k && b == j && c == i))
      return q;
  }
  return -1;
}

// Pull: per node V = sum A x n, W = sum A x n b^T, T(:,kl) = sum A x n b_k b_l, U(:,klm) = sum A x n b_k b_l b_m,
// b = point - node centre (each patch's own second and third moments included), children before parents.
void pull(const HierarchicalOperator::Impl& d, const Eigen::Ref<const Eigen::VectorXd>& x, double* rec, int k) {
  const HNode& nd = d.nodes[size_t(k)];
  double* r = rec + size_t(k) * kRec;
  Eigen::Map<Vec3> V(r + 3);
  Eigen::Map<Mat3> W(r + 6);
  Eigen::Map<Mat36> T(r + 15);
  Eigen::Map<Mat310> U(r + 33);
  if (nd.leaf()) {
    const int p = d.perm[size_t(nd.begin)];
    V = d.g->area[p] * x[p] * d.g->normal[p];
    W.setZero();
    for (int kl = 0; kl < 6; ++kl) T.col(kl) = V * d.P.M[p][kl];
    for (int q = 0; q < 10; ++q) U.col(q) = V * d.P.M3[p][q];
    return;
  }
  if (nd.end - nd.begin >= kParallelPatches)
    tbb::parallel_invoke([&] { pull(d, x, rec, nd.left); }, [&] { pull(d, x, rec, nd.right); });
  else {
    pull(d, x, rec, nd.left);
    pull(d, x, rec, nd.right);
  }
  V.setZero();
  W.setZero();
  T.setZero();
  U.setZero();
  for (const int c : {nd.left, nd.right}) {
    const double* rc = rec + size_t(c) * kRec;
    const Eigen::Map<const Vec3> Vc(rc + 3);
    const Eigen::Map<const Mat3> Wc(rc + 6);
    const Eigen::Map<const Mat36> Tc(rc + 15);
    const Eigen::Map<const Mat310> Uc(rc + 33);
    const Vec3 dl = d.nodes[size_t(c)].c - nd.c;
    V += Vc;
    W += Wc + Vc * dl.transpose();
    for (int kl = 0; kl < 6; ++kl) {
      const int a = kPairs[kl][0], b = kPairs[kl][1];
      T.col(kl) += Tc.col(kl) + Wc.col(a) * dl[b] + Wc.col(b) * dl[a] + Vc * (dl[a] * dl[b]);
    }
    for (int q = 0; q < 10; ++q) {  // sum v (b' + dl)_a (b' + dl)_b (b' + dl)_e, b' about the child's centre
      const int a = kTriples[q][0], b = kTriples[q][1], e = kTriples[q][2];
      U.col(q) += Uc.col(q) + Tc.col(pair_index(a, b)) * dl[e] + Tc.col(pair_index(a, e)) * dl[b] +
                  Tc.col(pair_index(b, e)) * dl[a] + Wc.col(a) * (dl[b] * dl[e]) + Wc.col(b) * (dl[a] * dl[e]) +
                  Wc.col(e) * (dl[a] * dl[b]) + Vc * (dl[a] * dl[b] * dl[e]);
    }
  }
}

// Push: the expansion h(a) = g - J a + H[a, a] / 2 - C[a, a, a] / 6 about a node's centre, moved to a child at
// offset a0 (a = a0 + a'): g - J a0 + H[a0, a0] / 2 - C[a0, a0, a0] / 6, J - H[a0, .] + C[a0, a0, .] / 2,
// H - C[a0, ., .] and C; node k's own record is final when it is called.
void push(const HierarchicalOperator::Impl& d, double* acc, int k) {
  const HNode& nd = d.nodes[size_t(k)];
  if (nd.leaf()) return;
  const double* rp = acc + size_t(k) * kAcc;
  const Eigen::Map<const Vec3> Gp(rp);
  const Eigen::Map<const Mat3> Jp(rp + 3);
  const Eigen::Map<const Mat36> Hp(rp + 12);
  const Eigen::Map<const Mat310> Cp(rp + 30);
  for (const int c : {nd.left, nd.right}) {
    const Vec3 a = d.nodes[size_t(c)].c - nd.c;
    Vec3 Haa = Vec3::Zero(), Caaa = Vec3::Zero();
    Mat3 Ha = Mat3::Zero(), Caa = Mat3::Zero();  // column l: sum_k H_kl a_k, sum_km C_klm a_k a_m
    Mat36 Ca = Mat36::Zero();                     // column lm: sum_k C_klm a_k
    for (int kl = 0; kl < 6; ++kl) {
      const int kk = kPairs[kl][0], ll = kPairs[kl][1];
      Haa += kPairMult[kl] * a[kk] * a[ll] * Hp.col(kl);
      Ha.col(ll) += a[kk] * Hp.col(kl);
      if (kk != ll) Ha.col(kk) += a[ll] * Hp.col(kl);
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int l = 0; l < 3; ++l) {
          const auto col = Cp.col(triple_index(i, j, l));
          Caaa += a[i] * a[j] * a[l] * col;
          Caa.col(l) += a[i] * a[j] * col;
          if (j <= l) Ca.col(pair_index(j, l)) += a[i] * col;
        }
    double* rc = acc + size_t(c) * kAcc;
    Eigen::Map<Vec3>(rc) += Gp - Jp * a + 0.5 * Haa - Caaa / 6;
    Eigen::Map<Mat3>(rc + 3) += Jp - Ha + 0.5 * Caa;
    Eigen::Map<Mat36>(rc + 12) += Hp - Ca;
    Eigen::Map<Mat310>(rc + 30) += Cp;
  }
  if (nd.end - nd.begin >= kParallelPatches)
    tbb::parallel_invoke([&] { push(d, acc, nd.left); }, [&] { push(d, acc, nd.right); });
  else {
    push(d, acc, nd.left);
    push(d, acc, nd.right);
  }
}

}  // namespace

// Work arrays of one product, kept between products (a million-patch operator's are ~1 GB: allocating and
// first touching them on every product cost more than the arithmetic).
struct HierarchicalOperator::Impl::Scratch {
  std::vector<double> rec, acc;
  std::vector<double> z;  // per leaf block, n values: sum over its rows s of F_st A_s x_s, per target t
};
HierarchicalOperator::Impl::~Impl() = default;

void HierarchicalOperator::apply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const Impl& d = *d_;
  const int n = d.n, nn = int(d.nodes.size());
  if (n == 0) return;
  const mesh::PatchGeometry& g = *d.g;
  const detail::PatchData& P = d.P;
  std::unique_ptr<Impl::Scratch> S;
  {
    std::lock_guard lock(d.scratch_mutex);
    if (!d.scratch.empty()) {
      S = std::move(d.scratch.back());
      d.scratch.pop_back();
    }
  }
  if (!S) {
    S = std::make_unique<Impl::Scratch>();
    S->rec.resize(size_t(nn) * kRec);
    S->acc.resize(size_t(nn) * kAcc);
    for (int k = 0; k < nn; ++k) std::copy_n(d.nodes[size_t(k)].c.data(), 3, S->rec.data() + size_t(k) * kRec);
    S->z.resize(size_t(std::max(0, int(d.leaf_blocks.size()) - 1)) * size_t(n));
  }
  double* rec = S->rec.data();
  double* acc = S->acc.data();
  pull(d, x, rec, 0);
  // Gather (batch.hpp's gather_links, SIMD over a receiver's links): each receiver node sums its own links in
  // stored order (deterministic for any thread count).
  const detail::BatchKernels& K = detail::batch_kernels();
  tbb::parallel_for(tbb::blocked_range<int>(0, nn, 256), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k < r.end(); ++k) {
      double* out = acc + size_t(k) * kAcc;
      std::fill_n(out, kAcc, 0.0);
      const std::int64_t e0 = d.far_off[k], e1 = d.far_off[k + 1];
      if (e0 < e1) K.gather_links(rec, d.nodes[size_t(k)].c.data(), d.far_src.data() + e0, d.far_vis.data() + e0, e1 - e0, out);
    }
  });
  push(d, acc, 0);
  // The leaf pairs' transposed entries F_ts = F_st A_s / A_t: each fixed block of source rows scatters into its
  // own array (blocks in parallel), summed below in block order.
  const int blocks = std::max(0, int(d.leaf_blocks.size()) - 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, blocks, 1), [&](const tbb::blocked_range<int>& r) {
    for (int b = r.begin(); b < r.end(); ++b) {
      double* z = S->z.data() + size_t(b) * size_t(n);
      std::fill_n(z, n, 0.0);
      for (int s = d.leaf_blocks[size_t(b)]; s < d.leaf_blocks[size_t(b) + 1]; ++s) {
        const double v = g.area[s] * x[s];
        if (v == 0) continue;
        for (std::int64_t e = d.leaf_off[s]; e < d.leaf_off[s + 1]; ++e) z[d.leaf_src[e]] += d.leaf_F[e] * v;
      }
    }
  });
  // Leaves: n_i . (g + H : M_i / 2 - C : M3_i / 6) (the patch's own extent) plus the exact entries, both directions.
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) {
      const double* ri = acc + size_t(d.leaf_of[i]) * kAcc;
      Vec3 gi = Eigen::Map<const Vec3>(ri);
      const Eigen::Map<const Mat36> H(ri + 12);
      const Eigen::Map<const Mat310> C(ri + 30);
      for (int kl = 0; kl < 6; ++kl) gi += 0.5 * kPairMult[kl] * P.M[i][kl] * H.col(kl);
      for (int q = 0; q < 10; ++q) gi -= kTripleMult[q] / 6 * P.M3[i][q] * C.col(q);
      double s = g.normal[i].dot(gi);
      for (std::int64_t e = d.leaf_off[i]; e < d.leaf_off[i + 1]; ++e) s += d.leaf_F[e] * x[d.leaf_src[e]];
      double in = 0;
      for (int b = 0; b < blocks; ++b) in += S->z[size_t(b) * size_t(n) + size_t(i)];
      y[i] = s + in / g.area[i];
    }
  });
  std::lock_guard lock(d.scratch_mutex);
  d.scratch.push_back(std::move(S));
}

void HierarchicalOperator::for_each_in_row(int i, const std::function<void(int j, double F)>& f) const {
  const Impl& d = *d_;
  std::call_once(d.transpose_once, [&d] {
    const int n = d.n;
    d.tr_off.assign(size_t(n) + 1, 0);
    for (std::int64_t e = 0; e < d.leaf_count; ++e) ++d.tr_off[size_t(d.leaf_src[e]) + 1];
    for (int k = 0; k < n; ++k) d.tr_off[size_t(k) + 1] += d.tr_off[size_t(k)];
    d.tr_entry.resize(size_t(d.leaf_count));
    d.tr_src.resize(size_t(d.leaf_count));
    std::vector<std::int64_t> at(d.tr_off.begin(), d.tr_off.end() - 1);
    for (int s = 0; s < n; ++s)  // by source: each transposed row comes out sorted
      for (std::int64_t e = d.leaf_off[s]; e < d.leaf_off[s + 1]; ++e) {
        const std::int64_t k = at[size_t(d.leaf_src[e])]++;
        d.tr_entry[size_t(k)] = e;
        d.tr_src[size_t(k)] = s;
      }
  });
  // The leaf entries of row i by column: its own (F_ij) merged with the transposed (F_ji A_j / A_i).
  std::int64_t ea = d.leaf_off[i], ka = d.tr_off[i];
  const std::int64_t ea1 = d.leaf_off[i + 1], ka1 = d.tr_off[i + 1];
  while (ea < ea1 || ka < ka1) {
    if (ka == ka1 || (ea < ea1 && d.leaf_src[ea] < d.tr_src[size_t(ka)])) {
      f(d.leaf_src[ea], d.leaf_F[ea]);
      ++ea;
    } else {
      const int j = d.tr_src[size_t(ka)];
      f(j, d.leaf_F[d.tr_entry[size_t(ka)]] * d.g->area[j] / d.g->area[i]);
      ++ka;
    }
  }
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
