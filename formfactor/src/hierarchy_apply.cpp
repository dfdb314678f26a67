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

using detail::kPairMult;
using detail::kPairs;
using detail::kTripleMult;
using detail::kTriples;
using detail::kTuples;

constexpr int kScal = detail::kScalarRecord;  // centre, axis, scalar moments (batch.hpp)
constexpr int kVec = detail::kVectorRecord;    // centre, vector moments
constexpr int kAccV = detail::kLocalRecord;    // a vector local record: 3 per index tuple
constexpr int kParallelPatches = 8192;  // subtrees at least this large are pulled / pushed as parallel tasks

// The index tuples (batch.hpp's order: (), x y z, kPairs, kTriples): their lengths, indices, and the tuple of any
// index sequence (sorted).
struct Tuples {
  int len[kTuples] = {};
  int idx[kTuples][3] = {};
  int of1[3] = {}, of2[3][3] = {}, of3[3][3][3] = {};
  constexpr Tuples() {
    for (int k = 0; k < 3; ++k) {
      len[1 + k] = 1, idx[1 + k][0] = k, of1[k] = 1 + k;
    }
    for (int q = 0; q < 6; ++q) {
      const int t = 4 + q, a = kPairs[q][0], b = kPairs[q][1];
      len[t] = 2, idx[t][0] = a, idx[t][1] = b, of2[a][b] = of2[b][a] = t;
    }
    for (int q = 0; q < 10; ++q) {
      const int t = 10 + q, a = kTriples[q][0], b = kTriples[q][1], c = kTriples[q][2];
      len[t] = 3, idx[t][0] = a, idx[t][1] = b, idx[t][2] = c;
      of3[a][b][c] = of3[a][c][b] = of3[b][a][c] = of3[b][c][a] = of3[c][a][b] = of3[c][b][a] = t;
    }
  }
  // The tuple of the sequence (i[0], ..., i[n-1]).
  constexpr int of(int n, const int* i) const {
    return n == 0 ? 0 : n == 1 ? of1[i[0]] : n == 2 ? of2[i[0]][i[1]] : of3[i[0]][i[1]][i[2]];
  }
};
constexpr Tuples kT;

// The products of a vector's components over each index tuple: P[t] = prod_{k in t} v_k.
void monomials(const Vec3& v, double* P) {
  P[0] = 1;
  for (int t = 1; t < kTuples; ++t) {
    double f = 1;
    for (int j = 0; j < kT.len[t]; ++j) f *= v[kT.idx[t][j]];
    P[t] = f;
  }
}

// The ways to write each tuple t as a kept tuple c and a rest r (t's indices split by a subset: 111 terms), for
// moments; and each tuple t extended by a tuple r of length at most 3 - |t| (84 terms) with the weight
// mult(r) / |r|!, for local records.
struct Splits {
  int count = 0, t[111] = {}, c[111] = {}, r[111] = {};
  constexpr Splits() {
    for (int tt = 0; tt < kTuples; ++tt) {
      const int n = kT.len[tt];
      for (int mask = 0; mask < (1 << n); ++mask) {
        int keep[3] = {}, rest[3] = {}, nk = 0, nr = 0;
        for (int j = 0; j < n; ++j) (mask >> j & 1 ? keep[nk++] : rest[nr++]) = kT.idx[tt][j];
        t[count] = tt, c[count] = kT.of(nk, keep), r[count] = kT.of(nr, rest);
        ++count;
      }
    }
  }
};
struct Extensions {
  int count = 0, t[84] = {}, c[84] = {}, r[84] = {};
  double w[84] = {};
  constexpr Extensions() {
    for (int tt = 0; tt < kTuples; ++tt)
      for (int rr = 0; rr < kTuples; ++rr) {
        const int n = kT.len[tt], m = kT.len[rr];
        if (n + m > 3) continue;
        int seq[3] = {};
        for (int j = 0; j < n; ++j) seq[j] = kT.idx[tt][j];
        for (int j = 0; j < m; ++j) seq[n + j] = kT.idx[rr][j];
        // mult(r) / |r|!: 1 / (product of the factorials of r's index counts)
        int cnt[3] = {};
        for (int j = 0; j < m; ++j) ++cnt[kT.idx[rr][j]];
        double f = 1;
        for (int k = 0; k < 3; ++k) f /= cnt[k] == 3 ? 6 : cnt[k] == 2 ? 2 : 1;
        t[count] = tt, c[count] = kT.of(n + m, seq), r[count] = rr, w[count] = f;
        ++count;
      }
  }
};
constexpr Splits kSplits;
constexpr Extensions kExt;
static_assert(kSplits.count == 111 && kExt.count == 84);

// Moments about a parent's centre from a child's (R = 3: vector moments m[3 t + i], R = 1: scalar ones) at offset
// dl from it: sum v (b' + dl)^t, each subset of t's indices taken from b' and the rest from dl.
template <int R>
void shift_moments(const double* child, const double* P, double* parent) {
#pragma GCC unroll 111
  for (int k = 0; k < kSplits.count; ++k) {
    const double f = P[kSplits.r[k]];
    for (int i = 0; i < R; ++i) parent[R * kSplits.t[k] + i] += f * child[R * kSplits.c[k] + i];
  }
}

