#include "htfeti/feti/dual_problem.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unordered_set>

#include "dual_setup.hpp"
#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/parallel/fresh_pages.hpp"
#include "htfeti/parallel/key_numbering.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

namespace {

// The factor release of the explicit operator (FetiOptions::keep_factors): fixed for all
// clusters by a budget, or decided cluster by cluster from the available memory. For the
// adaptive release, what the clusters not yet set up will still allocate: their F_i (known from
// the multipliers) and their dense K_i^+ C_i^T (estimated from the clusters done so far). A
// cluster keeps its factors only while the memory left after those stays above the reserve
// (MiB; updated as clusters finish).
class FactorRelease {
 public:
  FactorRelease(const FetiOptions& options, bool explicit_operator, double local_dofs,
                const Comm& comm, std::vector<double> cluster_explicit_mb)
      : limit_mb_(options.memory_limit_mb), cluster_explicit_mb_(std::move(cluster_explicit_mb)) {
    const double factor_bytes_estimate = 8.0 * 100.0 * local_dofs;
    all_ = explicit_operator && !options.keep_factors && options.factor_budget_bytes >= 0 &&
           factor_bytes_estimate > options.factor_budget_bytes;
    adaptive_ = explicit_operator && !options.keep_factors && options.factor_budget_bytes < 0;
    machine_ranks_ =
        adaptive_ && options.memory_limit_mb > 0 ? ranks_on_this_machine(comm.raw()) : 1;
    reserve_mb_ = adaptive_ ? kFactorReserve * usable_mb() : 0.0;
    if (adaptive_)
      for (double mb : cluster_explicit_mb_) pending_explicit_mb_ += mb;
  }
  // Whether local cluster c, just set up with dense_mb of dense blocks, frees its factors.
  // Thread-safe.
  bool after_cluster(int c, double dense_mb) {
    if (!adaptive_) return all_;
    double pending_mb = 0;
    const int ncl = static_cast<int>(cluster_explicit_mb_.size());
#pragma omp critical(htfeti_factor_release)
    {
      pending_explicit_mb_ -= cluster_explicit_mb_[c];
      dense_done_mb_ += dense_mb;
      ++clusters_done_;
      pending_mb = std::max(0.0, pending_explicit_mb_) +
                   dense_done_mb_ / clusters_done_ * (ncl - clusters_done_);
    }
    return usable_mb() - pending_mb < reserve_mb_;
  }

 private:
  double usable_mb() const { return usable_memory_mb(limit_mb_, machine_ranks_); }
  double limit_mb_;
  std::vector<double> cluster_explicit_mb_;
  bool all_ = false, adaptive_ = false;
  int machine_ranks_ = 1;
  double reserve_mb_ = 0, pending_explicit_mb_ = 0, dense_done_mb_ = 0;
  int clusters_done_ = 0;
};

}  // namespace

namespace {}  // namespace

DualProblem::DualProblem(const FetiLayout& layout,
                         const std::function<SubdomainInput(int)>& make_input, const Comm& comm,
                         const FetiOptions& options)
    : layout_(layout), comm_(comm) {
  Setup st(options);
  st.P = comm.size(), st.me = comm.rank();
  std::tie(first_cluster_, end_cluster_) = layout_.cluster_range(st.me, st.P);
  st.ncl = end_cluster_ - first_cluster_;
  st.s0 = layout_.cluster_first[first_cluster_];
  st.nsub = layout_.cluster_first[end_cluster_] - st.s0;
  sub_first_.resize(st.ncl + 1);
  for (int c = 0; c <= st.ncl; ++c)
    sub_first_[c] = layout_.cluster_first[first_cluster_ + c] - st.s0;
  // The one cache for equal subdomains and patterns (SubdomainCache): its matrix level always,
  // its factor levels when symbolic_cache_patterns > 0.
  cache_ = std::make_unique<SubdomainCache>(options.symbolic_cache_patterns,
                                            options.numeric_cache_bytes);
  assemble_subdomains(make_input, st);  // 1.
  number_multipliers(st);               // 2.
  choose_operator(st);
  plan_preconditioner(st);
  set_up_clusters(st);      // 3.
  set_up_coarse_space(st);  // 4.
  finish_setup(st);
}

