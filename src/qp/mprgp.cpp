#include "htfeti/qp/mprgp.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace htfeti::qp {

void projected_gradient(const Vec& x, const Vec& g, const Vec& lower, Vec& gp) {
  gp.resize(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) gp[i] = x[i] > lower[i] ? g[i] : std::min(g[i], 0.0);
}

namespace {
// phi: free gradient, beta: chopped gradient.
void split_gradient(const Vec& x, const Vec& g, const Vec& l, Vec& phi, Vec& beta) {
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const bool free = x[i] > l[i];
    phi[i] = free ? g[i] : 0.0;
    beta[i] = free ? 0.0 : std::min(g[i], 0.0);
  }
}
}  // namespace

MprgpResult mprgp(Operator& A, const Vec& b, const Vec& l, Vec& x, Vec& g, const Reducer& red,
                  const MprgpOptions& opt, const MprgpStop& stop, bool gradient_given,
                  MprgpWorkspace* workspace) {
  if (!(opt.alpha > 0)) throw std::invalid_argument("MPRGP: the expansion step length must be > 0");
  if (!(opt.gamma > 0)) throw std::invalid_argument("MPRGP: Gamma must be > 0");
  const Eigen::Index n = b.size();
  const double inf = std::numeric_limits<double>::infinity();
  MprgpResult res;
  MprgpWorkspace local;
  MprgpWorkspace& w = workspace ? *workspace : local;
  Operator* Z = opt.preconditioner;
  w.phi.resize(n), w.beta.resize(n), w.p.resize(n), w.Ap.resize(n);  // no-ops when reused
  if (Z) w.z.resize(n);
  Vec &phi = w.phi, &beta = w.beta, &p = w.p, &Ap = w.Ap, &z = w.z;
  // z = D_F Z phi: the preconditioned free gradient (phi itself without a preconditioner).
  auto precondition = [&]() -> const Vec& {
    if (!Z) return phi;
    Z->apply(phi, z);
    for (Eigen::Index i = 0; i < n; ++i)
      if (!(x[i] > l[i])) z[i] = 0.0;
    return z;
  };
  TrackedImage* T = opt.image;
  // T x after x -= a v, where A was applied to v last; T x = T v after A was applied to x.
  auto image_step = [&](double a) {
    if (T) T->tx -= a * *T->last;
  };
  auto image_reset = [&]() {
    if (T) T->tx = *T->last;
  };
  if (!gradient_given) {
    x = x.cwiseMax(l);
    A.apply(x, g);
    image_reset();
    g -= b;
  }
  split_gradient(x, g, l, phi, beta);
  p = precondition();
  for (int it = 0;; ++it) {
    res.iterations = it;
    res.projected_gradient = std::sqrt(red.dot(phi, phi) + red.dot(beta, beta));
    if (stop(x, g, res.projected_gradient)) {
      res.reason = StopReason::converged;
      return res;
    }
    if (it >= opt.max_iterations) {
      res.reason = StopReason::max_iterations;
      return res;
    }
    // Proportionality test ||beta||^2 <= Gamma^2 phi~'phi.
    // Ap is free here (both branches below compute it before use): the entries of phi~'phi.
    for (Eigen::Index i = 0; i < n; ++i)
      Ap[i] = phi[i] != 0.0 ? std::min((x[i] - l[i]) / opt.alpha, phi[i]) * phi[i] : 0.0;
    const double beta2 = red.dot(beta, beta);
    const double phi_red_phi = red.sum_entries(Ap);
    if (beta2 <= opt.gamma * opt.gamma * phi_red_phi) {
      A.apply(p, Ap);
      const double pAp = red.dot(p, Ap);
      if (!(pAp > 0)) {
        res.reason = StopReason::breakdown;
        return res;
      }
      const double a_cg = red.dot(g, p) / pAp;
      double a_f = inf;  // largest feasible step along -p
      for (Eigen::Index i = 0; i < n; ++i)
        if (p[i] > 0 && l[i] > -inf) a_f = std::min(a_f, (x[i] - l[i]) / p[i]);
      a_f = red.min(a_f);
      if (a_cg <= a_f) {  // conjugate gradient step
        ++res.cg_steps;
        x -= a_cg * p;
        image_step(a_cg);
        x = x.cwiseMax(l);
        g -= a_cg * Ap;
        split_gradient(x, g, l, phi, beta);
        const Vec& zz = precondition();
        const double gamma_cg = red.dot(zz, Ap) / pAp;
        p = zz - gamma_cg * p;
      } else {  // expansion step: feasible half step, then fixed-length projected gradient step
        ++res.expansion_steps;
        x -= a_f * p;
        x = x.cwiseMax(l);
        g -= a_f * Ap;
        split_gradient(x, g, l, phi, beta);
        x = (x - opt.alpha * phi).cwiseMax(l);
        A.apply(x, g);
        image_reset();
        g -= b;
        split_gradient(x, g, l, phi, beta);
        p = precondition();
      }
    } else {  // proportioning step along the chopped gradient
      ++res.proportioning_steps;
      A.apply(beta, Ap);
      const double dAd = red.dot(beta, Ap);
      if (!(dAd > 0)) {
        res.reason = StopReason::breakdown;
        return res;
      }
      const double a_cg = red.dot(g, beta) / dAd;
      x -= a_cg * beta;
      image_step(a_cg);
      g -= a_cg * Ap;
      split_gradient(x, g, l, phi, beta);
      p = precondition();
    }
  }
}

}  // namespace htfeti::qp
