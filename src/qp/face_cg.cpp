#include "htfeti/qp/face_cg.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "htfeti/clock.hpp"
#include "htfeti/qp/mprgp.hpp"

namespace htfeti::qp {

FaceResult face_cg(Operator& H, const Vec& b, const Vec& l, const Vec& u, Vec& x, Vec& g, Vec& nu,
                   const FaceHooks& face, Operator* Z, const Reducer& red, double tol, double gamma,
                   int max_iterations, FaceWorkspace& w, int max_changes, const FaceGoOn& go_on) {
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
  int steps = 0;  // products with H
  int last_steps = 0;
  int short_hits = 0;
  int go_on_until = -1;  // going on to a smaller tol (FaceGoOn): the step limit; -1: not
  double go_free = 0, go_held = 0;
  bool renew_budget = false;  // a change of the face while going on: CG starts over
  // The step limit going on from here to tol: CG's bound for the reduction asked, with the
  // spectrum seen on every face of this solve, plus kGoOnExtraSteps.
  const auto go_on_budget = [&](double factor) {
    SpectrumEstimate seen = res.spectrum;
    seen.merge(w.lanczos.estimate());
    return steps + kGoOnExtraSteps + cg_steps_for(seen, factor);
  };
  // A new face (d changed): set, the gradient's projection, CG restarted. False when G D G' is
  // singular: the solve ends (the last face's factor is gone, nu is that of the last face).
  const auto restart = [&]() {
    res.spectrum.merge(w.lanczos.estimate());
    const double ts = seconds_now();
    const bool ok = face.set(d);
    res.set_seconds += seconds_now() - ts;
    if (!ok) return false;
    ++res.changes;
    last_steps = steps;
    renew_budget = go_on_until >= 0;
    project(g, r, nu);
    precondition();
    p = z;
    rz = red.dot(r, z);
    w.lanczos.start(max_iterations);
    return true;
  };
  // x -= a p on the free rows; the rows whose bound the step reaches first (a = a_f, the
  // largest feasible step) are put onto it and held.
  const auto step_to_bound = [&](double a) {
    for (Eigen::Index i = 0; i < n; ++i) {
      if (d[i] == 0.0) continue;
      const bool lo = p[i] > 0 && l[i] > -inf && (x[i] - l[i]) / p[i] <= a;
      const bool hi = upper && p[i] < 0 && u[i] < inf && (x[i] - u[i]) / p[i] <= a;
      x[i] -= a * p[i];
      if (lo) x[i] = l[i], d[i] = 0.0;
      if (hi) x[i] = u[i], d[i] = 0.0;
      x[i] = std::max(x[i], l[i]);
      if (upper) x[i] = std::min(x[i], u[i]);
    }
  };
  for (;;) {
    if (!proportional()) {
      // Free the held rows with a chopped gradient (those MPRGP's proportioning step moves).
      if (res.changes < max_changes) {
        for (Eigen::Index i = 0; i < n; ++i)
          if (w.beta[i] != 0.0) d[i] = 1.0;
        if (restart()) continue;
      }
      res.outcome = FaceOutcome::release;
      break;
    }
    if (res.free_gradient <= tol) {
      const double next = go_on ? go_on(x, std::hypot(res.free_gradient, res.held_gradient)) : 0.0;
      if (!(next > 0 && next < tol) || res.free_gradient <= next) {
        res.outcome = FaceOutcome::converged;
        break;
      }
      w.go_x = x, w.go_g = g, w.go_nu = nu;
      go_free = res.free_gradient, go_held = res.held_gradient;
      go_on_until = go_on_budget(next / tol);
      tol = next;
      ++res.go_ons;
    }
    if (renew_budget) {  // CG started over on a new face: the bound's steps from here
      go_on_until = std::max(go_on_until, go_on_budget(tol / res.free_gradient));
      renew_budget = false;
    }
    if (steps >= max_iterations || (go_on_until >= 0 && steps >= go_on_until)) {
      res.outcome = FaceOutcome::max_iterations;
      break;
    }
    double a_f = inf;  // the largest step along -p that stays inside the bounds
    for (Eigen::Index i = 0; i < n; ++i) {
      if (d[i] == 0.0) continue;
      if (p[i] > 0 && l[i] > -inf) a_f = std::min(a_f, (x[i] - l[i]) / p[i]);
      if (upper && p[i] < 0 && u[i] < inf) a_f = std::min(a_f, (x[i] - u[i]) / p[i]);
    }
    a_f = red.min(a_f);
    if (!(a_f > 0)) {  // a row freed on its bound that -p would move out of the bounds
      if (res.changes < max_changes) {
        step_to_bound(0.0);
        if (restart()) continue;
      }
      res.outcome = FaceOutcome::bound;
      break;
    }
    H.apply(p, Hp);
    ++steps;
    const double pHp = red.dot(p, Hp);
    if (!(pHp > 0)) {
      res.outcome = FaceOutcome::breakdown;
      break;
    }
    const double a = rz / pHp;
    if (a > a_f) {
      // The feasible half step: the cost falls (a_f < a, the minimizer along p), G x = 0 holds.
      short_hits = steps - last_steps > 1 ? 0 : short_hits + 1;
      if (res.changes < max_changes && short_hits <= kMaxShortBounds) {
        step_to_bound(a_f);
        g -= a_f * Hp;
        if (restart()) continue;
        // (x moved: the outcome bound keeps it; nu is the last face's)
      }
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
  // Going on that ends short of its tol (a bound, a release, the step limit, a breakdown):
  // back to the point where it went on, which met the tol before.
  if (go_on_until >= 0 && res.outcome != FaceOutcome::converged) {
    x = w.go_x, g = w.go_g, nu = w.go_nu;
    res.free_gradient = go_free, res.held_gradient = go_held;
    res.go_on_failed = true;
    res.outcome = FaceOutcome::converged;
  }
  res.iterations = steps;
  nu = -nu;  // the face's equality multiplier G' mu: D (g + nu) = P_F D g
  res.spectrum.merge(w.lanczos.estimate());
  return res;
}

}  // namespace htfeti::qp
