// MPGP: modified proportioning with gradient projections (Dostal and Kozubek, "An optimal
// algorithm and superrelaxation for minimization of a quadratic function subject to separable
// convex constraints", Math. Program. 135, 2012; Dostal et al., "Scalable Algorithms for Contact
// Problems", 2016, ch. 7 and the chapters on friction) for
//     min 1/2 x'Ax - b'x   subject to  x in Omega = Omega_1 x ... x Omega_s,
// Omega a SeparableSet (qp.hpp): intervals on single entries, discs on pairs (Tresca friction in
// 3D). MPRGP (mprgp.hpp) stays the solver for bounds alone; MPGP is its generalization to
// blocks with curved boundaries.
//
// Per block i, at x feasible with g = Ax - b: the block is free when x_i lies inside Omega_i,
// active on its boundary. The free gradient phi is g on free blocks and 0 on active ones; the
// chopped gradient beta on an active block is what is left of g when its component along the
// outer normal n_i is removed where it points inward (g_i.n_i < 0: beta_i = g_i - (g_i.n_i) n_i;
// otherwise beta_i = g_i, the descent direction -g_i is feasible); a block that is a point (a
// disc of radius 0, l_i = u_i) has beta_i = 0. g^P = phi + beta is the projected gradient (-g^P
// is the projection of -g onto the tangent cone of Omega at x), zero exactly at the solution.
// The reduced free gradient phi~_i = (x_i - P_i(x_i - alpha phi_i)) / alpha on free blocks.
// An iteration is
//   - proportional (||beta||^2 <= Gamma^2 phi~'phi): a CG step in the face if it keeps x feasible
//     (the largest feasible step along -p solves |x_i - c_i - t p_i| = r_i on a disc), otherwise
//     an expansion step: the largest feasible CG step, then x <- P(x - alpha phi);
//   - not proportional: a gradient projection step x <- P(x - alpha g) (on a curved boundary a
//     step along -beta would leave the set; with alpha in (0, 2/||A||) the step decreases the
//     cost, which is what the convergence theory of MPGP needs).
// With bounds only, MPGP differs from MPRGP in the last kind of step alone.
// Preconditioning in face and the tracked image T x are as in MPRGP (mprgp.hpp): the CG steps
// use z = D_F Z phi, D_F zero on the active blocks.
// Cost of one iteration: one application of A (two for an expansion step or a gradient
// projection step, which both form A x afresh) and a few vector operations.
#pragma once

#include "htfeti/qp/mprgp.hpp"
#include "htfeti/qp/qp.hpp"

namespace htfeti::qp {

/// stop, gradient_given, workspace and the result as for mprgp(); `set` must have the size of b
/// (this rank's part over MPI). x: start in (projected onto the set), solution out.
MprgpResult mpgp(Operator& A, const Vec& b, const SeparableSet& set, Vec& x, Vec& g,
                 const Reducer& red, const MprgpOptions& options, const MprgpStop& stop,
                 bool gradient_given = false, MprgpWorkspace* workspace = nullptr);

/// The projected gradient g^P = phi + beta of min 1/2 x'Ax - b'x, x in `set`, for the gradient g
/// at the feasible x.
void projected_gradient(const Vec& x, const Vec& g, const SeparableSet& set, Vec& gp);

}  // namespace htfeti::qp
