#include "htfeti/qp/mprgp.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace htfeti::qp {

Expansion parse_expansion(const std::string& name) {
  return parse_name(kExpansionNames, name, "MPRGP expansion");
}

std::string to_string(Expansion value) { return name_of(kExpansionNames, value); }

namespace {
// Upper bounds given (u.size() == n) or none (empty: +infinity everywhere).
bool has_upper(const Vec& u, Eigen::Index n) {
  if (u.size() != 0 && u.size() != n)
    throw std::invalid_argument("MPRGP: the upper bounds have the wrong size");
  return u.size() == n;
}
// Preconditioned expansion steps that may raise the cost in one MPRGP run (then gradient ones).
constexpr int kMaxCostIncreases = 10;

}  // namespace

void clamp(Vec& x, const Vec& l, const Vec& u) {
  x = x.cwiseMax(l);
  if (u.size() == x.size()) x = x.cwiseMin(u);
}

void split_gradient(const Vec& x, const Vec& g, const Vec& l, const Vec& u, Vec& phi, Vec& beta) {
  const bool upper = u.size() == x.size();
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const bool at_lower = !(x[i] > l[i]), at_upper = upper && !(x[i] < u[i]);
    phi[i] = at_lower || at_upper ? 0.0 : g[i];
    beta[i] = at_lower && at_upper ? 0.0
              : at_lower           ? std::min(g[i], 0.0)
              : at_upper           ? std::max(g[i], 0.0)
                                   : 0.0;
  }
}

void projected_gradient(const Vec& x, const Vec& g, const Vec& lower, Vec& gp, const Vec& upper) {
  has_upper(upper, x.size());
  gp.resize(x.size());
  Vec beta(x.size());
  split_gradient(x, g, lower, upper, gp, beta);
  gp += beta;
}

