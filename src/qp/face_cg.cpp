#include "htfeti/qp/face_cg.hpp"

#include <cmath>
#include <limits>

#include "htfeti/clock.hpp"
#include "htfeti/qp/mprgp.hpp"

namespace htfeti::qp {

FaceResult face_cg(Operator& H, const Vec& b, const Vec& l, const Vec& u, Vec& x, Vec& g, Vec& nu,
                   const FaceHooks& face, Operator* Z, const Reducer& red, double tol, double gamma,
                   int max_iterations, FaceWorkspace& w) {
  const Eigen::Index n = b.size();
  const bool upper = u.size() == n;
  const double inf = std::numeric_limits<double>::infinity();
  FaceResult res;
  for (Vec* v : {&w.free, &w.c, &w.t, &w.w, &w.z, &w.p, &w.Hp, &w.phi, &w.beta}) v->resize(n);
  Vec &d = w.free, &c = w.c, &t = w.t, &r = w.w, &z = w.z, &p = w.p, &Hp = w.Hp;
  // nu holds G'(G D G')^{-1} G D g from the last projection of g (the multiplier is -nu).
  nu.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) d[i] = x[i] > l[i] && !(upper && !(x[i] < u[i])) ? 1.0 : 0.0;
  // out = P_F D v = D (v - corr), corr = G'(G D G')^{-1} G D v.
  const auto project = [&](const Vec& v, Vec& out, Vec& corr) {
    t = d.cwiseProduct(v);
    face.correction(t, corr);
    out = t - d.cwiseProduct(corr);
  };
  const auto precondition = [&]() {
    if (!Z) {
      z = r;
      return;
    }
    Z->apply(r, z);
    project(z, z, c);
  };
  // The held rows' share of the projected gradient of g - nu: the chopped gradient of MPRGP
  // (zero on the free rows).
  const auto held_gradient = [&]() {
    t = g - nu;
    split_gradient(x, t, l, u, w.phi, w.beta);
    return red.norm(w.beta);
  };
  const auto proportional = [&]() {
    res.free_gradient = red.norm(r);
    res.held_gradient = held_gradient();
    return res.held_gradient <= gamma * res.free_gradient;
  };
  const double t0 = seconds_now();
  const bool regular = face.set(d);
  res.set_seconds = seconds_now() - t0;
  if (!regular) return res;  // singular
  // The proportionality test at the given x and g (no product): a held row is to be freed
  // already, and the face solve is not taken.
  project(g, r, nu);
  if (!proportional()) {
    res.outcome = FaceOutcome::declined;
    return res;
  }
  // Step 1: onto G x = 0 by the free entries alone.
  face.correction(x, c);
  t = x - d.cwiseProduct(c);
  double inside = 1.0;
  for (Eigen::Index i = 0; i < n; ++i)
    if (d[i] != 0.0 && (t[i] < l[i] || (upper && t[i] > u[i]))) inside = 0.0;
  if (red.min(inside) == 0.0) {
    res.outcome = FaceOutcome::infeasible;
    return res;
  }
  x = t;
  H.apply(x, g);
  g -= b;
  project(g, r, nu);
  precondition();
  p = z;
  double rz = red.dot(r, z);
  w.lanczos.start(max_iterations);
  for (int it = 0;; ++it) {
    res.iterations = it;
    if (!proportional()) {
      res.outcome = FaceOutcome::release;
      break;
    }
    if (res.free_gradient <= tol) {
      res.outcome = FaceOutcome::converged;
      break;
    }
    if (it >= max_iterations) {
      res.outcome = FaceOutcome::max_iterations;
      break;
    }
    H.apply(p, Hp);
    const double pHp = red.dot(p, Hp);
    if (!(pHp > 0)) {
      res.outcome = FaceOutcome::breakdown;
      break;
    }
    const double a = rz / pHp;
    double a_f = inf;  // the largest step along -p that stays inside the bounds
    for (Eigen::Index i = 0; i < n; ++i) {
      if (d[i] == 0.0) continue;
      if (p[i] > 0 && l[i] > -inf) a_f = std::min(a_f, (x[i] - l[i]) / p[i]);
      if (upper && p[i] < 0 && u[i] < inf) a_f = std::min(a_f, (x[i] - u[i]) / p[i]);
    }
    if (a > red.min(a_f)) {
      res.outcome = FaceOutcome::bound;
      break;
    }
    w.lanczos.step(a);
    x -= a * p;
    g -= a * Hp;
    project(g, r, nu);
    precondition();
    const double rz_new = red.dot(r, z);
    w.lanczos.direction(rz_new / rz);
    p = z + (rz_new / rz) * p;
    rz = rz_new;
  }
  nu = -nu;  // the face's equality multiplier G' mu: D (g + nu) = P_F D g
  res.spectrum = w.lanczos.estimate();
  return res;
}

}  // namespace htfeti::qp
