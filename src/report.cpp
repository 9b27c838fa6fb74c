// The sections of the report of one solve (solve_parts.hpp): the problem and the solver's
// counts, timings and memory by phase, the contact rows and summaries and the displacement.
#include <mpi.h>
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>

#include "htfeti/options.hpp"
#include "htfeti/parallel/memory.hpp"
#include "solve_parts.hpp"

namespace htfeti::solve_parts {

// The problem, the choices in effect and the solver's counts.
void report_problem_and_solve(nlohmann::json& rep, const Model& model, DualProblem& dual,
                              const Comm& comm, const SolveRecord& r) {
  const SolveOptions& options = r.options;
  auto tmax = [&](double v) { return comm.max(v); };
  (void)tmax;
  const FetiOptions& feti = r.feti;
  const MemoryEstimate& estimate = r.estimate;
  const std::string& preconditioner_reason = r.preconditioner_reason;
  const QpSolve& qs = r.qs;
  const DualOperators& ops = r.ops;
  const bool merged = r.merged;
  const DualProblem::Kkt& kkt = r.kkt;
  const double energy = r.energy;
  rep["primal_dimension"] = model.primal_dimension();
  rep["dual_dimension"] = dual.dual_dimension();
  rep["equalities"] = dual.equalities();
  rep["inequalities"] = dual.inequalities();
  if (dual.has_friction()) rep["friction_rows"] = dual.friction_rows();
  rep["coarse_dimension"] = dual.coarse_dimension();
  {
    const auto dims = dual.cluster_kernel_dimensions();
    int sum = 0, larger = 0;
    for (int d : dims) sum += d, larger += d > model.physics().kernel_dimension();
    rep["cluster_kernel_dimension_sum"] = sum;
    // Clusters whose kernel exceeds the physics' (disconnected parts, weak primal joins).
    rep["clusters_with_larger_kernel"] = larger;
  }
  // Rigid motions fixed by no constraint (pure Neumann parts; in the reconstruction also bodies
  // whose contact multipliers are all zero): the solution is not unique, and its coefficients
  // along those motions are chosen zero (DualProblem::CoarseFactor).
  rep["unrestrained_rigid_motions"] = dual.unrestrained_rigid_motions();
  rep["unrestrained_at_solution"] = dual.unrestrained_at_solution();
  if (dual.inequalities() > 0 || dual.has_friction())
    rep["lambda_tilde"] = dual.lambda_tilde_choice();
  rep["ranks"] = comm.size();
  rep["threads"] = omp_get_max_threads();
  rep["rtol"] = options.rtol;
  rep["ordering"] = dual.ordering_in_effect();
  rep["dual_operator"] = dual.dual_operator_name();
  rep["factor_precision"] = dual.single_sweeps() ? "single" : "double";
  rep["factor_precision_reason"] = estimate.single_declined_for_memory ? "memory"
                                   : options.feti.factor_precision == FactorPrecision::automatic
                                       ? "automatic"
                                       : "requested";
  if (options.feti.dual_operator == DualOperator::checked) {
    const DualProblem::OperatorCheck check = dual.dual_operator_check();
    rep["dual_operator_check"] = {{"cluster_applications", check.applications},
                                  {"max_relative_difference", check.max_relative_difference}};
  }
  // Why: "requested", "automatic" (FetiOptions' rule) or "memory" (check_memory: the implicit
  // operator would not fit, or the explicit one the cost model prefers would take more than
  // kExplicitMemoryShare of the memory).
  rep["dual_operator_reason"] =
      estimate.explicit_for_memory || estimate.explicit_declined_for_memory ? "memory"
      : options.feti.dual_operator == DualOperator::automatic               ? "automatic"
                                                                            : "requested";
  if (r.cost) {
    // The cost model behind the automatic choice (operator_cost.hpp): the mean sampled
    // subdomain, and model seconds per subdomain on one thread.
    const OperatorCost& c = *r.cost;
    const SubdomainCostSample& m = c.mean;
    rep["dual_operator_model"] = {
        {"samples", c.samples},
        {"sample_mean",
         {{"unknowns", m.unknowns},
          {"multipliers", m.multipliers},
          {"interface_dofs", m.interface_dofs},
          {"factor_values", m.factor_values},
          {"factor_supernodes", m.factor_supernodes},
          {"factor_flops", m.factor_flops}}},
        {"implicit_s", {{"setup", c.implicit_setup}, {"F", c.implicit_per_F}}},
        {"explicit_s", {{"setup", c.explicit_setup}, {"F", c.explicit_per_F}}},
        {"expected_applications", c.expected_applications},
        {"break_even_applications",
         std::isfinite(c.break_even) ? nlohmann::json(c.break_even) : nlohmann::json(nullptr)},
        {"prefers", c.explicit_cheaper() ? "explicit" : "implicit"}};
  }
  if (dual.explicit_operator()) rep["explicit_precision"] = to_string(feti.explicit_precision);
  rep["factors_released"] = dual.factors_released();
  rep["clusters_released"] = comm.sum(static_cast<long long>(dual.clusters_released()));
  rep["preconditioner"] = to_string(dual.preconditioner());
  // Why: "requested", or the automatic rule (resolve_preconditioner); a Dirichlet choice of auto
  // in 2D whose dense blocks did not fit fell back to none.
  std::string why = preconditioner_reason;
  if (feti.preconditioner == PreconditionerKind::dirichlet &&
      dual.preconditioner() != PreconditionerKind::dirichlet)
    why +=
        "; Dirichlet's dense S_i exceed dirichlet_budget_gb: " + to_string(dual.preconditioner());
  rep["preconditioner_reason"] = why;
  rep["scaling"] = to_string(dual.scaling());
  if (ops.preconditioned)
    // lumped: the sparse K_bb; Dirichlet: S_i dense on every rank, or implicit somewhere.
    rep["preconditioner_storage"] = dual.preconditioner() == PreconditionerKind::lumped ? "sparse"
                                    : comm.min(dual.preconditioner_dense() ? 1.0 : 0.0) > 0
                                        ? "dense"
                                        : "implicit";
  // The Dirichlet preconditioner's layers of interior dofs (0: all of them).
  if (ops.preconditioned && dual.preconditioner() == PreconditionerKind::dirichlet)
    rep["preconditioner_layers"] = dual.preconditioner_layers();
  // The implicit Dirichlet preconditioner's solves with K_ii: single-precision factor copies
  // unless --factor-precision double.
  if (ops.preconditioned && dual.preconditioner() == PreconditionerKind::dirichlet &&
      comm.min(dual.preconditioner_dense() ? 1.0 : 0.0) == 0)
    rep["preconditioner_precision"] =
        comm.max(dual.preconditioner_single() ? 1.0 : 0.0) > 0 ? "single" : "double";
  rep["converged"] = qs.converged;
  rep["stop_reason"] = qs.reason;
  rep["outer_iterations"] = qs.outer;
  rep["inner_iterations"] = qs.inner;
  rep["matvecs"] = qs.matvecs;
  rep["F_applications"] = ops.F.count();
  rep["projector_applications"] = ops.P.count();
  // 2: P v, F, P per Hessian product; 1: F v, then one reduction and the coarse image (SMALBE-M
  // only: PCG and problems without contact keep 2).
  rep["coarse_steps_per_product"] = merged ? 1 : 2;
  rep["merged_coarse_steps"] = ops.merged_steps;
  if (merged) {
    const auto& cs = dual.coarse_image_stats();
    rep["coarse_image"] = {{"colours", cs.colours},
                           {"F_applications", cs.F_applications},
                           {"E_nonzeros", cs.E_nonzeros},
                           {"C_nonzeros", cs.C_nonzeros},
                           {"mb", (12.0 * cs.E_nonzeros + 12.0 * cs.C_nonzeros) / 1048576.0}};
  }
  rep["preconditioner_applications"] = ops.M.count();
  rep["objective"] = energy;
  rep["kkt"] = {{"equality_residual", kkt.equality_residual},
                {"relative_equality_residual",
                 kkt.equality_scale > 0 ? kkt.equality_residual / kkt.equality_scale : 0.0},
                {"max_violation", kkt.max_violation},
                {"min_multiplier", kkt.min_multiplier},
                {"complementarity", kkt.complementarity}};
  if (dual.has_friction())
    rep["friction"] = {{"tangential_force", r.friction.tangential_force},
                       {"stick_rows", r.friction.stick},
                       {"slip_rows", r.friction.slip}};
  rep["solver"] = qs.solver;
  // Every solver option in effect, defaults included (the app adds the output options).
  {
    RunOptions run;
    run.solve = options;
    rep["options"] = {{"solver", options_json(run)["solver"]}};
  }
}

// Timings by phase and memory by phase (maxima or sums over the ranks).
void report_timings_and_memory(nlohmann::json& rep, DualProblem& dual, const Comm& comm,
                               const SolveRecord& r) {
  const SolveOptions& options = r.options;
  const auto& st = dual.setup_timings();
  auto tmax = [&](double v) { return comm.max(v); };
  (void)tmax;
  const MemoryEstimate& estimate = r.estimate;
  const DualOperators& ops = r.ops;
  const double t_setup = r.t_setup, t_image = r.t_image, t_solve = r.t_solve, t_rec = r.t_rec,
               t_checks = r.t_checks, peak_mb_solve = r.peak_mb_solve;
  // Timings the model described (timings.partition of a METIS split) are kept beside these.
  const nlohmann::json before = rep.contains("timings") ? rep["timings"] : nlohmann::json::object();
  rep["timings"] = {{"setup", tmax(st.assembly + st.constraints)},
                    {"assembly", tmax(st.assembly)},
                    {"factorization", tmax(st.factorization)},
                    {"cluster_setup", tmax(st.cluster_setup)},
                    {"constraints", tmax(st.constraints)},
                    {"coarse_problem", tmax(st.coarse)},
                    {"solve", tmax(t_solve)},
                    {"F", tmax(ops.F.seconds())},
                    {"projector", tmax(ops.P.seconds() + ops.merged_seconds)},
                    {"preconditioner", tmax(ops.M.seconds())},
                    {"preconditioner_setup", tmax(st.preconditioner)},
                    // the part of "projector" spent in one-step products (after F v)
                    {"merged_coarse_steps", tmax(ops.merged_seconds)},
                    {"coarse_image", tmax(t_image)},
                    {"vector_work", tmax(t_solve - ops.F.seconds() - ops.P.seconds() -
                                         ops.merged_seconds - ops.M.seconds())},
                    {"reconstruction", tmax(t_rec)},
                    {"checks", tmax(t_checks)},
                    // the automatic operator's cost model, before the setup (not in "total")
                    {"operator_model", tmax(r.cost ? r.cost->seconds : 0.0)},
                    {"total", tmax(t_setup + t_image + t_solve + t_rec + t_checks)}};
  for (const auto& [key, value] : before.items()) rep["timings"][key] = value;
  // The subdomain factorizations in core-seconds (summed over subdomains and ranks): the
  // symbolic part (forming K_rr, ordering, analysis or its copy from the cache) and the numeric
  // one; and the symbolic analyses done and reused (FetiOptions::symbolic_cache_patterns).
  // Subdomains whose factor is held in single precision alone (Subdomain::SingleCopy), the double
  // solves refined with their K_rr, the refinement steps, and the factors made again in double.
  long long single_only = 0, refined = 0, steps = 0, refactored = 0;
  for (const auto& sd : dual.subdomains()) {
    const SparseCholesky::RefinementStats rs = sd->refinement_stats();
    single_only += sd->single_only() || rs.refactored ? 1 : 0;
    refined += rs.solves, steps += rs.steps, refactored += rs.refactored ? 1 : 0;
  }
  rep["factorization"] = {
      {"single_only", comm.sum(single_only)},
      {"refined_solves", comm.sum(refined)},
      {"refinement_steps", comm.sum(steps)},
      {"refactored_in_double", comm.sum(refactored)},
      {"symbolic_core_s", comm.sum(st.factor_symbolic)},
      {"numeric_core_s", comm.sum(st.factor_numeric)},
      {"symbolic_analyses", comm.sum(static_cast<long long>(st.symbolic_analyses))},
      {"symbolic_reuses", comm.sum(static_cast<long long>(st.symbolic_reuses))},
      {"numeric_reuses", comm.sum(static_cast<long long>(st.numeric_reuses))},
      {"cached_matrices", comm.sum(static_cast<long long>(st.numeric_matrices))},
      {"solve_reuses", comm.sum(static_cast<long long>(st.solve_reuses))},
      {"cached_patterns", comm.sum(static_cast<long long>(st.symbolic_patterns))}};
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  const double rss_mb = usage.ru_maxrss / 1024.0;  // ru_maxrss is in KiB on Linux
  // Peak resident memory of the largest rank at the end of each phase (a jump marks the phase
  // that set the peak).
  const nlohmann::json peak_by_phase = {{"assembly", comm.max(st.peak_mb_assembly)},
                                        {"constraints", comm.max(st.peak_mb_constraints)},
                                        {"factorization", comm.max(st.peak_mb_factorization)},
                                        {"coarse_problem", comm.max(st.peak_mb_coarse)},
                                        {"solve", comm.max(peak_mb_solve)},
                                        {"reconstruction", comm.max(peak_rss_mb())}};
  rep["memory"] = {
      {"peak_mb_by_phase", peak_by_phase},
      {"factor_mb", comm.sum(st.factor_mb)},
      {"distinct_factor_mb", comm.sum(st.distinct_factor_mb)},
      {"single_factor_mb", comm.sum(st.single_factor_mb)},
      {"refinement_mb", comm.sum(st.refinement_mb)},
      {"shared_matrices", comm.sum(static_cast<long long>(st.shared_matrices))},
      // The estimate made before setup (0 with check_memory off); sums over ranks.
      {"estimate_mb",
       {{"peak", comm.sum(estimate.peak_mb())},
        {"factors", comm.sum(estimate.factors_mb)},
        {"matrices", comm.sum(estimate.matrices_mb)},
        {"vectors", comm.sum(estimate.vectors_mb)},
        {"explicit", comm.sum(estimate.explicit_mb)},
        {"factors_held", comm.sum(estimate.factors_held_mb)},
        {"single_factors", comm.sum(estimate.single_mb)},
        // The implicit Dirichlet preconditioner's factors of K_ii (0 otherwise).
        {"preconditioner", comm.sum(estimate.preconditioner_mb)},
        {"sampled", comm.min(estimate.sampled ? 1.0 : 0.0) > 0},
        // Factors counted as shared by equal subdomains (a count; 0: one each).
        {"shared_factors", comm.sum(estimate.shared_factors)},
        // The implicit operator's, when it was estimated not to fit (0 otherwise).
        {"implicit_peak", estimate.implicit_peak_mb},
        // The explicit operator's, when the cost model preferred it and it was estimated to
        // take more than kExplicitMemoryShare of the memory (0 otherwise).
        {"explicit_peak", estimate.explicit_peak_mb},
        // The memory the estimate was compared with (the smallest over the machines).
        {"available", estimate.available_mb}}},
      {"limit_mb", options.feti.memory_limit_mb},
      {"factor_nonzeros", comm.sum(static_cast<long long>(dual.factor_nonzeros()))},
      {"coarse_factor_nonzeros", dual.coarse_factor_nonzeros()},
      {"coarse_factor_ranks", dual.coarse_factor_ranks()},
      {"explicit_mb", comm.sum(static_cast<double>(dual.explicit_bytes())) / 1048576.0},
      {"cluster_dense_mb", comm.sum(8.0 * dual.cluster_dense_doubles()) / 1048576.0},
      {"preconditioner_mb", comm.sum(static_cast<double>(dual.preconditioner_bytes())) / 1048576.0},
      {"peak_rss_mb_max_rank", comm.max(rss_mb)},
      {"peak_rss_mb_total", comm.sum(rss_mb)}};
}

// The per-row contact arrays, gathered on rank 0 and shared with every rank (collective).
void report_contact_arrays(nlohmann::json& rep, DualProblem& dual, const Comm& comm,
                           const std::vector<Vec>& u, const Vec& lambda) {
  const auto c = dual.contact_data(u, lambda);
  // Per contact row (DualProblem::ContactData): node a's (or the slave node's) coordinates,
  // n.u_a ("u_left"), n.u_b ("u_right", 0 for a rigid obstacle), the remaining gap, the row's
  // force ("multiplier"), its pressure and, with friction, the tangential values.
  nlohmann::json cj = {{"x", c.x},
                       {"y", c.y},
                       {"z", c.z},
                       {"u_left", c.u_a},
                       {"u_right", c.u_b},
                       {"gap", c.gap},
                       {"multiplier", c.force},
                       {"pressure", c.pressure}};
  if (dual.has_friction()) {
    cj["tangential_traction"] = c.tangential;
    cj["slip"] = c.slip;
    cj["state"] = c.state;
  }
  // Rank 0 holds the gathered arrays; share them so the report is the same everywhere.
  std::string s = comm.rank() == 0 ? cj.dump() : std::string();
  long long len = static_cast<long long>(s.size());
  MPI_Bcast(&len, 1, MPI_LONG_LONG, 0, comm.raw());
  s.resize(static_cast<size_t>(len));
  MPI_Bcast(s.data(), static_cast<int>(len), MPI_CHAR, 0, comm.raw());
  rep["contact"] = nlohmann::json::parse(s);
}

// The contact rows and the displacement summary (collective).
void report_solution(nlohmann::json& rep, const Model& model, DualProblem& dual, const Comm& comm,
                     const std::vector<Vec>& u, const Vec& lambda, long long max_contact_rows) {
  // The mesh the fullest rank holds (Model::held): the whole mesh with mesh.file, its own parts
  // with mesh.parts, nothing for a generated box.
  const Model::MeshCounts held = model.held();
  rep["mesh_held_max_rank"] = {
      {"cells", static_cast<long long>(comm.max(static_cast<double>(held.cells)))},
      {"nodes", static_cast<long long>(comm.max(static_cast<double>(held.points)))}};
  if (dual.has_inequalities() && dual.inequalities() > max_contact_rows) {
    rep["contact"] = {{"rows", dual.inequalities()},
                      {"arrays", "omitted: more than report_contact_rows = " +
                                     std::to_string(max_contact_rows) + " rows"}};
  } else if (dual.has_inequalities()) {
    report_contact_arrays(rep, dual, comm, u, lambda);
  }
  if (dual.has_inequalities()) {
    // One entry per contact condition, in the problem file's order.
    const auto conditions = model.contact_conditions();
    const auto summary =
        dual.contact_summary(u, lambda, static_cast<int>(std::max<size_t>(conditions.size(), 1)));
    nlohmann::json list = nlohmann::json::array();
    for (size_t i = 0; i < summary.size(); ++i) {
      nlohmann::json e;
      e["group"] =
          i < conditions.size() ? conditions[i].group : "contact #" + std::to_string(i + 1);
      if (i < conditions.size() && !conditions[i].master.empty())
        e["master"] = conditions[i].master;
      e["rows"] = summary[i].rows;
      e["active_rows"] = summary[i].active;
      e["area"] = summary[i].area;
      e["normal_force"] = summary[i].normal_force;
      e["max_penetration"] = summary[i].max_penetration;
      e["resultant"] = std::vector<double>(summary[i].resultant.begin(),
                                           summary[i].resultant.begin() + model.dim());
      if (summary[i].friction) {
        // 2D: the force along t = (-n_y, n_x); 3D: the vector in the global frame.
        e["tangential_force"] =
            model.dim() == 2 ? nlohmann::json(summary[i].tangential_force)
                             : nlohmann::json(std::vector<double>(summary[i].tangential.begin(),
                                                                  summary[i].tangential.end()));
        e["open_nodes"] = summary[i].open;
        e["stick_nodes"] = summary[i].stick;
        e["slip_nodes"] = summary[i].slip;
      }
      list.push_back(e);
    }
    rep["contact_summary"] = list;
  }
  {
    // Nodal displacement magnitudes: max and mean over the global nodes (a node's copies are
    // weighted by 1 / copies, so each node counts once).
    // Per-subdomain partial sums added in subdomain order (rank-count independent).
    const int dpn = model.physics().dofs_per_node(), ns = model.num_subdomains();
    double umax = 0;
    std::vector<double> usum(2 * static_cast<size_t>(ns), 0.0);
    for (size_t i = 0; i < u.size(); ++i) {
      const int id = dual.subdomains()[i]->id();
      const SubdomainMesh m = model.mesh(id);
      for (int k = 0; k < m.num_nodes(); ++k) {
        double n2 = 0;
        for (int d = 0; d < dpn; ++d) n2 += u[i][k * dpn + d] * u[i][k * dpn + d];
        const double w = 1.0 / m.num_copies(k);
        umax = std::max(umax, std::sqrt(n2));
        usum[2 * id] += w * std::sqrt(n2);
        usum[2 * id + 1] += w;
      }
    }
    if (comm.size() > 1)
      MPI_Allreduce(MPI_IN_PLACE, usum.data(), static_cast<int>(usum.size()), MPI_DOUBLE, MPI_SUM,
                    comm.raw());
    double total = 0, nodes = 0;
    for (int id = 0; id < ns; ++id) total += usum[2 * id], nodes += usum[2 * id + 1];
    rep["displacement"] = {{"max_norm", comm.max(umax)}, {"mean_norm", total / nodes}};
    // The applied load summed over the subdomains (each cell and boundary facet belongs to one),
    // in subdomain order: the loads as meshed (a curved boundary's facets, for instance).
    std::vector<double> f(static_cast<size_t>(dpn) * ns, 0.0);
    for (size_t i = 0; i < u.size(); ++i) {
      const auto& fi = dual.subdomains()[i]->f();
      for (Eigen::Index j = 0; j < fi.size(); ++j)
        f[static_cast<size_t>(dpn) * dual.subdomains()[i]->id() + j % dpn] += fi[j];
    }
    if (comm.size() > 1)
      MPI_Allreduce(MPI_IN_PLACE, f.data(), static_cast<int>(f.size()), MPI_DOUBLE, MPI_SUM,
                    comm.raw());
    std::vector<double> resultant(dpn, 0.0);
    for (int id = 0; id < ns; ++id)
      for (int d = 0; d < dpn; ++d) resultant[d] += f[static_cast<size_t>(dpn) * id + d];
    rep["load_resultant"] = resultant;
  }
}

}  // namespace htfeti::solve_parts
