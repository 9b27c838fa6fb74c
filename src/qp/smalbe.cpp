#include "htfeti/qp/smalbe.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "htfeti/clock.hpp"
#include "htfeti/qp/mpgp.hpp"

namespace htfeti::qp {

SmalbeResult smalbe(const QuadraticProgram& qp, double normA, Vec& x, const Reducer& red,
                    const SmalbeOptions& opt, const SmalbeHooks& hooks, const Progress& progress,
                    Vec* multiplier) {
  qp.check();
  // MPRGP solves the inner problems on bounds (lower, or a box), MPGP on a separable set with
  // discs (Tresca friction in 3D); the outer loop is the same for both.
  static const Vec no_upper;
  const Vec* lower = &no_upper;
  const Vec* upper = &no_upper;
  const auto* separable = dynamic_cast<const SeparableSet*>(qp.constraints.get());
  if (const auto* lb = dynamic_cast<const LowerBounds*>(qp.constraints.get())) {
    lower = &lb->lower();
  } else if (const auto* box = dynamic_cast<const BoxBounds*>(qp.constraints.get())) {
    lower = &box->lower(), upper = &box->upper();
  } else if (!separable) {
    throw std::invalid_argument(
        "SMALBE-M: the constraint set must be bounds (LowerBounds, BoxBounds: MPRGP) or a "
        "SeparableSet (MPGP)");
  }
  if (!qp.equality_projector) throw std::invalid_argument("SMALBE-M: the QP has no equalities");
  if (x.size() != qp.size()) throw std::invalid_argument("SMALBE-M: x has the wrong size");
  if (!(normA > 0)) throw std::invalid_argument("SMALBE-M: ||A|| estimate must be positive");
  SmalbeResult res;
  const Vec& b = qp.linear;
  const Vec& l = *lower;
  const Vec& u = *upper;
  const Eigen::Index n = b.size();
  const double rho0 = opt.rho_factor * normA;  // H.rho(): raised by the late update (step 4)
  if (!(opt.rho_start >= 0) || !(opt.M_start >= 0))
    throw std::invalid_argument("SMALBE-M: rho_start and M_start must be >= 0");
  ComplementOperator Q(qp.equality_projector);  // Q = I - P
  Vec qx(n);
  // H_rho = A + rho Q; the image Q v of every argument is left in H.image(), from which MPRGP
  // keeps Q x up to date for the stopping test (TrackedImage).
  PenalizedOperator H(*qp.hessian, Q, opt.rho_start > 0 ? opt.rho_start : rho0, n,
                      hooks.fused_hessian);
  res.rhs_norm = red.norm(b);
  const double bnorm = res.rhs_norm > 0 ? res.rhs_norm : 1.0;
  const double eta = opt.eta_factor * bnorm;
  double M = opt.M_start > 0 ? opt.M_start : opt.M0_factor * normA;
  // The stopping tests (smalbe.hpp): ||g^P|| <= tol and ||A|| ||G x|| <= tol, with
  // tol = max(rtol ||b||, kRoundoffFloor eps (||b|| + ||A|| ||lambda||)), all in the units of b.
  const double floor_rel = kRoundoffFloor * std::numeric_limits<double>::epsilon();
  const bool shifted = qp.shift.size() == n;
  Vec lam(shifted ? n : 0);         // lambda = shift + x (x itself without a shift)
  double grad_tol = 0, eq_tol = 0;  // eq_tol = grad_tol / ||A||: ||G x||'s bound, units of x
  res.rtol = opt.rtol;              // smaller where a face solve went on (SmalbeHooks::tighten)
  const auto set_tolerances = [&]() {
    if (shifted) lam = qp.shift + x;
    res.multiplier_norm = red.norm(shifted ? lam : x);
    const double floor = floor_rel * (res.rhs_norm + normA * res.multiplier_norm);
    grad_tol = std::max(res.rtol * bnorm, floor);
    eq_tol = grad_tol / normA;
    res.tolerance = grad_tol;
    res.roundoff_floor = floor > res.rtol * bnorm;
  };
  set_tolerances();
  // MPRGP's expansion step length for ||H_rho|| = max(||A||, rho).
  const auto step_length = [&]() { return 2.0 / (opt.norm_safety * std::max(normA, H.rho())); };
  res.alpha = step_length();

  FunctionOperator Z([&](const Vec& v, Vec& y) { hooks.preconditioner(v, H.rho(), y); });
  MprgpOptions mo;
  mo.gamma = opt.gamma;
  mo.expansion = opt.expansion;
  mo.alpha = res.alpha;
  if (hooks.preconditioner) mo.preconditioner = &Z;
  TrackedImage image;
  image.last = &H.image();
  image.tx = Vec::Zero(n);  // set by MPRGP's first application of H to the start x
  mo.image = &image;
  Vec nu = Vec::Zero(n), rhs(n), g(n), lag(n);
  if (multiplier && multiplier->size() == n) nu = *multiplier;
  if (multiplier && multiplier->size() != 0 && multiplier->size() != n)
    throw std::invalid_argument("SMALBE-M: the multiplier has the wrong size");
  MprgpWorkspace work;  // shared by all inner solves: no allocation inside the outer loop
  // The face solve (face_cg.hpp): held[i] = 1 where x_i was at a bound at the last inner exit
  // (-1: no exit yet); fg, fnu: the face's gradient H x - b and equality multiplier.
  const bool use_face = opt.face_solve && hooks.face && !separable;
  Vec held = Vec::Constant(use_face ? n : 0, -1.0), fg(use_face ? n : 0), fnu(use_face ? n : 0);
  FaceWorkspace face_work;
  bool face_tried = false;  // on the active set of the last inner exit
  bool face_kept = false;   // the last face solve's point was kept (the outer loop restarts)
  const bool has_upper = u.size() == n;
  // Faces are tried early (before the late phase, and in a warm start) only where they are cheap.
  const auto face_cheap = [&]() { return !hooks.face.cheap || hooks.face.cheap(); };
  // 1 where the active set differs from held (updating held): reduced over the ranks.
  const auto active_set_changed = [&]() {
    double changed = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double a = !(x[i] > l[i]) || (has_upper && !(x[i] < u[i])) ? 1.0 : 0.0;
      if (a != held[i]) changed = 1, held[i] = a;
    }
    return red.max(changed) > 0;
  };
  // A warm start (the multiplier given: a continuation of an earlier solve): the start point's
  // active set is the one the first inner exit is compared with.
  // x is put onto the bounds first, as MPRGP does (Coulomb's next solves have new bounds).
  // Agreed over the ranks: a rank that owns no entries cannot tell a warm start from a cold one.
  const bool warm = red.max(multiplier && n > 0 && multiplier->size() == n ? 1.0 : 0.0) > 0;
  if (use_face && warm) {
    clamp(x, l, u);
    active_set_changed();  // held = the start point's active set (collective: warm is agreed)
  }
  res.outer_log.reserve(static_cast<std::size_t>(std::clamp(opt.max_outer, 0, kMaxOuterRecords)));
  double L_prev = 0;
  double qnorm = 0, qnorm_prev = 0;
  int stalls = 0;  // consecutive stalled outer iterations (step 4)
  int idle = 0;    // consecutive inner solves without a step (step 3)
  bool global_stop = false;
  bool late = false;  // an inner solve has met the gradient test: only feasibility is left
  // The inner stopping test with ||G x|| = ||Q x|| from the tracked image (no projection); the
  // inner solve's last x is checked with Q x applied afresh below.
  const MprgpStop stop = [&](const Vec&, const Vec&, double gp) {
    const double q = image.norm >= 0 ? image.norm : red.norm(image.tx);
    return (gp <= grad_tol && q <= eq_tol) || gp <= std::min(M * q, eta);
  };
  // A solve that ends outside MPRGP's loop (a face solve, or a warm start already converged):
  // its final norms and reason, and its --progress line (label: the iteration or kFaceProgress).
  const auto converged_here = [&](double gp, double q, int label) {
    qnorm = q;
    res.projected_gradient = gp;
    res.equality_residual = q;
    res.reason = StopReason::converged;
    if (progress) progress(label, gp / bnorm, normA * q / bnorm);
  };
  // The face solve: CG on the face of x's active set with G x = 0 held exactly. It either ends
  // the solve (x and the face's multiplier pass the global test: true) or SMALBE-M restarts
  // from where it stopped: x (inside the bounds, G x = 0) with the face's multiplier as mu, M
  // and rho kept (face_kept). Only a breakdown or a face not taken leaves x as it was. One try
  // per active set: a face that did not finish is not tried again until the set changes.
  // Needs g = H x - (b - nu) at x.
  // At a converged face point that passes the global test (G x = 0 holds there to round-off),
  // the caller may ask for a smaller rtol (SmalbeHooks::tighten): the face solve goes on to it,
  // or, where it cannot, ends at that point with the rtol it met (rtol_met).
  double rtol_met = res.rtol;
  const FaceGoOn go_on = [&](const Vec& xf, double gp) {
    if (!hooks.tighten || !(gp <= grad_tol)) return 0.0;
    const double next = hooks.tighten(xf, res.rtol);
    if (!(next < res.rtol)) return 0.0;
    rtol_met = res.rtol;
    res.rtol = next;
    set_tolerances();
    return kFaceTolerance * grad_tol;
  };
  const auto face_attempt = [&]() {
    ++res.face_tries;
    face_tried = true;
    face_work.x_save = x;
    fg = g - nu;  // H x - b
    const FaceResult fr =
        face_cg(H, b, l, u, x, fg, fnu, hooks.face, hooks.preconditioner ? &Z : nullptr, red,
                kFaceTolerance * grad_tol, opt.gamma,
                opt.max_inner - res.inner_iterations - res.face_iterations, face_work,
                opt.face_changes, go_on);
    res.face_set_seconds += fr.set_seconds;
    res.go_ons += fr.go_ons;
    if (fr.go_on_failed) {
      ++res.go_ons_failed;
      res.rtol = rtol_met;
      set_tolerances();
    }
    if (!fr.taken()) return false;
    ++res.face_solves;
    res.face_iterations += fr.iterations;
    res.face_changes += fr.changes;
    res.face_spectrum.merge(fr.spectrum);
    if (fr.outcome == FaceOutcome::converged) {
      Q.apply(x, face_work.t);
      const double q = red.norm(face_work.t);
      face_work.c = fg + fnu;  // the gradient of L at (x, mu of the face)
      split_gradient(x, face_work.c, l, u, face_work.phi, face_work.beta);
      const double gp = std::sqrt(red.dot(face_work.phi, face_work.phi) +
                                  red.dot(face_work.beta, face_work.beta));
      // The test with the tolerances at this x (lambda sets the round-off floor).
      const double grad_tol_old = grad_tol, eq_tol_old = eq_tol;
      set_tolerances();
      if (gp <= grad_tol && q <= eq_tol) {
        ++res.face_converged;
        nu = fnu;
        g = face_work.c;
        qx = face_work.t;
        converged_here(gp, q, kFaceProgress);
        return true;
      }
      grad_tol = grad_tol_old, eq_tol = eq_tol_old;
    }
    if (fr.outcome != FaceOutcome::breakdown) {
      // Kept: x is feasible with G x = 0 and the face's CG steps lowered the cost there, and
      // the face's multiplier is what the outer loop's updates of mu approach on this face. At
      // most kMaxFaceSolves restarts, so the convergence is SMALBE-M's from the last one on.
      nu = fnu;
      g = fg + fnu;
      Q.apply(x, qx);  // G x = 0 up to round-off: the tracked image starts afresh
      qnorm = red.norm(qx);
      image.tx = qx;
      face_kept = true;
      set_tolerances();
      return false;
    }
    x = face_work.x_save;  // undone: g, nu, Q x and the tracked image are those of x
    set_tolerances();
    return false;
  };
  const auto face_finishes = [&]() {
    const double t0 = seconds_now();
    const bool done = face_attempt();
    res.face_seconds += seconds_now() - t0;
    return done;
  };
  // A warm start tries the face solve first, on the start point's face (one product for the
  // gradient): a continuation (the single-precision check, the accuracy refinement, Coulomb's
  // next solves) mostly starts on the face of the solution. A start point that passes the
  // stopping test already (the single-precision check of a solve whose copies were close
  // enough) ends there, after that one product, as the first inner solve would without faces.
  bool gradient_given = false, done_at_start = false;
  if (use_face && warm && face_cheap()) {
    H.apply(x, g);
    g -= b - nu;
    Q.apply(x, qx);
    image.tx = qx;
    gradient_given = true;
    face_work.phi.resize(n), face_work.beta.resize(n);
    split_gradient(x, g, l, u, face_work.phi, face_work.beta);
    const Vec* ta[3] = {&face_work.phi, &face_work.beta, &qx};
    double sums[3];
    red.dots(3, ta, ta, sums);
    const double gp = std::sqrt(sums[0] + sums[1]), q = std::sqrt(sums[2]);
    if (gp <= grad_tol && q <= eq_tol) {
      done_at_start = true;
      converged_here(gp, q, 0);
    } else {
      done_at_start = face_finishes();
      face_kept = false;  // no multiplier update is pending: the loop starts from the face's point
    }
    res.M = M;
  }
  for (int k = 0; !done_at_start; ++k) {
    rhs = b - nu;
    mo.max_iterations = opt.max_inner - res.inner_iterations - res.face_iterations;
    // After the first outer iteration g = H x - (b - nu) is kept up to date below.
    gradient_given = gradient_given || k > 0;
    const MprgpResult inner =
        separable ? mpgp(H, rhs, *separable, x, g, red, mo, stop, gradient_given, &work)
                  : mprgp(H, rhs, l, u, x, g, red, mo, stop, gradient_given, &work);
    // Q x afresh at the inner solve's exit: the outer update and the global test use it, and the
    // next inner solve starts its tracked image from it (round-off of the updates does not carry).
    Q.apply(x, qx);
    qnorm = red.norm(qx);
    image.tx = qx;
    set_tolerances();  // lambda at the inner solve's exit
    global_stop = inner.projected_gradient <= grad_tol && qnorm <= eq_tol;
    res.inner_iterations += inner.iterations;
    res.cg_steps += inner.cg_steps;
    res.expansion_steps += inner.expansion_steps;
    res.expansion_cost_increases += inner.expansion_cost_increases;
    res.projected_cg_expansions += inner.projected_cg_expansions;
    res.proportioning_steps += inner.proportioning_steps;
    res.outer_iterations = k + 1;
    res.projected_gradient = inner.projected_gradient;
    res.equality_residual = qnorm;
    res.M = M;
    if (res.outer_log.size() < res.outer_log.capacity())
      res.outer_log.push_back(
          {inner.iterations, inner.cg_steps, inner.expansion_steps, inner.proportioning_steps,
           H.count(), inner.projected_gradient / bnorm, normA * qnorm / bnorm, M, H.rho()});
    if (progress) progress(k + 1, inner.projected_gradient / bnorm, normA * qnorm / bnorm);
    if (global_stop) {
      res.reason = StopReason::converged;
      break;
    }
    if (inner.reason == StopReason::breakdown) {
      res.reason = StopReason::breakdown;
      break;
    }
    if (res.inner_iterations + res.face_iterations >= opt.max_inner || k + 1 >= opt.max_outer) {
      res.reason = StopReason::max_iterations;
      break;
    }
    // The face solve (face_cg.hpp) on the active set of this inner exit, once per active set
    // (before the late phase only where faces are cheap: FaceHooks::cheap); at most
    // kMaxFaceSolves taken per run. A kept face point restarts the outer loop: no
    // multiplier update (mu is the face's), and the M test compares with L there.
    if (use_face && active_set_changed()) face_tried = false;
    if (use_face && !face_tried && res.face_solves < kMaxFaceSolves &&
        (late || inner.projected_gradient <= grad_tol || face_cheap()) && face_finishes())
      break;
    if (face_kept) {
      face_kept = false;
      lag = g - b + nu;
      L_prev = 0.5 * red.dot(x, lag);
      continue;
    }
    // L(x^k, mu^k) = 1/2 x'(g - b + nu) with g = H x - b + nu.
    lag = g - b + nu;  // (into a vector of the solve: nothing is allocated per iteration)
    const double L = 0.5 * red.dot(x, lag);
    const double rho = H.rho();
    nu += rho * qx;  // mu^{k+1} = mu^k + rho G x^k, kept as nu = G' mu
    g += rho * qx;   // the gradient of L moves with nu; x does not change
    // Also after idle_count consecutive inner solves that took no step before the gradient
    // test was met: x stays, so the test above cannot pass (L grows by exactly rho ||G x||^2),
    // and only mu moves, by rho G x per outer iteration, until g^P outgrows M ||G x|| (on a
    // body held by friction alone that took hundreds of outer iterations).
    idle = inner.iterations == 0 && inner.projected_gradient > grad_tol ? idle + 1 : 0;
    if ((k > 0 && L < L_prev + 0.5 * rho * qnorm * qnorm) || idle >= opt.idle_count) M /= opt.beta;
    L_prev = L;
    // Step 4: the late penalty update, also when the multiplier updates stall: an inner solve
    // that took no step and ||G x|| down by less than kStallFactor since the last outer
    // iteration (only mu moves, at a rate set by rho).
    late = late || inner.projected_gradient <= grad_tol;
    stalls = k > 0 && qnorm > kStallFactor * qnorm_prev ? stalls + 1 : 0;
    const bool stalled = stalls >= kStallCount;
    if (stalled) stalls = 0;
    qnorm_prev = qnorm;
    if ((late || stalled) && opt.rho_update_late > 1 && normA * qnorm >= inner.projected_gradient &&
        rho * opt.rho_update_late <= kMaxRhoGrowth * rho0) {
      const double next = rho * opt.rho_update_late;
      g += (next - rho) * qx;  // H_rho x moves by (rho' - rho) Q x
      H.set_rho(next);
      mo.alpha = res.alpha = step_length();
      ++res.rho_updates;
    }
  }
  res.rho = H.rho();
  res.hessian_applications = H.count();
  if (multiplier) *multiplier = nu;
  return res;
}

}  // namespace htfeti::qp
