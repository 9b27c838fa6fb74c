#include "htfeti/feti/dual_problem.hpp"

#include "htfeti/clock.hpp"
#include "htfeti/parallel/memory.hpp"

#include <omp.h>


#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <cstddef>
#include <numeric>
#include <string>
#include <tuple>
#include <unordered_set>

#include "htfeti/parallel/key_numbering.hpp"

namespace htfeti {

namespace {
}  // namespace

DualProblem::DualProblem(const FetiLayout& layout,
                         const std::function<SubdomainInput(int)>& make_input, const Comm& comm,
                         const FetiOptions& options)
    : layout_(layout), comm_(comm) {
  const int P = comm.size(), me = comm.rank();
  std::tie(c0_, c1_) = layout_.cluster_range(me, P);
  const int ncl = c1_ - c0_;
  const int s0 = layout_.cluster_first[c0_];
  const int nsub = layout_.cluster_first[c1_] - s0;
  sub_first_.resize(ncl + 1);
  for (int c = 0; c <= ncl; ++c) sub_first_[c] = layout_.cluster_first[c0_ + c] - s0;

  // 1. Per cluster: generate and assemble the subdomains, their rows of B~ and the cluster's
  //    primal constraints, while the dof sharing is at hand; then drop the sharing.
  double t = seconds_now();
  subs_.resize(nsub);
  std::vector<std::vector<LocalRow>> local_rows(nsub);
  // Exact stiffness scaling on the nodes needs their copy counts. Copies joined primally (corner
  // glue) form groups, for which the identity used there does not hold: those runs weight each
  // per-node row over its own entries instead (build_scaling).
  exact_node_scaling_ =
      options.preconditioner != PreconditionerKind::none && options.scaling == Scaling::stiffness;
  if (exact_node_scaling_) {
    bool groups = false;
    for (int c = 0; c < layout_.num_clusters; ++c) groups |= layout_.cluster_size(c) > 1;
    exact_node_scaling_ = layout_.glue == Glue::averages || !groups;
  }
  if (exact_node_scaling_) node_copies_.resize(nsub);
  std::vector<std::vector<std::vector<ConstraintEntry>>> primal(ncl);
  MatrixPool matrices;  // equal K_i held once (a box's subdomains); freed with their holders
  outer_parallel_ = omp_get_max_threads() > 1 && ncl >= omp_get_max_threads();
  std::string error;
  bool input_error = false;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    try {
      const int ms = members(c);
      std::vector<SubdomainInput> in(ms);
      // Each K_i goes to the pool as soon as it is assembled: a cluster's members are all made
      // before its primal constraints, and held unpooled they would all be in memory at once.
      std::vector<std::shared_ptr<const MatrixPool::Matrix>> pooled(ms);
      std::string inner_error;
      bool inner_input = false;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && ms > 1)
      for (int i = 0; i < ms; ++i) {
        try {
          SubdomainInput made = make_input(layout_.cluster_first[c0_ + c] + i);
          Eigen::SparseMatrix<double> K;  // moved by swap: Eigen's SparseMatrix copies on move
          K.swap(made.system.K);
          in[i] = std::move(made);
          in[i].system.K.swap(K);
          if (in[i].system.K.rows() == in[i].system.f.size())
            pooled[i] = matrices.intern(in[i].system.K);  // leaves system.K empty
          subdomain_rows(layout_, in[i], local_rows[sub_of(c, i)]);
          if (!node_copies_.empty()) {
            auto& nc = node_copies_[sub_of(c, i)];
            for (int k = 0; k < in[i].sharing.num_nodes(); ++k)
              nc.push_back(in[i].sharing.num_copies(k));
          }
        } catch (const std::invalid_argument& e) {
#pragma omp critical
          inner_error = e.what(), inner_input = true;
        } catch (const std::exception& e) {
#pragma omp critical
          inner_error = e.what();
        }
      }
      if (!inner_error.empty()) {
        if (inner_input) throw std::invalid_argument(inner_error);
        throw std::runtime_error(inner_error);
      }
      std::vector<const SubdomainInput*> ptrs;
      for (auto& x : in) ptrs.push_back(&x);
      primal[c] = cluster_primal_constraints(layout_, c0_ + c, ptrs);
      for (int i = 0; i < ms; ++i) {
        subs_[sub_of(c, i)] =
            std::make_unique<Subdomain>(std::move(in[i].system), std::move(pooled[i]));
      }
    } catch (const std::invalid_argument& e) {
#pragma omp critical
      error = e.what(), input_error = true;
    } catch (const std::bad_alloc&) {
#pragma omp critical
      error = "out of memory while assembling the subdomains", input_error = true;
    } catch (const std::exception& e) {
#pragma omp critical
      error = e.what();
    }
  }
  comm_.agree(error, input_error);
  setup_.shared_matrices = matrices.reuses();
  setup_.assembly = seconds_now() - t;
  setup_.peak_mb_assembly = peak_rss_mb();

  // 2. Global numbering of the rows by key, owners, and the extended dual layout.
  t = seconds_now();
  std::vector<NumberingKey> keys;
  std::vector<int> key_owner;
  std::vector<const LocalRow*> key_row;
  {
    std::vector<std::pair<RowKey, const LocalRow*>> all;
    for (int s = 0; s < nsub; ++s)
      for (const auto& r : local_rows[s]) all.push_back({r.key, &r});
    std::sort(all.begin(), all.end(),
              [](const auto& x, const auto& y) { return x.first < y.first; });
    for (size_t i = 0; i < all.size(); ++i)
      if (i == 0 || all[i].first != all[i - 1].first) {
        keys.push_back(all[i].first);
        key_owner.push_back(layout_.rank_of_subdomain(all[i].second->owner_subdomain, P));
        key_row.push_back(all[i].second);
      }
  }
  // Bucket position: per-node rows by their node, object rows after all nodes by cluster.
  const long long nodes = layout_.num_nodes;
  const std::vector<long long> index = number_keys(
      comm_, keys, nodes + layout_.num_clusters,
      [nodes](const NumberingKey& k) { return k[0] == 0 ? k[1] : nodes + k[1]; }, n_dual_);
  {
    std::vector<long long> touched(index);
    std::vector<int> owner(key_owner);
    std::vector<size_t> perm(index.size());
    std::iota(perm.begin(), perm.end(), 0);
    std::sort(perm.begin(), perm.end(), [&](size_t a, size_t b) { return index[a] < index[b]; });
    for (size_t i = 0; i < perm.size(); ++i) touched[i] = index[perm[i]], owner[i] = key_owner[perm[i]];
    layout_dual_ = DualLayout(comm, touched, owner);
  }
  const int n_ext = layout_dual_.n_ext(), n_own = layout_dual_.n_owned();
  owner_.assign(n_ext, me);
  kind_.assign(n_own, MultiplierKind::gluing);
  c_ = Vec::Zero(n_own);
  contact_scale_.assign(n_own, 1.0);
  contact_gap_.assign(n_own, 0.0);
  contact_point_.assign(n_own, {0, 0, 0});
  long long my_inequalities = 0;
  block_.assign(n_own, 0);
  for (size_t i = 0; i < keys.size(); ++i) {
    const int k = layout_dual_.ext_index(index[i]);
    owner_[k] = key_owner[i];
    if (k < n_own) {
      const LocalRow& r = *key_row[i];
      block_[k] = layout_.cluster_of(r.owner_subdomain);
      kind_[k] = r.kind;
      c_[k] = r.rhs;
      contact_scale_[k] = r.scale;
      contact_gap_[k] = r.gap;
      contact_point_[k] = r.point;
      if (r.kind == MultiplierKind::contact) ++my_inequalities;
    }
  }
  n_inequalities_ = comm_.sum(my_inequalities);
  rows_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    auto& lr = local_rows[s];
    std::vector<std::pair<int, const LocalRow*>> ordered;
    for (const auto& r : lr) {
      const size_t i = std::lower_bound(keys.begin(), keys.end(), r.key) - keys.begin();
      ordered.push_back({layout_dual_.ext_index(index[i]), &r});
    }
    // Rows in global order (the order of the ext indices of owned entries, then ghosts, is the
    // global order within each part; sort by global index for a fixed accumulation order).
    std::sort(ordered.begin(), ordered.end(), [&](const auto& x, const auto& y) {
      return layout_dual_.global(x.first) < layout_dual_.global(y.first);
    });
    for (const auto& [k, r] : ordered) {
      const RowClass cls = r->kind != MultiplierKind::gluing ? RowClass::other
                           : r->key[0] == 0                  ? RowClass::node
                                                             : RowClass::object;
      const auto side = static_cast<std::int8_t>(r->side);
      for (const auto& [dof, v] : r->entries) rows_[s].push_back({k, -1, dof, side, cls, v});
    }
    lr = {};
  }
  local_rows = {};
  setup_.constraints = seconds_now() - t;
  setup_.peak_mb_constraints = peak_rss_mb();

  // Local numbering of the rows of B~ on each subdomain (distinct multipliers in extended order).
  mult_.resize(nsub);
  std::vector<std::vector<Subdomain::BEntry>> local_b(nsub);
  {
    std::vector<int> local_of(n_ext, -1);
    for (int s = 0; s < nsub; ++s) {
      for (const auto& r : rows_[s]) mult_[s].push_back(r.k);
      // By global index (not extended index, whose owned/ghost split depends on the ranks): the
      // local numbering fixes the summation order of the dense blocks F_i.
      std::sort(mult_[s].begin(), mult_[s].end(), [&](int a, int b) {
        return layout_dual_.global(a) < layout_dual_.global(b);
      });
      mult_[s].erase(std::unique(mult_[s].begin(), mult_[s].end()), mult_[s].end());
      for (size_t j = 0; j < mult_[s].size(); ++j) local_of[mult_[s][j]] = static_cast<int>(j);
      for (auto& r : rows_[s]) {
        r.j = local_of[r.k];
        local_b[s].push_back({r.j, r.dof, r.value});
      }
    }
  }
  // Ordered sums over subdomains (F, B u, d) and the owner cluster of every owned entry.
  {
    std::vector<int> pk;
    std::vector<long long> pc;
    flat_off_.assign(nsub + 1, 0);
    for (int s = 0; s < nsub; ++s) {
      for (int k : mult_[s]) pk.push_back(k), pc.push_back(s0 + s);
      flat_off_[s + 1] = static_cast<int>(pk.size());
    }
    sub_sum_ = OrderedSum(comm_, layout_dual_, pk, pc, owner_);
    flat_ = Vec::Zero(static_cast<int>(pk.size()));
    partial_.assign(layout_.num_clusters, 0.0);
  }
  double min_nodes = std::numeric_limits<double>::infinity(), local_dofs = 0;
  for (const auto& sd : subs_) {
    min_nodes = std::min(min_nodes, static_cast<double>(sd->size() / sd->dofs_per_node()));
    local_dofs += sd->size();
  }
  min_nodes = comm_.min(min_nodes);
  // Dense local blocks F_i take 8 n_i (n_i + 1) / 2 bytes packed (4 in single precision; n_i:
  // multipliers of subdomain i); automatic picks them only when they fit the same per-rank budget
  // as the factors (3D subdomains have large interfaces: 1,806 interface dofs per subdomain at
  // H_s/h = 10).
  const double value_bytes = options.explicit_precision == Precision::single ? 4.0 : 8.0;
  std::vector<double> packed_bytes(nsub);  // F_i of each subdomain, packed
  double explicit_bytes = 0;
  for (int s = 0; s < nsub; ++s) {
    const double m = static_cast<double>(mult_[s].size());
    explicit_bytes += packed_bytes[s] = value_bytes * m * (m + 1) / 2;
  }
  explicit_bytes = comm_.max(explicit_bytes);
  explicit_ = options.dual_operator == DualOperator::explicit_ ||
              (options.dual_operator == DualOperator::automatic && min_nodes >= kExplicitMinNodes &&
               explicit_bytes <= options.explicit_budget_bytes);

  // automatic: METIS in 3D, and for the explicit operator's interface-last factors (nested
  // dissection of the interior: 8% fewer nonzeros than constrained AMD on the 2D Table 3
  // subdomain, 14% less numeric time in 3D; docs/performance.md); AMD for the implicit
  // operator in 2D.
  ordering_ = options.ordering == Ordering::automatic
                  ? (layout_.dim == 3 || explicit_ ? Ordering::metis : Ordering::amd)
                  : options.ordering;
  const double factor_bytes_estimate = 8.0 * 100.0 * local_dofs;
  // Factor release (FetiOptions::keep_factors): fixed for all clusters by a budget, or decided
  // cluster by cluster from the available memory.
  const bool release_all = explicit_ && !options.keep_factors &&
                           options.factor_budget_bytes >= 0 &&
                           factor_bytes_estimate > options.factor_budget_bytes;
  const bool release_adaptive = explicit_ && !options.keep_factors && options.factor_budget_bytes < 0;
  const int machine_ranks =
      release_adaptive && options.memory_limit_mb > 0 ? ranks_on_this_machine(comm_.raw()) : 1;
  auto usable_mb = [&] { return usable_memory_mb(options.memory_limit_mb, machine_ranks); };
  const double reserve_mb = release_adaptive ? kFactorReserve * usable_mb() : 0.0;
  // What the clusters not yet set up will still allocate, for the adaptive release: their F_i
  // (known from the multipliers) and their dense K_i^+ C_i^T (estimated from the clusters done
  // so far). A cluster keeps its factors only while the memory left after those stays above
  // the reserve (MiB; updated as clusters finish).
  std::vector<double> cluster_explicit_mb(ncl, 0.0);
  double pending_explicit_mb = 0, dense_done_mb = 0;
  int clusters_done = 0;
  if (release_adaptive)
    for (int c = 0; c < ncl; ++c) {
      for (int i = 0; i < members(c); ++i)
        cluster_explicit_mb[c] += packed_bytes[sub_of(c, i)] / 1048576.0;
      pending_explicit_mb += cluster_explicit_mb[c];
    }
  released_.assign(ncl, 0);
  contrib_.resize(nsub);
  for (int s = 0; s < nsub; ++s) contrib_[s].assign(rows_[s].size(), 0.0);
  x_.resize(ncl);
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i) x_[c].push_back(Vec::Zero(subs_[sub_of(c, i)]->size()));

  // The preconditioner's interface per subdomain: the dofs its rows of B~ touch (sorted), and
  // per row entry the position of its dof there. Dense Dirichlet blocks when they fit.
  if (options.preconditioner == PreconditionerKind::automatic ||
      options.scaling == Scaling::automatic)
    throw std::logic_error("DualProblem: resolve the automatic preconditioner first");
  precond_kind_ = options.preconditioner;
  scaling_ = options.scaling;
  std::vector<std::vector<int>> interface(precond_kind_ != PreconditionerKind::none ? nsub : 0);
  std::vector<std::vector<double>> rho(
      precond_kind_ != PreconditionerKind::none && scaling_ == Scaling::stiffness ? nsub : 0);
  if (precond_kind_ != PreconditionerKind::none) {
    double dense_bytes = 0;
    ipos_.resize(nsub);
    for (int s = 0; s < nsub; ++s) {
      auto& in = interface[s];
      for (const auto& r : rows_[s]) in.push_back(r.dof);
      std::sort(in.begin(), in.end());
      in.erase(std::unique(in.begin(), in.end()), in.end());
      for (const auto& r : rows_[s])
        ipos_[s].push_back(
            static_cast<int>(std::lower_bound(in.begin(), in.end(), r.dof) - in.begin()));
      dense_bytes += 8.0 * in.size() * in.size();
    }
    const bool fits = comm_.max(dense_bytes) <= options.dirichlet_dense_budget_bytes;
    if (precond_kind_ == PreconditionerKind::dirichlet && options.dirichlet_storage == 0 &&
        !fits && options.dirichlet_fallback != PreconditionerKind::dirichlet) {
      precond_kind_ = options.dirichlet_fallback;
      if (precond_kind_ == PreconditionerKind::none) {
        interface.clear(), rho.clear(), ipos_.clear();
        exact_node_scaling_ = false;
        node_copies_ = {};
      }
    }
    precond_dense_ = precond_kind_ == PreconditionerKind::dirichlet &&
                     (options.dirichlet_storage == 1 || (options.dirichlet_storage == 0 && fits));
    if (precond_kind_ != PreconditionerKind::none) precond_.resize(nsub);
  }

  // 3. Clusters: factorizations, explicit blocks, the primal-constraint systems; d.
  t = seconds_now();
  if (options.symbolic_cache_patterns > 0)
    symbolic_ = std::make_unique<SymbolicCache>(options.symbolic_cache_patterns,
                                                options.numeric_cache_bytes);
  clusters_.resize(ncl);
  error.clear();
  input_error = false;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    std::vector<Subdomain*> ptrs;
    std::vector<std::vector<Subdomain::BEntry>> b;
    std::vector<int> nmult;
    for (int i = 0; i < members(c); ++i) {
      const int s = sub_of(c, i);
      ptrs.push_back(subs_[s].get());
      b.push_back(std::move(local_b[s]));
      nmult.push_back(static_cast<int>(mult_[s].size()));
    }
    try {
      clusters_[c] = std::make_unique<Cluster>(c0_ + c, std::move(ptrs), std::move(primal[c]),
                                               ordering_, std::move(b), std::move(nmult),
                                               explicit_, symbolic_.get(),
                                               options.explicit_precision);
      // The cluster's part of d = B~ K~^+ f, while its factors are at hand.
      cluster_rhs_from_ext(c, true, 0.0);
      clusters_[c]->solve(x_[c]);
      b_of_x(c);
      if (precond_kind_ != PreconditionerKind::none) {  // from K_i, before it is freed
        const double tp = seconds_now();
        std::string perr;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && members(c) > 1)
        for (int i = 0; i < members(c); ++i) {
          const int s = sub_of(c, i);
          try {
            const Eigen::SparseMatrix<double>& K = subs_[s]->K();
            if (!rho.empty())
              for (const auto& r : rows_[s]) rho[s].push_back(K.coeff(r.dof, r.dof));
            precond_[s] = std::make_unique<LocalPreconditioner>(
                K, std::move(interface[s]), precond_kind_, precond_dense_, ordering_,
                &subs_[s]->kernel(), symbolic_.get());
          } catch (const std::exception& e) {
#pragma omp critical
            perr = e.what();
          }
        }
        if (!perr.empty()) throw std::runtime_error(perr);
#pragma omp atomic
        setup_.preconditioner += seconds_now() - tp;
      }
      // Factored: energy() and refactoring rebuild K_i. Freed per cluster, so that the peak is
      // the factors plus the matrices of the clusters not yet factored, not both in full.
      double bytes = 0, own = 0, tsym = 0, tnum = 0;
      for (int i = 0; i < members(c); ++i) {
        subs_[sub_of(c, i)]->release_matrix();
        bytes += static_cast<double>(subs_[sub_of(c, i)]->factor_bytes());
        if (!subs_[sub_of(c, i)]->factor_shared())
          own += static_cast<double>(subs_[sub_of(c, i)]->factor_bytes());
        tsym += subs_[sub_of(c, i)]->symbolic_seconds();
        tnum += subs_[sub_of(c, i)]->numeric_seconds();
      }
