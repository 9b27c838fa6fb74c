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
  // Ends a run that cannot improve: the iterate with the smallest residual, and that residual.
  CgLanczos lanczos;
  lanczos.start(opt.max_iterations);
  const auto take_best = [&](StopReason why) {
    res.reason = why;
    res.spectrum = lanczos.estimate();
    if (best_residual < res.projected_residual) x = best, res.projected_residual = best_residual;
    return res;
  };
  P.apply(b, w);
  res.projected_rhs = red.norm(w);
  const double tol = opt.rtol * (res.projected_rhs > 0 ? res.projected_rhs : 1.0);
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
    if (progress) progress(it, res.projected_residual / (tol / opt.rtol), 0.0);
    if (res.projected_residual <= tol) {
      res.reason = StopReason::converged;
      res.spectrum = lanczos.estimate();
      return res;
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
    if (it >= opt.max_iterations) return take_best(StopReason::max_iterations);
    if (!(wz > 0)) {  // a preconditioner that is not positive definite on Ker G
      res.reason = StopReason::breakdown;
      res.spectrum = lanczos.estimate();
      return res;
    }
    A.apply(p, q);  // the bottleneck: one dual operator application
    const double pq = red.dot(p, q);
    if (!(pq > 0)) {
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
