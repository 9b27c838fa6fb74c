// The coarse space of the dual problem (paper, (13)-(15)): G~ = R~^T B~^T by rows per cluster,
// G~^T summed per (cluster, multiplier) pair, the coarse matrix G~ G~^T assembled at the owners
// of the multipliers in a fixed order, its factor (sparse Cholesky, or dense with the null space
// of unrestrained rigid motions), and the projector P = I - G~^T (G~ G~^T)^{-1} G~. Cost of one
// projection: one pass of G~ and of G~^T over the owned multipliers, one allreduce of a coarse
// vector, one sparse coarse solve on every rank (or, with coarse_ranks, on the first rank of
// each group and a broadcast of the coarse vector in the group).
#include "htfeti/feti/coarse_space.hpp"

#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "htfeti/errors.hpp"
#include "htfeti/linalg/nnls.hpp"
#include "htfeti/parallel/fresh_pages.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

CoarseSpace::~CoarseSpace() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (finalized) return;
  if (group_comm_ != MPI_COMM_NULL) MPI_Comm_free(&group_comm_);
  if (leader_comm_ != MPI_COMM_NULL) MPI_Comm_free(&leader_comm_);
}

void CoarseSpace::set_up(const std::vector<std::unique_ptr<Cluster>>& clusters, int first_cluster,
                         std::vector<int> sub_first, bool threads_over_clusters, int coarse_ranks) {
  {  // The ranks that factor: every rank, or the first of each group of consecutive ranks.
    const int P = comm_.size(), rank = comm_.rank();
    const int K = coarse_ranks <= 0 ? P : std::min(coarse_ranks, P);
    if (group_comm_ != MPI_COMM_NULL) MPI_Comm_free(&group_comm_);
    if (leader_comm_ != MPI_COMM_NULL) MPI_Comm_free(&leader_comm_);
    subset_ = K < P;
    leader_ = true;
    factor_ranks_ = P;
    if (subset_) {
      const int stride = (P + K - 1) / K;
      leader_ = rank % stride == 0;
      factor_ranks_ = (P + stride - 1) / stride;
      MPI_Comm_split(comm_.raw(), rank / stride, rank, &group_comm_);
      MPI_Comm_split(comm_.raw(), leader_ ? 0 : MPI_UNDEFINED, rank, &leader_comm_);
    }
  }
  first_cluster_ = first_cluster;
  sub_first_ = std::move(sub_first);
  outer_parallel_ = threads_over_clusters;
  const int P = comm_.size(), ncl = static_cast<int>(clusters.size());
  const int n_ext = m_.n_ext();
  // The kernel dimension of every cluster (allgathered), then the rows of G~:
  // (G~)_{(c,j),k} = R~_{c,j} . b_k.
  {
    std::vector<int> dims(ncl), counts(P), displs(P + 1, 0), all(layout_.num_clusters);
    for (int c = 0; c < ncl; ++c) dims[c] = clusters[c]->kernel_dimension();
    for (int r = 0; r < P; ++r) {
      const auto [a, b] = layout_.cluster_range(r, P);
      counts[r] = b - a;
      displs[r + 1] = displs[r] + counts[r];
    }
    MPI_Allgatherv(dims.data(), ncl, MPI_INT, all.data(), counts.data(), displs.data(), MPI_INT,
                   comm_.raw());
    first_.assign(layout_.num_clusters + 1, 0);
    for (int c = 0; c < layout_.num_clusters; ++c) first_[c + 1] = first_[c] + all[c];
  }
  rows_.resize(ncl);
  // One task per row (c, j) of G~: every row is formed as by one thread, in the same order, so
  // the bits do not depend on the threads. Each thread has its own accumulator over the
  // multipliers (n_ext doubles).
  std::vector<std::pair<int, int>> tasks;
  for (int c = 0; c < ncl; ++c) {
    rows_[c].resize(clusters[c]->kernel_dimension());
    for (int j = 0; j < clusters[c]->kernel_dimension(); ++j) tasks.push_back({c, j});
  }
  const int ntasks = static_cast<int>(tasks.size());
  RegionError failure;
#pragma omp parallel if (!omp_in_parallel() && ntasks > 1)
  {
    std::vector<double> acc;
    std::vector<int> hit;
    // The member's kernel entries (R~_{c,j} at a dof), each computed once per task at its first
    // use: a dof is in several rows of B~ (a face's averaged rows: about six).
    std::vector<double> entry;
    std::vector<int> known;
#pragma omp for schedule(dynamic)
    for (int t = 0; t < ntasks; ++t) {
      try {
        const auto [c, j] = tasks[t];
        if (acc.empty()) acc.assign(n_ext, 0.0);
        hit.clear();
        for (int i = 0; i < members(c); ++i) {
          for (int d : known) entry[d] = std::numeric_limits<double>::quiet_NaN();
          known.clear();
          for (const auto& r : m_.rows[sub_of(c, i)]) {
            if (r.dof >= static_cast<int>(entry.size()))
              entry.resize(r.dof + 1, std::numeric_limits<double>::quiet_NaN());
            double& z = entry[r.dof];
            if (std::isnan(z)) {
              z = clusters[c]->kernel_entry(i, r.dof, j);
              known.push_back(r.dof);
            }
            if (acc[r.k] == 0.0) hit.push_back(r.k);
            acc[r.k] += r.value * z;
          }
        }
        std::sort(hit.begin(), hit.end(), [&](int a, int b) {  // global order, as on one rank
          return m_.layout.global(a) < m_.layout.global(b);
        });
        hit.erase(std::unique(hit.begin(), hit.end()), hit.end());
        rows_[c][j].reserve(hit.size());  // written once, not grown (fresh pages: see above)
        for (int k : hit) {
          if (acc[k] != 0.0) rows_[c][j].push_back({k, acc[k]});
          acc[k] = 0.0;
        }
      } catch (const std::exception& e) {
        failure.record(e);
      }
    }
  }
  failure.rethrow();
  {  // G~^T by ordered sums over clusters: one pair per (cluster, multiplier)
    // Two passes over the clusters, each on the threads (a cluster's entries are its own): the
    // multipliers each cluster touches, then, with every array's size known and its pages made
    // resident in one call (parallel/fresh_pages.hpp), their places. Written once, not grown:
    // at 80^3 with 512 METIS parts the grown arrays' copies and page faults were a fifth of the
    // coarse phase.
    std::vector<std::vector<int>> touched(ncl);  // per cluster: its multipliers, sorted
    RegionError pass_failure;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && ncl > 1)
    for (int c = 0; c < ncl; ++c) {
      try {
        std::vector<int>& ks = touched[c];
        size_t n = 0;
        for (const auto& row : rows_[c]) n += row.size();
        ks.reserve(n);
        for (const auto& row : rows_[c])
          for (const auto& [k, g] : row) ks.push_back(k);
        std::sort(ks.begin(), ks.end());
        ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
      } catch (const std::exception& e) {
        pass_failure.record(e);
      }
    }
    pass_failure.rethrow();
    pair_first_.assign(ncl + 1, 0);
    value_first_.assign(ncl + 1, 0);
    for (int c = 0; c < ncl; ++c) {
      pair_first_[c + 1] = pair_first_[c] + static_cast<int>(touched[c].size());
      value_first_[c + 1] = value_first_[c] + static_cast<long>(touched[c].size()) *
                                                  static_cast<long>(rows_[c].size());
    }
    entry_first_ = pair_first_;  // one entry per (cluster, multiplier) pair
    const int npairs = pair_first_[ncl];
    std::vector<int> pk;
    std::vector<long long> pc;
    resize_resident(pk, npairs);
    resize_resident(pc, npairs);
    resize_resident(entry_k_, npairs);
    resize_resident(entry_p_, npairs);
    resize_resident(entry_g_, value_first_[ncl]);  // zeros where a row has no entry
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && ncl > 1)
    for (int c = 0; c < ncl; ++c) {
      try {
        const std::vector<int>& ks = touched[c];
        const int base = pair_first_[c];
        for (size_t i = 0; i < ks.size(); ++i)
          pk[base + i] = ks[i], pc[base + i] = first_cluster_ + c;
        // The entries in the global order of their multipliers (that of every row of rows_).
        std::vector<int> order(ks);
        std::sort(order.begin(), order.end(),
                  [&](int a, int b) { return m_.layout.global(a) < m_.layout.global(b); });
        const int r = static_cast<int>(rows_[c].size());
        const int e0 = entry_first_[c];
        for (size_t i = 0; i < order.size(); ++i) {
          entry_k_[e0 + i] = order[i];
          entry_p_[e0 + i] =
              base +
              static_cast<int>(std::lower_bound(ks.begin(), ks.end(), order[i]) - ks.begin());
        }
        for (int j = 0; j < r; ++j) {
          int e = e0;  // both in the global order
          for (const auto& [k, g] : rows_[c][j]) {
            while (entry_k_[e] != k) ++e;
            entry_g_[value_first_[c] + static_cast<long>(e - e0) * r + j] = g;
          }
        }
        std::vector<int>().swap(touched[c]);
      } catch (const std::exception& e) {
        pass_failure.record(e);
      }
    }
    pass_failure.rethrow();
    cluster_sum_ = OrderedSum(comm_, m_.layout, pk, pc, m_.owner_rank);
    pairs_ = Vec::Zero(static_cast<int>(pk.size()));
  }
  work_ = Vec::Zero(dimension());
}