void DualProblem::assemble_subdomains(const std::function<SubdomainInput(int)>& make_input,
                                      Setup& st) {
  const FetiOptions& options = st.options;
  const int ncl = st.ncl, nsub = st.nsub;
  auto& local_rows = st.local_rows;
  auto& primal = st.primal;
  local_rows.resize(nsub);
  primal.resize(ncl);
  // 1. Per cluster: generate and assemble the subdomains, their rows of B~ and the cluster's
  //    primal constraints, while the dof sharing is at hand; then drop the sharing.
  const double t = seconds_now();
  subs_.resize(nsub);
  preconditioner_.start(options, layout_, nsub);  // and the node copies it needs
  outer_parallel_ = omp_get_max_threads() > 1 && ncl >= omp_get_max_threads();
  std::string error;
  bool input_error = false;
  ObjectRowCache object_rows;         // the rows of equal averaged objects computed once
  std::vector<char> framed(nsub, 0);  // the model gave a kernel frame: a generated box
  // The coefficient's spread (largest over smallest value) on each subdomain, its extremes.
  std::vector<double> spread(nsub, 1.0), lowest(nsub, 1.0), highest(nsub, 1.0);
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    try {
      const int ms = members(c);
      std::vector<SubdomainInput> in(ms);
      // Each K_i goes to the cache as soon as it is assembled: a cluster's members are all made
      // before its primal constraints, and held unpooled they would all be in memory at once.
      std::vector<std::shared_ptr<const SubdomainCache::Matrix>> pooled(ms);
      RegionError inner_failure;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && ms > 1)
      for (int i = 0; i < ms; ++i) {
        try {
          if (c == 0 && i == 0) inject_failure("assembly", comm_.rank());
          SubdomainInput made = make_input(layout_.cluster_first[first_cluster_ + c] + i);
          Eigen::SparseMatrix<double> K;  // moved by swap: Eigen's SparseMatrix copies on move
          K.swap(made.system.K);
          in[i] = std::move(made);
          in[i].system.K.swap(K);
          if (in[i].system.K.rows() == in[i].system.f.size())
            pooled[i] = cache_->intern_matrix(in[i].system.K);  // leaves system.K empty
          subdomain_rows(layout_, in[i], local_rows[sub_of(c, i)], &object_rows);
          framed[sub_of(c, i)] = in[i].sharing.kernel_frame ? 1 : 0;
          spread[sub_of(c, i)] = in[i].system.coefficient_max / in[i].system.coefficient_min;
          lowest[sub_of(c, i)] = in[i].system.coefficient_min;
          highest[sub_of(c, i)] = in[i].system.coefficient_max;
          if (preconditioner_.collects_node_copies()) {
            auto& nc = preconditioner_.node_copies(sub_of(c, i));
            for (int k = 0; k < in[i].sharing.num_nodes(); ++k)
              nc.push_back(in[i].sharing.num_copies(k));
          }
        } catch (const std::exception& e) {
          inner_failure.record(e);
        }
      }
      inner_failure.rethrow();
      std::vector<const SubdomainInput*> ptrs;
      for (auto& x : in) ptrs.push_back(&x);
      primal[c] = cluster_primal_constraints(layout_, first_cluster_ + c, ptrs);
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
  // Subdomains and objects that repeat (every input has a kernel frame, on every rank): the
  // clusters' K_i^+ C_i^T by object (Cluster).
  by_object_ =
      comm_.min(std::all_of(framed.begin(), framed.end(), [](char f) { return f; }) ? 1.0 : 0.0) >
      0;
  coefficient_spread_ =
      comm_.max(spread.empty() ? 1.0 : *std::max_element(spread.begin(), spread.end()));
  coefficient_range_ =
      comm_.max(highest.empty() ? 1.0 : *std::max_element(highest.begin(), highest.end())) /
      comm_.min(lowest.empty() ? 1.0 : *std::min_element(lowest.begin(), lowest.end()));
  setup_.shared_matrices = cache_->matrix_reuses();
  setup_.assembly = seconds_now() - t;
  setup_.peak_mb_assembly = peak_rss_mb();
}

void DualProblem::number_multipliers(Setup& st) {
  // 2. The rows of B~ numbered globally by key, owners, the extended layout, the local rows.
  const double t = seconds_now();
  st.local_b = multipliers_.number(layout_, comm_, st.local_rows, st.s0);
  setup_.constraints = seconds_now() - t;
  setup_.peak_mb_constraints = peak_rss_mb();
}

