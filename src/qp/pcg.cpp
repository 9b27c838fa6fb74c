#include "htfeti/qp/pcg.hpp"

#include <limits>
#include <stdexcept>

namespace htfeti::qp {

PcgResult projected_cg(const QuadraticProgram& qp, Vec& x, const Reducer& red,
                       const PcgOptions& opt, const Progress& progress, Operator* Z) {
  qp.check();
  if (!qp.equality_projector) throw std::invalid_argument("PCG: the QP has no equality projector");
  if (qp.constraints) throw std::invalid_argument("PCG: the QP has a constraint set (SMALBE-M)");
  if (x.size() != qp.size()) throw std::invalid_argument("PCG: x has the wrong size");
  Operator& A = *qp.hessian;
  Operator& P = *qp.equality_projector;
  const Vec& b = qp.linear;
  PcgResult res;
  const Eigen::Index n = b.size();
  Vec r(n), w(n), p(n), q(n), z(Z ? n : 0);
  Vec best(n);  // the iterate with the smallest projected residual so far
  double best_residual = std::numeric_limits<double>::infinity();
  int best_iteration = 0;
  CgLanczos lanczos;
  lanczos.start(opt.max_iterations);
  P.apply(b, w);
  res.projected_rhs = red.norm(w);
  const double scale = res.projected_rhs > 0 ? res.projected_rhs : 1.0;
  res.rtol = opt.rtol;
  double tol = opt.rtol * scale;
  // Going on to a smaller rtol (PcgOptions::tighten): the rtol met where it went on, and the
  // iteration by which the new test has to be met (-1: not going on).
  double go_on_rtol = 0;
  int go_on_until = -1;
  // Ends a run that cannot improve: the iterate with the smallest residual, and that residual.
  // After going on, that iterate met the last rtol (the point where it went on, or a better
  // one): the run converged for it.
  const auto take_best = [&](StopReason why) {
    res.reason = why;
    res.spectrum = lanczos.estimate();
    if (best_residual < res.projected_residual) x = best, res.projected_residual = best_residual;
    if (go_on_until >= 0) {
      res.reason = StopReason::converged;
      res.rtol = go_on_rtol;
      res.go_on_failed = true;
    }
    return res;
  };
  A.apply(x, q);
  r = b - q;      // residual
  P.apply(r, w);  // projected residual (the gradient in Ker G)
  double ww = red.dot(w, w);
  double wz = ww;  // w'z (z = w without a preconditioner)
  if (Z) {
    Z->apply(w, z);
    wz = red.dot(w, z);
    p = z;
  } else {
    p = w;
  }
  for (int it = 0;; ++it) {
    res.iterations = it;
    res.projected_residual = std::sqrt(ww);
    if (progress) progress(it, res.projected_residual / scale, 0.0);
    if (res.projected_residual <= tol) {
      const double next = opt.tighten ? opt.tighten(x, res.rtol) : res.rtol;
      if (next < res.rtol && res.projected_residual <= next * scale) res.rtol = next;  // met
      if (!(next < res.rtol)) {
        res.reason = StopReason::converged;
        res.spectrum = lanczos.estimate();
        return res;
      }
      go_on_rtol = res.rtol;
      go_on_until = it + kGoOnExtraSteps + cg_steps_for(lanczos.estimate(), next / res.rtol);
      res.rtol = next;
      tol = next * scale;
      ++res.go_ons;
    }
    if (res.projected_residual < best_residual) {
      best_residual = res.projected_residual;
      best = x;
      best_iteration = it;
    } else if (res.projected_residual > kDivergence * best_residual) {
      return take_best(StopReason::diverged);
    } else if (it - best_iteration >= kStagnation) {
      return take_best(StopReason::stagnated);
    }
    if (it >= opt.max_iterations || (go_on_until >= 0 && it >= go_on_until))
      return take_best(StopReason::max_iterations);
    if (!(wz > 0)) {  // a preconditioner that is not positive definite on Ker G
      if (go_on_until >= 0) return take_best(StopReason::breakdown);
      res.reason = StopReason::breakdown;
      res.spectrum = lanczos.estimate();
      return res;
    }
    A.apply(p, q);  // the bottleneck: one dual operator application
    const double pq = red.dot(p, q);
    if (!(pq > 0)) {
      if (go_on_until >= 0) return take_best(StopReason::breakdown);
      res.reason = StopReason::breakdown;
      res.spectrum = lanczos.estimate();
      return res;
    }
    const double alpha = wz / pq;
    lanczos.step(alpha);
    x += alpha * p;
    r -= alpha * q;
    P.apply(r, w);
    ww = red.dot(w, w);
    if (Z) {
      Z->apply(w, z);
      const double wz_new = red.dot(w, z);
      lanczos.direction(wz_new / wz);
      p = z + (wz_new / wz) * p;  // new conjugate direction, still in Ker G
      wz = wz_new;
    } else {
      lanczos.direction(ww / wz);
      p = w + (ww / wz) * p;
      wz = ww;
    }
  }
}

}  // namespace htfeti::qp
