// MPGP (mpgp.hpp): MPRGP's steps on blocks that are intervals or discs.
#include "htfeti/qp/mpgp.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace htfeti::qp {

namespace {

// A disc block counts as active on its boundary up to the round-off of the projection onto it.
constexpr double kOnCircle = 1e-12;

// The blocks of a SeparableSet as MPGP walks them: disc_of[i] = the disc of entry i, -1 for an
// interval.
class Blocks {
 public:
  Blocks(const SeparableSet& set, std::vector<int>& disc_of)
      : l_(set.lower()),
        u_(set.upper()),
        c_(set.centers()),
        r_(set.radii()),
        discs_(set.discs()),
        disc_of_(disc_of) {
    disc_of_.assign(static_cast<size_t>(l_.size()), -1);
    for (size_t d = 0; d < discs_.size(); ++d)
      disc_of_[discs_[d][0]] = disc_of_[discs_[d][1]] = static_cast<int>(d);
  }
  Eigen::Index size() const { return l_.size(); }
  int disc(Eigen::Index i) const { return disc_of_[i]; }

  // (x - c) of disc d and its length.
  void offset(const Vec& x, size_t d, double& dx, double& dy, double& len) const {
    dx = x[discs_[d][0]] - c_[2 * d], dy = x[discs_[d][1]] - c_[2 * d + 1];
    len = std::hypot(dx, dy);
  }
  bool disc_active(const Vec& x, size_t d) const {
    double dx, dy, len;
    offset(x, d, dx, dy, len);
    const double r = r_[static_cast<Eigen::Index>(d)];
    return r == 0.0 || len >= r * (1 - kOnCircle);
  }
  bool active(const Vec& x, Eigen::Index i) const {
    const int d = disc_of_[i];
    if (d >= 0) return disc_active(x, static_cast<size_t>(d));
    return !(x[i] > l_[i]) || !(x[i] < u_[i]);
  }

  // phi: the free gradient; beta: the chopped gradient (mpgp.hpp).
  void split(const Vec& x, const Vec& g, Vec& phi, Vec& beta) const {
    for (Eigen::Index i = 0; i < size(); ++i) {
      if (disc_of_[i] >= 0) continue;
      const bool at_lower = !(x[i] > l_[i]), at_upper = !(x[i] < u_[i]);
      phi[i] = at_lower || at_upper ? 0.0 : g[i];
      beta[i] = at_lower && at_upper ? 0.0
                : at_lower           ? std::min(g[i], 0.0)
                : at_upper           ? std::max(g[i], 0.0)
                                     : 0.0;
    }
    for (size_t d = 0; d < discs_.size(); ++d) {
      const auto [i, j] = discs_[d];
      double dx, dy, len;
      offset(x, d, dx, dy, len);
      const double r = r_[static_cast<Eigen::Index>(d)];
      if (r == 0.0) {  // a point: nothing can move
        phi[i] = phi[j] = beta[i] = beta[j] = 0.0;
      } else if (len >= r * (1 - kOnCircle)) {
        phi[i] = phi[j] = 0.0;
        const double nx = dx / len, ny = dy / len, gn = g[i] * nx + g[j] * ny;
        beta[i] = gn >= 0 ? g[i] : g[i] - gn * nx;
        beta[j] = gn >= 0 ? g[j] : g[j] - gn * ny;
      } else {
        phi[i] = g[i], phi[j] = g[j];
        beta[i] = beta[j] = 0.0;
      }
    }
  }

  // out_i = phi~_i phi_i, the entries of phi~'phi (mpgp.hpp), for step length alpha.
  void reduced_products(const Vec& x, const Vec& phi, double alpha, Vec& out) const {
    for (Eigen::Index i = 0; i < size(); ++i) {
      if (disc_of_[i] >= 0) continue;
      out[i] = phi[i] == 0.0  ? 0.0
               : phi[i] < 0.0 ? std::max((x[i] - u_[i]) / alpha, phi[i]) * phi[i]
                              : std::min((x[i] - l_[i]) / alpha, phi[i]) * phi[i];
    }
    for (size_t d = 0; d < discs_.size(); ++d) {
      const auto [i, j] = discs_[d];
      double dx, dy, len;
      offset(x, d, dx, dy, len);
      const double r = r_[static_cast<Eigen::Index>(d)];
      // v = x - alpha phi - c projected onto the disc; phi~ = (x - c - P v) / alpha.
      double vx = dx - alpha * phi[i], vy = dy - alpha * phi[j];
      const double lv = std::hypot(vx, vy);
      if (lv > r) vx *= r / lv, vy *= r / lv;
      out[i] = (dx - vx) / alpha * phi[i];
      out[j] = (dy - vy) / alpha * phi[j];
    }
  }

