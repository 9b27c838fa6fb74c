// htfeti: the command-line program. `htfeti solve` runs the pipeline on a built-in problem;
// `htfeti spectrum` prints the extreme eigenvalues of a cluster Schur complement (Table 1).
// Every option is declared here with its default and help text; `htfeti solve --help` lists them.
#include <malloc.h>
#include <mpi.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <unistd.h>

#include "htfeti/io/vtu.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/parallel/threads.hpp"
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

// Writes text to path through a unique temporary name in the same directory, renamed only when
// complete; a special file (such as /dev/null) is written in place, never replaced.
void write_atomically(const std::string& path, const std::string& text) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
    std::ofstream o(path);
    o << text << '\n';
    o.flush();
    if (!o) throw std::runtime_error("error while writing " + path);
    return;
  }
  const std::string tmp = path + ".htfeti-tmp-" + std::to_string(::getpid());
  {
    std::ofstream o(tmp);
    if (!o) throw std::runtime_error("cannot write " + path);
    o << text << '\n';
    o.flush();
    if (!o) {
      o.close();
      std::filesystem::remove(tmp, ec);
      throw std::runtime_error("error while writing " + path + " (disk full?)");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error("cannot rename the report to " + path);
  }
}

// An output path must be usable before any work: not empty, its directory exists and is
// writable, and it is not a directory.
void check_output_path(const std::string& path, const std::string& option) {
  if (path.empty()) throw std::invalid_argument(option + " is empty");
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) throw std::invalid_argument(option + " '" + path + "' is a directory");
  if (p.filename().empty() || p.filename() == "." || p.filename() == "..")
    throw std::invalid_argument(option + " '" + path + "' names no file");
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  if (!fs::is_directory(dir, ec))
    throw std::invalid_argument(option + " '" + path + "': directory '" + dir.string() +
                                "' does not exist");
  if (::access(dir.c_str(), W_OK) != 0)
    throw std::invalid_argument(option + " '" + path + "': directory '" + dir.string() +
                                "' is not writable");
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
  const int free_motions = std::max(r["unrestrained_rigid_motions"].get<int>(),
                                    r["unrestrained_at_solution"].get<int>());
  if (free_motions > 0)
    std::printf("  note: the solution is not unique: %d rigid motion(s) restrained by no Dirichlet "
                "condition and no active contact; their components are chosen zero\n",
                free_motions);
  std::printf("  %s (%s): %d outer, %d inner iterations, %ld matvecs\n",
              r["converged"].get<bool>() ? "converged" : "NOT converged",
              r["stop_reason"].get<std::string>().c_str(), r["outer_iterations"].get<int>(),
              r["inner_iterations"].get<int>(), r["matvecs"].get<long>());
  const auto& k = r["kkt"];
  std::printf(
      "  energy %.12e; ||B_E u - c_E|| %.2e, max violation %.2e, min multiplier %.2e, "
      "complementarity %.2e\n",
      r["objective"].get<double>(), k["equality_residual"].get<double>(),
      k["max_violation"].get<double>(), k["min_multiplier"].get<double>(),
      k["complementarity"].get<double>());
  const auto& t = r["timings"];
  std::printf(
      "  time: setup %.2f s, factorization %.2f s, coarse %.2f s, solve %.2f s, "
      "reconstruction %.2f s\n",
      t["setup"].get<double>(), t["factorization"].get<double>(), t["coarse_problem"].get<double>(),
      t["solve"].get<double>(), t["reconstruction"].get<double>());
}

