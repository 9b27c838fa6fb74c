// htfeti: the command-line program. `htfeti solve` runs the pipeline on a built-in problem;
// `htfeti spectrum` prints the extreme eigenvalues of a cluster Schur complement (Table 1).
// Every option is declared here with its default and help text; `htfeti solve --help` lists them.
#include <malloc.h>
#include <mpi.h>
#include <omp.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/io/output_file.hpp"
#include "htfeti/io/vtu.hpp"
#include "htfeti/memory_estimate.hpp"
#include "htfeti/options.hpp"
#include "htfeti/parallel/memory.hpp"
#include "htfeti/parallel/threads.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/solver.hpp"

namespace htfeti {
int run_spectrum(int m, int n, const std::string& element, bool json);  // apps/spectrum.cpp
}

namespace {

using namespace htfeti;

int fail(const Comm& comm, const std::string& msg, int code) {
  if (comm.rank() == 0) std::fprintf(stderr, "htfeti: error: %s\n", msg.c_str());
  return code;
}

void print_summary(const nlohmann::json& r) {
  std::printf("htfeti: %s, %s elements, %d subdomains in %d clusters (glue %s)\n",
              r["problem"].get<std::string>().c_str(), r["element"].get<std::string>().c_str(),
              r["subdomains"].get<int>(), r["clusters"].get<int>(),
              r["glue"].get<std::string>().c_str());
  std::printf(
      "  primal %lld, dual %lld (%lld equalities, %lld inequalities), coarse %d, %d ranks x %d "
      "threads\n",
      r["primal_dimension"].get<long long>(), r["dual_dimension"].get<long long>(),
      r["equalities"].get<long long>(), r["inequalities"].get<long long>(),
      r["coarse_dimension"].get<int>(), r["ranks"].get<int>(), r["threads"].get<int>());
  std::printf("  %s operator (%s), preconditioner %s (%s)\n",
              r["dual_operator"].get<std::string>().c_str(),
              r["dual_operator_reason"].get<std::string>().c_str(),
              r["preconditioner"].get<std::string>().c_str(),
              r["preconditioner_reason"].get<std::string>().c_str());
  if (r.contains("dual_operator_check"))
    std::printf(
        "  checked operator: the explicit F differs from the implicit one by at most %.2e "
        "(relative, over %ld products)\n",
        r["dual_operator_check"]["max_relative_difference"].get<double>(),
        r["dual_operator_check"]["cluster_applications"].get<long>());
  const int free_motions = std::max(r["unrestrained_rigid_motions"].get<int>(),
                                    r["unrestrained_at_solution"].get<int>());
  if (free_motions > 0)
    std::printf(
        "  note: the solution is not unique: %d rigid motion(s) restrained by no Dirichlet "
        "condition and no active contact; their components are chosen zero\n",
        free_motions);
  // Name what ran: projected CG for equalities alone, SMALBE-M with MPRGP inside for contact.
  const bool pcg = r["solver"]["algorithm"] == "pcg";
  const std::string state = r["converged"].get<bool>()
                                ? std::string("converged")
                                : "NOT converged (" + r["stop_reason"].get<std::string>() + ")";
  if (pcg)
    std::printf("  PCG %s: %d iterations, %ld products with F\n", state.c_str(),
                r["outer_iterations"].get<int>(), r["matvecs"].get<long>());
  else
    std::printf(
        "  SMALBE-M %s: %d outer iterations, %d MPRGP iterations, %ld Hessian products "
        "(+%ld for the norm estimate)\n",
        state.c_str(), r["outer_iterations"].get<int>(), r["inner_iterations"].get<int>(),
        r["matvecs"].get<long>(), r["solver"]["norm_estimate_matvecs"].get<long>());
  if (!pcg) {  // which test held and which did not, relative to ||b|| (qp/smalbe.hpp)
    const auto& s = r["solver"];
    const double bn = s["rhs_norm"].get<double>() > 0 ? s["rhs_norm"].get<double>() : 1.0;
    const double tol = s["tolerance"].get<double>();
    const double g = s["projected_gradient"].get<double>();
    const double q = s["norm_estimate"].get<double>() * s["equality_residual"].get<double>();
    std::printf(
        "  stopping test: ||g^P||/||b|| %.2e %s %.2e, ||PFP|| ||G lambda||/||b|| %.2e %s %.2e%s\n",
        g / bn, g <= tol ? "<=" : ">", tol / bn, q / bn, q <= tol ? "<=" : ">", tol / bn,
        s["tolerance_set_by"] == "round-off floor"
            ? " (the round-off floor: rtol is finer than double precision can measure)"
            : "");
  }
  {  // the spectrum CG saw (qp/cg_spectrum.hpp): what sets the count on a hard mesh
    const auto& s = r["solver"];
    const char* key = pcg ? "spectrum_estimate" : "face_spectrum_estimate";
    if (s.contains(key) && !s[key].is_null())
      std::printf(
          "  %s: eigenvalues in [%.3g, %.3g], ratio %.3g (Lanczos estimate from %d CG steps)\n",
          pcg ? "PCG's operator" : "the face solves' operator", s[key]["min"].get<double>(),
          s[key]["max"].get<double>(), s[key]["ratio"].get<double>(),
          s[key]["cg_steps"].get<int>());
  }
  const auto& k = r["kkt"];
  std::printf(
      "  energy %.12e; ||B_E u - c_E|| %.2e, max violation %.2e, min multiplier %.2e, "
      "complementarity %.2e\n",
      r["objective"].get<double>(), k["equality_residual"].get<double>(),
      k["max_violation"].get<double>(), k["min_multiplier"].get<double>(),
      k["complementarity"].get<double>());
  if (r.contains("contact_summary"))
    for (const auto& c : r["contact_summary"]) {
      if (!c.contains("stick_nodes")) continue;
      const auto& tf = c["tangential_force"];
      std::string t = tf.is_number() ? std::to_string(tf.get<double>()) : tf.dump();
      std::printf(
          "  friction on %s: tangential force %s, %lld nodes in stick, %lld in slip, %lld "
          "open\n",
          c["group"].get<std::string>().c_str(), t.c_str(), c["stick_nodes"].get<long long>(),
          c["slip_nodes"].get<long long>(), c["open_nodes"].get<long long>());
    }
  if (r["solver"].contains("coulomb")) {
    const auto& cf = r["solver"]["coulomb"];
    std::printf("  Coulomb fixed point: %d Tresca solves, %s\n", cf["solves"].get<int>(),
                cf["converged"].get<bool>() ? "converged" : "NOT converged");
  }
  const auto& t = r["timings"];
  // Before the setup: the mesh read or generated and split (with METIS's split apart).
  std::string model;
  char buf[96];
  if (t.contains("model")) {
    std::snprintf(buf, sizeof buf, "model %.2f s", t["model"].get<double>());
    model = buf;
    if (t.contains("partition")) {
      std::snprintf(buf, sizeof buf, " (METIS split %.2f s)", t["partition"].get<double>());
      model += buf;
    }
    model += ", ";
  }
  std::printf(
      "  time: %ssetup %.2f s, factorization %.2f s, coarse %.2f s, solve %.2f s, "
      "reconstruction %.2f s\n",
      model.c_str(), t["setup"].get<double>(), t["factorization"].get<double>(),
      t["coarse_problem"].get<double>(), t["solve"].get<double>(),
      t["reconstruction"].get<double>());
}

// Integers are read strictly: decimal digits only (CLI11 alone accepts "0x10" and " 16").
const CLI::Validator kStrictInt(
    [](std::string& s) {
      const bool ok = !s.empty() && s.size() < 10 &&
                      std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
      return ok ? std::string()
                : "'" + s + "' is not a decimal integer from 0 to 999999999 (digits only)";
    },
    "INT");

// A positive integer (after kStrictInt): the message names the value and the range.
const CLI::Validator kPositive(
    [](std::string& s) {
      return s.find_first_not_of('0') == std::string::npos
                 ? "'" + s + "' must be a positive integer (1 to 999999999)"
                 : std::string();
    },
    "POSITIVE");

// What selects the problem (not options of the solve): a problem file or a built-in, and the
// built-ins' sizes. Each has a problem-file key of its own in [mesh] or [decomposition].
struct ProblemArgs {
  std::string file, problem = "membranes", element = "q1", glue = "averages", objective = "auto",
                    cluster_split = "mesh", shape = "compact";
  std::string elements = "128", subdomains = "8";
  int cluster_size = 1;
  int seed = kDefaultPartitionSeed;
  double jump_ratio = kDefaultJumpRatio;
  double amplitude = 1.0;
  CLI::Option *o_problem = nullptr, *o_elements = nullptr, *o_subdomains = nullptr, *o_m = nullptr,
              *o_glue = nullptr, *o_element = nullptr, *o_amplitude = nullptr,
              *o_objective = nullptr, *o_cluster_split = nullptr, *o_seed = nullptr,
              *o_jump_ratio = nullptr, *o_shape = nullptr;
};

void add_problem_args(CLI::App* cmd, ProblemArgs& p) {
  cmd->add_option("problem_file", p.file,
                  "a problem file (TOML, docs/user-guide.md); options given on the command line "
                  "override its keys");
  p.o_problem =
      cmd->add_option("--problem", p.problem,
                      "built-in: poisson2d | membranes | membranes-coercive | cube-obstacle")
          ->capture_default_str();
  p.o_elements = cmd->add_option("--elements,-n", p.elements,
                                 "built-ins: n, elements per side of each unit square (h = 1/n); "
                                 "a generated box: NX,NY[,NZ] [mesh.elements]")
                     ->capture_default_str();
  p.o_subdomains =
      cmd->add_option("--subdomains", p.subdomains,
                      "built-ins: N_s, subdomains per side of each unit square (n divisible by "
                      "N_s); problem files: N (METIS) or SX,SY[,SZ] (generated box) "
                      "[decomposition.subdomains]")
          ->capture_default_str();
  p.o_m = cmd->add_option("--cluster-size,-m", p.cluster_size,
                          "m: clusters of m x m (x m) subdomains (1 = TFETI; N_s divisible by m); "
                          "METIS: subdomains per cluster [decomposition.cluster_size]")
              ->capture_default_str()
              ->check(kStrictInt)
              ->check(kPositive);
  p.o_glue = cmd->add_option("--glue", p.glue,
                             "primal gluing inside clusters: corners | averages | "
                             "corners+averages [decomposition.glue]")
                 ->capture_default_str();
  p.o_objective = cmd->add_option("--partition-objective", p.objective,
                                  "problem files split by METIS: what METIS minimizes, volume "
                                  "(communication volume: interface nodes) | cut (cut facets) | "
                                  "area (area of the cut facets: interfaces across the small "
                                  "faces of stretched cells) | auto (area when at least 10% of "
                                  "the cells are stretched, largest facet >= 2.5 x smallest; else "
                                  "volume) [decomposition.objective]")
                      ->capture_default_str();
  p.o_seed = cmd->add_option("--partition-seed", p.seed,
                             "problem files split by METIS: METIS's random seed; other seeds give "
                             "other splits of the same quality by METIS's measure, and the "
                             "solver's iterations vary with them [decomposition.seed]")
                 ->capture_default_str()
                 ->check(kStrictInt);
  p.o_jump_ratio =
      cmd->add_option("--partition-jump-ratio", p.jump_ratio,
                      "problem files split by METIS with a coefficient field: a facet across "
                      "which the coefficient changes by more than this factor is a jump, and no "
                      "subdomain straddles one (each region between jumps gets its own "
                      "subdomains); 0 = off [decomposition.jump_ratio]")
          ->capture_default_str();
  p.o_shape = cmd->add_option("--partition-shape", p.shape,
                              "problem files split by METIS: compact (METIS's split moved toward "
                              "compact parts of equal cell counts, kept where it cuts fewer "
                              "facets) | metis (METIS's parts as they are) [decomposition.shape]")
                  ->capture_default_str();
  p.o_cluster_split =
      cmd->add_option("--cluster-split", p.cluster_split,
                      "problem files split by METIS, H-TFETI-DP: how clusters are formed, mesh "
                      "(METIS splits the mesh into clusters, then each cluster into its "
                      "subdomains: compact clusters) | subdomains (METIS splits the mesh into "
                      "the subdomains, then groups them: the same subdomains as TFETI's) "
                      "[decomposition.cluster_split]")
          ->capture_default_str();
  p.o_element =
      cmd->add_option("--element", p.element, "built-ins: q1 (bilinear) | p1 (linear triangles)")
          ->capture_default_str();
  p.o_amplitude = cmd->add_option("--obstacle-amplitude", p.amplitude,
                                  "cube-obstacle: the obstacle is u_z >= -A sin(pi x / 50) (A = "
                                  "1: every bottom node ends in contact; larger A: partial "
                                  "contact)")
                      ->capture_default_str();
}

// The options table on the command line: one flag (and a --no- flag where the table has one)
// per row, its help followed by its problem-file key and default.
struct TableArgs {
  std::vector<std::string> text;
  std::vector<CLI::Option*> option, negative;
};

void add_table_args(CLI::App* cmd, TableArgs& args) {
  const auto& table = option_table();
  const RunOptions defaults;
  args.text.resize(table.size());
  args.option.assign(table.size(), nullptr);
  args.negative.assign(table.size(), nullptr);
  for (size_t i = 0; i < table.size(); ++i) {
    const OptionSpec& o = table[i];
    const nlohmann::json d = o.get(defaults);
    const std::string def = d.is_null() ? "none" : d.is_string() ? d.get<std::string>() : d.dump();
    const std::string key = std::string(" [") + o.section + "." + o.key +
                            (*o.unit ? std::string(", ") + o.unit : std::string()) + "; default " +
                            def + "]";
    if (*o.flag && o.type == OptionType::boolean)
      args.option[i] = cmd->add_flag(std::string(o.flag))->description(o.help + key);
    else if (*o.flag)
      args.option[i] = cmd->add_option(o.flag, args.text[i], std::string(o.help) + key)
                           ->type_name(o.type == OptionType::integer  ? "INT"
                                       : o.type == OptionType::number ? (*o.unit ? o.unit : "NUM")
                                       : o.type == OptionType::path   ? "FILE"
                                                                      : "WORD");
    if (*o.negative_flag)
      args.negative[i] = cmd->add_flag(std::string(o.negative_flag))
                             ->description(*o.flag ? "no " + std::string(o.key) : o.help + key);
  }
}

// Command-line values over what the file (or the defaults) gave.
void apply_table_args(const TableArgs& args, RunOptions& run) {
  const auto& table = option_table();
  for (size_t i = 0; i < table.size(); ++i) {
    const OptionSpec& o = table[i];
    if (args.option[i] && args.option[i]->count() > 0) {
      OptionValue value = true;
      try {
        if (o.type != OptionType::boolean) value = parse_option_text(o, args.text[i]);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(std::string(o.flag) + ": " + e.what());
      }
      set_option(run, o, value, o.flag);
    }
    if (args.negative[i] && args.negative[i]->count() > 0)
      set_option(run, o, false, o.negative_flag);
  }
  check_option_combinations(run);
}

// The model of a problem file with the command line's problem arguments over its keys.
std::shared_ptr<const Model> file_model(const ProblemArgs& p, const TableArgs& args,
                                        RunOptions& run, const Comm& comm) {
  ProblemSpec spec = read_problem_file(p.file, run);
  apply_table_args(args, run);
  if (p.o_subdomains->count()) spec.subdomains = parse_int_list(p.subdomains, "--subdomains");
  if (p.o_m->count()) spec.cluster_size = p.cluster_size;
  if (p.o_glue->count()) spec.glue = parse_glue(p.glue);
  // The flags that steer METIS's split: refused where the file splits nothing by METIS.
  const bool metis = spec.subdomains.size() == 1 && spec.mesh_parts.empty();
  const auto metis_only = [&](const CLI::Option* o, const char* flag) {
    if (o->count() && !metis)
      throw std::invalid_argument(std::string(flag) +
                                  " is for meshes split by METIS (decomposition.subdomains = N)");
    return o->count() > 0;
  };
  if (metis_only(p.o_objective, "--partition-objective"))
    spec.partition_objective = parse_partition_objective(p.objective);
  if (metis_only(p.o_seed, "--partition-seed")) spec.partition_seed = p.seed;
  if (p.o_jump_ratio->count() &&
      (!std::isfinite(p.jump_ratio) || !(p.jump_ratio == 0 || p.jump_ratio > 1)))
    throw std::invalid_argument(
        "--partition-jump-ratio must be 0 (off) or a number greater than 1");
  if (metis_only(p.o_jump_ratio, "--partition-jump-ratio"))
    spec.partition_jump_ratio = p.jump_ratio;
  if (metis_only(p.o_shape, "--partition-shape"))
    spec.partition_shape = parse_partition_shape(p.shape);
  if (metis_only(p.o_cluster_split, "--cluster-split"))
    spec.cluster_split = parse_cluster_split(p.cluster_split);
  // The cluster-only keys as the file and the flags left them: named by unused_options() if
  // the run has no clusters.
  if (spec.glue != Glue::averages) run.given_decomposition.push_back("glue");
  if (spec.cluster_split != ClusterSplit::mesh) run.given_decomposition.push_back("cluster_split");
  if (!spec.builtin.empty() && p.o_elements->count()) {
    const auto e = parse_int_list(p.elements, "--elements");
    if (e.size() != 1) throw std::invalid_argument("--elements takes one number for a built-in");
    spec.builtin_options.elements = e[0];
  } else if (p.o_elements->count()) {
    if (!spec.mesh_file.empty() || !spec.mesh_parts.empty())
      throw std::invalid_argument("--elements is for generated boxes, not mesh files");
    const auto e = parse_int_list(p.elements, "--elements");
    if (static_cast<int>(e.size()) != spec.box.dim)
      throw std::invalid_argument("--elements needs " + std::to_string(spec.box.dim) +
                                  " numbers for this box");
    for (int d = 0; d < spec.box.dim; ++d) spec.box.elements[d] = e[d];
  }
  if (p.o_amplitude->count())
    throw std::invalid_argument("--obstacle-amplitude is for --problem cube-obstacle");
  if (p.o_element->count() && spec.builtin.empty())
    throw std::invalid_argument("--element is for the built-in problems; set mesh.element");
  if (p.o_element->count()) spec.builtin_options.element = parse_element(p.element);
  validate_solver(run.solve);
  if (run.solve.check_memory) check_memory_before_model(spec, run.solve.feti, comm);
  return make_model(spec, &comm);
}

// The model of a built-in problem (--problem).
std::shared_ptr<const Model> builtin_model(const ProblemArgs& p, const TableArgs& args,
                                           RunOptions& run, const Comm& comm) {
  apply_table_args(args, run);
  validate_solver(run.solve);
  if (p.o_glue->count() && parse_glue(p.glue) != Glue::averages)
    run.given_decomposition.push_back("glue");
  if (p.problem == "cube-obstacle") {
    const auto e = parse_int_list(p.o_elements->count() ? p.elements : "10,20,10", "--elements");
    const auto sd =
        parse_int_list(p.o_subdomains->count() ? p.subdomains : "2,4,2", "--subdomains");
    if (p.o_element->count()) throw std::invalid_argument("cube-obstacle uses hex8 elements");
    ProblemSpec spec = cube_obstacle_spec(e, sd, p.cluster_size, p.amplitude);
    spec.glue = parse_glue(p.glue);
    if (run.solve.check_memory) check_memory_before_model(spec, run.solve.feti, comm);
    return make_model(spec);
  }
  if (p.o_amplitude->count())
    throw std::invalid_argument("--obstacle-amplitude is for --problem cube-obstacle");
  for (const auto& [o, flag] :
       {std::pair<const CLI::Option*, const char*>{p.o_objective, "--partition-objective"},
        {p.o_cluster_split, "--cluster-split"},
        {p.o_seed, "--partition-seed"},
        {p.o_jump_ratio, "--partition-jump-ratio"},
        {p.o_shape, "--partition-shape"}})
    if (o->count())
      throw std::invalid_argument(std::string(flag) + " is for problem files split by METIS");
  DecompositionOptions& d = run.solve.decomposition;
  d.problem = parse_problem(p.problem);
  d.element = parse_element(p.element);
  d.glue = parse_glue(p.glue);
  d.cluster_size = p.cluster_size;
  const auto n = parse_int_list(p.elements, "--elements");
  const auto ns = parse_int_list(p.subdomains, "--subdomains");
  if (n.size() != 1 || ns.size() != 1)
    throw std::invalid_argument("--elements and --subdomains take one number for " + p.problem);
  d.elements = n[0];
  d.subdomains = ns[0];
  validate(run.solve);
  return make_builtin_model(d);
}

// Output paths are checked before any work: usable, and not the same file twice.
void check_outputs(const OutputOptions& out, const Comm& comm) {
  if (out.write_report) check_output_path(out.report, "--report");
  if (out.write_xdmf) {
    const auto ext = std::filesystem::path(out.xdmf).extension();
    if (ext != ".xdmf" && ext != ".xmf")
      throw std::invalid_argument("--xdmf '" + out.xdmf + "' must end in .xdmf or .xmf");
    for (const auto& f : xdmf_files(out.xdmf)) {
      check_output_path(f, "--xdmf");
      if (out.write_report && same_file(f, out.report))
        throw std::invalid_argument("--report and --xdmf name the same file '" + f + "'");
    }  // (the VTU's names end in .vtu or .pvtu: never these)
  }
  if (!out.write_vtu) return;
  check_output_path(out.vtu, "--vtu");
  const auto ext = std::filesystem::path(out.vtu).extension();
  if (ext != ".vtu" && ext != ".pvtu")
    throw std::invalid_argument("--vtu '" + out.vtu + "' must end in .vtu or .pvtu");
  for (const auto& f : vtu_files(out.vtu, comm.size())) {
    check_output_path(f, "--vtu");
    if (out.write_report && same_file(f, out.report))
      throw std::invalid_argument("--report and --vtu name the same file '" + f + "'");
  }
}

// --dry-run: what would run, printed on rank 0 (PETSc's -options_view and -ksp_view): the
// problem, the automatic choices with the rule that made them, the memory estimate and every
// option in effect as a problem file's tables. Nothing is set up, solved or written.
int dry_run(const Model& model, RunOptions run, const Comm& comm) {
  FetiOptions feti = run.solve.feti;
  const std::string why = resolve_preconditioner(model, feti);
  std::optional<OperatorCost> cost;
  auto resolve_cost = [&](FetiOptions& o) { cost = resolve_operator_cost(model, o, comm); };
  MemoryEstimate estimate;
  if (run.solve.check_memory)
    estimate = check_memory(model, feti, comm, resolve_cost);
  else
    resolve_cost(feti);
  // What each rank holds after reading and partitioning: the mesh and its peak memory so far.
  const Model::MeshCounts held = model.held();
  const double mine[3] = {static_cast<double>(held.cells), static_cast<double>(held.points),
                          peak_rss_mb()};
  std::vector<double> all(3 * static_cast<size_t>(comm.size()));
  MPI_Gather(mine, 3, MPI_DOUBLE, all.data(), 3, MPI_DOUBLE, 0, comm.raw());
  if (comm.rank() != 0) return 0;
  std::printf("htfeti solve --dry-run: nothing is set up, solved or written\n");
  {
    int fullest = 0;
    double lo[3] = {all[0], all[1], all[2]}, hi[3] = {all[0], all[1], all[2]};
    for (int r = 0; r < comm.size(); ++r)
      for (int i = 0; i < 3; ++i) {
        lo[i] = std::min(lo[i], all[3 * r + i]), hi[i] = std::max(hi[i], all[3 * r + i]);
        if (i == 2 && all[3 * r + 2] >= all[3 * fullest + 2]) fullest = r;
      }
    std::printf(
        "per rank (%d): mesh held %.0f-%.0f cells, %.0f-%.0f nodes; peak memory so far "
        "%.0f-%.0f MB (the most on rank %d)\n",
        comm.size(), lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], fullest);
  }
  std::printf("problem:\n%s\n", model.describe().dump(2).c_str());
  std::printf("choices:\n");
  std::printf("  algorithm: %s\n", model.has_contact() ? "SMALBE-M with MPRGP (contact)"
                                                       : "projected CG (equalities only)");
  std::printf("  preconditioner: %s, scaling %s (%s)\n", to_string(feti.preconditioner).c_str(),
              to_string(feti.scaling).c_str(), why.c_str());
  if (run.solve.check_memory) {
    const char* op = feti.dual_operator == DualOperator::explicit_  ? "explicit"
                     : feti.dual_operator == DualOperator::implicit ? "implicit"
                     : feti.dual_operator == DualOperator::checked  ? "checked"
                     : estimate.explicit_operator                   ? "explicit"
                                                                    : "implicit";
    // Why: the memory check's reasons first, then the rule of the automatic operator.
    std::string reason = "requested";
    if (estimate.explicit_for_memory) {
      reason = "the implicit operator would not fit in memory";
    } else if (estimate.explicit_declined_for_memory) {
      reason =
          "the explicit operator the cost model prefers would take more than 3/4 of the memory";
    } else if (run.solve.feti.dual_operator == DualOperator::automatic) {
      reason = "automatic";
      if (cost) reason += ", " + describe_operator_cost(*cost);
      if (cost && cost->explicit_cheaper())
        reason += run.solve.feti.explicit_budget_bytes < 0
                      ? ", where the run with its F_i fits 3/4 of the memory"
                      : ", where its F_i fit explicit_budget_gb";
    }
    std::printf("  dual operator: %s (%s)\n", op, reason.c_str());
    std::printf("memory estimate: %.0f MB at the peak on the fullest machine, %.0f MB available\n",
                estimate.machine_peak_mb, estimate.available_mb);
  } else {
    std::printf(
        "  dual operator: %s (decided in setup; no memory estimate with memory_check "
        "off)\n",
        to_string(feti.dual_operator).c_str());
    if (cost) std::printf("  %s\n", describe_operator_cost(*cost).c_str());
  }
  std::printf("options in effect (as a problem file's tables):\n%s", options_toml(run).c_str());
  return 0;
}

