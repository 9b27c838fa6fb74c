#include "htfeti/memory_estimate.hpp"

#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "htfeti/feti/dual_preconditioner.hpp"
#include "htfeti/feti/operator_cost.hpp"
#include "htfeti/feti/subdomain.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

namespace {

constexpr double kMiB = 1048576.0;
// Largest sample subdomain that is assembled and analysed (unknowns); larger ones are judged by
// the lower bound alone.
constexpr double kMaxSampleUnknowns = 4e6;

// Stored nonzeros per row of the lower triangle of K, at least (interior nodes of the sparsest
// element type of the dimension: tri3 has 7 neighbours and tet4 about 15, counting the node).
double lower_nonzeros_per_row(const Physics& ph) {
  const double nodes = ph.dim == 2 ? 7.0 : 15.0;
  return 0.5 * (nodes * ph.dofs_per_node() + 1);
}

// A size for the messages: GB with one decimal, MB below 1 GB.
std::string gb(double mb) {
  char buf[32];
  if (mb >= 1024.0)
    std::snprintf(buf, sizeof buf, "%.1f GB", mb / 1024.0);
  else
    std::snprintf(buf, sizeof buf, "%.*f MB", mb < 10 ? 1 : 0, mb);
  return buf;
}

// The memory the ranks of one machine (`node`) may use together: the smallest available memory
// any of them sees, or the limit (options.memory_limit_mb) when it is smaller. Collective on node.
double machine_available_mb(const FetiOptions& options, MPI_Comm node) {
  double available = available_memory_mb();
  MPI_Allreduce(MPI_IN_PLACE, &available, 1, MPI_DOUBLE, MPI_MIN, node);
  if (options.memory_limit_mb > 0 && (available <= 0 || options.memory_limit_mb < available))
    available = options.memory_limit_mb;
  return available;
}

// Whether the run will apply the Dirichlet preconditioner on the whole interior with factors of
// K_ii (DualPreconditioner::implicit_storage; in 2D the automatic storage is counted as dense,
// which the budget bounds).
bool implicit_dirichlet(const FetiOptions& o, int dim) {
  return o.preconditioner == PreconditionerKind::dirichlet && o.dirichlet_layers == 0 &&
         DualPreconditioner::implicit_storage(o, dim, true);
}

// Its factors of K_ii as a share of the subdomains' factors (memory_estimate.hpp): half, 0.57
// to 0.69 of them measured, with double solves; 0.3, 0.36 measured, with the single-precision
// copies (the doubles freed) that every precision but double takes.
double implicit_dirichlet_share(const FetiOptions& o) {
  return o.factor_precision == FactorPrecision::double_ ? 0.5 : 0.3;
}

}  // namespace