// G~ and G~^T: every cluster has its own rows of the coarse vector and its own pairs of pairs_,
// so threads take clusters and each value is formed in the same order as by one thread.
// out[base + j] = row j of cluster c times x (extended), for every j: each row's sum in the
// order of rows_[c][j] (the zeros between its entries add nothing).
void CoarseSpace::apply_rows(int c, const double* x, double* out) const {
  const int base = first_[first_cluster_ + c];
  const int r = static_cast<int>(rows_[c].size());
  const double* g = entry_g_.data() + value_first_[c];
  const int e0 = entry_first_[c], e1 = entry_first_[c + 1];
  if (r <= kFusedRows) {
    double s[kFusedRows] = {};
    for (int e = e0; e < e1; ++e, g += r) {
      const double xk = x[entry_k_[e]];
      for (int j = 0; j < r; ++j) s[j] += g[j] * xk;
    }
    for (int j = 0; j < r; ++j) out[base + j] = s[j];
    return;
  }
  for (int j = 0; j < r; ++j) {
    double s = 0;
    for (int e = e0; e < e1; ++e) s += g[(e - e0) * static_cast<long>(r) + j] * x[entry_k_[e]];
    out[base + j] = s;
  }
}

// pairs[p] of every multiplier of cluster c = the sum over its rows j of g_j z[base + j], in the
// order of j (as the sparse rows added them).
void CoarseSpace::pairs_from_rows(int c, const double* z, double* pairs) const {
  const double* zc = z + first_[first_cluster_ + c];
  const int r = static_cast<int>(rows_[c].size());
  const double* g = entry_g_.data() + value_first_[c];
  for (int e = entry_first_[c]; e < entry_first_[c + 1]; ++e, g += r) {
    double s = 0;
    for (int j = 0; j < r; ++j) s += g[j] * zc[j];
    pairs[entry_p_[e]] = s;
  }
}

