// The face solve of SMALBE-M (smalbe.hpp, docs/method.md "The face solve"; the paper's dual
// problem (11) on Ker G as in (15)-(16), the equality held on one face of the bounds): projected
// preconditioned CG on one face of the bounds with the equality G x = 0 held exactly,
//     min 1/2 x'Ax - b'x   subject to  x_i = l_i (or u_i) on the active set A,  G x = 0,
// the problem that SMALBE-M's outer loop approaches through its multiplier updates once the
// active set has settled. With D = diag(free) (1 off the bounds, 0 on A), the face projector is
// P_F = I - D G'(G D G')^{-1} G D, applied to free vectors; the FETI dual gives G D G' as the
// coarse matrix of the free rows (CoarseSpace::set_face), so P_F costs one pass of G, one
// sparse coarse solve and one pass of G', as P does.
//   1. x <- x - D G'(G D G')^{-1} G x: G x = 0, only free entries move; if one leaves its
//      bounds, the face solve ends without a product;
//   2. g = H x - b; w = P_F D g (the face's residual); z = P_F D Z w; p = z;
//   3. CG in the face: a = w'z / p'Hp; if x - a p leaves the bounds, the active set has to
//      grow: the feasible half step x -= a_f p onto the first bound (the cost falls, G x = 0
//      holds), that row held, a new face (its G D G' factored) and CG restarted from step 2's
//      w and z; else x -= a p, g -= a Hp, w, z anew, p = z + (w'z / w_old'z_old) p; until
//      ||w|| <= tol;
//      Before each step, MPRGP's proportionality test with the face's multiplier: when the
//      held rows' share of g^P(g + nu) exceeds Gamma ||w||, the held rows with a chopped
//      gradient are freed (those MPRGP's proportioning step would move), a new face, CG
//      restarted; a row so freed that -p would move out of its bounds (a_f = 0) is held again;
//      After max_changes such changes of the face, or at the kMaxShortBounds + 1-th bound in a
//      row reached by the first CG step on its face (the active set is far from settled: MPRGP's
//      expansion steps, which fill it many rows at a time, do better), the face solve ends at
//      the next bound or release instead, and SMALBE-M goes on from there;
//      At ||w|| <= tol the caller may have the solve go on to a smaller tol (FaceGoOn: the
//      accuracy refinement inside the solve): CG continues where it is, without a restart, for
//      at most kGoOnExtraSteps more than cg_steps_for(the spectrum seen on this solve's faces,
//      the reduction) steps (renewed from where CG restarts after a change of the face, which
//      goes on as above); where it does not meet the new tol within them, or ends at a bound
//      or a release, the solve ends at the point where it went on;
//   4. the equality's multiplier of the face, nu = G' mu = -G'(G D G')^{-1} G D g: then
//      D (g + nu) = w, and g + nu on the active set is what decides whether x is optimal.
// Every direction lies in Ker G, where H_rho = A + rho Q equals A, so rho plays no part; one
// iteration costs one product with H, two face projections and one application of Z; a change
// of the face costs one factorization of the coarse matrix of the free rows, no product. The step
// lengths and direction ratios give the estimate of FaceResult::spectrum (cg_spectrum.hpp).
// Nothing is allocated once the workspace has its sizes.
#pragma once

#include <functional>

#include "htfeti/qp/cg_spectrum.hpp"
#include "htfeti/qp/operator.hpp"