// Writes the VTU and the report after a solve; the report gets the output's cost.
void write_outputs(SolveOutput& out, const OutputOptions& o, const RunOptions& run,
                   const Comm& comm) {
  out.report["options"] = options_json(run);
  if (o.write_vtu) {
    VtuOptions vo;
    vo.ascii = o.vtu_ascii;
    vo.io = o.vtu_io;
    const double t0 = seconds_now();
    const VtuWritten written = write_vtu(o.vtu, *out.model, *out.dual, out.u, out.lambda, vo);
    const double seconds = comm.max(seconds_now() - t0);
    double bytes = 0;
    for (const auto& f : vtu_files(o.vtu, comm.size())) {
      std::error_code ec;  // (a piece on another machine's disk is not counted)
      const auto n = comm.rank() == 0 ? std::filesystem::file_size(f, ec) : 0;
      if (!ec) bytes += static_cast<double>(n);
    }
    out.report["timings"]["output"] = seconds;
    out.report["output_mb"] = bytes / 1048576.0;
    out.report["output_io"] = written.io;  // (rank 0's piece)
    if (comm.rank() == 0)
      std::printf("  solution: %s (%.0f MB in %.2f s)\n", written.path.c_str(), bytes / 1048576.0,
                  seconds);
  }
  if (o.write_xdmf) {
    const double t0 = seconds_now();
    write_xdmf(o.xdmf, *out.model, *out.dual, out.u, out.lambda);
    const double seconds = comm.max(seconds_now() - t0);
    out.report["timings"]["output_xdmf"] = seconds;
    if (comm.rank() == 0)
      std::printf("  solution: %s and %s (%.2f s)\n", o.xdmf.c_str(), xdmf_files(o.xdmf)[1].c_str(),
                  seconds);
  }
  if (o.write_report) {
    std::string error;
    if (comm.rank() == 0) {
      try {
        write_atomically(o.report, out.report.dump(2));
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
    comm.agree(error);
    if (comm.rank() == 0) std::printf("  report:   %s\n", o.report.c_str());
  }
}

int run(int argc, char** argv, const Comm& comm) {
  if (argc > 1) {
    const std::string first = argv[1];
    if (first != "solve" && first != "spectrum" && first.rfind("-", 0) != 0)
      return fail(comm, "unknown command '" + first + "' (expected solve or spectrum)", 2);
  }
  CLI::App app{
      "htfeti: TFETI and H-TFETI-DP domain decomposition for elliptic problems and "
      "contact (variational inequalities)"};
  app.require_subcommand(1);
  auto* solve_cmd = app.add_subcommand(
      "solve", "solve a problem file (PROBLEM.toml) or a built-in problem (--problem NAME)");
  ProblemArgs problem;
  add_problem_args(solve_cmd, problem);
  TableArgs table;
  add_table_args(solve_cmd, table);
  bool dry = false;
  solve_cmd->add_flag("--dry-run", dry,
                      "print the problem, the automatic choices, the memory estimate and every "
                      "option in effect, and exit without solving or writing anything");

  auto* spec_cmd = app.add_subcommand(
      "spectrum",
      "extreme non-zero eigenvalues of the Schur complement of one floating cluster "
      "of m x m subdomains joined by edge averages, and the estimate (19) (Table 1)");
  int spec_m = 2, spec_n = 64;
  std::string spec_element = "p1";
  bool spec_json = false;
  spec_cmd->add_option("--cluster-size,-m", spec_m, "m: subdomains per cluster side")
      ->capture_default_str()
      ->check(kStrictInt);
  spec_cmd->add_option("--elements,-n", spec_n, "n: elements per cluster side (h = 1/n)")
      ->capture_default_str()
      ->check(kStrictInt);
  spec_cmd->add_option("--element", spec_element, "q1 | p1 (Table 1 matches p1)")
      ->capture_default_str();
  spec_cmd->add_flag("--json", spec_json, "print one JSON object");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return comm.rank() == 0 ? app.exit(e) : 0;
  } catch (const CLI::CallForAllHelp& e) {
    return comm.rank() == 0 ? app.exit(e) : 0;
  } catch (const CLI::ParseError& e) {
    return fail(comm, e.what(), 2);
  }

  if (spec_cmd->parsed()) {
    if (comm.rank() != 0) return 0;
    try {
      return run_spectrum(spec_m, spec_n, spec_element, spec_json);
    } catch (const std::invalid_argument& e) {
      return fail(comm, e.what(), 2);
    }
  }

  // Defaults (the member initializers), then the problem file, then the command line.
  RunOptions opt;
  std::shared_ptr<const Model> model;
  double t_model = 0;  // reading or generating the mesh and splitting it (timings.model)
  try {
    if (!problem.file.empty() && problem.o_problem->count() > 0)
      throw std::invalid_argument("give a problem file or --problem, not both");
    const double t0 = seconds_now();
    model = problem.file.empty() ? builtin_model(problem, table, opt, comm)
                                 : file_model(problem, table, opt, comm);
    t_model = comm.max(seconds_now() - t0);
    if (dry) return dry_run(*model, opt, comm);
    check_outputs(opt.output, comm);
  } catch (const std::invalid_argument& e) {
    return fail(comm, e.what(), 2);
  }

  SolveOutput out = htfeti::solve(model, opt.solve, comm);
  out.report["timings"]["model"] = t_model;
  // Options given a value for a run they do not act in: a warning, and the report says so.
  nlohmann::json unused = nlohmann::json::array();
  for (const UnusedOption& u : unused_options(opt, out.report)) {
    unused.push_back({{"key", u.key}, {"reason", u.reason}});
    if (comm.rank() == 0)
      std::fprintf(stderr, "htfeti: warning: %s%s%s%s has no effect here: %s\n", u.key.c_str(),
                   u.flag.empty() ? "" : " (", u.flag.c_str(), u.flag.empty() ? "" : ")",
                   u.reason.c_str());
  }
  out.report["unused_options"] = unused;
  if (comm.rank() == 0) print_summary(out.report);
  try {
    write_outputs(out, opt.output, opt, comm);
  } catch (const IoError&) {
    throw;
  } catch (const std::runtime_error& e) {  // the VTU writer's errors, agreed on by all ranks
    throw IoError(e.what());
  }
  if (comm.rank() == 0 && std::fflush(stdout) != 0)
    throw IoError("cannot write to standard output");
  return out.converged ? 0 : 3;
}

// Every rank leaves through here. A failure that one rank saw alone, outside an agreement (an
// allocation that failed between two collectives, say), leaves the other ranks waiting for it in
// a collective they will never complete. So the ranks meet in a barrier on a communicator of
// their own before they finish: when every rank arrives (a success, or a failure agreed on or
// seen by all alike) the run ends normally; when a rank that failed has waited kExitWaitSeconds
// for the others, it prints its message and ends the whole job with its exit code (MPI_Abort).
// A rank that succeeded waits: any rank that keeps it waiting is one that failed and will end
// the job. (Cli.AddressSpaceLimitEndsEveryRankWithoutHanging.)
constexpr double kExitWaitSeconds = 10;

void meet_at_exit(MPI_Comm exit_comm, int code, const std::string& failure) {
  int size = 1, rank = 0;
  MPI_Comm_size(exit_comm, &size);
  MPI_Comm_rank(exit_comm, &rank);
  if (size == 1) return;
  MPI_Request request;
  MPI_Ibarrier(exit_comm, &request);
  const double t0 = seconds_now();
  for (int done = 0;;) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    if (code != 0 && seconds_now() - t0 > kExitWaitSeconds) {
      std::fprintf(
          stderr,
          "htfeti: error on rank %d: %s (the other ranks did not reach the end within "
          "%.0f s: ending the job)\n",
          rank, failure.empty() ? ("exit code " + std::to_string(code)).c_str() : failure.c_str(),
          kExitWaitSeconds);
      std::fflush(stderr);
      MPI_Abort(MPI_COMM_WORLD, code);
    }
    usleep(1000);
  }
}

}  // namespace