#pragma omp atomic
      setup_.factor_mb += bytes / 1048576.0;
#pragma omp atomic
      setup_.distinct_factor_mb += own / 1048576.0;
#pragma omp atomic
      setup_.factor_symbolic += tsym;
#pragma omp atomic
      setup_.factor_numeric += tnum;
      bool release = release_all;
      if (release_adaptive) {
        double pending_mb = 0;
#pragma omp critical(htfeti_factor_release)
        {
          pending_explicit_mb -= cluster_explicit_mb[c];
          dense_done_mb += 8.0 * static_cast<double>(clusters_[c]->dense_doubles()) / 1048576.0;
          ++clusters_done;
          pending_mb = std::max(0.0, pending_explicit_mb) +
                       dense_done_mb / clusters_done * (ncl - clusters_done);
        }
        release = usable_mb() - pending_mb < reserve_mb;
      }
      if (release) {
        clusters_[c]->release_factors();
        released_[c] = 1;
      }
    } catch (const std::bad_alloc&) {
#pragma omp critical
      error = "out of memory while factoring the subdomains", input_error = true;
    } catch (const std::exception& e) {
#pragma omp critical
      error = e.what();
    }
  }
  comm_.agree(error, input_error);
  if (symbolic_) setup_.distinct_factor_mb += symbolic_->kept_factor_bytes() / 1048576.0;
  if (explicit_) {  // every thread frees its F_i work arrays (they are kept between subdomains)
#pragma omp parallel
    Subdomain::release_dual_block_work();
  }
  setup_.factorization = seconds_now() - t;
  factors_released_ = comm_.max(static_cast<double>(clusters_released())) > 0;
  if (symbolic_) {
    setup_.symbolic_analyses = symbolic_->analyses();
    setup_.symbolic_reuses = symbolic_->reuses();
    setup_.symbolic_patterns = symbolic_->patterns();
    setup_.numeric_reuses = symbolic_->numeric_reuses();
    setup_.numeric_matrices = symbolic_->matrices();
    setup_.solve_reuses = symbolic_->solve_reuses();
  }
  setup_.peak_mb_factorization = peak_rss_mb();
  for (const auto& c : clusters_) setup_.cluster_setup += c->setup_seconds();
  lam_.resize(ncl);
  out_.resize(ncl);
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i) {
      lam_[c].push_back(Vec::Zero(mult_[sub_of(c, i)].size()));
      out_[c].push_back(Vec::Zero(mult_[sub_of(c, i)].size()));
    }

  // 4. Coarse space: the kernel dimension of every cluster (allgathered), G~ rows
  //    (G~)_{(c,j),k} = R~_{c,j} . b_k, the coarse matrix, e~ and lambda~.
  t = seconds_now();
  {
    std::vector<int> dims(ncl), counts(P), displs(P + 1, 0), all(layout_.num_clusters);
    for (int c = 0; c < ncl; ++c) dims[c] = clusters_[c]->kernel_dimension();
    for (int r = 0; r < P; ++r) {
      const auto [a, b] = layout_.cluster_range(r, P);
      counts[r] = b - a;
      displs[r + 1] = displs[r] + counts[r];
    }
    MPI_Allgatherv(dims.data(), ncl, MPI_INT, all.data(), counts.data(), displs.data(), MPI_INT,
                   comm_.raw());
    coarse_first_.assign(layout_.num_clusters + 1, 0);
    for (int c = 0; c < layout_.num_clusters; ++c) coarse_first_[c + 1] = coarse_first_[c] + all[c];
  }
  g_rows_.resize(ncl);
  std::vector<double> acc(n_ext, 0.0);
  std::vector<int> hit;
  for (int c = 0; c < ncl; ++c) {
    const int dk = clusters_[c]->kernel_dimension();
    g_rows_[c].resize(dk);
    for (int j = 0; j < dk; ++j) {
      hit.clear();
      for (int i = 0; i < members(c); ++i)
        for (const auto& r : rows_[sub_of(c, i)]) {
          if (acc[r.k] == 0.0) hit.push_back(r.k);
          acc[r.k] += r.value * clusters_[c]->kernel_entry(i, r.dof, j);
        }
      std::sort(hit.begin(), hit.end(), [&](int a, int b) {  // global order, as on one rank
        return layout_dual_.global(a) < layout_dual_.global(b);
      });
      hit.erase(std::unique(hit.begin(), hit.end()), hit.end());
      for (int k : hit) {
        if (acc[k] != 0.0) g_rows_[c][j].push_back({k, acc[k]});
        acc[k] = 0.0;
      }
    }
  }
  {  // G~^T by ordered sums over clusters: one pair per (cluster, multiplier)
    std::vector<int> pk;
    std::vector<long long> pc;
    g_pairs_.resize(ncl);
    g_first_.assign(ncl + 1, 0);
    for (int c = 0; c < ncl; ++c) {
      std::vector<int> ks;
      for (const auto& row : g_rows_[c])
        for (const auto& [k, g] : row) ks.push_back(k);
      std::sort(ks.begin(), ks.end());
      ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
      const int base = static_cast<int>(pk.size());
      for (int k : ks) pk.push_back(k), pc.push_back(c0_ + c);
      g_pairs_[c].resize(g_rows_[c].size());
      for (size_t j = 0; j < g_rows_[c].size(); ++j)
        for (const auto& [k, g] : g_rows_[c][j])
          g_pairs_[c][j].push_back(
              {base + static_cast<int>(std::lower_bound(ks.begin(), ks.end(), k) - ks.begin()), g});
      g_first_[c + 1] = static_cast<int>(pk.size());
    }
    clu_sum_ = OrderedSum(comm_, layout_dual_, pk, pc, owner_);
    gflat_ = Vec::Zero(static_cast<int>(pk.size()));
  }
  ext_in_ = Vec::Zero(n_ext);
  ext_out_ = Vec::Zero(n_ext);
  coarse_work_ = Vec::Zero(coarse_dimension());

  assemble_coarse(std::vector<double>(n_own, 1.0), coarse_factor_);

  scatter_contrib();  // d: the clusters' parts were computed with their setup
  contrib_ = {};      // needed for nothing else
  d_ = ext_out_.head(n_own) - c_;
  e_ = Vec::Zero(coarse_dimension());
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i)
      clusters_[c]->kernel_dot(i, subs_[sub_of(c, i)]->f(), &e_[coarse_first_[c0_ + c]]);
  comm_.sum_in_place(e_.data(), static_cast<int>(e_.size()));
  if (coarse_factor_.null_dimension() > 0) {
    // Solvable only if the load has no component along the unrestrained rigid motions
    // (e = R~^T f must lie in the range of G~).
    const Eigen::VectorXd along = coarse_factor_.null.transpose() * e_;
    if (along.norm() > 1e-10 * std::max(e_.norm(), 1e-300) || (e_.norm() == 0 && along.norm() > 0))
      throw std::invalid_argument(
          "the problem has no solution: the load has a resultant along " +
          describe_null(coarse_factor_.null) +
          " that no Dirichlet condition or contact restrains (add a Dirichlet condition or "
          "balance the load)");
  }
  coarse_work_ = e_;
  coarse_solve(coarse_work_);
  lambda_tilde_.resize(n_own);
  apply_Gt(coarse_work_, lambda_tilde_);
  lower_.resize(n_own);
  for (int k = 0; k < n_own; ++k)
    lower_[k] =
        kind_[k] == MultiplierKind::contact ? 0.0 : -std::numeric_limits<double>::infinity();
  if (precond_kind_ != PreconditionerKind::none) {
    pin_.resize(nsub), pout_.resize(nsub);
    for (int s = 0; s < nsub; ++s)
      pin_[s] = Vec::Zero(precond_[s]->size()), pout_[s] = Vec::Zero(precond_[s]->size());
    if (scaling_ == Scaling::stiffness) build_scaling(rho);
  }
  setup_.coarse = seconds_now() - t;
  setup_.peak_mb_coarse = peak_rss_mb();
}

