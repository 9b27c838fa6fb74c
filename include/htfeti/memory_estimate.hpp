// The memory check before the large allocations (issue "reliability"): an estimate of what a
// rank will hold at its peak, made before any subdomain is assembled in bulk, compared with the
// memory the machine can still give. A problem that does not fit ends with exit 2 and the
// estimate, not with an allocation failure (or the kernel's OOM killer) minutes later.
//
// Per rank, with D its primal unknowns (every subdomain with its own copies):
//  - matrices: the assembled K_i, all alive at the end of the assembly phase: 12 bytes per
//    stored nonzero;
//  - factors: CHOLMOD's symbolic analysis of one subdomain of the rank (its first), scaled by
//    D / its unknowns (the subdomains of a rank have similar sizes: boxes, METIS parts). With
//    the implicit operator on a generated box with one material and no coefficient field,
//    equal subdomains share one factor through the numeric cache
//    (FetiOptions::numeric_cache_bytes): the factors in memory are then those of the distinct
//    matrices, counted as 3^dim position classes (measured: 3 on the cube-obstacle), as many as
//    the cache holds, twice (the first subdomain of a pattern keeps its own), plus one per
//    subdomain of the classes it cannot hold;
//  - vectors: kernels, loads and work vectors, (kernel dimension + 4) doubles per unknown
//    (measured: 3.0 GB beyond the matrices at the end of the assembly of the 82.6 M-unknown
//    Table 2 row, against 3.4 GB estimated);
//  - explicit: the packed blocks F_i of the explicit operator, when it will be chosen (the same
//    rule as DualProblem's), with n_i estimated from the sample's shared dofs, Dirichlet dofs and
//    contact rows.
//  - preconditioner: the implicit Dirichlet preconditioner's factors of K_ii (3D with the
//    automatic storage, or --dirichlet-storage implicit; the whole interior), counted as half
//    of the factors with --factor-precision double (measured 0.57 to 0.69 of them on METIS parts
//    of the cube-obstacle and the graded Hertz blocks, hex8 and tet4: docs/performance.md, "The
//    Dirichlet preconditioner's storage"), else, with single-precision copies in place of the
//    factors' values, 0.3 of them (measured 0.36 on the 40^3 METIS cube and the graded Hertz
//    block: "Single-precision solves in the Dirichlet preconditioner"). Dense S_i (at most
//    dirichlet_budget_gb per rank with the automatic storage) and the layered preconditioner's
//    thinner factors are not counted.
// The matrices are freed cluster by cluster as the factors grow. With the explicit operator and
// the automatic factor release, clusters free their factors once memory runs short, so the
// factors held are bounded by the working set of the clusters being set up at one time
// (threads x the largest cluster's share), not by all of them. The peak is therefore
// max(matrices, factors held + explicit + preconditioner) + vectors, where factors held is all
// the factors unless they are released. Before the sample is assembled, a lower bound from the
// element type alone refuses sizes that cannot fit without building anything (a subdomain of 10^10
// unknowns). The ranks of one machine (MPI_COMM_TYPE_SHARED) add their estimates and compare the
// sum with MemAvailable (and the limit, when one is given). The estimate leaves out the dual
// vectors, the coarse problem, the preconditioner's other forms and the H-TFETI-DP clusters' dense
// K_i^+ C_i^T (2.4 GB on the paper's Table 2 row 1, docs/performance.md), and the
// interface-last factors of the
// explicit operator have more fill than the sample's plain analysis (1.46 times on the Table 3
// subdomain), so it errs low: what it refuses cannot fit.
#pragma once

#include <functional>
#include <string>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/model/model.hpp"
#include "htfeti/parallel/comm.hpp"