// The local record h(a) = sum_p L_p[(-a)^p] / p! moved to a child at offset a0 from the node's centre (a = a0 + a'):
// L'_t = sum_r mult(r) / |r|! E[r] L_{t + r}, E the monomials of e = -a0, added to the child's.
template <int R>
void shift_local(const double* parent, const double* E, double* child) {
#pragma GCC unroll 84
  for (int k = 0; k < kExt.count; ++k) {
    const double f = kExt.w[k] * E[kExt.r[k]];
    for (int i = 0; i < R; ++i) child[R * kExt.t[k] + i] += f * parent[R * kExt.c[k] + i];
  }
}

// The work arrays of one product (kept between products): per node its scalar record (centre, axis, scalar
// moments: Impl::rec_scalar's layout, batch.hpp) and scalar local record; per vector slot (Impl::vec_slot,
// acc_slot) a vector record (centre, vector moments) and a vector local record.
struct Work {
  double *rs, *rv, *as, *av;
  double* vec(const HierarchicalOperator::Impl& d, int k) const { return rv + size_t(d.vec_slot[size_t(k)]) * kVec; }
  double* vacc(const HierarchicalOperator::Impl& d, int k) const { return av + size_t(d.acc_slot[size_t(k)]) * kAccV; }
};

// Pull: per node the scalar moments sum A x b^t (flat nodes) and the vector moments sum A x n b^t (nodes with a
// vector slot: non-flat ones, and flat ones a non-flat receiver reads), b = point - node centre (each patch's own
// second and third moments included), children before parents.
void pull(const HierarchicalOperator::Impl& d, const Eigen::Ref<const Eigen::VectorXd>& x, const Work& w, int k) {
  const HNode& nd = d.nodes[size_t(k)];
  double* sm = w.rs + size_t(k) * kScal + 6;
  double* vm = d.vec_slot[size_t(k)] >= 0 ? w.vec(d, k) + 3 : nullptr;
  if (nd.leaf()) {
    const int p = d.perm[size_t(nd.begin)];
    const double wx = d.g->area[p] * x[p];
    sm[0] = wx;
    for (int t = 1; t < 4; ++t) sm[t] = 0;
    for (int q = 0; q < 6; ++q) sm[4 + q] = wx * d.P.M[p][q];
    for (int q = 0; q < 10; ++q) sm[10 + q] = wx * d.P.M3[p][q];
    if (vm)
      for (int t = 0; t < kTuples; ++t)
        for (int i = 0; i < 3; ++i) vm[3 * t + i] = sm[t] * nd.axis[i];
    return;
  }
  if (nd.end - nd.begin >= kParallelPatches)
    tbb::parallel_invoke([&] { pull(d, x, w, nd.left); }, [&] { pull(d, x, w, nd.right); });
  else {
    pull(d, x, w, nd.left);
    pull(d, x, w, nd.right);
  }
  // A flat node's children are flat: its scalar moments from theirs, and its vector moments (if it has a slot)
  // those times its axis (its normals are within kFlatCone of it). Other nodes: the vector moments from the
  // children's, a flat child's from its scalar ones times its axis.
  if (nd.flat) {
    std::fill_n(sm, kTuples, 0.0);
    for (const int c : {nd.left, nd.right}) {
      double P[kTuples];
      monomials(d.nodes[size_t(c)].c - nd.c, P);
      shift_moments<1>(w.rs + size_t(c) * kScal + 6, P, sm);
    }
    if (vm)
      for (int t = 0; t < kTuples; ++t)
        for (int i = 0; i < 3; ++i) vm[3 * t + i] = sm[t] * nd.axis[i];
    return;
  }
  std::fill_n(vm, 3 * kTuples, 0.0);
  for (const int c : {nd.left, nd.right}) {
    const HNode& ch = d.nodes[size_t(c)];
    double P[kTuples];
    monomials(ch.c - nd.c, P);
    if (ch.flat) {
      double t1[kTuples] = {};
      shift_moments<1>(w.rs + size_t(c) * kScal + 6, P, t1);
      for (int t = 0; t < kTuples; ++t)
        for (int i = 0; i < 3; ++i) vm[3 * t + i] += t1[t] * ch.axis[i];
    } else {
      shift_moments<3>(w.vec(d, c) + 3, P, vm);
    }
  }
}