void DualProblem::build_scaling(const std::vector<std::vector<double>>& rho) {
  // Per (subdomain s, row r): rho_{r,s}, the b^2-weighted mean of diag K_s over the row's
  // entries on s; summed over the subdomains of each row: W_r = sum_s rho_{r,s} and, for
  // per-node rows (one entry b_{r,s} per subdomain), V_r = sum_s rho_{r,s} b_{r,s}. With the
  // weights delta_s = rho_{r,s} / W_r the scaled entries are
  //   per-node rows: b - sum_s delta_s b_{r,s}, so that B_D^T B~ on a node with copies
  //     weighted by delta is the jump operator u_s - sum_t delta_t u_t (for uniform weights
  //     the sum vanishes: B_D = B~);
  //   averaged-object rows (w, -w)/sqrt(2) on two subdomains: 2 (1 - delta_s) b, the weight of
  //     the other side (again B_D = B~ for uniform weights);
  //   Dirichlet and contact rows: b.
  const int nsub = static_cast<int>(subs_.size()), n_own = layout_dual_.n_owned();
  const int npairs = static_cast<int>(flat_.size());
  Vec num = Vec::Zero(npairs), den = Vec::Zero(npairs), bpair = Vec::Zero(npairs);
  for (int s = 0; s < nsub; ++s)
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      const int p = flat_off_[s] + r.j;
      num[p] += r.value * r.value * rho[s][e];
      den[p] += r.value * r.value;
      if (r.cls == RowClass::node) bpair[p] = r.value;
    }
  const Vec rs = (den.array() > 0).select(num.cwiseQuotient(den.cwiseMax(1e-300)), 0.0);
  flat_ = rs;
  combine_subdomains();
  gather_to_ext(ext_out_.head(n_own).eval());
  const Vec W = ext_in_;
  flat_ = rs.cwiseProduct(bpair);
  combine_subdomains();
  gather_to_ext(ext_out_.head(n_own).eval());
  const Vec V = ext_in_;
  bd_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    bd_[s].resize(rows_[s].size());
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      const double w = W[r.k];
      double v = r.value;
      if (w > 0 && r.cls == RowClass::node && !exact_node_scaling_) v = r.value - V[r.k] / w;
      if (w > 0 && r.cls == RowClass::object) v = 2.0 * r.value * (1.0 - rs[flat_off_[s] + r.j] / w);
      bd_[s][e] = v;
    }
  }
  if (!exact_node_scaling_) return;
  // Nodes with per-node gluing rows and no groups: the rows are an orthonormal basis of the
  // differences of the node's m copies, so B_g^T B_g = I - 11^T / m there and the sum over the
  // copies of a node is m (v_e - (B_g^T B_g v)_e), computable from any copy e. The weights are
  // delta_e = rho_e / sum_c rho_c, and B_D = B_g (I - delta 1^T) on the node: applied in
  // apply_preconditioner as u - 1 (delta^T u) after B_g^T and v - delta (1^T v) before B_g.
  npos_.resize(nsub), ncopies_.resize(nsub), ndelta_.resize(nsub);
  pw_.resize(nsub), pq_.resize(nsub), psum_.resize(nsub);
  std::vector<Vec> rv(nsub);
  for (int s = 0; s < nsub; ++s) {
    const int nb = precond_[s]->size();
    pw_[s] = Vec::Zero(nb), pq_[s] = Vec::Zero(nb), psum_[s] = Vec::Zero(nb);
    rv[s] = Vec::Zero(nb);
    const int dpn = subs_[s]->dofs_per_node();
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      if (r.cls != RowClass::node) continue;
      npos_[s].push_back(ipos_[s][e]);
      ncopies_[s].push_back(node_copies_[s][r.dof / dpn]);
      rv[s][ipos_[s][e]] = rho[s][e];
    }
    // unique positions (a node dof carries several rows); copies follow their positions
    std::vector<size_t> idx(npos_[s].size());
    std::iota(idx.begin(), idx.end(), 0);
    std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return npos_[s][a] < npos_[s][b]; });
    std::vector<int> pos, cop;
    for (size_t i : idx)
      if (pos.empty() || pos.back() != npos_[s][i])
        pos.push_back(npos_[s][i]), cop.push_back(ncopies_[s][i]);
    npos_[s] = pos;
    ncopies_[s].assign(cop.begin(), cop.end());
  }
  node_copies_ = {};
  std::vector<Vec> rsum(nsub);
  for (int s = 0; s < nsub; ++s) rsum[s] = Vec::Zero(precond_[s]->size());
  copy_sums(rv, rsum);
  for (int s = 0; s < nsub; ++s) {
    ndelta_[s].resize(npos_[s].size());
    for (size_t i = 0; i < npos_[s].size(); ++i) {
      const int p = npos_[s][i];
      ndelta_[s][i] = rsum[s][p] > 0 ? rv[s][p] / rsum[s][p] : 1.0 / ncopies_[s][i];
    }
  }
}

