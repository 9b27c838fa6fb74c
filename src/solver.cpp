#include "htfeti/solver.hpp"

#include <omp.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <thread>

#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/feti/dual_reducer.hpp"
#include "htfeti/feti/operator_cost.hpp"
#include "htfeti/memory_estimate.hpp"
#include "htfeti/options.hpp"
#include "htfeti/parallel/blas_buffers.hpp"
#include "htfeti/parallel/memory.hpp"
#include "htfeti/qp/pcg.hpp"
#include "htfeti/qp/power_norm.hpp"
#include "htfeti/qp/qp.hpp"
#include "solve_parts.hpp"

namespace htfeti {

namespace {

using Vec = Eigen::VectorXd;
using namespace solve_parts;

// Throws NonFiniteError on every rank when some entry of v on some rank is not finite.
void require_finite(const Comm& comm, bool finite, const std::string& what) {
  if (comm.min(finite ? 1.0 : 0.0) < 1)
    throw NonFiniteError(what +
                         " is not finite (an overflow): check the magnitudes of the "
                         "loads, gaps and material values");
}

// f_j *= 1 + delta r_j, r_j in [-1, 1] from the dof's global node and component (SplitMix64),
// so that every copy of a node gets the same factor on any rank (SolveOptions::perturb_load).
void perturb_load(SubdomainInput& in, double delta) {
  const int dpn = in.system.dofs_per_node;
  for (int k = 0; k < in.sharing.num_nodes(); ++k)
    for (int c = 0; c < dpn; ++c) {
      std::uint64_t z =
          static_cast<std::uint64_t>(in.sharing.global_node[k]) * 3 + c + 0x9E3779B97F4A7C15ULL;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
      z ^= z >> 31;
      const double r = static_cast<double>(z >> 11) * 0x1.0p-52 - 1.0;  // [-1, 1)
      in.system.f[k * dpn + c] *= 1.0 + delta * r;
    }
}

// The accuracy refinement (solve_parts.hpp). The gluing residual of lambda is checked, and while
// it is too large (the first time above kRefineRatio, then until kRefineTarget) the solve goes on
// with rtol made smaller in proportion (the gluing residual falls about as the dual residual
// does: half of what brings it to kRefineTarget, between 1/1000 and 1/4 of the last rtol).
// The first check may come inside the solve (qp::Tighten: in_solve), at the first point that
// passes its test, where PCG and SMALBE-M's face solve go on without starting over; the
// others come after a converged solve (after), whose `again` solves on from where the last
// solve stopped, updating lambda and converged. steps() is the report's
// solver.accuracy_refinements (one entry per check).
class AccuracyRefinement {
 public:
  AccuracyRefinement(const AccuracyCheck& check, const StageNote& note)
      : check_(check), note_(note) {}

  // qp::Tighten for the first check: lambda passes its solve's test with rtol. The next rtol,
  // or rtol where the gluing residual is at most kRefineRatio rtol. Once per run: later calls
  // return rtol at once (no check).
  double in_solve(const Vec& lambda, double rtol) {
    if (!steps_.empty()) return rtol;
    const double t = seconds_now();
    const double ratio = check_(lambda);
    steps_.push_back({{"rtol", rtol},
                      {"gluing_residual_over_rtol", ratio},
                      {"within_the_solve", true},
                      {"seconds", seconds_now() - t}});
    if (!(ratio > kRefineRatio)) return rtol;
    const double next = rtol * factor(ratio);
    ++done_;
    note(ratio, kRefineRatio, next, "the solve goes on");
    return next;
  }

  // After a converged solve whose rtol is `rtol` (the one it met; in_solve's where it went on).
  void after(const Vec& lambda, double& rtol, const bool& converged,
             const std::function<void()>& again) {
    while (converged) {
      const double t = seconds_now();
      const double ratio = check_(lambda);  // in units of the asked rtol
      steps_.push_back(
          {{"rtol", rtol}, {"gluing_residual_over_rtol", ratio}, {"seconds", seconds_now() - t}});
      const double limit = done_ == 0 ? kRefineRatio : kRefineTarget;
      if (!(ratio > limit) || done_ >= kMaxRefinements) break;
      rtol *= factor(ratio);
      ++done_;
      note(ratio, limit, rtol, "on");
      again();
    }
  }

  const nlohmann::json& steps() const { return steps_; }
  bool refined() const { return done_ > 0; }
  // The report's solver.accuracy_checks: the checks made and their seconds (a check of the
  // lambda and factors of the last one is not made again and takes no time).
  nlohmann::json summary() const {
    double seconds = 0;
    for (const auto& s : steps_) seconds += s["seconds"].get<double>();
    return {{"checks", steps_.size()},
            {"seconds", seconds},
            {"within_the_solve", !steps_.empty() && steps_[0].contains("within_the_solve")}};
  }