void CoarseSpace::apply_G(const Vec& lambda, Vec& coarse) {
  m_.gather(lambda);
  coarse.setZero(dimension());
  const int nc = local_clusters();
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) apply_rows(c, m_.ext_in.data(), coarse.data());
  comm_.sum_in_place(coarse.data(), static_cast<int>(coarse.size()));
}

void CoarseSpace::gt_into_ext(const Vec& coarse) {
  const int nc = local_clusters();
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) pairs_from_rows(c, coarse.data(), pairs_.data());
  cluster_sum_.combine(pairs_.data(), m_.ext_out.data());
}

void CoarseSpace::apply_Gt(const Vec& coarse, Vec& lambda) {
  gt_into_ext(coarse);
  lambda = m_.ext_out.head(m_.layout.n_owned());
}

void CoarseSpace::coarse_correction(const Vec& v, Factor& factor) {
  apply_G(v, work_);          // G~ v
  solve_with(factor, work_);  // (G~ W G~^T)^{-1} G~ v
  gt_into_ext(work_);         // G~^T (G~ W G~^T)^{-1} G~ v, owned part in m_.ext_out
}

void CoarseSpace::project(const Vec& x, Vec& y) {
  coarse_correction(x, factor_);
  y = x - m_.ext_out.head(m_.layout.n_owned());
}

namespace {
bool bounded_row(MultiplierKind kind) {
  return kind == MultiplierKind::contact || kind == MultiplierKind::friction;
}
}  // namespace

void CoarseSpace::factor() {
  const bool bounded = m_.inequalities + m_.friction_rows > 0;  // (global counts)
  // Above kFaceCheapDimension the fixed part is left to its first use (faces are tried late
  // there, and the reconstruction may mask no row): its products would cost the setup several
  // seconds (Table 4 row 1: the pass over G~'s items 19.7 s at 24,576).
  if (!bounded || dimension() > kFaceCheapDimension) {
    assemble(std::vector<double>(m_.layout.n_owned(), 1.0), factor_);
    return;
  }
  // G~ G~^T as assemble() forms it (the same sums), and the fixed part from the same pass over
  // the items: each entry's sum of the never-held rows' products is kept beside its full sum.
  std::vector<CoarseTriplet> all;
  {
    const std::vector<GItem> items = g_columns_at_owners();  // freed before the factorization
    const std::vector<double> ones(m_.layout.n_owned(), 1.0);
    std::vector<CoarseTriplet> fixed;
    const std::vector<CoarseTriplet> mine = owner_cluster_sums(
        items, weighted_products(items, ones),
        [&](size_t i) { return !bounded_row(m_.kind[m_.layout.ext_index(items[i].k)]); }, &fixed);
    all = gather_to_factor_ranks(mine);
    set_face_parts(items, gather_to_factor_ranks(fixed));
  }
  factor_triplets(std::move(all), factor_, false);
}

void CoarseSpace::cache_face_parts(const std::vector<GItem>& items) {
  std::vector<double> fixed(m_.layout.n_owned(), 1.0);
  for (int k = 0; k < m_.layout.n_owned(); ++k)
    if (bounded_row(m_.kind[k])) fixed[k] = 0.0;
  set_face_parts(items, weighted_triplets(items, fixed));
}

void CoarseSpace::set_face_parts(const std::vector<GItem>& items,
                                 const std::vector<CoarseTriplet>& fixed) {
  face_fixed_.clear();
  for (const CoarseTriplet& t : fixed) {  // sorted by (a, b, cluster): sum each entry in order
    if (face_fixed_.empty() || face_fixed_.back().a != t.a || face_fixed_.back().b != t.b)
      face_fixed_.push_back({-1, t.a, t.b, 0.0});
    face_fixed_.back().v += t.v;
  }
  face_items_.clear();
  for (const GItem& it : items)
    if (bounded_row(m_.kind[m_.layout.ext_index(it.k)])) face_items_.push_back(it);
  face_cached_ = true;
}

int CoarseSpace::solve_weighted(const std::vector<double>& weight, Vec& coarse) {
  Factor factor;
  // The fixed part serves where only bounded rows are weighted other than 1 (agreed over the
  // ranks: each checks its own rows); formed here if factor() and set_face have not.
  bool other = false;
  for (int k = 0; k < m_.layout.n_owned() && !other; ++k)
    other = !bounded_row(m_.kind[k]) && weight[k] != 1.0;
  if (!(comm_.max(other ? 1.0 : 0.0) > 0)) {
    if (!face_cached_) cache_face_parts(g_columns_at_owners());
    std::vector<CoarseTriplet> all = face_fixed_;
    const std::vector<CoarseTriplet> bounded = weighted_triplets(face_items_, weight);
    all.insert(all.end(), bounded.begin(), bounded.end());
    factor_triplets(std::move(all), factor, false);
  } else {
    assemble(weight, factor);
  }
  solve_with(factor, coarse);
  return factor.null_dimension();
}