void DualProblem::gluing_BtB(const std::vector<Vec>& w, std::vector<Vec>& q) {
  const int nsub = static_cast<int>(subs_.size()), n_own = layout_dual_.n_owned();
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
    double* f = flat_.data() + flat_off_[s];
    const int* pos = ipos_[s].data();
    const auto& rows = rows_[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) f[rows[e].j] += rows[e].value * w[s][pos[e]];
  }
  combine_subdomains();
  ext_in_.head(n_own) = ext_out_.head(n_own);
  layout_dual_.forward(ext_in_.data());
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    q[s].setZero();
    const int* pos = ipos_[s].data();
    const auto& rows = rows_[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) q[s][pos[e]] += rows[e].value * ext_in_[rows[e].k];
  }
}

void DualProblem::copy_sums(std::vector<Vec>& v, std::vector<Vec>& sums) {
  gluing_BtB(v, pq_);
  const int nsub = static_cast<int>(subs_.size());
  for (int s = 0; s < nsub; ++s)
    for (size_t i = 0; i < npos_[s].size(); ++i) {
      const int p = npos_[s][i];
      sums[s][p] = ncopies_[s][i] * (v[s][p] - pq_[s][p]);
    }
}

void DualProblem::apply_preconditioner(const Vec& x, Vec& y) {
  if (precond_kind_ == PreconditionerKind::none)
    throw std::logic_error("apply_preconditioner: no preconditioner was built");
  gather_to_ext(x);
  const int nsub = static_cast<int>(subs_.size());
  const bool scaled = !bd_.empty(), nodes = exact_node_scaling_;
  auto value = [&](int s, size_t e) { return scaled ? bd_[s][e] : rows_[s][e].value; };
  if (!nodes) {  // one pass: B_D^T, the local operator, B_D
#pragma omp parallel for schedule(dynamic)
    for (int s = 0; s < nsub; ++s) {
      const auto& rows = rows_[s];
      const int* pos = ipos_[s].data();
      double* in = pin_[s].data();
      double* out = pout_[s].data();
      pin_[s].setZero();
      for (size_t e = 0; e < rows.size(); ++e)  // B_D^T x on the interface
        in[pos[e]] += value(s, e) * ext_in_[rows[e].k];
      precond_[s]->apply(in, out);
      double* f = flat_.data() + flat_off_[s];
      for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
      for (size_t e = 0; e < rows.size(); ++e)  // B_D (S B_D^T x)
        f[rows[e].j] += value(s, e) * out[pos[e]];
    }
    combine_subdomains();
    y = ext_out_.head(layout_dual_.n_owned());
    return;
  }
  // Exact node scaling (build_scaling): the gluing part of B^T x on node dofs is corrected by
  // u - 1 (delta^T u), and before B the local result by v - delta (1^T v).
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = rows_[s];
    const int* pos = ipos_[s].data();
    pin_[s].setZero(), pw_[s].setZero();
    for (size_t e = 0; e < rows.size(); ++e) {
      const double v = value(s, e) * ext_in_[rows[e].k];
      if (rows[e].cls == RowClass::node)
        pw_[s][pos[e]] += v;  // B_g^T x
      else
        pin_[s][pos[e]] += v;
    }
    for (size_t i = 0; i < npos_[s].size(); ++i) {  // u_g kept in pout_, w = delta u_g
      const int p = npos_[s][i];
      pout_[s][p] = pw_[s][p];
      pw_[s][p] *= ndelta_[s][i];
    }
  }
  copy_sums(pw_, psum_);  // delta^T u over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (size_t i = 0; i < npos_[s].size(); ++i) {
      const int p = npos_[s][i];
      pin_[s][p] += pout_[s][p] - psum_[s][p];
    }
    precond_[s]->apply(pin_[s].data(), pout_[s].data());
    pw_[s].setZero();
    for (size_t i = 0; i < npos_[s].size(); ++i) pw_[s][npos_[s][i]] = pout_[s][npos_[s][i]];
  }
  copy_sums(pw_, psum_);  // 1^T v over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = rows_[s];
    const int* pos = ipos_[s].data();
    pw_[s] = pout_[s];
    for (size_t i = 0; i < npos_[s].size(); ++i)
      pw_[s][npos_[s][i]] -= ndelta_[s][i] * psum_[s][npos_[s][i]];
    double* f = flat_.data() + flat_off_[s];
    for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
    for (size_t e = 0; e < rows.size(); ++e)
      f[rows[e].j] += value(s, e) * (rows[e].cls == RowClass::node ? pw_[s][pos[e]] : pout_[s][pos[e]]);
  }
  combine_subdomains();
  y = ext_out_.head(layout_dual_.n_owned());
}