MemoryEstimate estimate_memory(const Model& model, const FetiOptions& options, const Comm& comm,
                               bool sample_one) {
  MemoryEstimate e;
  const FetiLayout layout = model.layout();
  const auto [c0, c1] = layout.cluster_range(comm.rank(), comm.size());
  if (c0 == c1) {
    e.idle = true;
    return e;
  }
  const int s0 = layout.cluster_first[c0], s1 = layout.cluster_first[c1];
  const double share = static_cast<double>(s1 - s0) / model.num_subdomains();
  const double unknowns = static_cast<double>(model.primal_dimension()) * share;
  const double per_subdomain = unknowns / (s1 - s0);
  const Physics& ph = model.physics();
  e.vectors_mb = unknowns * 8.0 * (ph.kernel_dimension() + 4) / kMiB;
  const double lower_nnz = unknowns * lower_nonzeros_per_row(ph);
  e.matrices_mb = lower_nnz * 12.0 / kMiB;
  e.factors_mb = lower_nnz * 8.0 / kMiB;  // L has at least the nonzeros of K's lower triangle
  e.factors_held_mb = e.factors_mb;
  const bool implicit_preconditioner = implicit_dirichlet(options, layout.dim);
  if (implicit_preconditioner)
    e.preconditioner_mb = implicit_dirichlet_share(options) * e.factors_mb;
  if (!sample_one || per_subdomain > kMaxSampleUnknowns) return e;
  // Sample: the rank's first subdomain, assembled and analysed with the ordering in effect.
  SubdomainInput in = model.input(s0);
  const double n = static_cast<double>(in.system.f.size());
  if (n == 0) return e;
  const double k_bytes = 12.0 * static_cast<double>(in.system.K.nonZeros());
  // Its multipliers (the order of its F_i), counted as the operator's cost model counts them.
  const double nmult = count_multipliers(in, ph.dofs_per_node()).multipliers;
  const double nodes = n / ph.dofs_per_node();
  // The explicit operator (DualProblem's rule, with every subdomain like the sample).
  const double subdomains = s1 - s0;
  const double value_bytes = options.explicit_precision == Precision::single ? 4.0 : 8.0;
  const double explicit_bytes = subdomains * value_bytes * nmult * (nmult + 1) / 2;
  const bool is_explicit = options.dual_operator == DualOperator::explicit_ ||
                           options.dual_operator == DualOperator::checked ||
                           (options.dual_operator == DualOperator::automatic &&
                            automatic_prefers_explicit(options, layout.dim, nodes) &&
                            explicit_bytes <= explicit_budget(options));
  const Ordering ordering = resolve_ordering(options.ordering, layout.dim, is_explicit);
  e.explicit_operator = is_explicit;
  e.explicit_eligible = nodes >= kExplicitMinNodes;
  Subdomain sample(std::move(in.system));
  const double f_bytes = static_cast<double>(sample.symbolic_factor_bytes(ordering));
  e.matrices_mb = std::max(e.matrices_mb, k_bytes / n * unknowns / kMiB);
  e.factors_mb = std::max(e.factors_mb, f_bytes / n * unknowns / kMiB);
  // Equal subdomains share a factor (SubdomainCache): a generated box gives every subdomain the
  // same element matrices, so with one material the implicit operator's matrices are equal up
  // to a few position classes, counted as 3^dim (measured: 3 on the cube-obstacle). The
  // explicit operator's factors order each subdomain's interface last, which differs with its
  // Dirichlet and contact rows: counted one per subdomain (they are released as memory runs
  // short).
  const bool shareable = !is_explicit && options.symbolic_cache_patterns > 0 &&
                         options.numeric_cache_bytes > 0 && ph.coefficient.empty() &&
                         model.mesh(s0).uniform_period > 0;
  if (shareable) {
    const double classes = std::pow(3.0, layout.dim);
    const double kept = std::min(classes, std::floor(options.numeric_cache_bytes / f_bytes));
    // The cache keeps a factor from the second subdomain of a pattern on; the first holds its
    // own. Classes the cache cannot hold: a factor per subdomain.
    const double copies =
        std::min(subdomains, 2.0 * kept + subdomains * (classes - kept) / classes);
    if (copies < subdomains) {
      e.factors_mb = f_bytes * copies / kMiB;
      e.shared_factors = copies;
    }
  }
  e.factors_held_mb = e.factors_mb;
  // The preconditioner's factors of K_ii, shared as the subdomains' factors are (the numeric
  // cache serves both).
  if (implicit_preconditioner)
    e.preconditioner_mb = implicit_dirichlet_share(options) * e.factors_mb;
  // The implicit operator's single-precision copies (4 of a value's 8 bytes), where every
  // cluster of the rank is one subdomain (TFETI: no primal constraints).
  bool one_per_cluster = true;
  for (int c = c0; c < c1; ++c)
    one_per_cluster = one_per_cluster && layout.cluster_first[c + 1] - layout.cluster_first[c] == 1;
  if (!is_explicit && one_per_cluster && options.factor_precision != FactorPrecision::double_) {
    e.single_mb = 0.5 * e.factors_mb;
    // Subdomains that do not repeat (SubdomainSystem::repeats) keep the copy alone and K_rr
    // for the refinement (about K_i's lower triangle: matrices_mb); the double values exist
    // only while each thread factors one.
    if (model.mesh(s0).uniform_period == 0) {
      const double working = std::min(subdomains, static_cast<double>(omp_get_max_threads()));
      e.factors_working_mb = e.factors_mb * working / subdomains;
      e.factors_held_mb = e.matrices_mb;
    }
  }
  if (is_explicit) {
    e.explicit_mb = explicit_bytes / kMiB;
    // The factors of the clusters set up at one time (threads x the rank's largest cluster).
    int largest = 1;
    for (int c = c0; c < c1; ++c)
      largest = std::max(largest, layout.cluster_first[c + 1] - layout.cluster_first[c]);
    const double working =
        std::min(subdomains, static_cast<double>(largest) * std::max(1, omp_get_max_threads()));
    e.factors_working_mb = e.shared_factors > 0 ? std::min(e.factors_mb, f_bytes * working / kMiB)
                                                : e.factors_mb * working / subdomains;
    // Released factors (FetiOptions::keep_factors): at most the clusters being set up at one
    // time hold theirs.
    const bool released =
        !options.keep_factors && options.dual_operator != DualOperator::checked &&
        (options.factor_budget_bytes < 0 || 8.0 * 100.0 * unknowns > options.factor_budget_bytes);
    if (released) e.factors_held_mb = e.factors_working_mb;
  }
  e.sampled = true;
  return e;
}