namespace htfeti {

struct MemoryEstimate {
  double matrices_mb = 0, factors_mb = 0, vectors_mb = 0, explicit_mb = 0;
  /// The implicit Dirichlet preconditioner's factors of K_ii: half of factors_mb with double
  /// solves, 0.3 of it with single-precision copies (0 for other preconditioners, dense S_i and
  /// the layered one).
  double preconditioner_mb = 0;
  /// The factors held at the peak: factors_mb, or the working set when they are released.
  double factors_held_mb = 0;
  /// The single-precision copies of the implicit operator's factors (FetiOptions::
  /// factor_precision; TFETI): half of factors_mb. check_memory takes double instead for the
  /// automatic precision when the copies do not fit and the run without them does
  /// (single_declined_for_memory).
  double single_mb = 0;
  bool single_declined_for_memory = false;
  /// Factors counted as shared by equal subdomains (a generated box, the numeric cache on):
  /// the number of factors counted in factors_mb; 0 when every subdomain has its own.
  double shared_factors = 0;
  bool sampled = false;  ///< false: the lower bound only (no subdomain was assembled)
  bool idle = false;     ///< the rank holds no cluster (more ranks than clusters)
  /// The dual operator the estimate counted, and whether the explicit one was possible (the
  /// sample has at least kExplicitMinNodes nodes).
  bool explicit_operator = false, explicit_eligible = false;
  /// check_memory took the explicit operator because the implicit one does not fit; the
  /// implicit operator's estimated peak summed over the ranks of the fullest machine (MiB).
  bool explicit_for_memory = false;
  /// check_memory took the implicit operator although the cost model prefers the explicit one:
  /// the run with the explicit operator, estimated at explicit_peak_mb on the fullest machine,
  /// exceeds kExplicitMemoryShare of the memory (the automatic budget,
  /// FetiOptions::explicit_budget_bytes < 0).
  bool explicit_declined_for_memory = false;
  double explicit_peak_mb = 0;
  double implicit_peak_mb = 0;
  /// Set by check_memory: the peak summed over the ranks of the fullest machine (MiB).
  double machine_peak_mb = 0;
  /// Set by check_memory: the memory compared with (the smallest over the machines; MiB).
  double available_mb = 0;
  /// Explicit operator, and factors kept in single precision alone (factors_held_mb is then
  /// their K_rr): the factors of the clusters set up at one time.
  double factors_working_mb = 0;
  /// K_i is freed once factored, so the matrices of the clusters still to be set up and what
  /// those done keep (their factors, and the explicit operator's F_i) are in memory together:
  /// at most the larger of the two totals. The explicit operator adds the clusters in flight,
  /// which hold their matrices and their factors at once.
  double peak_mb() const {
    const double done = factors_held_mb + single_mb + explicit_mb + preconditioner_mb;
    return (matrices_mb > done ? matrices_mb : done) + vectors_mb + factors_working_mb;
  }
};

/// This rank's estimate (collective: no; it assembles one subdomain of the rank).
/// With sample_one = false only the lower bound (nothing is assembled).
MemoryEstimate estimate_memory(const Model& model, const FetiOptions& options, const Comm& comm,
                               bool sample_one = true);

/// Throws std::invalid_argument on every rank, with the estimate, when the ranks of some machine
/// together need more than its available memory (or options.memory_limit_mb); returns this
/// rank's estimate. With the automatic dual operator, when the operator DualProblem would pick
/// is the implicit one, which keeps every factor, and it does not fit on some machine while the
/// explicit one (its F_i, factors released as memory runs short) fits on all, it sets
/// options.dual_operator to explicit (explicit_for_memory). `before_sample` runs once the lower
/// bound fits, before anything is assembled for the estimate: solve() resolves the automatic
/// operator's cost model there (a problem refused by the bound costs nothing). Collective.
MemoryEstimate check_memory(const Model& model, FetiOptions& options, const Comm& comm,
                            const std::function<void(FetiOptions&)>& before_sample = {});

struct ProblemSpec;
/// Before the model is built (a generated box: the sizes are known from the problem file): the
/// lower bound of estimate_memory for the whole box, plus the whole mesh that a METIS split holds
/// on every rank, against the available memory (or options.memory_limit_mb); throws
/// std::invalid_argument on every rank when it cannot fit, so that refusing a problem costs
/// nothing. Nothing for mesh files and built-ins (checked by check_memory). Collective.
void check_memory_before_model(const ProblemSpec& spec, const FetiOptions& options,
                               const Comm& comm);

}  // namespace htfeti