bool CoarseSpace::set_face(const Vec& free) {
  // G~ D G~^T = (the rows that are never held: gluing and Dirichlet) + (the bounded rows times
  // free). The first part is the same for every face: formed once (by factor(), or here at the
  // first face), its entries summed, and kept with the bounded rows' items of G~ (few: the
  // contact and friction rows), so that a face costs the bounded rows' products, one small
  // gather and the sparse factorization, not a pass over all of G~'s items (1.9 s per face at
  // 80^3 with 512 METIS parts). Both parts are summed in a fixed order (cluster order, then
  // fixed part before the bounded rows), so the result does not depend on the rank count.
  if (!face_cached_) cache_face_parts(g_columns_at_owners());
  face_used_ = true;
  std::vector<CoarseTriplet> all = face_fixed_;
  const std::vector<CoarseTriplet> bounded =
      weighted_triplets(face_items_, std::vector<double>(free.data(), free.data() + free.size()));
  all.insert(all.end(), bounded.begin(), bounded.end());
  face_set_ = factor_triplets(std::move(all), face_, true);
  return face_set_;
}

void CoarseSpace::set_weighted(const std::vector<double>& q) {
  q_ = Eigen::Map<const Vec>(q.data(), static_cast<Eigen::Index>(q.size()));
  qx_.resize(q_.size());
  assemble(q, weighted_);
  weighted_set_ = true;
  work_.setZero(dimension());  // the factor's solve work arrays, allocated here once
  solve_with(weighted_, work_);
}

void CoarseSpace::project_weighted(const Vec& x, Vec& y, bool transpose) {
  if (!weighted_set_) throw std::logic_error("CoarseSpace::project_weighted: no weights set");
  const int n = m_.layout.n_owned();
  if (transpose) qx_ = q_.cwiseProduct(x);
  coarse_correction(transpose ? qx_ : x, weighted_);
  if (transpose)
    y = x - m_.ext_out.head(n);
  else
    y = x - q_.cwiseProduct(m_.ext_out.head(n));
}

void CoarseSpace::face_correction(const Vec& v, Vec& y) {
  if (!face_set_) throw std::logic_error("CoarseSpace::face_correction: no face is set");
  coarse_correction(v, face_);
  y = m_.ext_out.head(m_.layout.n_owned());
}

void CoarseSpace::solve_with(Factor& factor, Vec& x) {
  if (!subset_ || factor.use_dense) {
    factor.solve(x);
    return;
  }
  if (leader_) factor.sparse.solve(x.data(), x.data());
  MPI_Bcast(x.data(), static_cast<int>(x.size()), MPI_DOUBLE, 0, group_comm_);
}

namespace {
// MPI datatypes for arrays of a struct of (long long, int..., double) fields.
template <class T, size_t N>
MPI_Datatype struct_type(const std::array<MPI_Aint, N>& disp,
                         const std::array<MPI_Datatype, N>& types) {
  int bl[N];
  for (size_t i = 0; i < N; ++i) bl[i] = 1;
  MPI_Datatype tmp, out;
  MPI_Type_create_struct(static_cast<int>(N), bl, disp.data(), types.data(), &tmp);
  MPI_Type_create_resized(tmp, 0, sizeof(T), &out);
  MPI_Type_free(&tmp);
  MPI_Type_commit(&out);
  return out;
}
}  // namespace

MPI_Datatype CoarseSpace::triplet_type() {
  return struct_type<CoarseTriplet, 4>({offsetof(CoarseTriplet, k), offsetof(CoarseTriplet, a),
                                        offsetof(CoarseTriplet, b), offsetof(CoarseTriplet, v)},
                                       {MPI_LONG_LONG, MPI_INT, MPI_INT, MPI_DOUBLE});
}

