// MPRGP: modified proportioning with reduced gradient projections (Dostal, "Optimal Quadratic
// Programming Algorithms", 2009, ch. 8; Dostal et al., "Scalable Algorithms for Contact
// Problems", 2016, ch. 8; the paper's inner solver, Section 7.3) for
//     min 1/2 x'Ax - b'x   subject to  l_i <= x_i <= u_i
// (l_i = -infinity or u_i = +infinity: no bound on that side; without upper bounds at all, the
// form the frictionless contact problem needs, u is passed empty). Box constraints are
// MPRGP's form for Tresca friction in 2D (|lambda_t| <= g: an interval per tangential row).
//
// With g = Ax - b, the free gradient phi (g on the free set l_i < x_i < u_i), the chopped
// gradient beta (min(g_i, 0) at a lower bound, max(g_i, 0) at an upper bound) and the reduced free
// gradient phi~_i = min((x_i - l_i)/alpha, phi_i) for phi_i > 0, max((x_i - u_i)/alpha, phi_i)
// for phi_i < 0, an iteration is
//   - proportional (||beta||^2 <= Gamma^2 phi~'phi): a CG step in the face if the CG step length
//     keeps x feasible, otherwise an expansion step: the largest feasible CG step, then a
//     projected gradient step of fixed length alpha on the free gradient;
//   - not proportional: a proportioning step, an exact line search along beta (leaves the face;
//     with upper bounds shortened to the first bound it reaches, as a component leaving one bound
//     could otherwise pass the other).
// Preconditioning in face (Dostal 2009, Section 8.6; PERMON's and ESPRESO's MPRGP): with a
// preconditioner Z, symmetric positive definite, the CG steps in the face use the preconditioned
// free gradient z = D_F Z phi (D_F: zero on the active set) in place of phi: p = z after a
// restart, p = z - (z'Ap / p'Ap) p after a CG step; the step along p is the exact line search.
// Expansion and proportioning steps and the proportionality test stay unpreconditioned, so the
// convergence theory of the fixed-length projected gradient step is kept.
// Expansion::preconditioned (an option) takes the expansion step along
// the preconditioned free gradient d = D_F Z phi instead, with the length d'phi / d'Ad that
// minimizes the cost along d before the projection (one more product with A). The projected
// step can raise the cost; it is kept all the same, since what it buys is a better active set
// (accepting it only when the cost falls gave back most of the gain on the METIS-split 80^3
// cube-obstacle, A = 20). After 10 such cost increases in one run the remaining expansion steps
// of the run are the fixed-length gradient steps, so every run ends as MPRGP does and keeps its
// convergence. Counted in expansion_cost_increases.
// Without a preconditioner d = phi. Measured in docs/performance.md.
// Expansion::projected_cg (an option) takes the whole CG step instead and projects it,
// x' = P(x - a_cg p) (Kruzik et al., "Active set expansion strategies in MPRGP algorithm",
// 2020; PERMON's "projcg"): the step length comes from the curvature along p, not from ||A||.
// It is kept when its cost is below that of the feasible half step x - a_f p (known without a
// product: f(x) - a_f g'p + a_f^2 p'Ap / 2); otherwise it is undone and the fixed-length step is
// taken from the half step, so the cost never rises and the theory's decrease holds. Undone
// steps are counted in expansion_cost_increases.
// Expansion::automatic (SMALBE-M's default; MprgpOptions defaults to gradient) tries the
// projected CG step only where it is long: where a_cg ||p|| >= kAutoCgStepRatio alpha ||phi||,
// the whole CG step moves x at least twice as far as the fixed-length gradient step; otherwise
// it takes the fixed-length step. With p preconditioned both are lengths in x, whatever Z's
// scale. On METIS-split cubes with many expansion steps it needs 0.6-0.9 of the gradient step's
// products, and on the contact examples and graded Hertz blocks about as many (docs/performance.md,
// "MPRGP's expansion step chosen by its length"). One more reduction per expansion step.
// Cost of one iteration: one application of A (two for an expansion step, three for a
// preconditioned one or an undone projected CG one) and a few vector ops (and one of Z when
// preconditioned). Global reductions (Reducer::dots fuses what is known at the same time): a CG
// step makes four, ||g^P||, phi~'phi and the tracked image's norm in one, p'Ap with g'p in
// one, the feasible step's minimum and the conjugation's zz'Ap; a proportioning step two (three
// with upper bounds).
// A tracked linear image t = T x (MprgpOptions::image): x changes by x -= a v after A v was formed,
// or is reset where A x itself is formed, so T x follows from the images T v that A's
// application leaves behind, at the cost of one axpy. SMALBE-M uses it for ||G x|| = ||Q x|| at
// every stop test, which would otherwise cost one projection per iteration.
// Stops when the caller's test holds for the projected gradient g^P = phi + beta.
#pragma once

#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/qp/operator.hpp"