void DualProblem::choose_operator(Setup& st) {
  const FetiOptions& options = st.options;
  const int nsub = st.nsub;
  auto& packed_bytes = st.packed_bytes;
  double& local_dofs = st.local_dofs;
  double min_nodes = std::numeric_limits<double>::infinity();
  local_dofs = 0;
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
  packed_bytes.assign(nsub, 0.0);  // F_i of each subdomain, packed
  double explicit_bytes = 0;
  for (int s = 0; s < nsub; ++s) {
    const double m = static_cast<double>(multipliers_.of_subdomain[s].size());
    explicit_bytes += packed_bytes[s] = value_bytes * m * (m + 1) / 2;
  }
  explicit_bytes = comm_.max(explicit_bytes);
  checked_ = options.dual_operator == DualOperator::checked;
  explicit_ = options.dual_operator == DualOperator::explicit_ || checked_ ||
              (options.dual_operator == DualOperator::automatic &&
               automatic_prefers_explicit(options, layout_.dim, min_nodes) &&
               explicit_bytes <= explicit_budget(options));

  // automatic: METIS in 3D, and for the explicit operator's interface-last factors (nested
  // dissection of the interior: 8% fewer nonzeros than constrained AMD on the 2D Table 3
  // subdomain, 14% less numeric time in 3D; docs/performance.md); AMD for the implicit
  // operator in 2D.
  ordering_ = resolve_ordering(options.ordering, layout_.dim, explicit_);
}

void DualProblem::plan_preconditioner(Setup& st) {
  st.interface = preconditioner_.plan(st.options, multipliers_, comm_);
  st.rho.resize(preconditioner_.wants_diagonal() ? st.nsub : 0);
}

void DualProblem::set_up_clusters(Setup& st) {
  const FetiOptions& options = st.options;
  const int ncl = st.ncl, nsub = st.nsub;
  auto& primal = st.primal;
  auto& local_b = st.local_b;
  auto& interface = st.interface;
  auto& rho = st.rho;
  const auto& packed_bytes = st.packed_bytes;
  std::vector<double> cluster_explicit_mb(ncl, 0.0);
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i)
      cluster_explicit_mb[c] += packed_bytes[sub_of(c, i)] / 1048576.0;
  // The checked operator applies the implicit one too: it keeps the factors.
  FactorRelease release_policy(options, explicit_ && !checked_, st.local_dofs, comm_,
                               std::move(cluster_explicit_mb));
  released_.assign(ncl, 0);
  contrib_.resize(nsub);
  for (int s = 0; s < nsub; ++s) contrib_[s].assign(multipliers_.rows[s].size(), 0.0);
  x_.resize(ncl);
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i) x_[c].push_back(Vec::Zero(subs_[sub_of(c, i)]->size()));

  // 3. Clusters: factorizations, explicit blocks, the primal-constraint systems; d.
  const double t = seconds_now();
  clusters_.resize(ncl);
  std::string error;
  bool input_error = false;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    std::vector<Subdomain*> ptrs;
    std::vector<std::vector<Subdomain::BEntry>> b;
    std::vector<int> nmult;
    for (int i = 0; i < members(c); ++i) {
      const int s = sub_of(c, i);
      ptrs.push_back(subs_[s].get());
      b.push_back(std::move(local_b[s]));
      nmult.push_back(static_cast<int>(multipliers_.of_subdomain[s].size()));
    }
    try {
      if (c == 0) inject_failure("factorization", comm_.rank());
      clusters_[c] =
          std::make_unique<Cluster>(first_cluster_ + c, std::move(ptrs), std::move(primal[c]),
                                    ordering_, std::move(b), std::move(nmult),
                                    checked_    ? DualOperator::checked
                                    : explicit_ ? DualOperator::explicit_
                                                : DualOperator::implicit,
                                    factor_cache(), options.explicit_precision, by_object_,
                                    options.factor_precision != FactorPrecision::double_);
      // The cluster's part of d = B~ K~^+ f, while its factors are at hand.
      cluster_rhs_from_ext(c, true, 0.0);
      clusters_[c]->solve(x_[c]);
      b_of_x(c);
      if (preconditioner_.built()) {  // from K_i, before it is freed
        const double tp = seconds_now();
        RegionError perr;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && members(c) > 1)
        for (int i = 0; i < members(c); ++i) {
          const int s = sub_of(c, i);
          try {
            const Eigen::SparseMatrix<double>& K = subs_[s]->K();
            if (!rho.empty())
              for (const auto& r : multipliers_.rows[s]) rho[s].push_back(K.coeff(r.dof, r.dof));
            preconditioner_.set_up_subdomain(s, K, std::move(interface[s]), ordering_,
                                             &subs_[s]->kernel(), factor_cache());
          } catch (const std::exception& e) {
            perr.record(e);
          }
        }
        perr.rethrow();
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
      const bool release = release_policy.after_cluster(
          c, 8.0 * static_cast<double>(clusters_[c]->dense_doubles()) / 1048576.0);
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
  release_idle_blocks();  // the factorizations' freed blocks (parallel/fresh_pages.hpp)
  comm_.agree(error, input_error);
  if (factor_cache()) setup_.distinct_factor_mb += cache_->kept_factor_bytes() / 1048576.0;
  if (explicit_) {  // every thread frees its F_i work arrays (they are kept between subdomains)
#pragma omp parallel
    Subdomain::release_dual_block_work();
  }
  setup_.factorization = seconds_now() - t;
  factors_released_ = comm_.max(static_cast<double>(clusters_released())) > 0;
  {
    std::unordered_set<const void*> seen;
    double single = 0, any = 0;
    for (const auto& c : clusters_) {
      single += static_cast<double>(c->single_bytes(&seen));
      any = std::max(any, c->single_sweeps() ? 1.0 : 0.0);
    }
    setup_.single_factor_mb = single / 1048576.0;
    double kept = 0;
    for (const auto& sd : subs_) kept += static_cast<double>(sd->refinement_bytes());
    setup_.refinement_mb = kept / 1048576.0;
    single_sweeps_ = comm_.max(any) > 0;
  }
  if (factor_cache()) {
    setup_.symbolic_analyses = cache_->analyses();
    setup_.symbolic_reuses = cache_->reuses();
    setup_.symbolic_patterns = cache_->patterns();
    setup_.numeric_reuses = cache_->numeric_reuses();
    setup_.numeric_matrices = cache_->matrices();
    setup_.solve_reuses = cache_->solve_reuses();
  }
  setup_.peak_mb_factorization = peak_rss_mb();
  for (const auto& c : clusters_) setup_.cluster_setup += c->setup_seconds();
  lam_.resize(ncl);
  out_.resize(ncl);
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i) {
      lam_[c].push_back(Vec::Zero(multipliers_.of_subdomain[sub_of(c, i)].size()));
      out_[c].push_back(Vec::Zero(multipliers_.of_subdomain[sub_of(c, i)].size()));
    }
}