std::vector<CoarseSpace::CoarseTriplet> CoarseSpace::gather_to_factor_ranks(
    const std::vector<CoarseTriplet>& mine) const {
  if (!subset_) return allgather_sorted(mine, comm_.raw());
  // The group's triplets to its first rank, then every first rank gets all of them; sorted by
  // key there, so the order of arrival does not matter.
  MPI_Datatype trip_type = triplet_type();
  int G = 1, nmine = static_cast<int>(mine.size());
  MPI_Comm_size(group_comm_, &G);
  std::vector<int> counts(G), disp(G + 1, 0);
  MPI_Gather(&nmine, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, group_comm_);
  for (int r = 0; r < G; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<CoarseTriplet> group(leader_ ? disp[G] : 0);
  MPI_Gatherv(mine.data(), nmine, trip_type, group.data(), counts.data(), disp.data(), trip_type, 0,
              group_comm_);
  MPI_Type_free(&trip_type);
  if (!leader_) return {};
  return allgather_sorted(group, leader_comm_);
}

std::vector<CoarseSpace::GItem> CoarseSpace::g_columns_at_owners() const {
  // Every cluster sends (k, coarse row, g) for its nonzeros of G~ to the owner of k. Counts are
  // in items (MPI datatypes), not bytes.
  // The items are written once, each into its place (counted first) in a buffer made resident
  // in one call: no growing per-rank lists and no copies (at 80^3 with 512 METIS parts the
  // items are 200 MB, and fresh pages cost more than the work on them).
  const int P = comm_.size();
  if (P == 1) {
    // One rank owns every multiplier, and its extended order is the global one: each item goes
    // straight to its place in (multiplier, row) order (a counting sort: the rows are visited
    // in increasing order), with no sort and no second buffer.
    std::vector<long> at(m_.layout.n_ext() + 1, 0);
    for (const auto& cluster_rows : rows_)
      for (const auto& row : cluster_rows)
        for (const auto& entry : row) ++at[entry.first + 1];
    for (int k = 0; k < m_.layout.n_ext(); ++k) at[k + 1] += at[k];
    std::vector<GItem> items;
    resize_resident(items, static_cast<size_t>(at.back()));
    for (size_t c = 0; c < rows_.size(); ++c) {
      const int base = first_[first_cluster_ + c];
      for (size_t j = 0; j < rows_[c].size(); ++j)
        for (const auto& [k, g] : rows_[c][j])
          items[at[k]++] = {m_.layout.global(k), base + static_cast<int>(j), g};
    }
    return items;
  }
  MPI_Datatype item_type =
      struct_type<GItem, 3>({offsetof(GItem, k), offsetof(GItem, row), offsetof(GItem, g)},
                            {MPI_LONG_LONG, MPI_INT, MPI_DOUBLE});
  std::vector<int> scount(P, 0), rcount(P), sdisp(P + 1, 0), rdisp(P + 1, 0);
  for (const auto& cluster_rows : rows_)
    for (const auto& row : cluster_rows)
      for (const auto& entry : row) ++scount[m_.owner_rank[entry.first]];
  for (int r = 0; r < P; ++r) sdisp[r + 1] = sdisp[r] + scount[r];
  std::vector<GItem> sbuf;
  resize_resident(sbuf, static_cast<size_t>(sdisp[P]));
  {
    std::vector<int> pos(sdisp.begin(), sdisp.end() - 1);
    for (size_t c = 0; c < rows_.size(); ++c) {
      const int base = first_[first_cluster_ + c];
      for (size_t j = 0; j < rows_[c].size(); ++j)
        for (const auto& [k, g] : rows_[c][j])
          sbuf[pos[m_.owner_rank[k]]++] = {m_.layout.global(k), base + static_cast<int>(j), g};
    }
  }
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm_.raw());
  for (int r = 0; r < P; ++r) rdisp[r + 1] = rdisp[r] + rcount[r];
  std::vector<GItem> rbuf;
  resize_resident(rbuf, static_cast<size_t>(rdisp[P]));
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), item_type, rbuf.data(), rcount.data(),
                rdisp.data(), item_type, comm_.raw());
  sbuf = {};
  MPI_Type_free(&item_type);
  // (k, row) is unique: a coarse row lists each multiplier once (set_up sums its entries), so
  // this order is total and an in-place sort gives what a stable one would, without its buffer.
  std::sort(rbuf.begin(), rbuf.end(),
            [](const GItem& x, const GItem& y) { return x.k != y.k ? x.k < y.k : x.row < y.row; });
  return rbuf;
}