namespace htfeti::qp {

/// The expansion step (see above): the fixed-length step along the free gradient, the step
/// along the preconditioned free gradient with its optimal length, or the projected CG step.
/// automatic: the projected CG step where it is at least kAutoCgStepRatio times as long as the
/// fixed-length one, else the fixed-length step (see above).
enum class Expansion { gradient, preconditioned, projected_cg, automatic };
inline constexpr std::array<EnumName<Expansion>, 4> kExpansionNames{
    {{Expansion::gradient, "gradient"},
     {Expansion::preconditioned, "preconditioned"},
     {Expansion::projected_cg, "projected-cg"},
     {Expansion::automatic, "auto"}}};
Expansion parse_expansion(const std::string& name);  // throws std::invalid_argument
std::string to_string(Expansion kind);

/// A linear image t = T x of the iterate, kept up to date without applying T (see above). The
/// caller's operator A writes T v into *last whenever it is applied to v.
struct TrackedImage {
  const Vec* last = nullptr;  ///< T v of the vector A was applied to last (written by A)
  Vec tx;                     ///< T x; on entry with gradient_given it must hold T x of the given x
  /// ||T x||, formed by MPRGP in the reduction of ||g^P|| just before each call of its stopping
  /// test and valid inside that call only (negative otherwise: the test then forms it itself).
  double norm = -1.0;
};

/// Expansion::automatic: the projected CG step is tried where it moves x at least this many
/// times as far as the fixed-length gradient step (see above).
inline constexpr double kAutoCgStepRatio = 2.0;

struct MprgpOptions {
  double gamma = 1.0;  ///< proportioning parameter Gamma > 0
  double alpha = 0.0;  ///< expansion step length in (0, 2/||A||]; required (> 0)
  Expansion expansion = Expansion::gradient;
  int max_iterations = 10000;
  /// Preconditioner in face (see above); nullptr: none. Not owned.
  Operator* preconditioner = nullptr;
  /// T x tracked through the iterations (see above); nullptr: none. Not owned.
  TrackedImage* image = nullptr;
};

struct MprgpResult {
  StopReason reason = StopReason::max_iterations;
  int iterations = 0;
  int cg_steps = 0, expansion_steps = 0, proportioning_steps = 0;
  /// Preconditioned expansion steps that raised the cost (kept), or projected CG expansion steps
  /// that would have raised it above the half step's (undone).
  int expansion_cost_increases = 0;
  int projected_cg_expansions = 0;  ///< expansion steps that tried the projected CG step
  double projected_gradient = 0;    ///< ||g^P|| at exit
};

/// Work vectors of one MPRGP run; pass the same one to repeated runs (SMALBE-M's inner solves)
/// so that nothing is allocated after the first.
struct MprgpWorkspace {
  Vec phi, beta, p, Ap, z;
  Vec x_old, g_old;          ///< Expansion::projected_cg: where an undone step started
  std::vector<int> disc_of;  ///< MPGP: the disc of each entry
};

/// stop(x, g, ||g^P||) decides convergence. x: start in (projected onto the bounds), solution out;
/// g: the gradient A x - b at exit; if gradient_given, also on entry (x must then be feasible),
/// which saves the first application of A (SMALBE-M updates g itself between outer iterations).
using MprgpStop = std::function<bool(const Vec& x, const Vec& g, double gp_norm)>;
/// upper: empty (no upper bounds) or of the size of b (std::invalid_argument otherwise); over
/// MPI, each rank's part (some ranks may give none). One allreduce per call decides whether any
/// rank has upper bounds.
MprgpResult mprgp(Operator& A, const Vec& b, const Vec& lower, const Vec& upper, Vec& x, Vec& g,
                  const Reducer& red, const MprgpOptions& options, const MprgpStop& stop,
                  bool gradient_given = false, MprgpWorkspace* workspace = nullptr);
/// Lower bounds only.
inline MprgpResult mprgp(Operator& A, const Vec& b, const Vec& lower, Vec& x, Vec& g,
                         const Reducer& red, const MprgpOptions& options, const MprgpStop& stop,
                         bool gradient_given = false, MprgpWorkspace* workspace = nullptr) {
  static const Vec no_upper;
  return mprgp(A, b, lower, no_upper, x, g, red, options, stop, gradient_given, workspace);
}

/// The free gradient phi (g where l < x < u, else 0) and the chopped gradient beta (min(g, 0) at
/// a lower bound, max(g, 0) at an upper one, 0 where both hold and off the bounds) of g at x
/// (u empty: no upper bounds); phi and beta must have x's size. Allocates nothing.
void split_gradient(const Vec& x, const Vec& g, const Vec& l, const Vec& u, Vec& phi, Vec& beta);
/// x <- the projection of x onto [l, u] (u empty: no upper bounds).
void clamp(Vec& x, const Vec& l, const Vec& u);

/// The projected gradient g^P = phi + beta of min 1/2 x'Ax - b'x, l <= x <= u, for the gradient
/// g at x (upper empty: no upper bounds).
void projected_gradient(const Vec& x, const Vec& g, const Vec& lower, Vec& gp,
                        const Vec& upper = Vec());

}  // namespace htfeti::qp