long DualProblem::preconditioner_bytes() const {
  long b = 0;
  for (const auto& p : precond_) b += p ? p->bytes() : 0;
  for (const auto& v : ipos_) b += 4 * static_cast<long>(v.size());
  for (const auto& v : bd_) b += 8 * static_cast<long>(v.size());
  return b;
}

void DualProblem::gather_to_ext(const Vec& owned) {
  ext_in_.head(layout_dual_.n_owned()) = owned;
  layout_dual_.forward(ext_in_.data());
}

void DualProblem::cluster_rhs_from_ext(int c, bool add_f, double sign) {
  for (int i = 0; i < members(c); ++i) {
    Vec& x = x_[c][i];
    if (add_f)
      x = subs_[sub_of(c, i)]->f();
    else
      x.setZero();
    if (sign != 0.0)
      for (const auto& r : rows_[sub_of(c, i)]) x[r.dof] += sign * r.value * ext_in_[r.k];
  }
}

void DualProblem::b_of_x(int c) {
  for (int i = 0; i < members(c); ++i) {
    const Vec& x = x_[c][i];
    const auto& rows = rows_[sub_of(c, i)];
    double* out = contrib_[sub_of(c, i)].data();
    for (size_t j = 0; j < rows.size(); ++j) out[j] = rows[j].value * x[rows[j].dof];
  }
}

