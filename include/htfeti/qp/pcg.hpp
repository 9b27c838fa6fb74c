// Projected conjugate gradients for the equality-constrained dual problem (paper, (11) without
// inequalities): min 1/2 x'Ax - b'x subject to G x = e, started from a feasible x0 (G x0 = e), with
// P the orthogonal projector onto Ker G (the QP's equality projector, qp.hpp). Every iterate stays
// feasible because every direction is a P-image. Stops when ||P(b - A x)|| <= rtol ||P b||.
//
// With a preconditioner Z (the caller's P M^{-1} P, symmetric positive definite on Ker G) the
// directions are built from z = Z w, w = P r (FETI's preconditioned conjugate projected
// gradients, Farhat, Mandel, Roux 1994): beta = w'z / w_old'z_old. The stopping test is the
// same, so both variants stop at the same accuracy.
//
// Round-off can make the recursively updated residual grow again once it is near the accuracy
// the problem allows (a coefficient jump of 1e4 with the Dirichlet preconditioner: 3e-11 at
// iteration 100, then 1e-6 at 1000). PCG keeps the iterate with the smallest projected residual
// and returns it when the residual has grown kDivergence times above that smallest one
// (StopReason::diverged), when it has not come below it for kStagnation iterations (the same
// accuracy limit on a machine whose round-off holds the residual on a plateau, 3e-11 to 5e-11
// from iteration 100 to 1000 on that problem: StopReason::stagnated), or at the iteration limit;
// in every case it has not converged.
//
// Where the caller asks for it (PcgOptions::tighten), PCG goes on from a point that passes its
// test to a smaller rtol, as a new run from that point would, without starting the recurrences
// (and CG's Krylov space) over.
//
// Cost of one iteration: one application of A, one of P, three dot products, three axpys, one
// copy of x while the residual decreases (and one of Z, one more dot product, when
// preconditioned). The step lengths and direction ratios are kept for the estimate of the
// preconditioned operator's extreme eigenvalues (PcgResult::spectrum, cg_spectrum.hpp).
#pragma once

#include "htfeti/qp/cg_spectrum.hpp"
#include "htfeti/qp/qp.hpp"

namespace htfeti::qp {

/// The growth of ||P r|| over its smallest value at which PCG stops (round-off has taken over).
inline constexpr double kDivergence = 1e3;
/// Iterations without a new smallest ||P r|| after which PCG stops (round-off has taken over).
/// No converging run of the test suite or of bench/compare_reports.py reaches it: all their
/// counts and energies stayed the same bits when it came in.
inline constexpr int kStagnation = 200;

struct PcgOptions {
  double rtol = 1e-4;  ///< relative precision on the projected residual
  int max_iterations = 1000;
  /// Asked at every point that passes the test whether to go on to a smaller rtol (operator.hpp;
  /// none: PCG stops there). Going on continues the recurrences; within kGoOnExtraSteps more
  /// than cg_steps_for(the run's spectrum estimate, the reduction) CG steps, or PCG returns the
  /// point where it went on, converged for the rtol met there (PcgResult::go_on_failed).
  Tighten tighten;
};

struct PcgResult {
  StopReason reason = StopReason::max_iterations;
  int iterations = 0;
  double projected_residual = 0;  ///< ||P(b - A x)|| at exit
  double projected_rhs = 0;       ///< ||P b||
  double rtol = 0;                ///< the rtol of the last test met (or asked, unconverged)
  int go_ons = 0;                 ///< times PCG went on to a smaller rtol (PcgOptions::tighten)
  bool go_on_failed = false;      ///< the last went on in vain: its start point was returned
  /// The extreme eigenvalues of Z A on Ker G (A without Z) from the run's coefficients
  /// (cg_spectrum.hpp): empty when no step was taken.
  SpectrumEstimate spectrum;
};

/// qp: the Hessian A, the linear term b and the equality projector P (required); no constraint
/// set (std::invalid_argument otherwise). x: feasible start in, solution out. A counts its
/// applications (see Operator).
PcgResult projected_cg(const QuadraticProgram& qp, Vec& x, const Reducer& red,
                       const PcgOptions& options, const Progress& progress = {},
                       Operator* preconditioner = nullptr);

}  // namespace htfeti::qp