  // The largest t >= 0 with x - t p in the set (this rank's blocks).
  double feasible_step(const Vec& x, const Vec& p) const {
    const double inf = std::numeric_limits<double>::infinity();
    double a = inf;
    for (Eigen::Index i = 0; i < size(); ++i) {
      if (disc_of_[i] >= 0) continue;
      if (p[i] > 0 && l_[i] > -inf) a = std::min(a, (x[i] - l_[i]) / p[i]);
      if (p[i] < 0 && u_[i] < inf) a = std::min(a, (x[i] - u_[i]) / p[i]);
    }
    for (size_t d = 0; d < discs_.size(); ++d) {
      const auto [i, j] = discs_[d];
      const double px = p[i], py = p[j], pp = px * px + py * py;
      if (pp == 0.0) continue;
      double dx, dy, len;
      offset(x, d, dx, dy, len);
      const double r = r_[static_cast<Eigen::Index>(d)];
      // |y - t p| = r: t^2 pp - 2 t y.p + |y|^2 - r^2 = 0, the larger root.
      const double yp = dx * px + dy * py;
      const double disc = std::max(0.0, yp * yp - pp * (len * len - r * r));
      a = std::min(a, std::max(0.0, (yp + std::sqrt(disc)) / pp));
    }
    return a;
  }

 private:
  const Vec &l_, &u_, &c_, &r_;
  const std::vector<SeparableSet::Pair>& discs_;
  std::vector<int>& disc_of_;
};

}  // namespace

void projected_gradient(const Vec& x, const Vec& g, const SeparableSet& set, Vec& gp) {
  std::vector<int> disc_of;
  const Blocks blocks(set, disc_of);
  gp.resize(x.size());
  Vec beta(x.size());
  blocks.split(x, g, gp, beta);
  gp += beta;
}

MprgpResult mpgp(Operator& A, const Vec& b, const SeparableSet& set, Vec& x, Vec& g,
                 const Reducer& red, const MprgpOptions& opt, const MprgpStop& stop,
                 bool gradient_given, MprgpWorkspace* workspace) {
  if (!(opt.alpha > 0)) throw std::invalid_argument("MPGP: the expansion step length must be > 0");
  if (!(opt.gamma > 0)) throw std::invalid_argument("MPGP: Gamma must be > 0");
  const Eigen::Index n = b.size();
  if (set.size() != n) throw std::invalid_argument("MPGP: the set has the wrong size");
  MprgpResult res;
  MprgpWorkspace local;
  MprgpWorkspace& w = workspace ? *workspace : local;
  const Blocks blocks(set, w.disc_of);
  Operator* Z = opt.preconditioner;
  w.phi.resize(n), w.beta.resize(n), w.p.resize(n), w.Ap.resize(n);  // no-ops when reused
  if (Z) w.z.resize(n);
  Vec &phi = w.phi, &beta = w.beta, &p = w.p, &Ap = w.Ap, &z = w.z;
  // z = D_F Z phi: the preconditioned free gradient, zero on the active blocks.
  auto precondition = [&]() -> const Vec& {
    if (!Z) return phi;
    Z->apply(phi, z);
    for (Eigen::Index i = 0; i < n; ++i)
      if (blocks.active(x, i)) z[i] = 0.0;
    return z;
  };
  TrackedImage* T = opt.image;
  auto image_step = [&](double a) {
    if (T) T->tx -= a * *T->last;
  };
  // x changed along no direction A was applied to: A x afresh, and T x with it.
  auto fresh_gradient = [&]() {
    A.apply(x, g);
    if (T) T->tx = *T->last;
    g -= b;
  };
  if (!gradient_given) {
    set.project(x);
    fresh_gradient();
  }
  blocks.split(x, g, phi, beta);
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
    // Proportionality test ||beta||^2 <= Gamma^2 phi~'phi (Ap holds the products for a moment).
    blocks.reduced_products(x, phi, opt.alpha, Ap);
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
      const double a_f = red.min(blocks.feasible_step(x, p));
      if (a_cg <= a_f) {  // conjugate gradient step
        ++res.cg_steps;
        x -= a_cg * p;
        image_step(a_cg);
        set.project(x);  // round-off only
        g -= a_cg * Ap;
        blocks.split(x, g, phi, beta);
        const Vec& zz = precondition();
        const double gamma_cg = red.dot(zz, Ap) / pAp;
        p = zz - gamma_cg * p;
      } else {  // expansion step: feasible half step, then fixed-length projected gradient step
        ++res.expansion_steps;
        x -= a_f * p;
        set.project(x);
        g -= a_f * Ap;
        blocks.split(x, g, phi, beta);
        x -= opt.alpha * phi;
        set.project(x);
        fresh_gradient();
        blocks.split(x, g, phi, beta);
        p = precondition();
      }
    } else {  // gradient projection step (in place of MPRGP's step along beta)
      ++res.proportioning_steps;
      x -= opt.alpha * g;
      set.project(x);
      fresh_gradient();
      blocks.split(x, g, phi, beta);
      p = precondition();
    }
  }
}

}  // namespace htfeti::qp