void DualProblem::scatter_contrib() {
  flat_.setZero();
  for (size_t s = 0; s < subs_.size(); ++s) {
    const auto& rows = rows_[s];
    const double* in = contrib_[s].data();
    for (size_t j = 0; j < rows.size(); ++j) flat_[flat_off_[s] + rows[j].j] += in[j];
  }
  combine_subdomains();
}

void DualProblem::combine_subdomains() { sub_sum_.combine(flat_.data(), ext_out_.data()); }

double DualProblem::reduce_blocks(std::vector<double>& partial) const {
  // Every cluster's partial sum is non-zero on one rank only, so the allreduce adds exact zeros;
  // the partial sums are then added in cluster order on every rank.
  if (comm_.size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, partial.data(), static_cast<int>(partial.size()), MPI_DOUBLE,
                  MPI_SUM, comm_.raw());
  double s = 0;
  for (double v : partial) s += v;
  return s;
}

double DualProblem::dot(const Vec& a, const Vec& b) const {
  std::fill(partial_.begin(), partial_.end(), 0.0);
  for (Eigen::Index i = 0; i < a.size(); ++i) partial_[block_[i]] += a[i] * b[i];
  return reduce_blocks(partial_);
}

double DualProblem::sum(const Vec& v) const {
  std::fill(partial_.begin(), partial_.end(), 0.0);
  for (Eigen::Index i = 0; i < v.size(); ++i) partial_[block_[i]] += v[i];
  return reduce_blocks(partial_);
}

template <class Body>
void DualProblem::for_each_cluster(Body body) {
  const int nc = static_cast<int>(clusters_.size());
  std::string error;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) {
    try {
      body(c);
    } catch (const std::exception& e) {
#pragma omp critical
      error = e.what();
    }
  }
  if (!error.empty()) throw std::runtime_error(error);
}

void DualProblem::apply_F(const Vec& lambda, Vec& y) {
  gather_to_ext(lambda);
  const int nc = static_cast<int>(clusters_.size());
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) {
    for (int i = 0; i < members(c); ++i) {  // the cluster's part of lambda
      const auto& mult = mult_[sub_of(c, i)];
      Vec& l = lam_[c][i];
      for (size_t j = 0; j < mult.size(); ++j) l[j] = ext_in_[mult[j]];
    }
    clusters_[c]->apply_dual(lam_[c], out_[c]);  // the bottleneck
    for (int i = 0; i < members(c); ++i)          // each subdomain's own segment of flat_
      flat_.segment(flat_off_[sub_of(c, i)], out_[c][i].size()) = out_[c][i];
  }
  combine_subdomains();  // F lambda, summed over subdomains in a fixed order
  y = ext_out_.head(layout_dual_.n_owned());
}

// G~ and G~^T: every cluster has its own rows of the coarse vector and its own pairs of gflat_,
// so threads take clusters and each value is formed in the same order as by one thread.
void DualProblem::apply_G(const Vec& lambda, Vec& coarse) {
  gather_to_ext(lambda);
  coarse.setZero(coarse_dimension());
  const int nc = static_cast<int>(clusters_.size());
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) {
    const int base = coarse_first_[clusters_[c]->id()];
    for (size_t j = 0; j < g_rows_[c].size(); ++j) {
      double s = 0;
      for (const auto& [k, g] : g_rows_[c][j]) s += g * ext_in_[k];
      coarse[base + static_cast<int>(j)] = s;
    }
  }
  comm_.sum_in_place(coarse.data(), static_cast<int>(coarse.size()));
}

void DualProblem::gt_into_ext(const Vec& coarse) {
  const int nc = static_cast<int>(clusters_.size());
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) {
    for (int p = g_first_[c]; p < g_first_[c + 1]; ++p) gflat_[p] = 0.0;
    const int base = coarse_first_[clusters_[c]->id()];
    for (size_t j = 0; j < g_pairs_[c].size(); ++j) {
      const double z = coarse[base + static_cast<int>(j)];
      for (const auto& [p, g] : g_pairs_[c][j]) gflat_[p] += g * z;
    }
  }
  clu_sum_.combine(gflat_.data(), ext_out_.data());
}

void DualProblem::apply_Gt(const Vec& coarse, Vec& lambda) {
  gt_into_ext(coarse);
  lambda = ext_out_.head(layout_dual_.n_owned());
}

void DualProblem::project(const Vec& x, Vec& y) {
  apply_G(x, coarse_work_);    // G~ x
  coarse_solve(coarse_work_);  // (G~ G~^T)^{-1} G~ x
  gt_into_ext(coarse_work_);   // G~^T (G~ G~^T)^{-1} G~ x, owned part in ext_out_
  y = x - ext_out_.head(layout_dual_.n_owned());
}

namespace {
// MPI datatypes for arrays of a struct of (long long, int..., double) fields.
template <class T, size_t N>
MPI_Datatype struct_type(const std::array<MPI_Aint, N>& disp, const std::array<MPI_Datatype, N>& types) {
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

std::vector<DualProblem::GItem> DualProblem::g_columns_at_owners() const {
  // Every cluster sends (k, coarse row, g) for its nonzeros of G~ to the owner of k. Counts are
  // in items (MPI datatypes), not bytes.
  MPI_Datatype item_type = struct_type<GItem, 3>(
      {offsetof(GItem, k), offsetof(GItem, row), offsetof(GItem, g)},
      {MPI_LONG_LONG, MPI_INT, MPI_DOUBLE});
  const int P = comm_.size();
  std::vector<std::vector<GItem>> out(P);
  for (size_t c = 0; c < clusters_.size(); ++c) {
    const int base = coarse_first_[clusters_[c]->id()];
    for (size_t j = 0; j < g_rows_[c].size(); ++j)
      for (const auto& [k, g] : g_rows_[c][j])
        out[owner_[k]].push_back({layout_dual_.global(k), base + static_cast<int>(j), g});
  }
  std::vector<int> scount(P), rcount(P), sdisp(P + 1, 0), rdisp(P + 1, 0);
  for (int r = 0; r < P; ++r) scount[r] = static_cast<int>(out[r].size());
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm_.raw());
  for (int r = 0; r < P; ++r)
    sdisp[r + 1] = sdisp[r] + scount[r], rdisp[r + 1] = rdisp[r] + rcount[r];
  std::vector<GItem> sbuf(sdisp[P]), rbuf(rdisp[P]);
  for (int r = 0, pos = 0; r < P; ++r)
    for (const auto& it : out[r]) sbuf[pos++] = it;
  out = {};
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), item_type, rbuf.data(), rcount.data(),
                rdisp.data(), item_type, comm_.raw());
  MPI_Type_free(&item_type);
  std::stable_sort(rbuf.begin(), rbuf.end(), [](const GItem& x, const GItem& y) {
    return x.k != y.k ? x.k < y.k : x.row < y.row;
  });
  return rbuf;
}