// Exit codes: 0 solved, 2 bad input (or it does not fit), 3 not converged (the report is
// written), 4 a numerical failure, 5 a value that is not finite (an overflow), 6 an output
// that could not be written (nothing is left behind). Errors raised by the library are agreed on by
// every rank, so every rank leaves through the same path; a failure one rank saw alone ends the
// job after kExitWaitSeconds (meet_at_exit); anything else aborts the MPI job.
int main(int argc, char** argv) {
  // Blocks of 1 MiB and more (matrices, factors, dense blocks) are mapped and unmapped
  // directly. glibc's default raises this threshold to the largest block freed so far, after
  // which freed subdomain matrices stay in the heap, fragmented, while the factors grow: on the
  // 512-subdomain cube the factorization peak was 6.6 GiB instead of 5.0 GiB for the same data.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  // Below that size blocks come from the heaps, and glibc gives a heap's free top back to the
  // system once it exceeds 128 KiB: the setup's per-subdomain work arrays (CHOLMOD's transposes,
  // K_rr, the row lists) then met fresh pages again for every subdomain, and on this machine's
  // virtual machines a fresh page costs far more than its zeroing (docs/performance.md, "Fresh
  // pages"). Up to 32 MiB of free top per heap stays for the next subdomain: 15% fewer page faults
  // on the 40^3 METIS cube, the same peak memory.
  mallopt(M_TRIM_THRESHOLD, 32 << 20);
  // Past a file size limit (ulimit -f) a write fails with EFBIG instead of killing the process,
  // so the writers remove their temporary files and the run ends with exit 6.
  std::signal(SIGXFSZ, SIG_IGN);
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  init_threads();
  MPI_Comm exit_comm;
  MPI_Comm_dup(MPI_COMM_WORLD, &exit_comm);
  int code = 0;
  std::string failure;
  {
    const Comm comm(MPI_COMM_WORLD);
    try {
      code = run(argc, argv, comm);
    } catch (const std::invalid_argument& e) {
      code = fail(comm, failure = e.what(), 2);
    } catch (const std::bad_alloc&) {
      code = fail(comm, failure = "out of memory", 2);
    } catch (const NonFiniteError& e) {
      code = fail(comm, failure = e.what(), 5);
    } catch (const IoError& e) {
      code = fail(comm, failure = e.what(), 6);
    } catch (const std::runtime_error& e) {
      code = fail(comm, failure = e.what(), 4);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "htfeti: internal error on rank %d: %s\n", comm.rank(), e.what());
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
  }
  meet_at_exit(exit_comm, code, failure);
  MPI_Comm_free(&exit_comm);
  MPI_Finalize();
  return code;
}
