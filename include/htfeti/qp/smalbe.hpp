// SMALBE-M: semimonotonic augmented Lagrangian for bound and equality constraints (Dostal 2009,
// ch. 9; Dostal et al. 2016, ch. 9; the paper's outer solver, Section 7.3) for the QP (qp.hpp)
//     min 1/2 x'Ax - b'x   subject to  x_i >= l_i  and  G x = 0,
// where G has orthonormal rows and is given only through the QP's projector P onto Ker G, and
// Q = I - P = G'G (then ||G x|| = ||Q x||). The multiplier mu of G x = 0 is kept as nu = G' mu.
//
// Outer iteration k (paper, (12)/(15), with H_rho = A + rho Q, here A = PFP so ||H|| = max(||A||,
// rho)):
//   1. MPRGP finds x^k >= l with ||g^P(x^k, mu^k, rho)|| <= min(M_k ||G x^k||, eta), where
//      g = H_rho x - b + nu (the gradient of the augmented Lagrangian L);
//   2. nu^{k+1} = nu^k + rho Q x^k;
//   3. if L(x^k, mu^k) < L(x^{k-1}, mu^{k-1}) + rho/2 ||G x^k||^2, then M_{k+1} = M_k / beta;
//      also after idle_count (kIdleCount; kWarmIdleCount warm-started) consecutive inner solves
//      that took no step with the gradient test unmet (x is then unchanged and the test cannot
//      pass: L grows by rho ||G x||^2 exactly;
//      only mu moves, and on a body held by friction alone it crept for hundreds of outer
//      iterations before g^P outgrew M ||G x||);
//   4. late penalty update (PERMON's SMALXE, rho_update_late): once an inner solve has ended
//      with the gradient test ||g^P|| <= tol met and only the equality test left, rho is
//      multiplied by rho_update_late after every outer iteration whose equality residual
//      ||A|| ||G x^k|| is at least ||g^P|| (the feasibility is then what is left to gain; a
//      larger rho shrinks ||G x|| faster per multiplier update, and H_rho = A + rho Q keeps its
//      conditioning on Im Q, where it is rho I), up to kMaxRhoGrowth times the first rho.
//      rho_update_late = 1 turns it off. The gradient g moves with rho by (rho' - rho) Q x.
// Stops when both hold (the paper's relative precision eps = rtol):
//   ||g^P|| <= tol  and  ||A|| ||G x|| <= tol,  tol = rtol ||b||,
// which are Dostal's tests ||g^P|| <= eps ||b||, ||G x|| <= eps ||b|| for the problem scaled to
// ||A|| = 1 (his analyses of SMALBE-M assume ||F|| = 1). Both sides are in the units of b
// (displacements for the FETI dual; ||G x|| alone is in the units of the multipliers, forces):
// multiplying the stiffness, the load or the length unit by any factor leaves both tests, and so
// every iteration, unchanged, and ||A|| ||G x|| bounds what the equality residual adds to the
// gradient, so the primal error is controlled by rtol in both. (Comparing ||G x|| with ||b||, as
// before, mixed units: with E = 2.1e11, lambda ~ 1e8, ||G x|| cannot come below ||b|| 1e-8 in
// double precision, and the same problem in other units stopped or never did.)
// tol never asks for less than the round-off of what is measured: it is at least
// kRoundoffFloor eps (||b|| + ||A|| ||lambda||) (F lambda and b are computed to about that, and
// ||G x|| to eps ||lambda||), lambda = shift + x the unhomogenized variable;
// SmalbeResult::roundoff_floor says when the floor, not rtol, set it.
// Cost: the inner MPRGP iterations, each one H_rho application (PenalizedOperator: one A, one Q;
// with A = PFP and a fused PenalizedHessian, two projections in all); the stopping test's
// ||G x|| comes from Q x tracked by MPRGP (TrackedImage of H_rho's image(), one axpy); an outer
// iteration adds one Q (x checked afresh) and a few vector operations.
#pragma once

#include <vector>

#include "htfeti/qp/face_cg.hpp"
#include "htfeti/qp/mprgp.hpp"
#include "htfeti/qp/qp.hpp"