MprgpResult mprgp(Operator& A, const Vec& b, const Vec& l, const Vec& u, Vec& x, Vec& g,
                  const Reducer& red, const MprgpOptions& opt, const MprgpStop& stop,
                  bool gradient_given, MprgpWorkspace* workspace) {
  if (!(opt.alpha > 0)) throw std::invalid_argument("MPRGP: the expansion step length must be > 0");
  if (!(opt.gamma > 0)) throw std::invalid_argument("MPRGP: Gamma must be > 0");
  const Eigen::Index n = b.size();
  const double inf = std::numeric_limits<double>::infinity();
  const bool upper = has_upper(u, n);  // this rank's entries have upper bounds
  // Some rank's entries have (a rank may own no entries): the collective step below needs it.
  const bool any_upper = red.max(upper ? 1.0 : 0.0) > 0;
  MprgpResult res;
  MprgpWorkspace local;
  MprgpWorkspace& w = workspace ? *workspace : local;
  Operator* Z = opt.preconditioner;
  w.phi.resize(n), w.beta.resize(n), w.p.resize(n), w.Ap.resize(n);  // no-ops when reused
  if (Z) w.z.resize(n);
  Vec &phi = w.phi, &beta = w.beta, &p = w.p, &Ap = w.Ap, &z = w.z;
  int cost_increases = 0;  // preconditioned expansion steps that raised the cost in this run
  // z = D_F Z phi: the preconditioned free gradient (phi itself without a preconditioner).
  auto precondition = [&]() -> const Vec& {
    if (!Z) return phi;
    Z->apply(phi, z);
    for (Eigen::Index i = 0; i < n; ++i)
      if (!(x[i] > l[i]) || (upper && !(x[i] < u[i]))) z[i] = 0.0;
    return z;
  };
  // x'g - x'b (twice the cost f = 1/2 x'(g - b)) in one reduction, each dot as red.dot forms it.
  auto cost_terms = [&red](const Vec& xv, const Vec& gv, const Vec& bv) {
    const Vec* ca[2] = {&xv, &xv};
    const Vec* cb[2] = {&gv, &bv};
    double d[2];
    red.dots(2, ca, cb, d);
    return d[0] - d[1];
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
    clamp(x, l, u);
    A.apply(x, g);
    image_reset();
    g -= b;
  }
  split_gradient(x, g, l, u, phi, beta);
  p = precondition();
  for (int it = 0;; ++it) {
    res.iterations = it;
    // For the proportionality test ||beta||^2 <= Gamma^2 phi~'phi below: Ap is free here (both
    // branches compute it before use) and takes the entries of phi~'phi.
    // phi~_i = min((x_i - l_i) / alpha, phi_i) for phi_i > 0, max((x_i - u_i) / alpha, phi_i)
    // for phi_i < 0 (the lower-bound form alone when there are no upper bounds).
    for (Eigen::Index i = 0; i < n; ++i)
      Ap[i] = phi[i] == 0.0           ? 0.0
              : upper && phi[i] < 0.0 ? std::max((x[i] - u[i]) / opt.alpha, phi[i]) * phi[i]
                                      : std::min((x[i] - l[i]) / opt.alpha, phi[i]) * phi[i];
    // One reduction: phi'phi, beta'beta, phi~'phi and, with a tracked image, ||T x||^2 for the
    // caller's stopping test (TrackedImage::norm).
    const Vec* ta[4] = {&phi, &beta, &Ap, T ? &T->tx : nullptr};
    const Vec* tb[4] = {&phi, &beta, nullptr, T ? &T->tx : nullptr};
    double sums[4];
    red.dots(T ? 4 : 3, ta, tb, sums);
    if (T) T->norm = std::sqrt(sums[3]);
    res.projected_gradient = std::sqrt(sums[0] + sums[1]);
    const bool converged = stop(x, g, res.projected_gradient);
    if (T) T->norm = -1.0;  // valid inside stop() only
    if (converged) {
      res.reason = StopReason::converged;
      return res;
    }
    if (it >= opt.max_iterations) {
      res.reason = StopReason::max_iterations;
      return res;
    }
    const double beta2 = sums[1];
    const double phi_red_phi = sums[2];
    if (beta2 <= opt.gamma * opt.gamma * phi_red_phi) {
      A.apply(p, Ap);
      const Vec* ca[2] = {&p, &g};
      const Vec* cb[2] = {&Ap, &p};
      double pair[2];  // p'Ap, g'p
      red.dots(2, ca, cb, pair);
      const double pAp = pair[0], g_p = pair[1];
      if (!(pAp > 0)) {
        res.reason = StopReason::breakdown;
        return res;
      }
      const double a_cg = g_p / pAp;
      double a_f = inf;  // largest feasible step along -p
      for (Eigen::Index i = 0; i < n; ++i) {
        if (p[i] > 0 && l[i] > -inf) a_f = std::min(a_f, (x[i] - l[i]) / p[i]);
        if (upper && p[i] < 0 && u[i] < inf) a_f = std::min(a_f, (x[i] - u[i]) / p[i]);
      }
      a_f = red.min(a_f);
      if (a_cg <= a_f) {  // conjugate gradient step
        ++res.cg_steps;
        x -= a_cg * p;
        image_step(a_cg);
        clamp(x, l, u);
        g -= a_cg * Ap;
        split_gradient(x, g, l, u, phi, beta);
        const Vec& zz = precondition();
        const double gamma_cg = red.dot(zz, Ap) / pAp;
        p = zz - gamma_cg * p;
      } else {  // expansion step: feasible half step, then fixed-length projected gradient step
        ++res.expansion_steps;
        // automatic: the projected CG step where it moves x at least kAutoCgStepRatio times as
        // far as the fixed-length step would (a_cg ||p|| against alpha ||phi||).
        bool try_cg = opt.expansion == Expansion::projected_cg;
        if (opt.expansion == Expansion::automatic) {
          const Vec* ea[2] = {&p, &phi};
          double lengths[2];  // p'p, phi'phi
          red.dots(2, ea, ea, lengths);
          try_cg =
              a_cg * std::sqrt(lengths[0]) >= kAutoCgStepRatio * opt.alpha * std::sqrt(lengths[1]);
        }
        if (try_cg) {
          ++res.projected_cg_expansions;
          // The whole CG step, projected onto the bounds: kept when its cost is below that of
          // the feasible half step x - a_f p (known without a product), else undone, and the
          // fixed-length step below is taken from the half step (its product resets T x).
          const double f_half = 0.5 * cost_terms(x, g, b) - a_f * g_p + 0.5 * a_f * a_f * pAp;
          w.x_old = x;
          w.g_old = g;
          x -= a_cg * p;
          clamp(x, l, u);
          A.apply(x, g);
          image_reset();
          g -= b;
          if (0.5 * cost_terms(x, g, b) < f_half) {
            split_gradient(x, g, l, u, phi, beta);
            p = precondition();
            continue;
          }
          ++res.expansion_cost_increases;
          x = w.x_old;
          g = w.g_old;
        }
        x -= a_f * p;
        clamp(x, l, u);
        g -= a_f * Ap;
        split_gradient(x, g, l, u, phi, beta);
        bool done = false;
        if (opt.expansion == Expansion::preconditioned && cost_increases < kMaxCostIncreases) {
          // Along d = D_F Z phi with the length that minimizes the cost along d. The projected
          // step may raise the cost f = 1/2 x'(g - b); it is kept all the same (it finds the
          // active set faster), but after kMaxCostIncreases such steps in this run the
          // remaining expansion steps are the fixed-length gradient steps of the theory, so
          // the run ends as MPRGP does.
          const double f_before = 0.5 * cost_terms(x, g, b);
          const Vec& d = precondition();
          A.apply(d, Ap);
          const double dAd = red.dot(d, Ap);
          if (dAd > 0) {
            x -= (red.dot(phi, d) / dAd) * d;
            clamp(x, l, u);
            A.apply(x, g);
            image_reset();
            g -= b;
            done = true;
            if (!(0.5 * cost_terms(x, g, b) < f_before)) {
              ++cost_increases;
              ++res.expansion_cost_increases;
            }
          }
        }
        if (!done) {
          x -= opt.alpha * phi;
          clamp(x, l, u);
          A.apply(x, g);
          image_reset();
          g -= b;
        }
        split_gradient(x, g, l, u, phi, beta);
        p = precondition();
      }
    } else {  // proportioning step along the chopped gradient
      ++res.proportioning_steps;
      A.apply(beta, Ap);
      const Vec* pa[2] = {&beta, &g};
      const Vec* pb[2] = {&Ap, &beta};
      double pair[2];  // beta'A beta, g'beta
      red.dots(2, pa, pb, pair);
      const double dAd = pair[0];
      if (!(dAd > 0)) {
        res.reason = StopReason::breakdown;
        return res;
      }
      double a_cg = pair[1] / dAd;
      if (any_upper) {
        // With both bounds the line search along -beta can carry a component from one bound past
        // the other: the step stops at the first bound it reaches (a descent step still).
        double a_f = inf;
        for (Eigen::Index i = 0; i < n; ++i) {
          if (beta[i] > 0 && l[i] > -inf) a_f = std::min(a_f, (x[i] - l[i]) / beta[i]);
          if (upper && beta[i] < 0 && u[i] < inf) a_f = std::min(a_f, (x[i] - u[i]) / beta[i]);
        }
        a_cg = std::min(a_cg, red.min(a_f));
      }
      x -= a_cg * beta;
      if (upper) clamp(x, l, u);  // round-off of the shortened step
      image_step(a_cg);
      g -= a_cg * Ap;
      split_gradient(x, g, l, u, phi, beta);
      p = precondition();
    }
  }
}

}  // namespace htfeti::qp