void DualProblem::set_up_coarse_space(Setup& st) {
  // 4. The coarse space: cluster kernel dimensions, the rows of G~, the pairs of G~^T.
  st.coarse_start = seconds_now();
  coarse_.set_up(clusters_, first_cluster_, sub_first_, outer_parallel_, st.options.coarse_ranks);
}

void DualProblem::finish_setup(Setup& st) {
  const int ncl = st.ncl, nsub = st.nsub;
  const int n_own = multipliers_.layout.n_owned();
  auto& rho = st.rho;
  coarse_.factor();

  multipliers_.combine_row_entries(
      contrib_);  // d: the clusters' parts were computed with their setup
  contrib_ = {};  // needed for nothing else
  d_ = multipliers_.ext_out.head(n_own) - multipliers_.rhs;
  e_ = Vec::Zero(coarse_dimension());
  for (int c = 0; c < ncl; ++c)
    for (int i = 0; i < members(c); ++i)
      clusters_[c]->kernel_dot(i, subs_[sub_of(c, i)]->f(), &e_[coarse_.first(first_cluster_ + c)]);
  comm_.sum_in_place(e_.data(), static_cast<int>(e_.size()));
  if (coarse_.null_dimension() > 0) {
    // Solvable only if the load has no component along the unrestrained rigid motions
    // (e = R~^T f must lie in the range of G~).
    const Eigen::VectorXd along = coarse_.null_space().transpose() * e_;
    if (along.norm() > 1e-10 * std::max(e_.norm(), 1e-300) || (e_.norm() == 0 && along.norm() > 0))
      throw std::invalid_argument(
          "the problem has no solution: the load has a resultant along " +
          coarse_.describe_null(coarse_.null_space()) +
          " that no Dirichlet condition or contact restrains (add a Dirichlet condition or "
          "balance the load)");
  }
  Vec coarse_work = e_;
  coarse_solve(coarse_work);
  lambda_tilde_.resize(n_own);
  apply_Gt(coarse_work, lambda_tilde_);
  choose_feasible_lambda_tilde();
  {
    double mine = 0;
    for (int k = 0; k < n_own; ++k)
      mine = std::max(mine, multipliers_.friction_mu[k] >= 0 ? 1.0 : 0.0);
    coulomb_ = comm_.max(mine) > 0;
  }
  {
    std::vector<int> dofs_per_node(nsub);
    for (int s = 0; s < nsub; ++s) dofs_per_node[s] = subs_[s]->dofs_per_node();
    preconditioner_.finish(multipliers_, rho, dofs_per_node);
  }
  setup_.coarse = seconds_now() - st.coarse_start;
  setup_.peak_mb_coarse = peak_rss_mb();
}