std::vector<DualProblem::CoarseTriplet> DualProblem::allgather_sorted(
    const std::vector<CoarseTriplet>& mine) const {
  MPI_Datatype trip_type = struct_type<CoarseTriplet, 4>(
      {offsetof(CoarseTriplet, k), offsetof(CoarseTriplet, a), offsetof(CoarseTriplet, b),
       offsetof(CoarseTriplet, v)},
      {MPI_LONG_LONG, MPI_INT, MPI_INT, MPI_DOUBLE});
  const int P = comm_.size();
  int nmine = static_cast<int>(mine.size());
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Allgather(&nmine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_.raw());
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<CoarseTriplet> all(disp[P]);
  MPI_Allgatherv(mine.data(), nmine, trip_type, all.data(), counts.data(), disp.data(), trip_type,
                 comm_.raw());
  MPI_Type_free(&trip_type);
  // Each entry's partial sums in key order, whatever rank formed them.
  std::sort(all.begin(), all.end(), [](const CoarseTriplet& x, const CoarseTriplet& y) {
    return x.a != y.a ? x.a < y.a : x.b != y.b ? x.b < y.b : x.k < y.k;
  });
  return all;
}

std::vector<DualProblem::CoarseTriplet> DualProblem::owner_cluster_sums(
    const std::vector<GItem>& gcol, const ProductsOf& products_of) const {
  // Products summed per owner cluster of the multiplier (all of a cluster's multipliers live on
  // one rank whatever the rank count), in multiplier order; the caller adds the partial sums in
  // cluster order (allgather_sorted). Rank-count independent, and O(entries touched per
  // cluster) memory instead of one triplet per product (78 per multiplier for G~ G~^T in 3D
  // elasticity).
  std::vector<std::pair<int, size_t>> groups;  // (owner cluster, first item of the multiplier)
  for (size_t i = 0; i < gcol.size(); ++i)
    if (i == 0 || gcol[i].k != gcol[i - 1].k)
      groups.push_back({block_[layout_dual_.ext_index(gcol[i].k)], i});
  std::stable_sort(groups.begin(), groups.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<CoarseTriplet> mine, products;
  for (size_t g0 = 0; g0 < groups.size();) {
    size_t g1 = g0;
    while (g1 < groups.size() && groups[g1].first == groups[g0].first) ++g1;
    products.clear();
    for (size_t g = g0; g < g1; ++g) {
      const size_t i = groups[g].second;
      size_t j = i;
      while (j < gcol.size() && gcol[j].k == gcol[i].k) ++j;
      products_of(i, j, products);
    }
    std::stable_sort(products.begin(), products.end(),
                     [](const CoarseTriplet& x, const CoarseTriplet& y) {
                       return x.a != y.a ? x.a < y.a : x.b < y.b;  // stable: multiplier order
                     });
    for (size_t p = 0; p < products.size();) {
      size_t q = p;
      double v = 0;
      for (; q < products.size() && products[q].a == products[p].a &&
             products[q].b == products[p].b;
           ++q)
        v += products[q].v;
      mine.push_back({groups[g0].first, products[p].a, products[p].b, v});
      p = q;
    }
    g0 = g1;
  }
  return mine;
}

void DualProblem::assemble_coarse(const std::vector<double>& weight, CoarseFactor& factor) {
  // (G~ W G~^T)_{ab} = sum_k w_k g_ak g_bk. The owners of the multipliers form the products and
  // sum equal entries; the summed triplets are shared (every rank factors the coarse matrix).
  using Triplet = CoarseTriplet;
  std::vector<GItem> rbuf = g_columns_at_owners();
  std::vector<Triplet> mine = owner_cluster_sums(
      rbuf, [&](size_t i, size_t j, std::vector<Triplet>& products) {
        const double w = weight[layout_dual_.ext_index(rbuf[i].k)];
        if (w != 0.0)
          for (size_t a = i; a < j; ++a)
            for (size_t b = a; b < j; ++b) {
              int ca = rbuf[a].row, cb = rbuf[b].row;
              if (ca > cb) std::swap(ca, cb);
              products.push_back({rbuf[i].k, ca, cb, w * rbuf[a].g * rbuf[b].g});
            }
      });
  rbuf = {};
  // Sum each entry's partial sums in cluster order whatever rank formed them (k: the cluster).
  const std::vector<Triplet> all = allgather_sorted(mine);
  mine = {};
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(all.size());
  for (const auto& t : all) trip.emplace_back(t.a, t.b, t.v);
  Eigen::SparseMatrix<double> GGt(coarse_dimension(), coarse_dimension());
  GGt.setFromTriplets(trip.begin(), trip.end());
  factor.sparse = SparseCholesky(Ordering::amd);
  factor.use_dense = false;
  factor.null.resize(0, 0);
  bool singular = false;
  {
    // BLAS on one thread: called outside a parallel region, OpenBLAS's OpenMP flavour would
    // use every thread, and its threaded blocks round differently per thread count (the coarse
    // factor of Table 3's 2,048 clusters moved by an ulp between 1 and 2 threads, and with it
    // lambda~ and the energy by 1e-11). The coarse matrix is small; nothing is lost.
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    try {
      factor.sparse.factorize(GGt);
    } catch (const std::exception&) {
      singular = true;  // the same on every rank: every rank factors the same matrix
    }
    omp_set_num_threads(threads);
  }
  if (!singular) return;
  const int nc = coarse_dimension();
  if (nc > kMaxDenseCoarse)
    throw std::runtime_error(
        "the coarse problem G G^T is singular: some rigid motion of a subdomain or cluster is "
        "restrained by no Dirichlet condition or contact row (coarse dimension " +
        std::to_string(nc) + " is too large to name it)");
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
  factor.use_dense = true;
  if (factor.dense.info() != Eigen::Success)
    throw std::runtime_error("the coarse problem G G^T could not be factored");
}

std::string DualProblem::describe_null(const Eigen::MatrixXd& Z) const {
  // Clusters carrying the null directions (largest coefficients), by global cluster id.
  std::vector<int> clusters;
  const double top = Z.size() ? Z.cwiseAbs().maxCoeff() : 0.0;
  for (int c = 0; c < layout_.num_clusters; ++c) {
    double m = 0;
    for (int j = coarse_first_[c]; j < coarse_first_[c + 1]; ++j)
      m = std::max(m, Z.row(j).cwiseAbs().maxCoeff());
    if (m > 1e-3 * top) clusters.push_back(c);
  }
  std::string s;
  for (size_t i = 0; i < clusters.size() && i < 8; ++i)
    s += (i ? ", " : "") + std::to_string(clusters[i]);
  if (clusters.size() > 8) s += ", ... (" + std::to_string(clusters.size()) + " in all)";
  const bool one = layout_.num_clusters == layout_.num_subdomains;
  return std::to_string(Z.cols()) + " rigid motion(s) of " + (one ? "subdomain(s) " : "cluster(s) ") + s;
}

void DualProblem::apply_B(const std::vector<Vec>& u, Vec& out) {
  flat_.setZero();
  for (size_t s = 0; s < subs_.size(); ++s)
    for (const auto& r : rows_[s]) flat_[flat_off_[s] + r.j] += r.value * u[s][r.dof];
  combine_subdomains();
  out = ext_out_.head(layout_dual_.n_owned());
}

std::vector<DualProblem::Vec> DualProblem::reconstruct(const Vec& lambda) {
  const int n_own = layout_dual_.n_owned();
  gather_to_ext(lambda);
  std::vector<Vec> u(subs_.size());
  std::string error;
  try {
    for_each_cluster([&](int c) {
      // Freed factors are rebuilt plain (ordering_, no interface last): solve() is all the
      // reconstruction needs, and that factor is cheaper (docs/method.md); u then
      // agrees with the kept factors' u to round-off.
      if (released_[c]) clusters_[c]->refactor(ordering_, symbolic_.get(), false);
      cluster_rhs_from_ext(c, true, -1.0);  // f - B~^T lambda
      clusters_[c]->solve(x_[c]);
      for (int i = 0; i < members(c); ++i) u[sub_of(c, i)] = x_[c][i];
      if (released_[c]) clusters_[c]->release_factors();
    });
  } catch (const std::exception& e) {
    error = e.what();
  }
  comm_.agree(error);
  // B u0 = d + c - F lambda; alpha solves G~ D G~^T alpha = G~ D (c - B u0), D masking the
  // contact rows with lambda_i = 0 (paper, (10)).
  Vec r;
  apply_B(u, r);
  r = c_ - r;
  std::vector<double> weight(n_own, 1.0);
  bool masked = false;
  for (int k = 0; k < n_own; ++k)
    if (kind_[k] == MultiplierKind::contact && !(lambda[k] > 0.0)) {
      weight[k] = 0.0;
      r[k] = 0.0;
      masked = true;
    }
  Vec alpha;
  apply_G(r, alpha);
  if (comm_.max(masked ? 1.0 : 0.0) > 0.0) {
    CoarseFactor masked_factor;
    assemble_coarse(weight, masked_factor);
    reconstruction_null_ = masked_factor.null_dimension();
    masked_factor.solve(alpha);
  } else {
    coarse_solve(alpha);
  }
  for (size_t c = 0; c < clusters_.size(); ++c) {
    const double* a = &alpha[coarse_first_[clusters_[c]->id()]];
    for (int i = 0; i < members(static_cast<int>(c)); ++i)
      clusters_[c]->kernel_add(i, a, u[sub_of(static_cast<int>(c), i)]);
  }
  return u;
}

double DualProblem::energy(const std::vector<Vec>& u) const {
  // Per-subdomain energies summed in subdomain order (rank-count independent).
  // Threads take subdomains (each rebuilds its K_i if it was freed: the cost of this function);
  // the sum below is in subdomain order, so the result does not depend on the thread count.
  std::vector<double> e(layout_.num_subdomains, 0.0);
  const int n = static_cast<int>(subs_.size());
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < n; ++s) e[subs_[s]->id()] = subs_[s]->energy(u[s]);
  if (comm_.size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, e.data(), static_cast<int>(e.size()), MPI_DOUBLE, MPI_SUM, comm_.raw());
  double q = 0;
  for (double v : e) q += v;
  return q;
}

