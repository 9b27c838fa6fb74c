// SMALBE-M: semimonotonic augmented Lagrangian for bound and equality constraints (Dostal 2009,
// ch. 9; Dostal et al. 2016, ch. 9; the paper's outer solver, Section 7.3) for
//     min 1/2 x'Ax - b'x   subject to  x_i >= l_i  and  G x = 0,
// where G has orthonormal rows and is given only through Q = G'G, the orthogonal projector onto
// Im G' (then ||G x|| = ||Q x||). The multiplier mu of G x = 0 is kept as nu = G' mu.
//
// Outer iteration k (paper, (12)/(15), with H_rho = A + rho Q, here A = PFP so ||H|| = max(||A||,
// rho)):
//   1. MPRGP finds x^k >= l with ||g^P(x^k, mu^k, rho)|| <= min(M_k ||G x^k||, eta), where
//      g = H_rho x - b + nu (the gradient of the augmented Lagrangian L);
//   2. nu^{k+1} = nu^k + rho Q x^k;
//   3. if L(x^k, mu^k) < L(x^{k-1}, mu^{k-1}) + rho/2 ||G x^k||^2, then M_{k+1} = M_k / beta.
// Stops when ||g^P|| <= rtol ||b|| and ||G x|| <= rtol ||b||.
// Cost: the inner MPRGP iterations, each one H_rho application (one A, one Q; with A = PFP and a
// PenalizedHessian, two projections in all); the stopping test's ||G x|| comes from Q x tracked
// by MPRGP (TrackedImage, one axpy); an outer iteration adds one Q (x checked afresh) and a few
// vector operations.
#pragma once

#include "htfeti/qp/mprgp.hpp"

namespace htfeti::qp {

struct SmalbeOptions {
  double rtol = 1e-4;        ///< relative precision eps (paper: 1e-4)
  double rho_factor = 1.1;   ///< rho = rho_factor * ||A|| (theory: rho close to ||F~||)
  double M0_factor = 100.0;  ///< M_0 = M0_factor * ||A||
  double eta_factor = 0.1;   ///< eta = eta_factor * ||b||
  double beta = 2.0;         ///< M is divided by beta when the Lagrangian grows too little
  double norm_safety = 1.1;  ///< the expansion step is alpha = 2 / (norm_safety * ||H||_est)
  double gamma = 1.0;        ///< MPRGP proportioning parameter Gamma
  int max_outer = 200;
  int max_inner = 100000;  ///< total MPRGP iterations over all outer iterations
};

struct SmalbeResult {
  StopReason reason = StopReason::max_iterations;
  int outer_iterations = 0;
  int inner_iterations = 0;
  int cg_steps = 0, expansion_steps = 0, proportioning_steps = 0;
  double projected_gradient = 0;  ///< ||g^P|| at exit
  double equality_residual = 0;   ///< ||G x|| at exit
  double rhs_norm = 0;            ///< ||b||
  double rho = 0, M = 0, alpha = 0;
};

/// y = A x + rho Q x and qx = Q x in one go, for callers that can share work between the two
/// (with A = PFP and Q = I - P, one projection of x serves both). Without it SMALBE-M applies A
/// and Q apart.
using PenalizedHessian = std::function<void(const Vec& x, double rho, Vec& y, Vec& qx)>;
/// y = Z_rho x (the preconditioner in face, which depends on rho).
using PenalizedApply = std::function<void(const Vec& x, double rho, Vec& y)>;

/// normA: an estimate of ||A|| (estimate_norm). x: start in, solution out. H_rho applications are
/// counted by the operator `counted_H` if given (so a caller can report them), else not at all.
/// preconditioner (optional): y = Z_rho x, a symmetric positive definite approximation of
/// H_rho^{-1}, used by MPRGP in face (for A = PFP: P M^{-1} P + Q / rho, exact on Im Q).
SmalbeResult smalbe(Operator& A, Operator& Q, const Vec& b, const Vec& lower, Vec& x, double normA,
                    const Reducer& red, const SmalbeOptions& options, const Progress& progress = {},
                    long* H_applications = nullptr, const PenalizedHessian& penalized = {},
                    const PenalizedApply& preconditioner = {});

}  // namespace htfeti::qp