namespace htfeti::qp {

/// The round-off floor of the stopping tests, in units of the machine epsilon (64 eps = 1.4e-14).
inline constexpr double kRoundoffFloor = 64.0;
/// The late penalty update never takes rho beyond this multiple of its first value (the
/// expansion step length of MPRGP, 2 / max(||A||, rho), shrinks with rho).
inline constexpr double kMaxRhoGrowth = 1024.0;
/// An outer iteration stalls when its inner solve took no step and ||G x|| fell by less than
/// this factor; kStallCount consecutive stalls raise rho (step 4).
inline constexpr double kStallFactor = 0.9;
inline constexpr int kStallCount = 5;
/// After this many consecutive outer iterations whose inner solve took no step (x unchanged, the
/// gradient test not met), each further one divides M by beta (step 3).
inline constexpr int kIdleCount = 10;
/// The same count for a solve warm-started from an earlier one's solution and equality
/// multiplier (Coulomb's Tresca solves after the first): such a solve opens with idle outer
/// iterations in which only mu moves. Measured on the cube-obstacle with Coulomb friction
/// (docs/results.md): 3 takes TFETI from 319 to 229 products and H-TFETI-DP from 454 to 300 at
/// 1 x 1 x 1; a cold solve keeps 10 (5 or 1 raised the membranes' products, n = 512, m = 1).
inline constexpr int kWarmIdleCount = 3;

/// Face solves (face_cg.hpp) in one SMALBE-M run at most, and the face CG's tolerance on
/// ||P_F D g|| relative to the global test's (the held rows' share of g^P needs the rest).
inline constexpr int kMaxFaceSolves = 3;
inline constexpr double kFaceTolerance = 0.5;
/// Face changes one face solve may make (SmalbeOptions::face_changes, face_cg.hpp). Over the 26
/// cases of bench/contact_products.py: none 1,910 products, 5: 1,810, 10 and 25: 1,792, each
/// case alike (bench/results/contact_products_face_changes_*.json); over METIS's seeds 1-5 of
/// the strongly graded Hertz block 25 takes 168 -> 132 and 114 -> 110 products on seeds 3 and 5
/// (docs/performance.md, "Changes of the face").
inline constexpr int kFaceChanges = 25;
struct SmalbeOptions {
  double rtol = 1e-4;            ///< relative precision eps (paper: 1e-4)
  double rho_factor = 1.1;       ///< rho = rho_factor * ||A|| (theory: rho close to ||F~||)
  double M0_factor = 1.0;        ///< M_0 = M0_factor * ||A|| (docs/performance.md)
  double eta_factor = 0.1;       ///< eta = eta_factor * ||b||
  double beta = 2.0;             ///< M is divided by beta when the Lagrangian grows too little
  double rho_update_late = 2.0;  ///< rho's factor in the late phase (step 4; 1: off)
  double norm_safety = 1.1;      ///< the expansion step is alpha = 2 / (norm_safety * ||H||_est)
  double gamma = 1.0;            ///< MPRGP proportioning parameter Gamma
  Expansion expansion = Expansion::automatic;  ///< MPRGP's expansion step (mprgp.hpp)
  int max_outer = 200;
  int max_inner = 100000;       ///< total MPRGP iterations over all outer iterations
  int idle_count = kIdleCount;  ///< kIdleCount, or kWarmIdleCount for a warm-started solve
  /// A continuation: the penalty and M to start from instead of rho_factor ||A|| and
  /// M0_factor ||A|| (0: those). The accuracy refinement passes the last solve's rho and M
  /// (SmalbeResult), so that a solve asked for a smaller rtol goes on where the last one
  /// stopped instead of restarting SMALBE-M's adaptation (docs/method.md). The late update's
  /// bound kMaxRhoGrowth stays relative to rho_factor ||A||.
  double rho_start = 0, M_start = 0;
  /// The face solve (face_cg.hpp; needs SmalbeHooks::face and bounds, not a SeparableSet):
  /// after an outer iteration, on the active set where its inner solve ended (once per active
  /// set), and first of all in a warm start (multiplier given): CG on that face with G x = 0
  /// held exactly, and the face's equality multiplier. It ends the solve when its point passes the
  /// global test; else the outer loop restarts from its point and multiplier.
  bool face_solve = true;
  /// Face changes one face solve may make and go on (face_cg.hpp; 0: it ends at the first
  /// bound or release).
  int face_changes = kFaceChanges;
};

/// One outer iteration of SMALBE-M (SmalbeResult::outer_log): what its inner solve did and
/// where it ended, for the report's solver.outer_log.
struct SmalbeOuterRecord {
  int inner_iterations = 0;  ///< MPRGP iterations of this inner solve
  int cg_steps = 0, expansion_steps = 0, proportioning_steps = 0;
  long products = 0;              ///< H_rho applications of this SMALBE-M call up to its end
  double projected_gradient = 0;  ///< ||g^P|| / ||b|| at the inner exit
  double equality = 0;            ///< ||A|| ||G x|| / ||b|| at the inner exit
  double M = 0, rho = 0;          ///< the inner stopping test's M and the penalty it used
};
/// SmalbeResult::outer_log keeps the first this many outer iterations (its room is reserved
/// before the loop, so that the loop allocates nothing).
inline constexpr int kMaxOuterRecords = 1000;

struct SmalbeResult {
  StopReason reason = StopReason::max_iterations;
  int outer_iterations = 0;
  int inner_iterations = 0;
  int cg_steps = 0, expansion_steps = 0, proportioning_steps = 0;
  int expansion_cost_increases = 0;  ///< preconditioned expansion steps that raised the cost
  int projected_cg_expansions = 0;   ///< expansion steps that tried the projected CG step
  long hessian_applications = 0;     ///< of H_rho (the products the paper counts)
  double projected_gradient = 0;     ///< ||g^P|| at exit
  double equality_residual = 0;      ///< ||G x|| at exit
  double rhs_norm = 0;               ///< ||b||
  double multiplier_norm = 0;        ///< ||lambda|| = ||shift + x|| at exit
  double tolerance = 0;              ///< tol = max(rtol ||b||, round-off floor) at exit
  /// The rtol of the test at exit: options.rtol, or smaller where a face solve went on to it
  /// (SmalbeHooks::tighten).
  double rtol = 0;
  int go_ons = 0;         ///< face solves that went on to a smaller rtol (SmalbeHooks::tighten)
  int go_ons_failed = 0;  ///< of them, those that ended where they went on (face_cg.hpp)
  bool roundoff_floor = false;       ///< the round-off floor, not rtol ||b||, set tol
  double rho = 0, M = 0, alpha = 0;  ///< at exit
  int rho_updates = 0;               ///< late penalty updates made (step 4)
  int face_solves = 0;               ///< face solves taken (face_cg.hpp)
  int face_iterations = 0;           ///< their CG steps
  int face_changes = 0;              ///< their changes of the face on the way (face_cg.hpp)
  int face_converged = 0;            ///< of them, those that ended the solve
  int face_tries = 0;                ///< face solves begun (also those declined or not taken)
  double face_seconds = 0;           ///< wall time in face solves, their products included
  double face_set_seconds = 0;       ///< of it, setting the faces (coarse matrices)
  /// The face solves' estimates of the preconditioned Hessian's extreme eigenvalues on their
  /// faces, merged (FaceResult::spectrum).
  SpectrumEstimate face_spectrum;
  /// Per outer iteration, the first kMaxOuterRecords (a face solve's products fall in the
  /// record after it, or only in hessian_applications when it ends the solve).
  std::vector<SmalbeOuterRecord> outer_log;
  /// Adds another solve's step and face counts (MPRGP's steps, the face solves' counts, times
  /// and spectrum) to these: the totals over a run's solves (a continuation, Coulomb's next
  /// solves). Iterations, products, the final state and the log stay this solve's.
  void add_counts(const SmalbeResult& o) {
    cg_steps += o.cg_steps, expansion_steps += o.expansion_steps;
    proportioning_steps += o.proportioning_steps;
    expansion_cost_increases += o.expansion_cost_increases;
    projected_cg_expansions += o.projected_cg_expansions;
    face_solves += o.face_solves, face_iterations += o.face_iterations;
    face_changes += o.face_changes, face_converged += o.face_converged;
    face_tries += o.face_tries;
    go_ons += o.go_ons, go_ons_failed += o.go_ons_failed;
    face_seconds += o.face_seconds, face_set_seconds += o.face_set_seconds;
    face_spectrum.merge(o.face_spectrum);
  }
};

/// y = Z_rho x (the preconditioner in face, which depends on rho).
using PenalizedApply = std::function<void(const Vec& x, double rho, Vec& y)>;

/// Faster ways to do SMALBE-M's work that a caller may know (both optional).
struct SmalbeHooks {
  /// H_rho x and Q x in one go (PenalizedOperator); without it A and Q are applied apart.
  PenalizedHessian fused_hessian;
  /// y = Z_rho x, a symmetric positive definite approximation of H_rho^{-1}, used by MPRGP in
  /// face (for A = PFP: P M^{-1} P + Q / rho, exact on Im Q).
  PenalizedApply preconditioner;
  /// The face of the bounds for the face solve (SmalbeOptions::face_solve).
  FaceHooks face;
  /// The accuracy refinement inside the solve (operator.hpp): asked with x at a converged face
  /// point that passes the global test; a smaller rtol than the one given has the face solve go
  /// on to it (face_cg.hpp, step 3) with the test's tolerances made from it. Where the face solve
  /// cannot meet it (it ends at a bound or a release, or the steps run out) the solve ends
  /// where it went on, with the rtol met there (SmalbeResult::rtol). An MPRGP exit that passes
  /// the test ends the solve without asking.
  Tighten tighten;
};

/// qp: bounds (LowerBounds or BoxBounds) and an equality projector are required
/// (std::invalid_argument otherwise). normA: an estimate of ||A|| (estimate_norm). x: start in,
/// solution out (of qp; its shift is the caller's to add). multiplier (optional): nu = G' mu,
/// the equality's multiplier, to start from (zero when empty) and its last value out; with x it
/// warm-starts a sequence of QPs that differ only in their bounds (Coulomb's fixed point).
SmalbeResult smalbe(const QuadraticProgram& qp, double normA, Vec& x, const Reducer& red,
                    const SmalbeOptions& options, const SmalbeHooks& hooks = {},
                    const Progress& progress = {}, Vec* multiplier = nullptr);

}  // namespace htfeti::qp