std::vector<CoarseSpace::CoarseTriplet> CoarseSpace::allgather_sorted(
    const std::vector<CoarseTriplet>& mine, MPI_Comm comm) const {
  MPI_Datatype trip_type = triplet_type();
  int P = 1;
  MPI_Comm_size(comm, &P);
  int nmine = static_cast<int>(mine.size());
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Allgather(&nmine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<CoarseTriplet> all(disp[P]);
  MPI_Allgatherv(mine.data(), nmine, trip_type, all.data(), counts.data(), disp.data(), trip_type,
                 comm);
  MPI_Type_free(&trip_type);
  // Each entry's partial sums in key order, whatever rank formed them.
  std::sort(all.begin(), all.end(), [](const CoarseTriplet& x, const CoarseTriplet& y) {
    return x.a != y.a ? x.a < y.a : x.b != y.b ? x.b < y.b : x.k < y.k;
  });
  return all;
}

std::vector<CoarseSpace::CoarseTriplet> CoarseSpace::owner_cluster_sums(
    const std::vector<GItem>& gcol, const ProductsOf& products_of,
    const std::function<bool(size_t)>& also_sum_of, std::vector<CoarseTriplet>* also_out) const {
  // Products summed per owner cluster of the multiplier (all of a cluster's multipliers live on
  // one rank whatever the rank count), in multiplier order; the caller adds the partial sums in
  // cluster order (allgather_sorted). Rank-count independent, and O(entries touched per
  // cluster) memory instead of one triplet per product (78 per multiplier for G~ G~^T in 3D
  // elasticity).
  const bool also = also_out && also_sum_of;
  if (also_out) also_out->clear();
  std::vector<std::pair<int, size_t>> groups;  // (owner cluster, first item of the multiplier)
  for (size_t i = 0; i < gcol.size(); ++i)
    if (i == 0 || gcol[i].k != gcol[i - 1].k) groups.push_back({0, i});
  const long ngroups = static_cast<long>(groups.size());
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && ngroups > 4096)
  for (long g = 0; g < ngroups; ++g)  // (a binary search each)
    groups[g].first = m_.owner_cluster[m_.layout.ext_index(gcol[groups[g].second].k)];
  std::stable_sort(groups.begin(), groups.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<size_t> block;  // the owner clusters' first groups (+ the end)
  for (size_t g = 0; g < groups.size(); ++g)
    if (g == 0 || groups[g].first != groups[g - 1].first) block.push_back(g);
  block.push_back(groups.size());
  const int nblocks = static_cast<int>(block.size()) - 1;
  // One slot per distinct entry (a, b) of a cluster: its sum, and with also_sum_of the sum of
  // the chosen multipliers' products (touched: some product was added to it).
  struct Slot {
    CoarseTriplet t;
    double also_v;
    bool touched;
  };
  // The owner clusters on the threads, each cluster's sums formed by one thread in the same
  // order whatever the threads, then put together in cluster order.
  std::vector<std::vector<CoarseTriplet>> part(nblocks), also_part(also ? nblocks : 0);
  RegionError failure;
#pragma omp parallel if (!omp_in_parallel() && nblocks > 1)
  {
    std::vector<CoarseTriplet> products;
    std::vector<Slot> sums;
    std::vector<std::pair<size_t, bool>> ranges;  // per multiplier: end of its products, chosen
    std::unordered_map<unsigned long long, size_t> slot;  // entry (a, b) -> its place in sums
#pragma omp for schedule(dynamic)
    for (int blk = 0; blk < nblocks; ++blk) {
      try {
        const size_t g0 = block[blk], g1 = block[blk + 1];
        products.clear();
        ranges.clear();
        for (size_t g = g0; g < g1; ++g) {
          const size_t i = groups[g].second;
          size_t j = i;
          while (j < gcol.size() && gcol[j].k == gcol[i].k) ++j;
          products_of(i, j, products);
          if (also) ranges.push_back({products.size(), also_sum_of(i)});
        }
        // Each entry (a, b) sums its products in the order they were formed (multiplier
        // order), as a stable sort by (a, b) followed by a running sum would, without sorting
        // the products (78 per multiplier in 3D elasticity; the sort was 7% of a METIS
        // H-TFETI-DP run): a slot per distinct entry, then the few distinct entries sorted.
        slot.clear();
        sums.clear();
        size_t range = 0;
        for (size_t p = 0; p < products.size(); ++p) {
          const CoarseTriplet& t = products[p];
          const auto key = (static_cast<unsigned long long>(static_cast<unsigned>(t.a)) << 32) |
                           static_cast<unsigned>(t.b);
          const auto [it, added] = slot.try_emplace(key, sums.size());
          if (added) sums.push_back({{groups[g0].first, t.a, t.b, 0.0}, 0.0, false});
          Slot& sl = sums[it->second];
          sl.t.v += t.v;
          if (also) {
            while (p >= ranges[range].first) ++range;
            if (ranges[range].second) sl.also_v += t.v, sl.touched = true;
          }
        }
        std::sort(sums.begin(), sums.end(), [](const Slot& x, const Slot& y) {
          return x.t.a != y.t.a ? x.t.a < y.t.a : x.t.b < y.t.b;  // distinct entries: any sort
        });
        part[blk].reserve(sums.size());
        for (const Slot& sl : sums) {
          part[blk].push_back(sl.t);
          if (also && sl.touched) also_part[blk].push_back({sl.t.k, sl.t.a, sl.t.b, sl.also_v});
        }
      } catch (const std::exception& e) {
        failure.record(e);
      }
    }
  }
  failure.rethrow();
  const auto join = [](std::vector<std::vector<CoarseTriplet>>& parts,
                       std::vector<CoarseTriplet>& out) {
    size_t n = 0;
    for (const auto& q : parts) n += q.size();
    resize_resident(out, n);
    n = 0;
    for (auto& q : parts) {
      std::copy(q.begin(), q.end(), out.begin() + static_cast<long>(n));
      n += q.size();
      std::vector<CoarseTriplet>().swap(q);
    }
  };
  std::vector<CoarseTriplet> mine;
  join(part, mine);
  if (also) join(also_part, *also_out);
  return mine;
}

bool CoarseSpace::assemble(const std::vector<double>& weight, Factor& factor,
                           bool fail_if_singular) {
  std::vector<CoarseTriplet> all;
  {
    const std::vector<GItem> items = g_columns_at_owners();  // freed before the factorization
    all = weighted_triplets(items, weight);
  }
  return factor_triplets(std::move(all), factor, fail_if_singular);
}

CoarseSpace::ProductsOf CoarseSpace::weighted_products(const std::vector<GItem>& items,
                                                       const std::vector<double>& weight) const {
  // (G~ W G~^T)_{ab} = sum_k w_k g_ak g_bk: the products at one multiplier's items [i, j).
  return [&items, &weight, this](size_t i, size_t j, std::vector<CoarseTriplet>& products) {
    const double w = weight[m_.layout.ext_index(items[i].k)];
    if (w != 0.0)
      for (size_t a = i; a < j; ++a)
        for (size_t b = a; b < j; ++b) {
          int ca = items[a].row, cb = items[b].row;
          if (ca > cb) std::swap(ca, cb);
          products.push_back({items[i].k, ca, cb, w * items[a].g * items[b].g});
        }
  };
}

std::vector<CoarseSpace::CoarseTriplet> CoarseSpace::weighted_triplets(
    const std::vector<GItem>& rbuf, const std::vector<double>& weight) const {
  // The owners of the multipliers form the products and sum equal entries; the summed triplets
  // are shared (every rank factors the coarse matrix). Each entry's partial sums in cluster
  // order whatever rank formed them (k: the cluster); on the ranks that factor (coarse_ranks),
  // the others have none.
  return gather_to_factor_ranks(owner_cluster_sums(rbuf, weighted_products(rbuf, weight)));
}

bool CoarseSpace::factor_triplets(std::vector<CoarseTriplet> all, Factor& factor,
                                  bool fail_if_singular) {
  Eigen::SparseMatrix<double> GGt(dimension(), dimension());
  const auto build = [&]() {
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(all.size());
    for (const auto& t : all) trip.emplace_back(t.a, t.b, t.v);
    GGt.setFromTriplets(trip.begin(), trip.end());
  };
  build();
  factor.sparse = SparseCholesky(Ordering::amd);
  factor.use_dense = false;
  factor.null.resize(0, 0);
  bool singular = false, oom = false;
  {
    // BLAS on one thread: called outside a parallel region, OpenBLAS's OpenMP flavour would
    // use every thread, and its threaded blocks round differently per thread count (the coarse
    // factor of Table 3's 2,048 clusters moved by an ulp between 1 and 2 threads, and with it
    // lambda~ and the energy by 1e-11). The coarse matrix is small; nothing is lost.
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    try {
      inject_failure("coarse", comm_.rank());
      if (leader_) factor.sparse.factorize(GGt);
      // A semidefinite G~ W G~^T (a rigid motion that only the masked rows restrain) can factor
      // with a round-off pivot instead of failing: the sphere of examples/sphere-on-block.toml,
      // split with the cut objective, with its contact rows masked did (rcond 1.2e-16; its null
      // eigenvalue 3e-17 of 0.84). rcond >= 1 / cond, so below 1e-15 the matrix is singular to
      // working precision: taken as singular (the dense path finds its null space).
      if (leader_ && factor.sparse.rcond() < kSingularRcond) singular = true;
    } catch (const std::bad_alloc&) {
      oom = true;  // this rank alone, maybe: agreed on below
    } catch (const std::exception&) {
      singular = true;  // the same on every rank: every rank factors the same matrix
    }
    omp_set_num_threads(threads);
  }
  // Every rank factors the same matrix, so a singular one is singular everywhere; running out of
  // memory is not, and is agreed on before the ranks' paths could part.
  comm_.agree(oom ? "out of memory while factoring the coarse problem" : "", true);
  if (subset_) {  // the ranks that factored tell the others (all of them found the same)
    long long s[2] = {singular ? 1 : 0, leader_ ? factor.sparse.factor_nonzeros() : 0};
    MPI_Allreduce(MPI_IN_PLACE, s, 2, MPI_LONG_LONG, MPI_MAX, comm_.raw());
    singular = s[0] != 0;
    factor.nonzeros = static_cast<long>(s[1]);
  } else {
    factor.nonzeros = factor.sparse.factor_nonzeros();
  }
  if (!singular) return true;
  if (fail_if_singular) {
    factor = Factor();
    return false;
  }
  const int nc = dimension();
  if (nc > kMaxDense)
    throw std::runtime_error(
        "the coarse problem G G^T is singular: some rigid motion of a subdomain or cluster is "
        "restrained by no Dirichlet condition or contact row (coarse dimension " +
        std::to_string(nc) + " is too large to name it)");
  factor.nonzeros = static_cast<long>(nc) * (nc + 1) / 2;
  if (subset_) {  // the dense path runs on every rank: the group's first rank sends the matrix
    int n = static_cast<int>(all.size());
    MPI_Bcast(&n, 1, MPI_INT, 0, group_comm_);
    all.resize(n);
    MPI_Datatype trip_type = triplet_type();
    MPI_Bcast(all.data(), n, trip_type, 0, group_comm_);
    MPI_Type_free(&trip_type);
    if (!leader_) build();
  }
  try {
    const Eigen::MatrixXd upper(GGt);  // entries (a, b) with a <= b
    Eigen::MatrixXd A = upper.selfadjointView<Eigen::Upper>();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A);
    const auto& ev = eig.eigenvalues();
    const double top = std::max(ev.cwiseAbs().maxCoeff(), 1e-300);
    int nnull = 0;
    while (nnull < nc && ev[nnull] <= 1e-10 * top) ++nnull;
    factor.null = eig.eigenvectors().leftCols(nnull);
    A.noalias() += factor.null * factor.null.transpose();
    factor.dense.compute(A);
  } catch (const std::bad_alloc&) {
    oom = true;
  }
  comm_.agree(oom ? "out of memory while factoring the singular coarse problem densely" : "", true);
  factor.use_dense = true;
  if (factor.dense.info() != Eigen::Success)
    throw std::runtime_error("the coarse problem G G^T could not be factored");
  return true;
}

