// The automatic dual operator's cost model: which of the implicit and the explicit operator
// (paper, Section 6: F = sum_i B_i K_i^+ B_i^T applied by sparse triangular sweeps over the
// factor of K_i, or by dense blocks F_i formed once) costs less for the whole solve, counted,
// not timed, so that the choice does not depend on the machine's load or on the number of ranks.
//
// Per subdomain, from its assembled K_i, its multipliers and CHOLMOD's symbolic analysis of its
// factor (no numeric work):
//   implicit: setup  c_factor * flops(L) + c_unknown * n
//                    (the numeric factorization; forming K_rr, its ordering and analysis)
//             one F  c_sweep * 16 * values(L) + c_supernode * supernodes(L)
//                    (a forward and a backward sweep, each reads L once; BLAS-2 calls per
//                    supernode)
//   explicit: setup  the implicit one + c_dense * n_b^3 + c_explicit_unknown * n
//                    (the interface-last factor's dense block of the n_b interface dofs: its
//                    factorization n_b^3 / 3 and its inverse by dpotri 2 n_b^3 / 3; the
//                    interface-last ordering of the n unknowns)
//             one F  c_packed * bytes(F_i) = c_packed * w * m (m + 1) / 2
//                    (m multipliers, w = 8 or 4 bytes per value: one pass over the packed block)
// The explicit operator pays for its extra setup after
//   N* = (c_dense n_b^3 + c_explicit_unknown n) / (F_implicit - F_explicit)
// applications of F; it is taken when N* is below the applications the solve is expected to
// need: kExpectedApplicationsContact for a contact problem (SMALBE-M's products and its norm
// estimate), kExpectedApplicationsLinear without contact (PCG). The constants are this machine's
// (one thread), fitted by bench/operator_cost.py to the phases of runs with either operator;
// only their ratios decide. docs/performance.md, "The automatic operator: a cost model".
#pragma once

#include <limits>
#include <optional>

#include "htfeti/feti/sparse_cholesky.hpp"

namespace htfeti {

class Comm;
class Model;
struct FetiOptions;
struct SubdomainInput;

/// Seconds per unit of work, one thread of the machine the constants were fitted on.
struct OperatorCostConstants {
  double sweep_per_byte = 0;        ///< c_sweep: per byte of L read by one sweep
  double per_supernode = 0;         ///< c_supernode: per supernode and F (both sweeps)
  double packed_per_byte = 0;       ///< c_packed: per byte of a packed F_i
  double factor_per_flop = 0;       ///< c_factor: CHOLMOD's numeric factorization
  double per_unknown = 0;           ///< c_unknown: K_rr, its ordering and analysis, per unknown
  double dense_per_flop = 0;        ///< c_dense: per n_b^3 of the interface block
  double explicit_per_unknown = 0;  ///< c_explicit_unknown: the interface-last ordering
  static OperatorCostConstants fitted();
};

/// Applications of F a solve is expected to need (the median of the examples and benchmark
/// cases of each kind, docs/performance.md).
constexpr double kExpectedApplicationsContact = 80;
constexpr double kExpectedApplicationsLinear = 40;
/// Subdomains sampled: 0, S / 2 and S - 1 (fixed ids: the same on any number of ranks).
constexpr int kCostSamples = 3;

/// One subdomain's sizes as the model counts them.
struct SubdomainCostSample {
  double unknowns = 0;        ///< n_i
  double multipliers = 0;     ///< m: rows of B~ on the subdomain, the order of F_i
  double interface_dofs = 0;  ///< n_b: the dofs B~ touches
  double factor_values = 0;   ///< values stored in the factor of K_rr (supernode blocks)
  double factor_supernodes = 0;
  double factor_flops = 0;  ///< flops of its numeric factorization (CHOLMOD's count)
};

/// The rows of B~ on one subdomain (one per further copy of a shared dof, per Dirichlet dof,
/// per contact row counted once with its tangential rows) and the dofs they touch. The memory
/// estimate counts its sample's F_i with it too.
struct MultiplierCount {
  double multipliers = 0, interface_dofs = 0;
};
MultiplierCount count_multipliers(const SubdomainInput& in, int dofs_per_node);

/// Counts one subdomain: its multipliers (one per further copy of a shared dof, per Dirichlet
/// dof, per contact row), the dofs they touch, and the symbolic analysis of K_rr with
/// `ordering` (the implicit operator's).
SubdomainCostSample sample_subdomain_cost(SubdomainInput in, int dofs_per_node, Ordering ordering);

struct OperatorCost {
  int samples = 0;
  SubdomainCostSample mean;  ///< the samples' average
  double expected_applications = 0;
  /// Model seconds per subdomain, one thread.
  double implicit_setup = 0, implicit_per_F = 0, explicit_setup = 0, explicit_per_F = 0;
  /// Applications of F after which the explicit operator costs less (infinity: never).
  double break_even = std::numeric_limits<double>::infinity();
  bool explicit_cheaper() const { return break_even <= expected_applications; }
  /// Wall seconds of estimate_operator_cost on this rank (the report's timings.operator_model).
  double seconds = 0;
};

/// The model from its sample and constants (no communication).
OperatorCost operator_cost(const SubdomainCostSample& mean, int samples, bool contact,
                           double value_bytes,
                           const OperatorCostConstants& c = OperatorCostConstants::fitted());

/// Samples subdomains 0, S / 2 and S - 1 on the ranks holding them (collective) and evaluates
/// the model for the operator settings of `options` (the ordering the implicit operator would
/// use, the precision of the explicit blocks). Empty when a sample could not be assembled or
/// analysed on some rank: the setup meets the same input and reports it.
std::optional<OperatorCost> estimate_operator_cost(const Model& model, const FetiOptions& options,
                                                   const Comm& comm);

}  // namespace htfeti
