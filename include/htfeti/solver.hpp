// The whole pipeline of DESIGN.md for one solve: decomposition -> subdomains and clusters ->
// dual problem -> QP solve (projected CG for equalities only, SMALBE-M + MPRGP with contact)
// -> primal reconstruction -> report. Collective over the communicator.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/qp/smalbe.hpp"

namespace htfeti {

struct SolveOptions {
  DecompositionOptions decomposition;
  FetiOptions feti;
  double rtol = 1e-4;        ///< relative precision eps of the QP solvers (paper: 1e-4)
  int max_iterations = 0;    ///< PCG iterations or SMALBE-M outer iterations; 0: 1000 / 200
  qp::SmalbeOptions smalbe;  ///< rtol and max_outer are taken from the fields above
  bool progress = false;     ///< print one line per (outer) iteration on rank 0 (stderr)
};

struct SolveOutput {
  nlohmann::json report;  ///< identical on every rank
  std::unique_ptr<Decomposition> decomposition;
  std::unique_ptr<DualProblem> dual;
  std::vector<Eigen::VectorXd> u;  ///< primal solution of this rank's subdomains
  Eigen::VectorXd lambda;          ///< owned multipliers
  bool converged = false;
};

/// Throws std::invalid_argument for bad options (the same on every rank).
SolveOutput solve(const SolveOptions& options, const Comm& comm);

/// Checks options that do not need a decomposition; throws std::invalid_argument.
void validate(const SolveOptions& options);

}  // namespace htfeti