// Push: a node's local record moved to its children (node k's own record is final when it is called). A flat node
// first dots its vector record (from non-flat sources, or its parent's if that is not flat) with its axis into its
// scalar one, and passes the scalar record on: its children are flat. A non-flat node's children have vector slots.
void push(const HierarchicalOperator::Impl& d, const Work& w, int k) {
  const HNode& nd = d.nodes[size_t(k)];
  if (nd.leaf()) return;
  double* sp = w.as + size_t(k) * kTuples;
  const double* vp = d.acc_slot[size_t(k)] >= 0 ? w.vacc(d, k) : nullptr;
  if (nd.flat && vp)
    for (int t = 0; t < kTuples; ++t)
      sp[t] += nd.axis[0] * vp[3 * t] + nd.axis[1] * vp[3 * t + 1] + nd.axis[2] * vp[3 * t + 2];
  for (const int c : {nd.left, nd.right}) {
    double E[kTuples];
    monomials(nd.c - d.nodes[size_t(c)].c, E);  // e = -a0
    if (nd.flat)
      shift_local<1>(sp, E, w.as + size_t(c) * kTuples);
    else
      shift_local<3>(vp, E, w.vacc(d, c));
  }
  if (nd.end - nd.begin >= kParallelPatches)
    tbb::parallel_invoke([&] { push(d, w, nd.left); }, [&] { push(d, w, nd.right); });
  else {
    push(d, w, nd.left);
    push(d, w, nd.right);
  }
}

}  // namespace

// Work arrays of one product, kept between products (a million-patch operator's are ~0.8 GB: allocating and
// first touching them on every product cost more than the arithmetic).
struct HierarchicalOperator::Impl::Scratch {
  std::vector<double> rs, rv, as, av;  // Work's arrays
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
    S->rs.resize(size_t(nn) * kScal);
    S->rv.resize(size_t(d.vec_slots) * kVec);
    S->as.resize(size_t(nn) * kTuples);
    S->av.resize(size_t(d.acc_slots) * kAccV);
    for (int k = 0; k < nn; ++k) {
      std::copy_n(d.nodes[size_t(k)].c.data(), 3, S->rs.data() + size_t(k) * kScal);
      std::copy_n(d.nodes[size_t(k)].axis.data(), 3, S->rs.data() + size_t(k) * kScal + 3);
      if (d.vec_slot[size_t(k)] >= 0)
        std::copy_n(d.nodes[size_t(k)].c.data(), 3, S->rv.data() + size_t(d.vec_slot[size_t(k)]) * kVec);
    }
    S->z.resize(size_t(std::max(0, int(d.leaf_blocks.size()) - 1)) * size_t(n));
  }
  const Work w{S->rs.data(), S->rv.data(), S->as.data(), S->av.data()};
  pull(d, x, w, 0);
  // Gather (batch.hpp's gather_links, SIMD over a receiver's links): each receiver node sums its own links in
  // stored order (deterministic for any thread count). A flat receiver's flat sources (its links' first
  // far_flat[k]) take the scalar kernel; the rest the vector kernel, reading the sources' vector slots.
  const detail::BatchKernels& K = detail::batch_kernels();
  tbb::parallel_for(tbb::blocked_range<int>(0, nn, 256), [&](const tbb::blocked_range<int>& r) {
    std::vector<int> slots;
    for (int k = r.begin(); k < r.end(); ++k) {
      const HNode& nd = d.nodes[size_t(k)];
      double* sacc = w.as + size_t(k) * kTuples;
      double* vacc = d.acc_slot[size_t(k)] >= 0 ? w.vacc(d, k) : nullptr;
      std::fill_n(sacc, kTuples, 0.0);
      if (vacc) std::fill_n(vacc, kAccV, 0.0);
      const std::int64_t e0 = d.far_off[k], e1 = d.far_off[k + 1];
      const std::int64_t e_mid = nd.flat ? e0 + d.far_flat[size_t(k)] : e0;
      if (e0 < e_mid)
        K.gather_links_flat(w.rs, nd.c.data(), nd.axis.data(), d.far_src.data() + e0, d.far_vis.data() + e0,
                            e_mid - e0, sacc);
      if (e_mid < e1) {
        slots.clear();
        for (std::int64_t e = e_mid; e < e1; ++e) slots.push_back(d.vec_slot[size_t(d.far_src[size_t(e)])]);
        K.gather_links(w.rv, nd.c.data(), slots.data(), d.far_vis.data() + e_mid, e1 - e_mid, vacc);
      }
    }
  });
  push(d, w, 0);
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
  // Leaves: g + H : M_i / 2 - C : M3_i / 6 (the patch's own extent) plus the exact entries, both directions.
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) {
      const int k = d.leaf_of[i];
      const double* sr = w.as + size_t(k) * kTuples;
      const double* vr = d.acc_slot[size_t(k)] >= 0 ? w.vacc(d, k) : nullptr;
      // The scalar record plus the vector one dotted with the normal, averaged over the patch (its first moments
      // about the centroid vanish).
      const Vec3& ni = g.normal[i];
      auto at = [&](int t) {
        return sr[t] + (vr ? ni[0] * vr[3 * t] + ni[1] * vr[3 * t + 1] + ni[2] * vr[3 * t + 2] : 0.0);
      };
      double s = at(0);
      for (int q = 0; q < 6; ++q) s += 0.5 * kPairMult[q] * P.M[i][q] * at(4 + q);
      for (int q = 0; q < 10; ++q) s -= kTripleMult[q] / 6 * P.M3[i][q] * at(10 + q);
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