MemoryEstimate check_memory(const Model& model, FetiOptions& options, const Comm& comm,
                            const std::function<void(FetiOptions&)>& before_sample) {
  // The lower bound first, everywhere (nothing is assembled); then the sample where the bound
  // fits. Both are summed over the ranks of each machine.
  MPI_Comm node;
  MPI_Comm_split_type(comm.raw(), MPI_COMM_TYPE_SHARED, comm.rank(), MPI_INFO_NULL, &node);
  int node_ranks = 1;
  MPI_Comm_size(node, &node_ranks);
  const double available = machine_available_mb(options, node);
  // One estimate and its sums over the machine: peak, factors, matrices, vectors, explicit,
  // factors held, preconditioner.
  struct Sums {
    MemoryEstimate e;
    std::string error;
    double sum[7] = {0, 0, 0, 0, 0, 0, 0};
    bool fits(double avail) const { return error.empty() && !(avail > 0 && sum[0] > avail); }
  };
  auto estimate = [&](const FetiOptions& o, bool sample) {
    Sums s;
    try {
      s.e = estimate_memory(model, o, comm, sample);
    } catch (const std::bad_alloc&) {
      s.error = "out of memory while estimating the memory needed";
    } catch (const std::exception& ex) {
      s.error = ex.what();
    }
    const MemoryEstimate& e = s.e;
    double mine[7] = {e.peak_mb(),   e.factors_mb,      e.matrices_mb,      e.vectors_mb,
                      e.explicit_mb, e.factors_held_mb, e.preconditioner_mb};
    MPI_Allreduce(mine, s.sum, 7, MPI_DOUBLE, MPI_SUM, node);
    return s;
  };
  // The lower bound alone first: a problem that cannot fit is refused before a subdomain is
  // assembled and analysed (which costs as much as a large subdomain: 1.2 GB for one 40^3 hex8
  // subdomain), unless the automatic operator may still take the explicit one.
  // What any operator needs (the matrices and vectors) decides for the automatic one.
  Sums s = estimate(options, false);
  const bool over_any = s.error.empty() && available > 0 && s.sum[2] + s.sum[3] > available;
  const bool refuse_early =
      comm.max(over_any || (options.dual_operator != DualOperator::automatic && !s.fits(available))
                   ? 1.0
                   : 0.0) > 0;
  if (!refuse_early && before_sample) before_sample(options);
  // The automatic budget of the explicit blocks (FetiOptions::explicit_budget_bytes < 0): when
  // the cost model prefers the explicit operator, its F_i may take what the machine has, as long
  // as the whole run with them is estimated at most kExplicitMemoryShare of every machine's
  // memory; otherwise none (the implicit operator, unless it does not fit: below). Without a
  // known available memory, the fixed budget of an unchecked run. Resolved here, the same on
  // every rank, so that DualProblem's rule gives the operator counted.
  // Whether cond holds on every rank that holds clusters, and some rank does (a rank without
  // clusters has no say in the operator).
  const auto every_active = [&](const MemoryEstimate& e, bool cond) {
    return comm.min(e.idle || cond ? 1.0 : 0.0) > 0 && comm.max(e.idle ? 0.0 : 1.0) > 0;
  };
  const bool auto_budget =
      options.dual_operator == DualOperator::automatic && options.explicit_budget_bytes < 0;
  if (!refuse_early && auto_budget && comm.min(available > 0 ? 1.0 : 0.0) > 0) {
    FetiOptions wide = options;
    wide.explicit_budget_bytes = std::numeric_limits<double>::infinity();
    Sums t = estimate(wide, true);
    const bool wants =
        comm.max(t.error.empty() ? 0.0 : 1.0) == 0 && every_active(t.e, t.e.explicit_operator);
    const bool within =
        wants && comm.min(t.sum[0] <= kExplicitMemoryShare * available ? 1.0 : 0.0) > 0;
    // Subdomains too large to sample (kMaxSampleUnknowns) leave the choice to the fixed budget.
    const bool sampled = comm.min(t.e.idle || t.e.sampled ? 1.0 : 0.0) > 0;
    options.explicit_budget_bytes = within    ? std::numeric_limits<double>::infinity()
                                    : sampled ? 0.0
                                              : kExplicitBudgetUnchecked;
    const double explicit_peak = comm.max(t.sum[0]);
    if (within || !wants) {
      s = std::move(t);  // the operator counted is the one the budget now gives
    } else {
      s = estimate(options, true);
      s.e.explicit_declined_for_memory = true;
      s.e.explicit_peak_mb = explicit_peak;
    }
  } else if (!refuse_early) {
    if (auto_budget) options.explicit_budget_bytes = kExplicitBudgetUnchecked;
    s = estimate(options, true);
  }
  // The implicit operator keeps every factor; the explicit one can free them. When the automatic
  // choice (the explicit blocks' size budget) gives the implicit operator and it does not fit,
  // the explicit operator is taken if it fits everywhere.
  const bool implicit_over =
      comm.max(s.fits(available) ? 0.0 : 1.0) > 0 && comm.max(s.error.empty() ? 0.0 : 1.0) == 0;
  if (!refuse_early && options.dual_operator == DualOperator::automatic && implicit_over &&
      every_active(s.e, s.e.sampled && s.e.explicit_eligible && !s.e.explicit_operator)) {
    FetiOptions alt = options;
    alt.dual_operator = DualOperator::explicit_;
    Sums t = estimate(alt, true);
    if (comm.min(t.fits(available) ? 1.0 : 0.0) > 0) {
      const double implicit_peak = comm.max(s.sum[0]);
      options.dual_operator = DualOperator::explicit_;
      s = std::move(t);
      s.e.explicit_for_memory = true;
      s.e.implicit_peak_mb = implicit_peak;
    }
  }
  // The automatic factor precision takes the factors alone (double) when the single-precision
  // copies would not fit and the run without them does.
  if (!refuse_early && options.factor_precision == FactorPrecision::automatic &&
      comm.max(s.fits(available) ? 0.0 : 1.0) > 0 && comm.max(s.e.single_mb > 0 ? 1.0 : 0.0) > 0) {
    FetiOptions alt = options;
    alt.factor_precision = FactorPrecision::double_;
    Sums t = estimate(alt, true);
    if (comm.min(t.fits(available) ? 1.0 : 0.0) > 0) {
      options.factor_precision = FactorPrecision::double_;
      s = std::move(t);
      s.e.single_declined_for_memory = true;
    }
  }
  MPI_Comm_free(&node);
  s.e.machine_peak_mb = comm.max(s.sum[0]);
  s.e.available_mb = comm.min(available);
  const double* sum = s.sum;
  std::string error = s.error;
  if (error.empty() && available > 0 && sum[0] > available)
    error = "the problem does not fit in memory: estimated " + gb(sum[0]) + " on " +
            std::to_string(node_ranks) + " rank(s) of this machine (factors " + gb(sum[1]) +
            (sum[5] < sum[1] ? " of which " + gb(sum[5]) + " held at once" : std::string()) +
            ", matrices " + gb(sum[2]) + ", vectors " + gb(sum[3]) +
            (sum[4] > 0 ? ", explicit F_i " + gb(sum[4]) : std::string()) +
            (sum[6] > 0 ? ", Dirichlet preconditioner " + gb(sum[6]) : std::string()) + "), " +
            (options.memory_limit_mb > 0 && available == options.memory_limit_mb
                 ? "limit (--memory-limit) "
                 : "available ") +
            gb(available) +
            "; use fewer unknowns, more machines, or --no-memory-check to try anyway" +
            (refuse_early ? " (a lower bound: nothing was assembled)" : "");
  comm.agree(error, true);
  return s.e;
}