DualProblem::Kkt DualProblem::kkt(const std::vector<Vec>& u, const Vec& lambda) {
  Vec bu;
  apply_B(u, bu);
  double viol = 0, minmult = std::numeric_limits<double>::infinity(), compl_ = 0;
  bool any_contact = false;
  Vec sq = Vec::Zero(layout_dual_.n_owned());
  for (int k = 0; k < layout_dual_.n_owned(); ++k) {
    if (kind_[k] != MultiplierKind::contact) {
      sq[k] = (bu[k] - c_[k]) * (bu[k] - c_[k]);
      continue;
    }
    any_contact = true;
    const double s = contact_scale_[k];
    const double gap = (c_[k] - bu[k]) / s;  // gap - n.(u_a - u_b), >= 0 when feasible
    const double force = s * lambda[k];
    viol = std::max(viol, -gap);
    minmult = std::min(minmult, force);
    compl_ = std::max(compl_, std::abs(force * gap));
  }
  Kkt r;
  r.equality_residual = std::sqrt(sum(sq));
  r.max_violation = comm_.max(viol);
  r.min_multiplier = comm_.sum(any_contact ? 1.0 : 0.0) > 0 ? comm_.min(minmult) : 0.0;
  r.complementarity = comm_.max(compl_);
  return r;
}

DualProblem::ContactData DualProblem::contact_data(const std::vector<Vec>& u, const Vec& lambda) {
  // n.(avg u_a) from the entries on node a (coefficients scale n_i / k_a), n.(avg u_b) likewise.
  const int n_own = layout_dual_.n_owned();
  Vec a = Vec::Zero(layout_dual_.n_ext()), b = Vec::Zero(layout_dual_.n_ext());
  for (int side : {1, -1}) {
    flat_.setZero();
    for (size_t s = 0; s < subs_.size(); ++s)
      for (const auto& r : rows_[s])
        if (r.side == side) flat_[flat_off_[s] + r.j] += side * r.value * u[s][r.dof];
    combine_subdomains();
    (side > 0 ? a : b).head(n_own) = ext_out_.head(n_own);
  }
  std::vector<double> mine;
  for (int k = 0; k < n_own; ++k)
    if (kind_[k] == MultiplierKind::contact) {
      const double s = contact_scale_[k];
      const auto& p = contact_point_[k];
      mine.insert(mine.end(),
                  {p[0], p[1], p[2], a[k] / s, b[k] / s, contact_gap_[k], s * lambda[k]});
    }
  constexpr int W = 7;
  const int P = comm_.size();
  int count = static_cast<int>(mine.size());
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_.raw());
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<double> all(comm_.rank() == 0 ? disp[P] : 0);
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), disp.data(), MPI_DOUBLE, 0,
              comm_.raw());
  ContactData data;
  if (comm_.rank() != 0) return data;
  std::vector<std::array<double, W>> rows(all.size() / W);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int j = 0; j < W; ++j) rows[i][j] = all[W * i + j];
  std::sort(rows.begin(), rows.end());
  for (const auto& r : rows) {
    data.x.push_back(r[0]);
    data.y.push_back(r[1]);
    data.z.push_back(r[2]);
    data.u_a.push_back(r[3]);
    data.u_b.push_back(r[4]);
    data.gap.push_back(r[5]);
    data.force.push_back(r[6]);
  }
  return data;
}

std::vector<DualProblem::Vec> DualProblem::contact_forces(const Vec& lambda) {
  gather_to_ext(lambda);
  std::vector<Vec> out(subs_.size());
  for (size_t s = 0; s < subs_.size(); ++s) {
    out[s] = Vec::Zero(subs_[s]->size());
    for (const auto& r : rows_[s])
      if (r.side != 0) out[s][r.dof] -= r.value * ext_in_[r.k];
  }
  return out;
}

std::vector<DualProblem::Vec> DualProblem::contact_gap_field(const std::vector<Vec>& u) {
  Vec bu;
  apply_B(u, bu);
  const int n_own = layout_dual_.n_owned();
  Vec rem = Vec::Zero(layout_dual_.n_ext());
  for (int k = 0; k < n_own; ++k)
    if (kind_[k] == MultiplierKind::contact) rem[k] = (c_[k] - bu[k]) / contact_scale_[k];
  layout_dual_.forward(rem.data());
  std::vector<Vec> out(subs_.size());
  for (size_t s = 0; s < subs_.size(); ++s) {
    const int dpn = subs_[s]->dofs_per_node();
    out[s] = Vec::Constant(subs_[s]->size() / dpn, std::numeric_limits<double>::quiet_NaN());
    for (const auto& r : rows_[s])
      if (r.side != 0) out[s][r.dof / dpn] = rem[r.k];
  }
  return out;
}

long DualProblem::factor_nonzeros() const {
  long n = 0;
  for (const auto& s : subs_) n += s->factor_nonzeros();
  return n;
}

int DualProblem::clusters_released() const {
  int n = 0;
  for (char r : released_) n += r;
  return n;
}

long DualProblem::explicit_bytes() const {
  long n = 0;
  for (const auto& c : clusters_) n += c->explicit_bytes();
  return n;
}

long DualProblem::cluster_dense_doubles() const {
  long n = 0;
  std::unordered_set<const void*> seen;  // blocks shared by equal subdomains counted once
  for (const auto& c : clusters_) n += c->dense_doubles(&seen);
  return n;
}

}  // namespace htfeti