// Integers are read strictly: decimal digits only (CLI11 alone accepts "0x10" and " 16").
const CLI::Validator kStrictInt(
    [](std::string& s) {
      const bool ok = !s.empty() && s.size() < 10 &&
                      std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
      return ok ? std::string() : "'" + s + "' is not a non-negative decimal integer";
    },
    "INT");

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
  std::string problem_file, problem = "membranes", element = "q1", glue = "averages",
                            ordering = "auto";
  std::string dual_operator = "auto", elements_text = "128", subdomains_text = "8";
  OutputOptions out_opt;
  bool no_report = false, no_vtu = false, no_memory_check = false;
  SolveOptions opt;
  opt.decomposition.elements = 128;
  opt.decomposition.subdomains = 8;
  solve_cmd->add_option("problem_file", problem_file,
                        "a problem file (TOML, docs/user-guide.md); options given on the command "
                        "line override its keys");
  auto* o_problem =
      solve_cmd->add_option("--problem", problem,
                            "built-in: poisson2d | membranes | membranes-coercive | cube-obstacle")
          ->capture_default_str();
  auto* o_elements =
      solve_cmd
          ->add_option("--elements,-n", elements_text,
                       "built-ins: n, elements per side of each unit square (h = 1/n); a generated "
                       "box: NX,NY[,NZ]")
          ->capture_default_str();
  auto* o_subdomains =
      solve_cmd
          ->add_option("--subdomains", subdomains_text,
                       "built-ins: N_s, subdomains per side of each unit square (n divisible by "
                       "N_s); problem files: N (METIS) or SX,SY[,SZ] (generated box)")
          ->capture_default_str();
  auto* o_m = solve_cmd
                   ->add_option("--cluster-size,-m", opt.decomposition.cluster_size,
                                "m: clusters of m x m (x m) subdomains (1 = TFETI; N_s divisible "
                                "by m); METIS: subdomains per cluster")
                   ->capture_default_str()
                   ->check(kStrictInt)
                   ->check(CLI::PositiveNumber);
  auto* o_glue = solve_cmd
                     ->add_option("--glue", glue,
                                  "primal gluing inside clusters: corners | averages | "
                                  "corners+averages")
                     ->capture_default_str();
  auto* o_element =
      solve_cmd->add_option("--element", element, "built-ins: q1 (bilinear) | p1 (linear triangles)")
          ->capture_default_str();
  auto* o_rtol = solve_cmd->add_option("--rtol", opt.rtol, "relative precision eps, in (0, 1)")
                     ->capture_default_str();
  auto* o_maxit =
      solve_cmd
          ->add_option("--max-it", opt.max_iterations,
                       "iteration limit: PCG iterations, or SMALBE-M outer iterations (0: 1000 / 200)")
          ->capture_default_str()
          ->check(kStrictInt);
  auto* o_ordering = solve_cmd
                         ->add_option("--ordering", ordering,
                                      "fill-reducing ordering of subdomain factors: amd | metis | "
                                      "auto (METIS, except AMD for the implicit operator in 2D); "
                                      "the explicit operator orders the interface last and the "
                                      "rest by constrained AMD (amd) or nested dissection (metis)")
                         ->capture_default_str();
  auto* o_dual =
      solve_cmd
          ->add_option("--dual-operator", dual_operator,
                       "how F is applied: implicit (sparse solves), explicit (dense local blocks "
                       "from Schur complements), auto (explicit from 25 nodes per subdomain)")
          ->capture_default_str();
  std::string precond_text = "auto", scaling_text = "auto";
  auto* o_precond =
      solve_cmd
          ->add_option("--preconditioner", precond_text,
                       "FETI preconditioner: none | lumped (B_D K B_D^T) | dirichlet "
                       "(B_D S B_D^T, S the subdomain Schur complement on the interface) | auto "
                       "(Dirichlet with a coefficient field; elasticity: lumped, but Dirichlet "
                       "for H-TFETI-DP with contact; otherwise none); used by PCG and, in face, by "
                       "MPRGP inside SMALBE-M")
          ->capture_default_str();
  auto* o_scaling =
      solve_cmd
          ->add_option("--scaling", scaling_text,
                       "B_D of the preconditioner: multiplicity | stiffness (weights by the "
                       "diagonal of K, for coefficient jumps between subdomains) | auto "
                       "(stiffness with a coefficient field)")
          ->capture_default_str();
  std::string storage_text = "auto";
  auto* o_storage =
      solve_cmd
          ->add_option("--dirichlet-storage", storage_text,
                       "Dirichlet preconditioner: dense (S_i stored, 8 n_b^2 bytes per subdomain) "
                       "| implicit (applied with a factor of K_ii) | auto (dense when all fit 2 "
                       "GiB per rank)")
          ->check(CLI::IsMember({"auto", "dense", "implicit"}))
          ->capture_default_str();
  int symbolic_cache = 64;
  auto* o_symcache =
      solve_cmd
          ->add_option("--symbolic-cache", symbolic_cache,
                       "subdomain factorizations share the symbolic analysis (ordering, "
                       "supernodes) of subdomains with the same sparsity pattern; at most this "
                       "many patterns are kept per rank (0: analyse every subdomain anew); the "
                       "factors are the same either way")
          ->check(CLI::NonNegativeNumber)
          ->capture_default_str();
  auto* o_keep = solve_cmd->add_flag("--keep-factors", opt.feti.keep_factors,
                      "explicit operator: always keep the subdomain factors during the iterations "
                      "(by default a cluster frees them after its setup, and they are rebuilt for "
                      "the reconstruction, once the available memory, less what the clusters "
                      "still to be set up will allocate, has fallen below 30% of what it was "
                      "when the factorizations began)");
  double numeric_cache_mb = 512;
  auto* o_numcache =
      solve_cmd
          ->add_option("--numeric-cache", numeric_cache_mb,
                       "MB per rank of numeric factors kept for subdomains whose matrix repeats a "
                       "kept one entry for entry (generated boxes): such a subdomain shares the "
                       "kept factor instead of factoring; the factors are the same either way (0: off; "
                       "needs --symbolic-cache > 0)")
          ->check(CLI::NonNegativeNumber)
          ->capture_default_str();
  bool release_factors = false;
  auto* o_release =
      solve_cmd
          ->add_flag("--release-factors", release_factors,
                     "explicit operator: every cluster frees its subdomain factors right after "
                     "its setup and factors again for the reconstruction (the least memory; by "
                     "default factors are freed only once memory runs short)")
          ->excludes(o_keep);
  auto* o_rho =
      solve_cmd
          ->add_option("--rho-factor", opt.smalbe.rho_factor, "SMALBE-M penalty rho = factor * ||PFP||")
          ->capture_default_str();
  auto* o_M0 =
      solve_cmd
          ->add_option("--M0-factor", opt.smalbe.M0_factor, "SMALBE-M initial M = factor * ||PFP||")
          ->capture_default_str();
  auto* o_eta =
      solve_cmd->add_option("--eta-factor", opt.smalbe.eta_factor, "SMALBE-M eta = factor * ||b||")
          ->capture_default_str();
  auto* o_beta =
      solve_cmd
          ->add_option("--beta", opt.smalbe.beta, "SMALBE-M: M is divided by beta on a failed test")
          ->capture_default_str();
  auto* o_gamma =
      solve_cmd->add_option("--gamma", opt.smalbe.gamma, "MPRGP proportioning parameter Gamma")
          ->capture_default_str();
  auto* o_report = solve_cmd->add_option("--report", out_opt.report, "write the report JSON here")
                       ->capture_default_str();
  solve_cmd->add_flag("--no-report", no_report, "do not write a report");
  auto* o_vtu = solve_cmd
                    ->add_option("--vtu", out_opt.vtu,
                                 "write the solution for ParaView here (.vtu, or .pvtu with "
                                 "several ranks; binary)")
                    ->capture_default_str();
  solve_cmd->add_flag("--no-vtu", no_vtu, "do not write VTU output");
  double explicit_budget_gb = opt.feti.explicit_budget_bytes / (1 << 30);
  auto* o_expbudget =
      solve_cmd
          ->add_option("--explicit-budget", explicit_budget_gb,
                       "GB per rank: --dual-operator auto takes the explicit operator only when "
                       "its F_i fit this, or when the implicit operator would not fit in memory")
          ->check(CLI::NonNegativeNumber)
          ->capture_default_str();
  double memory_limit_gb = 0;
  auto* o_memlimit =
      solve_cmd
          ->add_option("--memory-limit", memory_limit_gb,
                       "GB the solve may use on each machine (default: the machine's available "
                       "memory); the memory check, the automatic dual operator and the factor "
                       "release count with it")
          ->check(CLI::PositiveNumber);
  solve_cmd->add_flag("--no-memory-check", no_memory_check,
                      "skip the memory estimate before setup (exit 2 when the estimate exceeds "
                      "the available memory)");
  double amplitude = 1.0;
  auto* o_amplitude =
      solve_cmd
          ->add_option("--obstacle-amplitude", amplitude,
                       "cube-obstacle: the obstacle is u_z >= -A sin(pi x / 50) (A = 1: every "
                       "bottom node ends in contact; larger A: partial contact)")
          ->capture_default_str();
  auto* o_ascii = solve_cmd->add_flag("--vtu-ascii", out_opt.vtu_ascii, "write the VTU as ASCII");
  auto* o_vtu_io =
      solve_cmd
          ->add_option("--vtu-io", out_opt.vtu_io,
                       "how the binary VTU reaches the disk: buffered (through the page cache), "
                       "direct (whole 4 KiB blocks by direct I/O from the writer's buffers, the "
                       "rest through the page cache; buffered where the file system refuses "
                       "it) or auto (direct for a piece of 256 MiB and more)")
          ->check(CLI::IsMember({"auto", "buffered", "direct"}))
          ->capture_default_str();
  std::string precision_text = "double";
  auto* o_precision =
      solve_cmd
          ->add_option("--explicit-precision", precision_text,
                       "storage of the explicit F_i (lower triangle, packed): double | single "
                       "(half the memory and bytes per F; values rounded to single precision, "
                       "sums in double)")
          ->check(CLI::IsMember({"double", "single"}))
          ->capture_default_str();
  int coarse_steps = 2;
  auto* o_coarse_steps =
      solve_cmd
          ->add_option("--coarse-steps-per-product", coarse_steps,
                       "coarse steps per SMALBE-M Hessian product: 2 (P, F, P) | 1 (F, then one "
                       "reduction with E = F G~^T formed in setup; memory and setup time, for "
                       "many ranks)")
          ->check(CLI::IsMember({1, 2}))
          ->capture_default_str();
  std::string norm_text = "power";
  auto* o_norm = solve_cmd
                     ->add_option("--norm-estimate", norm_text,
                                  "SMALBE-M's estimate of ||PFP||: power (power method) | "
                                  "lanczos (largest Ritz value of the Lanczos process); at most "
                                  "50 products, relative change 1e-3")
                     ->check(CLI::IsMember({"lanczos", "power"}))
                     ->capture_default_str();
  auto* o_progress =
      solve_cmd->add_flag("--progress", opt.progress, "print one line per (outer) iteration");

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

  std::shared_ptr<const Model> model;
  try {
    if (!problem_file.empty() && o_problem->count() > 0)
      throw std::invalid_argument("give a problem file or --problem, not both");
    if (!problem_file.empty()) {
      // Defaults, then the file, then what the command line gives.
      SolveOptions from_file;
      ProblemSpec spec = read_problem_file(problem_file, from_file, out_opt);
      if (o_rtol->count()) from_file.rtol = opt.rtol;
      if (o_maxit->count()) from_file.max_iterations = opt.max_iterations;
      if (o_ordering->count()) from_file.feti.ordering = parse_ordering(ordering);
      if (o_dual->count()) from_file.feti.dual_operator = parse_dual_operator(dual_operator);
      if (o_keep->count()) from_file.feti.keep_factors = opt.feti.keep_factors;
      if (o_precond->count()) from_file.feti.preconditioner = parse_preconditioner(precond_text);
      if (o_scaling->count()) from_file.feti.scaling = parse_scaling(scaling_text);
      if (o_storage->count())
        from_file.feti.dirichlet_storage = storage_text == "dense" ? 1 : storage_text == "implicit" ? 2 : 0;
      if (o_rho->count()) from_file.smalbe.rho_factor = opt.smalbe.rho_factor;
      if (o_M0->count()) from_file.smalbe.M0_factor = opt.smalbe.M0_factor;
      if (o_eta->count()) from_file.smalbe.eta_factor = opt.smalbe.eta_factor;
      if (o_beta->count()) from_file.smalbe.beta = opt.smalbe.beta;
      if (o_gamma->count()) from_file.smalbe.gamma = opt.smalbe.gamma;
      if (o_progress->count()) from_file.progress = opt.progress;
      if (o_subdomains->count()) spec.subdomains = parse_int_list(subdomains_text, "--subdomains");
      if (o_m->count()) spec.cluster_size = opt.decomposition.cluster_size;
      if (o_glue->count()) spec.glue = parse_glue(glue);
      if (!spec.builtin.empty() && o_elements->count()) {
        const auto e = parse_int_list(elements_text, "--elements");
        if (e.size() != 1) throw std::invalid_argument("--elements takes one number for a built-in");
        spec.builtin_options.elements = e[0];
      } else if (o_elements->count()) {
        if (!spec.mesh_file.empty())
          throw std::invalid_argument("--elements is for generated boxes, not mesh files");
        const auto e = parse_int_list(elements_text, "--elements");
        if (static_cast<int>(e.size()) != spec.box.dim)
          throw std::invalid_argument("--elements needs " + std::to_string(spec.box.dim) +
                                      " numbers for this box");
        for (int d = 0; d < spec.box.dim; ++d) spec.box.elements[d] = e[d];
      }
      if (o_amplitude->count())
        throw std::invalid_argument("--obstacle-amplitude is for --problem cube-obstacle");
      if (o_element->count() && spec.builtin.empty())
        throw std::invalid_argument("--element is for the built-in problems; set mesh.element");
      if (o_element->count()) spec.builtin_options.element = parse_element(element);
      if (o_report->count()) out_opt.report = o_report->as<std::string>(), out_opt.write_report = true;
      if (o_vtu->count()) out_opt.vtu = o_vtu->as<std::string>(), out_opt.write_vtu = true;
      if (o_ascii->count()) out_opt.vtu_ascii = true;
      if (o_vtu_io->count()) out_opt.vtu_io = o_vtu_io->as<std::string>();
      opt = from_file;
      validate_solver(opt);
      model = make_model(spec);
    } else if (problem == "cube-obstacle") {
      const auto e = parse_int_list(o_elements->count() ? elements_text : "10,20,10", "--elements");
      const auto sd = parse_int_list(o_subdomains->count() ? subdomains_text : "2,4,2", "--subdomains");
      if (o_element->count()) throw std::invalid_argument("cube-obstacle uses hex8 elements");
      ProblemSpec spec = cube_obstacle_spec(e, sd, opt.decomposition.cluster_size, amplitude);
      spec.glue = parse_glue(glue);
      opt.feti.ordering = parse_ordering(ordering);
      opt.feti.dual_operator = parse_dual_operator(dual_operator);
      opt.feti.preconditioner = parse_preconditioner(precond_text);
      opt.feti.scaling = parse_scaling(scaling_text);
      opt.feti.dirichlet_storage = storage_text == "dense" ? 1 : storage_text == "implicit" ? 2 : 0;
      validate_solver(opt);
      model = make_model(spec);
    } else {
      if (o_amplitude->count())
        throw std::invalid_argument("--obstacle-amplitude is for --problem cube-obstacle");
      opt.decomposition.problem = parse_problem(problem);
      opt.decomposition.element = parse_element(element);
      opt.decomposition.glue = parse_glue(glue);
      const auto n = parse_int_list(elements_text, "--elements");
      const auto ns = parse_int_list(subdomains_text, "--subdomains");
      if (n.size() != 1 || ns.size() != 1)
        throw std::invalid_argument("--elements and --subdomains take one number for " + problem);
      opt.decomposition.elements = n[0];
      opt.decomposition.subdomains = ns[0];
      opt.feti.ordering = parse_ordering(ordering);
      opt.feti.dual_operator = parse_dual_operator(dual_operator);
      opt.feti.preconditioner = parse_preconditioner(precond_text);
      opt.feti.scaling = parse_scaling(scaling_text);
      opt.feti.dirichlet_storage = storage_text == "dense" ? 1 : storage_text == "implicit" ? 2 : 0;
      validate(opt);
      model = make_builtin_model(opt.decomposition);
    }
    if (o_symcache->count()) opt.feti.symbolic_cache_patterns = symbolic_cache;
    if (o_numcache->count()) opt.feti.numeric_cache_bytes = numeric_cache_mb * 1048576.0;
    if (release_factors) {
      if (opt.feti.keep_factors)
        throw std::invalid_argument("--release-factors contradicts solver.keep_factors = true");
      opt.feti.factor_budget_bytes = 0;
    }
    if (o_norm->count()) opt.norm_estimate = qp::parse_norm_estimate(norm_text);
    if (o_coarse_steps->count()) opt.coarse_steps_per_product = coarse_steps;
    if (o_precision->count()) opt.feti.explicit_precision = parse_precision(precision_text);
    if (no_report) out_opt.write_report = false;
    if (no_vtu) out_opt.write_vtu = false;
    if (no_memory_check) opt.check_memory = false;
    if (o_memlimit->count()) opt.feti.memory_limit_mb = memory_limit_gb * 1024.0;
    if (o_expbudget->count()) opt.feti.explicit_budget_bytes = explicit_budget_gb * (1 << 30);
    if (out_opt.write_report) check_output_path(out_opt.report, "--report");
    if (out_opt.write_vtu) {
      check_output_path(out_opt.vtu, "--vtu");
      const auto ext = std::filesystem::path(out_opt.vtu).extension();
      if (ext != ".vtu" && ext != ".pvtu")
        throw std::invalid_argument("--vtu '" + out_opt.vtu + "' must end in .vtu or .pvtu");
      for (const auto& f : vtu_files(out_opt.vtu, comm.size())) {
        check_output_path(f, "--vtu");
        if (out_opt.write_report &&
            std::filesystem::weakly_canonical(f) == std::filesystem::weakly_canonical(out_opt.report))
          throw std::invalid_argument("--report and --vtu name the same file '" + f + "'");
      }
    }
  } catch (const std::invalid_argument& e) {
    return fail(comm, e.what(), 2);
  }

  SolveOutput out = htfeti::solve(model, opt, comm);
  if (comm.rank() == 0) print_summary(out.report);
  if (out_opt.write_vtu) {
    VtuOptions vo;
    vo.ascii = out_opt.vtu_ascii;
    vo.io = parse_vtu_io(out_opt.vtu_io);
    const auto t0 = std::chrono::steady_clock::now();
    const VtuWritten written = write_vtu(out_opt.vtu, *out.model, *out.dual, out.u, out.lambda, vo);
    const std::string& where = written.path;
    const double seconds =
        comm.max(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    double bytes = 0;
    for (const auto& f : vtu_files(out_opt.vtu, comm.size())) {
      std::error_code ec;  // (a piece on another machine's disk is not counted)
      const auto n = comm.rank() == 0 ? std::filesystem::file_size(f, ec) : 0;
      if (!ec) bytes += static_cast<double>(n);
    }
    // The output's cost in the report (written after it): seconds and size of the VTU files.
    out.report["timings"]["output"] = seconds;
    out.report["output_mb"] = bytes / 1048576.0;
    out.report["output_io"] = written.io;  // (rank 0's piece)
    if (comm.rank() == 0)
      std::printf("  solution: %s (%.0f MB in %.2f s)\n", where.c_str(), bytes / 1048576.0, seconds);
  }
  if (out_opt.write_report) {
    std::string error;
    if (comm.rank() == 0) {
      try {
        write_atomically(out_opt.report, out.report.dump(2));
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
    comm.agree(error);
    if (comm.rank() == 0) std::printf("  report:   %s\n", out_opt.report.c_str());
  }
  if (comm.rank() == 0 && std::fflush(stdout) != 0)
    throw std::runtime_error("cannot write to standard output");
  return out.converged ? 0 : 3;
}

}  // namespace

// Exit codes: 0 solved, 2 bad input (or it does not fit), 3 not converged (the report is
// written), 4 a numerical failure. Errors raised by the library are agreed on by every rank, so
// every rank leaves through the same path; anything else aborts the MPI job.
int main(int argc, char** argv) {
  // Blocks of 1 MiB and more (matrices, factors, dense blocks) are mapped and unmapped
  // directly. glibc's default raises this threshold to the largest block freed so far, after
  // which freed subdomain matrices stay in the heap, fragmented, while the factors grow: on the
  // 512-subdomain cube the factorization peak was 6.6 GiB instead of 5.0 GiB for the same data.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  init_threads();
  int code = 0;
  {
    const Comm comm(MPI_COMM_WORLD);
    try {
      code = run(argc, argv, comm);
    } catch (const std::invalid_argument& e) {
      code = fail(comm, e.what(), 2);
    } catch (const std::bad_alloc&) {
      code = fail(comm, "out of memory", 2);
    } catch (const std::runtime_error& e) {
      code = fail(comm, e.what(), 4);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "htfeti: internal error on rank %d: %s\n", comm.rank(), e.what());
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
  }
  MPI_Finalize();
  return code;
}