 private:
  static double factor(double ratio) { return std::clamp(0.5 * kRefineTarget / ratio, 1e-3, 0.25); }
  void note(double ratio, double limit, double next, const char* how) const {
    char line[200];
    std::snprintf(line, sizeof line,
                  "accuracy refinement %d: gluing residual %.3g rtol (above %g); %s to rtol %.3g",
                  done_, ratio, limit, how, next);
    note_(line);
  }
  const AccuracyCheck& check_;
  const StageNote& note_;
  nlohmann::json steps_ = nlohmann::json::array();
  int done_ = 0;  // refinements begun
};

// The report's form of a CG run's estimate of its operator's extreme eigenvalues
// (qp/cg_spectrum.hpp): null when no CG step was taken.
nlohmann::json spectrum_json(const qp::SpectrumEstimate& s) {
  if (s.empty()) return nullptr;
  return {{"min", s.min}, {"max", s.max}, {"ratio", s.ratio()}, {"cg_steps", s.steps}};
}

constexpr const char* kGoOnFailedNote =
    "accuracy refinement: the solve did not meet the smaller rtol where it went on; on from the "
    "point where it did";
constexpr const char* kSingleCheckNote =
    "check: converged with the factors' single-precision copies; on with the factors (double)";

// The dual problem without contact (the paper's (11) with equalities only): projected CG from
// lambda~, preconditioned by P M^{-1} P when a preconditioner was built.
QpSolve solve_without_contact(DualProblem& dual, DualOperators& ops, Vec& lambda,
                              const SolveOptions& options, const qp::Reducer& red,
                              const qp::Progress& progress, const AccuracyCheck& check,
                              const StageNote& note) {
  const int n = dual.n_owned();
  qp::QuadraticProgram qp;
  qp.hessian = qp::borrow(ops.F);
  qp.linear = dual.d();
  qp.equality_projector = qp::borrow(ops.P);
  qp::PcgOptions po;
  po.rtol = options.rtol;
  po.max_iterations = options.max_iterations > 0 ? options.max_iterations : 1000;
  // PCG applies Z only to projected residuals w = P w, so Z = P M^{-1} is P M^{-1} P there.
  // With the weighted projector Z = P_Q M^{-1} P_Q^T: P_Q^T P = P_Q^T, so on projected residuals
  // it is the preconditioner of Rixen and Farhat's FETI with Q, and it maps into Ker G~ as P
  // does; the iterates and the stopping test stay those of the orthogonal P.
  const bool stiffness = ops.preconditioned && dual.scaling() == Scaling::stiffness;
  if (options.pcg_projector == PcgProjector::weighted && !stiffness)
    throw std::invalid_argument(
        "solver.pcg_projector = weighted needs a preconditioner with stiffness scaling");
  const bool weighted = stiffness &&
                        (options.pcg_projector == PcgProjector::weighted ||
                         (options.pcg_projector == PcgProjector::automatic &&
                          dual.coefficient_spread() <= kWeightedProjectorSpread &&
                          dual.coefficient_range() > kWeightedProjectorSpread)) &&
                        dual.set_weighted_projector();
  Vec pz(ops.preconditioned ? n : 0), qx(weighted ? n : 0);
  long weighted_projections = 0;
  double weighted_seconds = 0;
  qp::FunctionOperator Z([&](const Vec& x, Vec& y) {
    if (weighted) {
      double t = seconds_now();
      dual.project_weighted(x, qx, true);
      weighted_seconds += seconds_now() - t;
      ops.M.apply(qx, pz);
      t = seconds_now();
      dual.project_weighted(pz, y, false);
      weighted_seconds += seconds_now() - t;
      weighted_projections += 2;
      return;
    }
    ops.M.apply(x, pz);
    ops.P.apply(pz, y);
  });
  // The first accuracy check comes where PCG first meets its test, which goes on from there
  // when the check asks for a smaller rtol (AccuracyRefinement::in_solve); not with the
  // factors' single-precision copies, where that check's reconstruction would be one more than
  // the solution's (about one product) and linear solves rarely need a refinement.
  AccuracyRefinement refinement(check, note);
  if (!dual.single_sweeps())
    po.tighten = [&](const Vec& x, double rtol) { return refinement.in_solve(x, rtol); };
  lambda = dual.lambda_tilde();
  auto r = qp::projected_cg(qp, lambda, red, po, progress, ops.preconditioned ? &Z : nullptr);
  po.tighten = nullptr;
  po.rtol = r.rtol;  // the rtol it met
  if (r.go_on_failed) note(kGoOnFailedNote);
  qp::SpectrumEstimate spectrum = r.spectrum;  // merged over the runs below
  QpSolve out;
  out.outer = r.iterations;
  out.converged = r.reason == qp::StopReason::converged;
  // Single-precision sweeps: PCG converged for the operator of the factors' copies; from here on
  // F is the factors' own, and PCG goes on from lambda with the same rtol (one product when
  // lambda already passes its test).
  nlohmann::json single_check = nullptr;
  if (dual.single_sweeps()) {
    dual.set_single_sweeps(false);
    if (out.converged) {
      note(kSingleCheckNote);
      const long before = ops.F.count();
      r = qp::projected_cg(qp, lambda, red, po, progress, ops.preconditioned ? &Z : nullptr);
      spectrum.merge(r.spectrum);
      out.outer += r.iterations;
      out.converged = r.reason == qp::StopReason::converged;
      single_check = {{"check_products", ops.F.count() - before},
                      {"check_iterations", r.iterations}};
    }
  }
  // The accuracy refinement after the solve: PCG again from lambda (in lambda~ + Ker G~) with a
  // smaller rtol.
  refinement.after(lambda, po.rtol, out.converged, [&]() {
    r = qp::projected_cg(qp, lambda, red, po, progress, ops.preconditioned ? &Z : nullptr);
    spectrum.merge(r.spectrum);
    out.outer += r.iterations;
    out.converged = r.reason == qp::StopReason::converged;
  });
  out.matvecs = ops.F.count();
  out.reason = to_string(r.reason);
  out.solver = {{"algorithm", "pcg"},
                {"projected_residual", r.projected_residual},
                {"projected_rhs", r.projected_rhs},
                {"pcg_projector", weighted ? "weighted" : "orthogonal"},
                {"coefficient_spread", dual.coefficient_spread()},
                {"coefficient_range", dual.coefficient_range()}};
  if (weighted)
    out.solver["weighted_projections"] = weighted_projections,
    out.solver["weighted_projection_seconds"] = weighted_seconds;
  out.solver["spectrum_estimate"] = spectrum_json(spectrum);
  if (!single_check.is_null()) out.solver["single_sweeps"] = single_check;
  out.solver["accuracy_checks"] = refinement.summary();
  if (refinement.refined()) out.solver["accuracy_refinements"] = refinement.steps();
  return out;
}

// The contact problem (the paper's (11)): the dual QP min 1/2 l'F l - d'l, l_I >= 0, G~ l = e~,
// homogenized by lambda~ ((12)) and put on Ker G~ by the projector ((15)), then SMALBE-M with
// MPRGP inside. With one coarse step per product (merged) the Hessian P F P and H_rho are
// formed from F v and the coarse image (DualProblem::hessian_from_Fv).
QpSolve solve_with_contact(DualProblem& dual, DualOperators& ops, Vec& lambda,
                           const SolveOptions& options, const qp::Reducer& red,
                           const qp::Progress& progress, bool merged, const AccuracyCheck& check,
                           const StageNote& note) {
  const int n = dual.n_owned();
  qp::QuadraticProgram dual_qp;
  dual_qp.hessian = qp::borrow(ops.F);
  dual_qp.linear = dual.d();
  // Bounds: lambda_I >= 0 on contact rows; with Tresca friction also -g <= lambda_T <= g on the
  // tangential rows (a box: the same MPRGP).
  dual_qp.constraints = dual.constraint_set();
  dual_qp.equality_projector = qp::borrow(ops.P);
  // lambda = lambda~ + x: b = P(d - F lambda~), x_I >= -lambda~_I, A = P F P.
  // b is formed once, so with the factors themselves (single sweeps would leave their
  // perturbation in the QP that the check below solves).
  const bool single = dual.single_sweeps();
  if (single) dual.set_single_sweeps(false);
  qp::QuadraticProgram qp = qp::enforce_by_projector(qp::homogenize(dual_qp, dual.lambda_tilde()));
  if (single) dual.set_single_sweeps(true);
  Vec fv(merged ? n : 0), qtmp(merged ? n : 0);
  auto coarse_step = [&](const Vec& v, double rho, Vec& y, Vec& qv) {
    ops.F.apply(v, fv);
    const double t = seconds_now();
    dual.hessian_from_Fv(v, fv, rho, y, qv);
    ops.merged_seconds += seconds_now() - t;
    ++ops.merged_steps;
  };
  if (merged)  // P F P in one coarse step
    qp.hessian = std::make_shared<qp::FunctionOperator>(
        [&](const Vec& x, Vec& y) { coarse_step(x, 0.0, y, qtmp); });
  Vec start(n);
  for (int i = 0; i < n; ++i)  // depends on global indices only, not on the rank count
    start[i] = 1.0 + 0.5 * std::sin(0.7 * static_cast<double>(dual.global_index(i)) + 0.3);
  ops.P.apply(start, start);
  const double normA = options.norm_estimate == qp::NormEstimate::lanczos
                           ? qp::estimate_norm_lanczos(*qp.hessian, start, red)
                           : qp::estimate_norm(*qp.hessian, start, red);
  const long norm_matvecs = qp.hessian->count();
  qp::SmalbeOptions so = options.smalbe;
  so.rtol = options.rtol;
  if (options.max_iterations > 0) so.max_outer = options.max_iterations;
  Vec px(n), pw(ops.preconditioned ? n : 0), pz(ops.preconditioned ? n : 0);
  qp::SmalbeHooks hooks;
  // PFP v + rho (v - P v), and Q v = v - P v: one projection of v serves all three.
  hooks.fused_hessian = [&](const Vec& v, double rho, Vec& y, Vec& qv) {
    if (merged) return coarse_step(v, rho, y, qv);
    ops.P.apply(v, px);
    ops.F.apply(px, y);
    ops.P.apply(y, y);
    qv = v - px;
    y += rho * qv;
  };
  // In face: Z_rho = P M^{-1} P + Q / rho, exact on Im Q where H_rho = rho I.
  if (ops.preconditioned)
    hooks.preconditioner = [&](const Vec& v, double rho, Vec& y) {
      ops.P.apply(v, pw);
      ops.M.apply(pw, pz);
      ops.P.apply(pz, y);
      y += (v - pw) / rho;
    };
  // The face solve: the coarse matrix of the free rows (CoarseSpace::set_face).
  hooks.face.set = [&](const Vec& free) { return dual.set_face(free); };
  hooks.face.correction = [&](const Vec& v, Vec& y) { dual.face_correction(v, y); };
  hooks.face.cheap = [&]() { return dual.face_cheap(); };
  // The first accuracy check comes where a face solve first ends the solve, which goes on from
  // there when the check asks for a smaller rtol (AccuracyRefinement::in_solve). Not with
  // Coulomb friction, whose refinement comes after the fixed point.
  AccuracyRefinement refinement(check, note);
  Vec lam_check(dual.has_coulomb() ? 0 : n);
  if (!dual.has_coulomb())
    hooks.tighten = [&](const Vec& x, double rtol) {
      lam_check = qp.shift + x;
      return refinement.in_solve(lam_check, rtol);
    };
  Vec x = Vec::Zero(n);
  Vec nu;  // the equality's multiplier: each Coulomb solve starts from the last one's
  auto r = qp::smalbe(qp, normA, x, red, so, hooks, progress, &nu);
  hooks.tighten = nullptr;
  so.rtol = r.rtol;  // the rtol it met
  if (r.go_ons_failed > 0) note(kGoOnFailedNote);
  lambda = qp.shift + x;
  // The report's solver.outer_log: every outer iteration of every SMALBE-M call of the run
  // (the first, the Coulomb fixed point's, the single-precision check, the refinements), with
  // the products counted from the first call's start.
  nlohmann::json outer_log = nlohmann::json::array();
  int calls = 0;
  const auto log_outer = [&](const qp::SmalbeResult& res, long products_before) {
    ++calls;
    for (std::size_t i = 0; i < res.outer_log.size(); ++i) {
      const qp::SmalbeOuterRecord& o = res.outer_log[i];
      outer_log.push_back({{"solve", calls},
                           {"outer", static_cast<int>(i) + 1},
                           {"inner_iterations", o.inner_iterations},
                           {"cg_steps", o.cg_steps},
                           {"expansion_steps", o.expansion_steps},
                           {"proportioning_steps", o.proportioning_steps},
                           {"products", products_before + o.products},
                           {"projected_gradient", o.projected_gradient},
                           {"equality", o.equality},
                           {"M", o.M},
                           {"rho", o.rho}});
    }
  };
  log_outer(r, 0);
  QpSolve out;
  out.outer = r.outer_iterations;
  out.inner = r.inner_iterations;
  out.matvecs = r.hessian_applications;
  out.converged = r.reason == qp::StopReason::converged;
  out.reason = to_string(r.reason);
  // The MPRGP steps and face solves of every solve (the report's step counts add up to the
  // inner iterations).
  qp::SmalbeResult total = r;
  // SMALBE-M once more from x and nu (warm), its counts added to the first solve's.
  const auto solve_again = [&]() {
    r = qp::smalbe(qp, normA, x, red, so, hooks, progress, &nu);
    lambda = qp.shift + x;
    log_outer(r, out.matvecs);
    out.outer += r.outer_iterations;
    out.inner += r.inner_iterations;
    out.matvecs += r.hessian_applications;
    total.add_counts(r);
    out.converged = r.reason == qp::StopReason::converged;
    out.reason = to_string(r.reason);
  };
  // Coulomb friction: the fixed point on the slip bound. The first solve had no bound on the
  // Coulomb rows whose gap was closed (they stick: a solution whenever the normal contact holds
  // the bodies) and bound 0 on the open ones (constraints.cpp);
  // each next one takes mu lambda_n of the last and starts from its solution and its equality
  // multiplier (the set changes, the QP's operators and shift do not).
  nlohmann::json history = nlohmann::json::array();
  bool fixed_point = !dual.has_coulomb();
  int solves = 1;
  so.idle_count = qp::kWarmIdleCount;  // the next solves are warm-started (smalbe.hpp)
  for (int it = 1; !fixed_point && out.converged; ++it) {
    const auto [change, size] = dual.update_coulomb_bounds(lambda, false);
    const double rel = size > 0 ? change / size : 0.0;
    history.push_back(rel);
    // Attainable: the bounds come from multipliers solved to rtol, and change from one solve to
    // the next by about 5 rtol at the fixed point (measured), so never less than 10 rtol is asked.
    if (rel <= std::max(options.coulomb_rtol, 10 * options.rtol)) {
      fixed_point = true;
      break;
    }
    if (it >= options.coulomb_max_iterations) break;
    dual.update_coulomb_bounds(lambda, true);
    qp.constraints = dual.constraint_set()->shifted(qp.shift);
    solve_again();
    ++solves;
  }
  if (out.converged && !fixed_point) {
    out.converged = false;
    out.reason = "coulomb_fixed_point";
  }
  // The accuracy refinement (solve_parts.hpp): SMALBE-M again from x and its multiplier with a
  // smaller rtol (with Coulomb friction on the bounds of the fixed point's last solve). The QP
  // is the same, so the refinement continues the last solve: its penalty rho and its M too
  // (restarted from M_0, then 100 ||PFP||, the first inner solves stopped at once on the loose
  // M test while only mu moved, by rho G x per outer iteration, and raised ||g^P|| several
  // times before M came down again: docs/method.md, "Accuracy refinement").
  const auto refine_again = [&]() {
    so.rho_start = r.rho;
    so.M_start = r.M;
    solve_again();
  };
  // Single-precision sweeps (FetiOptions::factor_precision): the solve converged for the
  // operator of the factors' copies; from here on F is the factors' own, and SMALBE-M goes on
  // from x and its multiplier with the same rtol, its penalty and M (one product when x already
  // passes the test with the exact operator). The accuracy refinement below and the
  // reconstruction use the factors too.
  nlohmann::json single_check = nullptr;
  if (single) {
    dual.set_single_sweeps(false);
    if (out.converged) {
      note(kSingleCheckNote);
      const long before = out.matvecs;
      const int outer_before = out.outer;
      refine_again();
      single_check = {{"check_products", out.matvecs - before},
                      {"check_outer_iterations", out.outer - outer_before}};
    }
  }
  refinement.after(lambda, so.rtol, out.converged, refine_again);
  const bool discs = dynamic_cast<const qp::SeparableSet*>(qp.constraints.get()) != nullptr;
  out.solver = {{"algorithm", discs ? "smalbe-m+mpgp" : "smalbe-m+mprgp"},
                {"projected_gradient", r.projected_gradient},
                {"equality_residual", r.equality_residual},
                {"rhs_norm", r.rhs_norm},
                {"multiplier_norm", r.multiplier_norm},
                {"tolerance", r.tolerance},
                {"tolerance_set_by", r.roundoff_floor ? "round-off floor" : "rtol ||b||"},
                {"stopping_test", "||g^P|| <= tolerance and ||PFP|| ||G lambda|| <= tolerance"},
                {"norm_estimate", normA},
                {"norm_estimate_matvecs", norm_matvecs},
                {"norm_estimate_method", qp::to_string(options.norm_estimate)},
                {"rho", r.rho},
                {"rho_updates", r.rho_updates},
                {"M_final", r.M},
                {"alpha", r.alpha},
                {"cg_steps", total.cg_steps},
                {"expansion_steps", total.expansion_steps},
                {"expansion_cost_increases", total.expansion_cost_increases},
                {"projected_cg_expansions", total.projected_cg_expansions},
                {"mprgp_expansion", qp::to_string(so.expansion)},
                {"proportioning_steps", total.proportioning_steps},
                {"face_solves", total.face_solves},
                {"face_iterations", total.face_iterations},
                {"face_changes", total.face_changes},
                {"face_converged", total.face_converged},
                {"face_tries", total.face_tries},
                {"face_seconds", total.face_seconds},
                {"face_set_seconds", total.face_set_seconds}};
  out.solver["face_spectrum_estimate"] = spectrum_json(total.face_spectrum);
  if (!single_check.is_null()) out.solver["single_sweeps"] = single_check;
  out.solver["accuracy_checks"] = refinement.summary();
  if (refinement.refined()) out.solver["accuracy_refinements"] = refinement.steps();
  out.solver["outer_log"] = std::move(outer_log);
  // The fixed point's history: per step the relative change of the slip bounds.
  if (dual.has_coulomb())
    out.solver["coulomb"] = {
        {"solves", solves}, {"bound_changes", history}, {"converged", fixed_point}};
  return out;
}

}  // namespace

void check_equality_residual(const DualProblem::Kkt& kkt, double rtol) {
  if (!(kkt.equality_scale > 0)) return;
  const double rel = kkt.equality_residual / kkt.equality_scale;
  const double limit = std::min(0.1, 1e3 * rtol);
  if (rel > limit) {
    char msg[512];
    std::snprintf(msg, sizeof msg,
                  "the solution does not hold the subdomains together: ||B_E u - c_E|| is %.2e "
                  "of ||u|| + ||c_E|| (a converged solve leaves at most %.1e at rtol %.1e); a "
                  "subdomain's stiffness is singular beyond its rigid body motions (a mechanism: "
                  "cells joined only at a node or an edge)",
                  rel, limit, rtol);
    throw std::runtime_error(msg);
  }
}

void validate_solver(const SolveOptions& o) {
  // Every range is the options table's (options.hpp): each value is checked by its own row.
  RunOptions run;
  run.solve = o;
  RunOptions scratch = run;
  for (const auto& spec : option_table()) {
    if (std::string(spec.section) != "solver") continue;
    const nlohmann::json v = spec.get(run);
    OptionValue value;
    if (v.is_null()) continue;
    if (v.is_boolean())
      value = v.get<bool>();
    else if (v.is_number_integer())
      value = v.get<long long>();
    else if (v.is_number())
      value = v.get<double>();
    else
      value = v.get<std::string>();
    set_option(scratch, spec, value, *spec.flag ? spec.flag : spec.key);
  }
  check_option_combinations(run);
}

void validate(const SolveOptions& o) {
  validate_solver(o);
  Decomposition check(o.decomposition);  // throws for bad sizes
}

std::string resolve_preconditioner(const Model& model, FetiOptions& o) {
  const bool coefficient = !model.physics().coefficient.empty();
  std::string why = "requested";
  if (o.preconditioner == PreconditionerKind::automatic) {
    // Measured on this machine (docs/results.md, "The default"): Dirichlet's setup (dense S_i
    // from an interface-last factorization, or a factor of K_ii) costs more than the products it
    // saves wherever the coefficients are smooth, H-TFETI-DP with contact included (the cube,
    // one cluster of 64: 22.9 s against 5.7 s lumped and 5.1 s none).
    if (coefficient) {
      o.preconditioner = PreconditionerKind::dirichlet;
      why = "automatic: a coefficient field";
    } else if (model.physics().kind == PhysicsKind::elasticity) {
      o.preconditioner = PreconditionerKind::lumped;
      why = "automatic: elasticity";
    } else {
      o.preconditioner = PreconditionerKind::none;
      why = "automatic: Laplace without a coefficient field";
    }
    // Dirichlet by choice of auto: in 2D only where its dense blocks fit (else none, see
    // FetiOptions); in 3D with the implicit storage.
    if (o.preconditioner == PreconditionerKind::dirichlet)
      o.dirichlet_fallback = PreconditionerKind::none;
  }
  if (o.scaling == Scaling::automatic)
    o.scaling = coefficient ? Scaling::stiffness : Scaling::multiplicity;
  return why;
}

std::optional<OperatorCost> resolve_operator_cost(const Model& model, FetiOptions& o,
                                                  const Comm& comm) {
  if (o.dual_operator != DualOperator::automatic) return std::nullopt;
  std::optional<OperatorCost> cost = estimate_operator_cost(model, o, comm);
  if (cost) o.explicit_by_cost = cost->explicit_cheaper();
  return cost;
}

std::string describe_operator_cost(const OperatorCost& c) {
  char buf[256];
  if (std::isfinite(c.break_even))
    std::snprintf(buf, sizeof buf,
                  "cost model: the explicit F_i pay for their setup after %.3g applications of "
                  "F; %.0f expected: %s",
                  c.break_even, c.expected_applications,
                  c.explicit_cheaper() ? "explicit" : "implicit");
  else
    std::snprintf(buf, sizeof buf,
                  "cost model: the explicit F_i are no faster per F than the factor sweeps "
                  "(%.3g against %.3g model s per subdomain): implicit",
                  c.explicit_per_F, c.implicit_per_F);
  return buf;
}

SolveOutput solve(const SolveOptions& options, const Comm& comm) {
  validate(options);
  return solve(std::shared_ptr<const Model>(make_builtin_model(options.decomposition)), options,
               comm);
}

SolveOutput solve(std::shared_ptr<const Model> model_ptr, const SolveOptions& options,
                  const Comm& comm) {
  validate_solver(options);
  comm.agree(reserve_blas_buffers(), true);  // before anything fills the address space
  // More ranks x threads on a machine than it has cores: OpenMP threads that wait and MPI's
  // polling take each other's cores (the 2D friction example on 2 cores: 0.46 s on 1 rank x 2
  // threads, 10.8 s on 2 x 2, 25.9 s on 4 x 2, 0.67 s on 4 x 1). Said once, on rank 0.
  {
    const int machine_ranks = ranks_on_this_machine(comm.raw());
    const int threads = omp_get_max_threads();
    const int cores = static_cast<int>(std::thread::hardware_concurrency());
    const bool over = comm.max(cores > 0 && machine_ranks * threads > cores ? 1.0 : 0.0) > 0;
    if (over && comm.rank() == 0)
      std::fprintf(stderr,
                   "htfeti: note: %d ranks x %d threads on a machine with %d cores: the threads "
                   "and MPI's polling compete for the cores and the run can be many times "
                   "slower; set OMP_NUM_THREADS=%d\n",
                   machine_ranks, threads, cores, std::max(1, cores / machine_ranks));
  }
  SolveOutput out;
  out.model = std::move(model_ptr);
  const Model& model = *out.model;
  const bool verbose = options.progress && comm.rank() == 0;

  FetiOptions feti = options.feti;
  const std::string preconditioner_reason = resolve_preconditioner(model, feti);
  // The weighted projector is PCG's; asked for on a contact problem it would not be used.
  if (options.pcg_projector == PcgProjector::weighted && model.has_contact())
    throw std::invalid_argument(
        "solver.pcg_projector = weighted is for problems without contact (projected CG); "
        "SMALBE-M keeps the orthogonal projector: leave pcg_projector at auto or orthogonal");
  // The automatic operator's cost model (operator_cost.hpp): once the memory check's lower
  // bound fits, before its sample is assembled (which counts the operator chosen).
  std::optional<OperatorCost> cost;
  auto resolve_cost = [&](FetiOptions& o) { cost = resolve_operator_cost(model, o, comm); };
  MemoryEstimate estimate;
  if (options.check_memory)
    estimate = check_memory(model, feti, comm, resolve_cost);
  else
    resolve_cost(feti);
  // Where the memory the check counted with came from, for its messages.
  const char* memory_source =
      feti.memory_limit_mb > 0 && estimate.available_mb == feti.memory_limit_mb
          ? "of --memory-limit"
          : "available";
  if (verbose && estimate.explicit_for_memory)
    std::fprintf(stderr,
                 "  memory: the implicit operator would need %.0f MB on this machine, more than "
                 "the %.0f MB %s; taking the explicit operator (estimated %.0f MB, factors freed "
                 "as memory runs short)\n",
                 estimate.implicit_peak_mb, estimate.available_mb, memory_source,
                 estimate.machine_peak_mb);
  if (verbose && estimate.single_declined_for_memory)
    std::fprintf(stderr,
                 "  memory: the single-precision copies of the factors would not fit (%.0f MB "
                 "%s); the factor sweeps read the factors (double)\n",
                 estimate.available_mb, memory_source);
  if (verbose && estimate.explicit_declined_for_memory && !estimate.explicit_for_memory)
    std::fprintf(stderr,
                 "  memory: the explicit operator would need %.0f MB on this machine, more than "
                 "%.0f%% of the %.0f MB %s; taking the implicit operator (estimated %.0f MB; "
                 "--explicit-budget sets a fixed budget for the F_i)\n",
                 estimate.explicit_peak_mb, 100 * kExplicitMemoryShare, estimate.available_mb,
                 memory_source, estimate.machine_peak_mb);
  if (verbose && cost) std::fprintf(stderr, "  %s\n", describe_operator_cost(*cost).c_str());
  double t0 = seconds_now();
  if (verbose)
    std::fprintf(stderr,
                 "  setup: %d subdomains in %d clusters on %d ranks: assembling, factoring...\n",
                 model.num_subdomains(), model.num_clusters(), comm.size());
  out.dual = std::make_unique<DualProblem>(
      model.layout(),
      [&model, &options](int s) {
        SubdomainInput in = model.input(s);
        if (options.perturb_load != 0) perturb_load(in, options.perturb_load);
        return in;
      },
      comm, feti);
  DualProblem& dual = *out.dual;
  const DualReducer red(comm, dual);
  require_finite(comm, dual.d().allFinite(), "the dual right-hand side d = B K^+ f - c");
  require_finite(comm, dual.e().allFinite() && dual.lambda_tilde().allFinite(),
                 "the coarse right-hand side e = R^T f");
  const double t_setup = seconds_now() - t0;
  if (verbose)
    std::fprintf(stderr, "  setup done in %.2f s (dual dimension %lld, coarse %d, %s operator)\n",
                 t_setup, dual.dual_dimension(), dual.coarse_dimension(),
                 dual.dual_operator_name().c_str());
  DualOperators ops(dual);
  Vec lambda;
  // One coarse step per Hessian product: only SMALBE-M's products take it (PCG's iterates stay
  // in Ker G, where P F needs one projection anyway).
  const bool merged = options.coarse_steps_per_product == 1 && dual.has_inequalities();
  if (merged) {  // part of the setup: E = F G~^T and C = G~ E
    dual.build_coarse_image(options.feti.memory_limit_mb);
    if (verbose) {
      const auto& cs = dual.coarse_image_stats();
      std::fprintf(stderr,
                   "  coarse image: %d colours, %d F applications, %lld entries of E, %.2f s\n",
                   cs.colours, cs.F_applications, cs.E_nonzeros, cs.seconds);
    }
  }
  const double t_image = merged ? dual.coarse_image_stats().seconds : 0.0;
  double t_solve = seconds_now();
  const bool contact = dual.has_inequalities();
  // Friction in 3D puts each node's tangential pair in a disc: SMALBE-M runs MPGP there, which
  // has no expansion step of MPRGP's kinds. A variant asked for is then not used: say so.
  const bool discs =
      contact && dual.layout().dim == 3 && comm.max(dual.has_friction() ? 1.0 : 0.0) > 0;
  if (discs && options.smalbe.expansion != qp::Expansion::gradient &&
      options.smalbe.expansion != qp::Expansion::automatic && comm.rank() == 0)
    std::fprintf(stderr,
                 "htfeti: warning: --mprgp-expansion %s is not used: friction in 3D is solved "
                 "by MPGP, whose expansion step is the projected gradient step\n",
                 name_of(qp::kExpansionNames, options.smalbe.expansion).c_str());
  auto progress = [&](int it, double gp, double gx) {
    if (!verbose) return;
    // F applications so far, the norm estimate's included. A face solve that ends the solve
    // (SMALBE-M) is its own line.
    char label[16];
    if (it == qp::kFaceProgress)
      std::snprintf(label, sizeof label, "face    ");
    else
      std::snprintf(label, sizeof label, "it %5d", it);
    if (contact)
      std::fprintf(stderr,
                   "  %s  ||g^P||/||b|| %.3e  ||PFP|| ||G lambda||/||b|| %.3e  %ld F  %.2f s\n",
                   label, gp, gx, ops.F.count(), seconds_now() - t_solve);
    else
      std::fprintf(stderr, "  %s  ||P r||/||P b|| %.3e  %ld F  %.2f s\n", label, gp, ops.F.count(),
                   seconds_now() - t_solve);
  };
  // The accuracy check reconstructs u; the last check's u is the solution's (its lambda is the
  // final one), so the reconstruction below is not repeated.
  std::vector<Vec> checked_u;
  double t_rec = 0, t_kkt = 0;
  DualProblem::Kkt checked_kkt;
  // A check of the lambda of the last check with the same factors (the first check inside the
  // solve, then the one after it when the solve did not go on) is not made again.
  Vec checked_lambda;
  bool checked_single = false;
  double checked_ratio = 0;
  const AccuracyCheck check = [&](const Vec& lam) {
    const bool again = checked_lambda.size() == lam.size() &&
                       checked_single == dual.single_sweeps() && checked_lambda == lam;
    if (comm.min(again ? 1.0 : 0.0) > 0) return checked_ratio;
    double t = seconds_now();
    require_finite(comm, lam.allFinite(), "the multipliers lambda at the end of the solve");
    checked_u = dual.reconstruct(lam);
    t_rec = seconds_now() - t;
    t = seconds_now();
    checked_kkt = dual.kkt(checked_u, lam);
    t_kkt = seconds_now() - t;
    checked_lambda = lam;
    checked_single = dual.single_sweeps();
    checked_ratio = checked_kkt.equality_scale > 0
                        ? checked_kkt.equality_residual / checked_kkt.equality_scale / options.rtol
                        : 0.0;
    return checked_ratio;
  };
  const StageNote note = [&](const std::string& line) {
    if (verbose) std::fprintf(stderr, "  %s\n", line.c_str());
  };
  const QpSolve qs =
      contact ? solve_with_contact(dual, ops, lambda, options, red, progress, merged, check, note)
              : solve_without_contact(dual, ops, lambda, options, red, progress, check, note);
  t_solve = seconds_now() - t_solve - (qs.converged ? t_rec + t_kkt : 0.0);
  const double peak_mb_solve = peak_rss_mb();
  // A contact solve that did not converge may have had no solution to find: a body the load
  // pulls away from its obstacles. Then the input is at fault (exit 2), not the solver.
  if (!qs.converged && contact) {
    const std::string why = dual.unbounded_motion();
    if (!why.empty()) throw std::invalid_argument(why);
  }

  // A converged solve's last check was on its final lambda; reconstruct the others the same way.
  if (!qs.converged) check(lambda);
  out.u = std::move(checked_u);
  if (verbose) std::fprintf(stderr, "  reconstruction done in %.2f s\n", t_rec);
  double t_checks = seconds_now() - t_kkt;  // the report's checks of the solution
  const DualProblem::Kkt& kkt = checked_kkt;
  if (qs.converged) check_equality_residual(kkt, options.rtol);
  if (qs.converged && comm.rank() == 0 && kkt.equality_scale > 0 &&
      kkt.equality_residual / kkt.equality_scale > kRefineRatio * options.rtol)
    std::fprintf(stderr,
                 "htfeti: warning: the gluing residual ||B_E u - c_E|| is %.1f rtol of ||u|| + "
                 "||c_E|| after %d accuracy refinements: the solution is less accurate than rtol "
                 "says; solve with a smaller rtol, or with TFETI (cluster_size = 1)\n",
                 kkt.equality_residual / kkt.equality_scale / options.rtol, kMaxRefinements);
  const double energy = dual.energy(out.u);
  {
    bool finite = std::isfinite(energy);
    for (const auto& ui : out.u) finite = finite && ui.allFinite();
    require_finite(comm, finite, "the displacement or its energy");
  }
  t_checks = seconds_now() - t_checks;

  const SolveRecord record{
      options,
      feti,
      estimate,
      preconditioner_reason,
      cost,
      qs,
      ops,
      merged,
      t_setup,
      t_image,
      t_solve,
      t_rec,
      t_checks,
      peak_mb_solve,
      kkt,
      energy,
      dual.has_friction() ? dual.friction_summary(lambda) : DualProblem::FrictionSummary{}};
  nlohmann::json& rep = out.report;
  rep = model.describe();
  report_problem_and_solve(rep, model, dual, comm, record);
  report_timings_and_memory(rep, dual, comm, record);
  report_solution(rep, model, dual, comm, out.u, lambda, options.report_contact_rows);
  out.lambda = std::move(lambda);
  out.converged = qs.converged;
  return out;
}

}  // namespace htfeti