namespace htfeti::qp {

/// The face of the bounds, from the owner of G (FETI: DualProblem::set_face, face_correction).
struct FaceHooks {
  /// Sets the face: free[i] = 1 where x_i is off its bounds, 0 where it is held. Returns false
  /// when G D G' is singular (some direction of Im G' is restrained only by held rows), in
  /// which case the face solve is not taken. Collective.
  std::function<bool(const Vec& free)> set;
  /// y = G'(G D G')^{-1} G v for the face last set. Collective.
  std::function<void(const Vec& v, Vec& y)> correction;
  /// Whether setting a face costs little beside a product (none given: it does). SMALBE-M tries
  /// a face before its late phase, and in a warm start, only then. The same on every rank.
  std::function<bool()> cheap;
  explicit operator bool() const { return set && correction; }
};

/// Asked at a converged face point whether to go on (step 3): x there and ||g^P|| with the face's
/// multiplier (its free and held rows); returns the tolerance on ||P_F D g|| to go on to, or 0 to
/// stop. Collective: the same answer on every rank.
using FaceGoOn = std::function<double(const Vec& x, double projected_gradient)>;

/// How a face solve ended.
enum class FaceOutcome {
  converged,       ///< ||P_F D g|| <= tol
  bound,           ///< the next CG step would leave the bounds (x is the last point inside)
  release,         ///< not proportional: the held rows' gradient exceeds Gamma ||P_F D g||
  singular,        ///< G D G' singular: not taken
  declined,        ///< not proportional at the given x already (see release): not taken
  infeasible,      ///< step 1 would leave the bounds: not taken (x unchanged)
  max_iterations,  ///< the iteration budget is spent
  breakdown        ///< p'Hp <= 0
};

struct FaceResult {
  FaceOutcome outcome = FaceOutcome::singular;
  int iterations = 0;         ///< CG steps (products with H: iterations + 1 when taken)
  int changes = 0;            ///< faces set anew on the way (rows held at a bound or freed)
  int go_ons = 0;             ///< times it went on to a smaller tol (FaceGoOn)
  bool go_on_failed = false;  ///< the last did not meet it: the point where it went on is x
  double free_gradient = 0;   ///< ||P_F D g|| at exit
  double held_gradient = 0;   ///< the held rows' share of g^P (g + nu) at exit
  double set_seconds = 0;     ///< wall time of FaceHooks::set (the face's coarse matrix)
  /// The extreme eigenvalues of the preconditioned Hessian on the face from the CG steps taken
  /// (cg_spectrum.hpp; empty when none was).
  SpectrumEstimate spectrum;
  bool taken() const {
    return outcome != FaceOutcome::singular && outcome != FaceOutcome::declined &&
           outcome != FaceOutcome::infeasible;
  }
};

/// Bounds in a row reached by the first CG step on a face after which a face solve stops changing
/// its face (step 3). Over bench/contact_products.py's 26 cases with 10 changes (the others in
/// a temporary build): 0: 1,825 products, 1: 1,809, 3: 1,792, no limit: 1,787, but then the
/// 40^3 cube-obstacle at A = 20 took 8-9 products more than without changes of the face (one
/// row held per product), with 3: 2.
inline constexpr int kMaxShortBounds = 3;

struct FaceWorkspace {
  Vec free, c, t, w, z, p, Hp, phi, beta, x_save;
  Vec go_x, go_g, go_nu;  ///< the point where the solve went on (FaceGoOn), its g and nu
  CgLanczos lanczos;      ///< the CG coefficients (FaceResult::spectrum)
};

/// H: the Hessian (SMALBE-M's H_rho); b: the linear term (without the equality's multiplier);
/// lower, upper: the bounds (upper empty: none); x: a feasible point in, the face solution out
/// (unchanged unless taken()); g: H x - b at the given x in, at the face solution out; nu: the
/// face's equality multiplier G' mu out (when taken()); Z: the preconditioner or nullptr; tol: on
/// ||P_F D g||; gamma: MPRGP's proportioning parameter (the solve leaves the face, outcome release,
/// when the held rows' share of the projected gradient exceeds gamma ||P_F D g||: a held row is to
/// be freed); max_changes: changes of the face on the way (step 3; 0: the solve ends at the
/// first bound or release, outcome bound or release); go_on: asked at a converged point whether
/// to go on to a smaller tol (none: the solve ends there).
FaceResult face_cg(Operator& H, const Vec& b, const Vec& lower, const Vec& upper, Vec& x, Vec& g,
                   Vec& nu, const FaceHooks& face, Operator* Z, const Reducer& red, double tol,
                   double gamma, int max_iterations, FaceWorkspace& work, int max_changes = 0,
                   const FaceGoOn& go_on = {});

}  // namespace htfeti::qp
