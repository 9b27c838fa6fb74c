// The parts of one solve that the driver (solver.cpp) and the report (report.cpp) share: the
// dual problem's operators as the QP solvers see them, what a QP solve gives the report, and the
// functions that write the report's sections. Private to src/.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/feti/operator_cost.hpp"
#include "htfeti/memory_estimate.hpp"
#include "htfeti/model/model.hpp"
#include "htfeti/qp/operator.hpp"
#include "htfeti/solver.hpp"

namespace htfeti::solve_parts {

using Vec = Eigen::VectorXd;

// The dual problem's operators for the QP solvers, each counted and timed apart (qp::Operator):
// F, the projector P onto Ker G~ and the preconditioner M^{-1}; and the one-step products.
struct DualOperators {
  explicit DualOperators(DualProblem& dual)
      : F([&dual](const Vec& x, Vec& y) { dual.apply_F(x, y); }),
        P([&dual](const Vec& x, Vec& y) { dual.project(x, y); }),
        M([&dual](const Vec& x, Vec& y) { dual.apply_preconditioner(x, y); }),
        preconditioned(dual.preconditioner() != PreconditionerKind::none) {}
  qp::FunctionOperator F, P, M;
  bool preconditioned;
  long merged_steps = 0;      // products taken in one coarse step
  double merged_seconds = 0;  // their time after F v
};

// What a QP solve gives the report.
struct QpSolve {
  bool converged = false;
  std::string reason;
  int outer = 0, inner = 0;
  long matvecs = 0;
  nlohmann::json solver;
};

// The accuracy refinement (solver.cpp): a converged dual solve whose primal gluing residual
// ||B_E u - c_E|| / (||u|| + ||c_E||) exceeds kRefineRatio x rtol is solved again from where it
// stopped, with a smaller rtol, until that residual is at most kRefineTarget x rtol, at most
// kMaxRefinements times. The dual tests bound the dual problem's residuals; on an
// ill-conditioned F (H-TFETI-DP on clusters of METIS parts) a dual residual of rtol left the
// gluing residual at 8-72 rtol and the energy 3e-5 to 1.3% off, where the examples and
// built-ins all end below 2.6 rtol (docs/reliability.md). One check costs a reconstruction,
// which a converged solve needs anyway: the last check's u is the solution's.
constexpr double kRefineRatio = 3.0;
constexpr double kRefineTarget = 0.1;
constexpr int kMaxRefinements = 4;
// The check: the gluing residual of lambda over rtol (it reconstructs u, which the driver keeps).
using AccuracyCheck = std::function<double(const Vec& lambda)>;
// One line for --progress where a solve goes on after it converged (the single-precision check,
// an accuracy refinement); does nothing without --progress.
using StageNote = std::function<void(const std::string&)>;

// What one solve leaves for its report (make_report).
struct SolveRecord {
  const SolveOptions& options;
  const FetiOptions& feti;  // with the automatic choices resolved
  const MemoryEstimate& estimate;
  const std::string& preconditioner_reason;
  const std::optional<OperatorCost>& cost;  // the automatic operator's model, where it ran
  const QpSolve& qs;
  const DualOperators& ops;
  bool merged;
  double t_setup, t_image, t_solve, t_rec, t_checks, peak_mb_solve;
  DualProblem::Kkt kkt;
  double energy;
  DualProblem::FrictionSummary friction;
};

// The problem, the choices in effect and the solver's counts.
void report_problem_and_solve(nlohmann::json& rep, const Model& model, DualProblem& dual,
                              const Comm& comm, const SolveRecord& r);
// Timings by phase and memory by phase (maxima or sums over the ranks).
void report_timings_and_memory(nlohmann::json& rep, DualProblem& dual, const Comm& comm,
                               const SolveRecord& r);
// The contact rows (their arrays up to max_contact_rows rows) and the displacement summary
// (collective).
void report_solution(nlohmann::json& rep, const Model& model, DualProblem& dual, const Comm& comm,
                     const std::vector<Vec>& u, const Vec& lambda, long long max_contact_rows);

}  // namespace htfeti::solve_parts
