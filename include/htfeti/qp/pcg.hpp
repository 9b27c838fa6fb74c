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
// Cost of one iteration: one application of A, one of P, three dot products, three axpys
// (and one of Z, one more dot product, when preconditioned).
#pragma once

#include "htfeti/qp/qp.hpp"

namespace htfeti::qp {

struct PcgOptions {
  double rtol = 1e-4;  ///< relative precision on the projected residual
  int max_iterations = 1000;
};

struct PcgResult {
  StopReason reason = StopReason::max_iterations;
  int iterations = 0;
  double projected_residual = 0;  ///< ||P(b - A x)|| at exit
  double projected_rhs = 0;       ///< ||P b||
};

/// qp: the Hessian A, the linear term b and the equality projector P (required); no constraint
/// set (std::invalid_argument otherwise). x: feasible start in, solution out. A counts its
/// applications (see Operator).
PcgResult projected_cg(const QuadraticProgram& qp, Vec& x, const Reducer& red,
                       const PcgOptions& options, const Progress& progress = {},
                       Operator* preconditioner = nullptr);

}  // namespace htfeti::qp
