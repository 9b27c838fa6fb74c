#include "htfeti/qp/smalbe.hpp"

#include <algorithm>
#include <stdexcept>

namespace htfeti::qp {

SmalbeResult smalbe(Operator& A, Operator& Q, const Vec& b, const Vec& l, Vec& x, double normA,
                    const Reducer& red, const SmalbeOptions& opt, const Progress& progress,
                    long* H_applications, const PenalizedApply& penalized,
                    const PenalizedApply& preconditioner) {
  if (!(normA > 0)) throw std::invalid_argument("SMALBE-M: ||A|| estimate must be positive");
  SmalbeResult res;
  const Eigen::Index n = b.size();
  const double rho = opt.rho_factor * normA;
  Vec qx(n), tmp(n);
  FunctionOperator H([&](const Vec& v, Vec& y) {  // H_rho = A + rho Q
    if (penalized) {
      penalized(v, rho, y);
      return;
    }
    A.apply(v, y);
    Q.apply(v, tmp);
    y += rho * tmp;
  });
  res.rhs_norm = red.norm(b);
  const double bnorm = res.rhs_norm > 0 ? res.rhs_norm : 1.0;
  const double tol = opt.rtol * bnorm;
  const double eta = opt.eta_factor * bnorm;
  double M = opt.M0_factor * normA;
  res.rho = rho;
  res.alpha = 2.0 / (opt.norm_safety * std::max(normA, rho));

  FunctionOperator Z([&](const Vec& v, Vec& y) { preconditioner(v, rho, y); });
  MprgpOptions mo;
  mo.gamma = opt.gamma;
  mo.alpha = res.alpha;
  if (preconditioner) mo.preconditioner = &Z;
  Vec nu = Vec::Zero(n), rhs(n), g(n);
  MprgpWorkspace work;  // shared by all inner solves: no allocation inside the outer loop
  double L_prev = 0;
  double qnorm = 0;
  bool global_stop = false;
  const MprgpStop stop = [&](const Vec& xx, const Vec&, double gp) {
    Q.apply(xx, qx);  // ||G x|| = ||Q x||
    qnorm = red.norm(qx);
    global_stop = gp <= tol && qnorm <= tol;
    return global_stop || gp <= std::min(M * qnorm, eta);
  };
  for (int k = 0;; ++k) {
    rhs = b - nu;
    mo.max_iterations = opt.max_inner - res.inner_iterations;
    // After the first outer iteration g = H x - (b - nu) is kept up to date below.
    const MprgpResult inner = mprgp(H, rhs, l, x, g, red, mo, stop, k > 0, &work);
    res.inner_iterations += inner.iterations;
    res.cg_steps += inner.cg_steps;
    res.expansion_steps += inner.expansion_steps;
    res.proportioning_steps += inner.proportioning_steps;
    res.outer_iterations = k + 1;
    res.projected_gradient = inner.projected_gradient;
    res.equality_residual = qnorm;  // the stop test ran last at the returned x
    res.M = M;
    if (progress) progress(k + 1, inner.projected_gradient, qnorm);
    if (global_stop) {
      res.reason = StopReason::converged;
      break;
    }
    if (inner.reason == StopReason::breakdown) {
      res.reason = StopReason::breakdown;
      break;
    }
    if (res.inner_iterations >= opt.max_inner || k + 1 >= opt.max_outer) {
      res.reason = StopReason::max_iterations;
      break;
    }
    // L(x^k, mu^k) = 1/2 x'(g - b + nu) with g = H x - b + nu.
    const double L = 0.5 * red.dot(x, g - b + nu);
    nu += rho * qx;  // mu^{k+1} = mu^k + rho G x^k, kept as nu = G' mu
    g += rho * qx;   // the gradient of L moves with nu; x does not change
    if (k > 0 && L < L_prev + 0.5 * rho * qnorm * qnorm) M /= opt.beta;
    L_prev = L;
  }
  if (H_applications) *H_applications = H.count();
  return res;
}

}  // namespace htfeti::qp
