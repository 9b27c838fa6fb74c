// The whole pipeline of DESIGN.md for one solve: decomposition -> subdomains and clusters ->
// dual problem -> QP solve (projected CG for equalities only, SMALBE-M + MPRGP with contact)
// -> primal reconstruction -> report. Collective over the communicator.
#pragma once

#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "htfeti/enum_names.hpp"
#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/feti/operator_cost.hpp"
#include "htfeti/model/model.hpp"
#include "htfeti/qp/power_norm.hpp"
#include "htfeti/qp/smalbe.hpp"

namespace htfeti {

/// The projector in PCG's preconditioner (problems without contact): orthogonal, P M^{-1} P;
/// weighted, P_Q M^{-1} P_Q^T with P_Q = I - Q G~^T (G~ Q G~^T)^{-1} G~ and Q the stiffness of
/// each multiplier's copies (the stiffness scaling's harmonic mean; Klawonn and Widlund 2001's
/// projector for coefficient jumps between subdomains); automatic, weighted where the scaling is
/// stiffness, the coefficient varies by more than kWeightedProjectorSpread over the mesh and by
/// no more than that over any subdomain (the weighted projector loses where a jump runs through
/// subdomains, and gains nothing where the field hardly varies: docs/results.md).
enum class PcgProjector { automatic, orthogonal, weighted };
inline constexpr std::array<EnumName<PcgProjector>, 3> kPcgProjectorNames{
    {{PcgProjector::automatic, "auto"},
     {PcgProjector::orthogonal, "orthogonal"},
     {PcgProjector::weighted, "weighted"}}};
inline constexpr double kWeightedProjectorSpread = 10;

inline FetiOptions automatic_preconditioner() {
  FetiOptions o;
  o.preconditioner = PreconditionerKind::automatic;
  o.scaling = Scaling::automatic;
  return o;
}

struct SolveOptions {
  DecompositionOptions decomposition;  ///< the built-in problem (solve(options, comm) only)
  /// preconditioner and scaling default to automatic here (resolve_preconditioner).
  FetiOptions feti = automatic_preconditioner();
  double rtol = 1e-4;        ///< relative precision eps of the QP solvers (paper: 1e-4)
  int max_iterations = 0;    ///< PCG iterations or SMALBE-M outer iterations; 0: 1000 / 200
  qp::SmalbeOptions smalbe;  ///< rtol and max_outer are taken from the fields above
  /// How SMALBE-M's ||PFP|| is estimated (qp/power_norm.hpp); its products are reported in
  /// solver.norm_estimate_matvecs. The power method stays the default because the committed
  /// tables (docs/results.md) were measured with it; Lanczos needs fewer products in total
  /// (docs/performance.md) and moves SMALBE-M's counts through rho = 1.1 ||PFP||.
  qp::NormEstimate norm_estimate = qp::NormEstimate::lanczos;
  /// Coarse steps per SMALBE-M Hessian product: 2 (P v, F, P: two global reductions, each
  /// waiting for the last) or 1 (F v, then [G~ v, G~ F v] in one reduction, with E = F G~^T and
  /// C = G~ F G~^T formed once in setup: DualProblem::build_coarse_image). 1 costs memory (about
  /// 12 entries of E per multiplier in 2D Laplace, 216 in 3D elasticity) and setup time, and on
  /// one machine no time per product (docs/performance.md); its gain is one synchronization per
  /// product over many ranks. Projected CG (no contact) always takes 2.
  int coarse_steps_per_product = 2;
  PcgProjector pcg_projector = PcgProjector::automatic;  ///< see PcgProjector
  bool progress = false;  ///< print one line per (outer) iteration on rank 0 (stderr)
  /// The report's per-row contact arrays up to this many contact rows (output.report_contact_rows;
  /// above: the count and the summary per condition only). 0: never.
  int report_contact_rows = 100000;
  /// Coulomb friction, the fixed point on the slip bound (docs/method.md): Tresca solves, each
  /// with the bound mu lambda_n of the previous one, until the bounds change by at most
  /// max(coulomb_rtol, 10 rtol) relative (||g_k - g_{k-1}|| <= that ||g_k||; the bounds come
  /// from multipliers solved to rtol and move by about 5 rtol at the fixed point), at most
  /// coulomb_max_iterations solves (then exit 3).
  double coulomb_rtol = 1e-6;
  int coulomb_max_iterations = 50;
  /// A robustness check of the iteration counts (bench/perturbation.py): every entry of the load
  /// f is multiplied by 1 + perturb_load r, with r in [-1, 1] a hash of the entry's global node
  /// and component (the same on every rank and thread). 0: the load as given.
  double perturb_load = 0;
  /// Estimate the memory before setup and refuse (std::invalid_argument) what cannot fit
  /// (memory_estimate.hpp).
  bool check_memory = true;
};

struct SolveOutput {
  nlohmann::json report;  ///< identical on every rank
  std::shared_ptr<const Model> model;
  std::unique_ptr<DualProblem> dual;
  std::vector<Eigen::VectorXd> u;  ///< primal solution of this rank's subdomains
  Eigen::VectorXd lambda;          ///< owned multipliers
  bool converged = false;
};

/// Solves a model. Throws std::invalid_argument for bad options or input (on every rank alike),
/// std::runtime_error for a numerical failure (agreed on by all ranks).
SolveOutput solve(std::shared_ptr<const Model> model, const SolveOptions& options,
                  const Comm& comm);
/// Solves the built-in problem of options.decomposition.
SolveOutput solve(const SolveOptions& options, const Comm& comm);

/// The preconditioner and scaling that `auto` stands for, chosen by measurement
/// (docs/results.md, "Preconditioners"): a model with a coefficient field gets Dirichlet with
/// stiffness scaling; elasticity gets lumped (TFETI and H-TFETI-DP, with or without contact);
/// Laplace without a coefficient field none (on the measured 2D cases its setup costs more than
/// the iterations it saves). A Dirichlet choice of auto is taken only where the dense S_i fit the
/// budget (else none). Explicit choices are kept. Returns the reason ("requested" or the rule
/// that chose), which the report repeats as preconditioner_reason.
std::string resolve_preconditioner(const Model& model, FetiOptions& options);

/// Where the dual operator is automatic: evaluates its cost model (operator_cost.hpp) and sets
/// options.explicit_by_cost; the model, or nothing where the operator was requested or a sample
/// could not be assembled (the setup then meets the same input). Collective.
std::optional<OperatorCost> resolve_operator_cost(const Model& model, FetiOptions& options,
                                                  const Comm& comm);
/// One line for --progress and --dry-run: what the model found.
std::string describe_operator_cost(const OperatorCost& cost);

/// The last check of a converged solve: B~ has orthonormal rows, so the equality residual
/// ||B_E u - c_E|| is at most ||u|| + ||c_E|| (kkt.equality_scale), and a solve that met its
/// stopping test leaves at most about rtol of it (measured: below 0.1 rtol on every example).
/// A residual above min(0.1, 1000 rtol) of it means the subdomains are not held together, e.g.
/// a subdomain stiffness singular beyond its rigid body motions: throws std::runtime_error
/// (exit 4) instead of returning the wrong answer.
void check_equality_residual(const DualProblem::Kkt& kkt, double rtol);

/// Checks the solver options; throws std::invalid_argument.
void validate_solver(const SolveOptions& options);
/// validate_solver() and the built-in decomposition.
void validate(const SolveOptions& options);

}  // namespace htfeti