std::string CoarseSpace::describe_null(const Eigen::MatrixXd& Z) const {
  // Clusters carrying the null directions (largest coefficients), by global cluster id.
  std::vector<int> clusters;
  const double top = Z.size() ? Z.cwiseAbs().maxCoeff() : 0.0;
  for (int c = 0; c < layout_.num_clusters; ++c) {
    double m = 0;
    for (int j = first_[c]; j < first_[c + 1]; ++j) m = std::max(m, Z.row(j).cwiseAbs().maxCoeff());
    if (m > 1e-3 * top) clusters.push_back(c);
  }
  std::string s;
  for (size_t i = 0; i < clusters.size() && i < 8; ++i)
    s += (i ? ", " : "") + std::to_string(clusters[i]);
  if (clusters.size() > 8) s += ", ... (" + std::to_string(clusters.size()) + " in all)";
  const bool one = layout_.num_clusters == layout_.num_subdomains;
  return std::to_string(Z.cols()) + " rigid motion(s) of " +
         (one ? "subdomain(s) " : "cluster(s) ") + s;
}

// Farkas' lemma on the rigid motions that no equality row restrains (the null space Z of
// G~_E G~_E^T, the coarse matrix without the contact rows): the dual constraints
// lambda_I >= 0, G~ lambda = e~ have no solution iff some motion y = Z t opens or keeps every
// contact (A t <= 0, A = (G~^T Z)_I: B_I u for the rigid u = R~ Z t) while the load does positive
// work along it (e~^T Z t > 0). Then the energy decreases without bound along y. The certificate
// t is the residual of min ||A^T mu - Z^T e~||, mu >= 0 (nnls.hpp). Collective; every rank solves
// the same small problem on the gathered contact rows (ordered by global index).
std::string CoarseSpace::unbounded_motion(const Vec& e) {
  if (m_.inequalities == 0) return "";
  const int n_own = m_.layout.n_owned();
  std::vector<double> weight(n_own, 1.0);
  for (int k = 0; k < n_own; ++k)
    if (m_.kind[k] == MultiplierKind::contact) weight[k] = 0.0;
  Factor equalities;
  try {
    assemble(weight, equalities);
  } catch (const std::runtime_error&) {
    return "";  // too large for the dense null space (kMaxDense): no diagnosis
  }
  const Eigen::MatrixXd& Z = equalities.null;
  const int k = static_cast<int>(Z.cols());
  if (k == 0) return "";  // every rigid motion restrained by equalities: the QP is feasible
  // Rows of A at the owned contact multipliers: (global index, k values), gathered to all.
  std::vector<long long> mine_k;
  std::vector<double> mine_v;
  std::vector<Vec> cols(k);
  for (int j = 0; j < k; ++j) {
    Vec z = Z.col(j);
    apply_Gt(z, cols[j]);
  }
  for (int e = 0; e < n_own; ++e)
    if (m_.kind[e] == MultiplierKind::contact) {
      mine_k.push_back(m_.layout.global(e));
      for (int j = 0; j < k; ++j) mine_v.push_back(cols[j][e]);
    }
  const MPI_Comm mc = comm_.raw();
  const int P = comm_.size();
  int nmine = static_cast<int>(mine_k.size());
  std::vector<int> counts(P), disp(P + 1, 0), vcounts(P), vdisp(P + 1, 0);
  MPI_Allgather(&nmine, 1, MPI_INT, counts.data(), 1, MPI_INT, mc);
  for (int r = 0; r < P; ++r) {
    disp[r + 1] = disp[r] + counts[r];
    vcounts[r] = counts[r] * k;
    vdisp[r + 1] = vdisp[r] + vcounts[r];
  }
  std::vector<long long> all_k(disp[P]);
  std::vector<double> all_v(vdisp[P]);
  MPI_Allgatherv(mine_k.data(), nmine, MPI_LONG_LONG, all_k.data(), counts.data(), disp.data(),
                 MPI_LONG_LONG, mc);
  MPI_Allgatherv(mine_v.data(), nmine * k, MPI_DOUBLE, all_v.data(), vcounts.data(), vdisp.data(),
                 MPI_DOUBLE, mc);
  std::vector<int> order(all_k.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return all_k[a] < all_k[b]; });
  Eigen::MatrixXd M(k, static_cast<Eigen::Index>(order.size()));  // M = A^T
  for (size_t c = 0; c < order.size(); ++c)
    for (int j = 0; j < k; ++j)
      M(j, static_cast<Eigen::Index>(c)) = all_v[static_cast<size_t>(order[c]) * k + j];
  const Eigen::VectorXd b = Z.transpose() * e;
  if (b.norm() == 0) return "";
  const NnlsResult fit = nnls(M, b);
  // Bounded iff the contact forces can balance the load on those motions (r = 0 to round-off);
  // an NNLS that did not finish proves nothing, and nothing is claimed.
  if (!fit.converged || fit.r.norm() <= 1e-8 * b.norm()) return "";
  const Eigen::MatrixXd y = Z * (fit.r / fit.r.norm());
  return "the problem has no solution: the load moves " + describe_null(y) +
         " away from every contact (no Dirichlet condition holds them and no obstacle stops "
         "them: the energy decreases without bound); add a Dirichlet condition, an obstacle on "
         "the other side, or reverse the load";
}

}  // namespace htfeti