void check_memory_before_model(const ProblemSpec& spec, const FetiOptions& options,
                               const Comm& comm) {
  if (!spec.builtin.empty() || !spec.mesh_file.empty() || !spec.mesh_parts.empty())
    return;  // sizes known from the box only
  const BoxGridOptions& b = spec.box;
  double nodes = 1, cells = 1;
  for (int d = 0; d < b.dim; ++d) nodes *= b.elements[d] + 1.0, cells *= b.elements[d];
  Physics ph = spec.physics;
  ph.dim = b.dim;
  // The decomposed problem has at least one copy of every node; its matrices (all alive at the
  // end of the assembly, whatever the operator) and vectors at least the lower bound of
  // estimate_memory. A box split by METIS is also held whole on rank 0 (coordinates, cells)
  // while it is partitioned.
  const double unknowns = nodes * ph.dofs_per_node();
  const double lower_nnz = unknowns * lower_nonzeros_per_row(ph);
  const bool metis = spec.subdomains.size() == 1;
  const double whole_mesh_mb =
      metis ? (24.0 * nodes + 4.0 * cell_nodes(b.cell) * cells) / kMiB : 0.0;
  MPI_Comm node;
  MPI_Comm_split_type(comm.raw(), MPI_COMM_TYPE_SHARED, comm.rank(), MPI_INFO_NULL, &node);
  int node_ranks = 1, first_rank = comm.rank();
  MPI_Comm_size(node, &node_ranks);
  MPI_Allreduce(MPI_IN_PLACE, &first_rank, 1, MPI_INT, MPI_MIN, node);
  const double available = machine_available_mb(options, node);
  MPI_Comm_free(&node);
  // The ranks of this machine share the problem (their shares add up to the whole), and rank 0
  // holds the whole box while it splits it by METIS.
  const double problem_mb = (lower_nnz * 12.0 + unknowns * 8.0 * (ph.kernel_dimension() + 4)) /
                                kMiB *
                                std::min(1.0, static_cast<double>(node_ranks) / comm.size()) +
                            (first_rank == 0 ? whole_mesh_mb : 0.0);
  std::string error;
  if (available > 0 && problem_mb > available)
    error = "the problem does not fit in memory: at least " + gb(problem_mb) + " on " +
            std::to_string(node_ranks) + " rank(s) of this machine for " +
            std::to_string(static_cast<long long>(unknowns)) + " unknowns (estimated from the " +
            "box before it is generated), " +
            (options.memory_limit_mb > 0 && available == options.memory_limit_mb
                 ? "limit (--memory-limit) "
                 : "available ") +
            gb(available) +
            "; use fewer unknowns, more machines, or --no-memory-check to try anyway";
  comm.agree(error, true);
}

}  // namespace htfeti