void DualProblem::cluster_rhs_from_ext(int c, bool add_f, double sign) {
  for (int i = 0; i < members(c); ++i) {
    Vec& x = x_[c][i];
    if (add_f)
      x = subs_[sub_of(c, i)]->f();
    else
      x.setZero();
    if (sign != 0.0)
      for (const auto& r : multipliers_.rows[sub_of(c, i)])
        x[r.dof] += sign * r.value * multipliers_.ext_in[r.k];
  }
}

void DualProblem::b_of_x(int c) {
  for (int i = 0; i < members(c); ++i) {
    const Vec& x = x_[c][i];
    const auto& rows = multipliers_.rows[sub_of(c, i)];
    double* out = contrib_[sub_of(c, i)].data();
    for (size_t j = 0; j < rows.size(); ++j) out[j] = rows[j].value * x[rows[j].dof];
  }
}

void DualProblem::set_single_sweeps(bool on) {
  for (auto& c : clusters_) c->set_single_sweeps(on);
}

void DualProblem::apply_F(const Vec& lambda, Vec& y) {
  multipliers_.gather(lambda);
  // A solve can throw (out of memory when a refined solve's matrix is factored again in double,
  // or CHOLMOD's first work arrays): for_each_cluster carries it out of the parallel region.
  for_each_cluster([&](int c) {
    for (int i = 0; i < members(c); ++i) {  // the cluster's part of lambda
      const auto& mult = multipliers_.of_subdomain[sub_of(c, i)];
      Vec& l = lam_[c][i];
      for (size_t j = 0; j < mult.size(); ++j) l[j] = multipliers_.ext_in[mult[j]];
    }
    clusters_[c]->apply_dual(lam_[c], out_[c]);  // the bottleneck
    for (int i = 0; i < members(c); ++i)  // each subdomain's own segment of multipliers_.pairs
      multipliers_.pairs.segment(multipliers_.pair_first[sub_of(c, i)], out_[c][i].size()) =
          out_[c][i];
  });
  multipliers_.combine_subdomains();  // F lambda, summed over subdomains in a fixed order
  y = multipliers_.ext_out.head(multipliers_.layout.n_owned());
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

DualProblem::OperatorCheck DualProblem::dual_operator_check() const {
  OperatorCheck check;
  double worst = 0;
  for (const auto& c : clusters_)
    if (const auto* op = dynamic_cast<const CheckedClusterOperator*>(&c->dual_operator())) {
      check.applications = std::max(check.applications, op->applications());
      if (!(op->max_relative_difference() <= worst)) worst = op->max_relative_difference();
    }
  // Every cluster is applied once per product with F: the count is the same on every rank that
  // holds a cluster.
  check.applications = static_cast<long>(comm_.max(static_cast<double>(check.applications)));
  check.max_relative_difference = comm_.max(worst);
  return check;
}

long DualProblem::cluster_dense_doubles() const {
  long n = 0;
  std::unordered_set<const void*> seen;  // blocks shared by equal subdomains counted once
  for (const auto& c : clusters_) n += c->dense_doubles(&seen);
  return n;
}

void DualProblem::choose_feasible_lambda_tilde() {
  const int n_own = multipliers_.layout.n_owned();
  double violation = 0;                    // of the least-squares lambda~ against the bounds
  std::vector<double> weight(n_own, 1.0);  // 0 on the bounded rows
  for (int k = 0; k < n_own; ++k) {
    const MultiplierKind kind = multipliers_.kind[k];
    if (kind == MultiplierKind::contact) violation = std::max(violation, -lambda_tilde_[k]);
    if (kind == MultiplierKind::friction)
      violation = std::max(violation, std::abs(lambda_tilde_[k]));
    if (kind == MultiplierKind::contact || kind == MultiplierKind::friction) weight[k] = 0.0;
  }
  if (comm_.max(violation) <= 0) return;
  Vec coarse = e_;
  if (coarse_.solve_weighted(weight, coarse) > 0) return;  // contact holds some rigid motion
  Vec candidate(n_own);
  apply_Gt(coarse, candidate);
  for (int k = 0; k < n_own; ++k) candidate[k] *= weight[k];
  // A semidefinite G~ W G~^T can factor with a round-off pivot instead of failing (a body that
  // only contact holds, as the sphere of examples/sphere-on-block.toml): then G~ lambda = e~
  // does not hold. Keep the candidate only if it solves the equation to round-off.
  Vec residual(coarse_dimension());
  apply_G(candidate, residual);
  residual -= e_;
  if (!(residual.norm() <= 1e-9 * e_.norm())) return;
  lambda_tilde_ = std::move(candidate);
  lambda_tilde_choice_ = "equality rows";
}

}  // namespace htfeti
