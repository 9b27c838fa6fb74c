// htfeti: the command-line program. `htfeti solve` runs the pipeline on a built-in problem;
// `htfeti spectrum` prints the extreme eigenvalues of a cluster Schur complement (Table 1).
// Every option is declared here with its default and help text; `htfeti solve --help` lists them.
#include <mpi.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "htfeti/io/vtu.hpp"
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

void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream o(tmp);
    if (!o) throw std::runtime_error("cannot write " + path);
    o << text << '\n';
    if (!o) throw std::runtime_error("error while writing " + path);
  }
  std::filesystem::rename(tmp, path);
}

void print_summary(const nlohmann::json& r) {
  std::printf(
      "htfeti: %s, %s elements, n = %d, %d subdomains (H/h = %d), %d clusters of %dx%d (%s)\n",
      r["problem"].get<std::string>().c_str(), r["element"].get<std::string>().c_str(),
      r["elements"].get<int>(), r["subdomains"].get<int>(), r["H_over_h"].get<int>(),
      r["clusters"].get<int>(), r["cluster_size"].get<int>(), r["cluster_size"].get<int>(),
      r["glue"].get<std::string>().c_str());
  std::printf(
      "  primal %lld, dual %lld (%lld equalities, %lld inequalities), coarse %d, %d ranks x %d "
      "threads\n",
      r["primal_dimension"].get<long long>(), r["dual_dimension"].get<long long>(),
      r["equalities"].get<long long>(), r["inequalities"].get<long long>(),
      r["coarse_dimension"].get<int>(), r["ranks"].get<int>(), r["threads"].get<int>());
  std::printf("  %s (%s): %d outer, %d inner iterations, %ld matvecs\n",
              r["converged"].get<bool>() ? "converged" : "NOT converged",
              r["stop_reason"].get<std::string>().c_str(), r["outer_iterations"].get<int>(),
              r["inner_iterations"].get<int>(), r["matvecs"].get<long>());
  const auto& k = r["kkt"];
  std::printf(
      "  energy %.12e; ||B_E u|| %.2e, max violation %.2e, min multiplier %.2e, "
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

int run(int argc, char** argv, const Comm& comm) {
  CLI::App app{
      "htfeti: TFETI and H-TFETI-DP domain decomposition for elliptic problems and "
      "contact (variational inequalities)"};
  app.require_subcommand(1);
  auto* solve_cmd = app.add_subcommand("solve", "solve a built-in problem");
  std::string problem = "membranes", element = "q1", glue = "averages", ordering = "amd";
  std::string dual_operator = "auto";
  std::string report = "htfeti-report.json", vtu = "htfeti-solution.vtu";
  bool no_report = false, no_vtu = false;
  SolveOptions opt;
  opt.decomposition.elements = 128;
  opt.decomposition.subdomains = 8;
  solve_cmd->add_option("--problem", problem, "poisson2d | membranes | membranes-coercive")
      ->capture_default_str();
  solve_cmd
      ->add_option("--elements,-n", opt.decomposition.elements,
                   "n: elements per side of each unit square (h = 1/n)")
      ->capture_default_str();
  solve_cmd
      ->add_option("--subdomains", opt.decomposition.subdomains,
                   "N_s: subdomains per side of each unit square (n divisible by N_s)")
      ->capture_default_str();
  solve_cmd
      ->add_option("--cluster-size,-m", opt.decomposition.cluster_size,
                   "m: clusters of m x m subdomains (1 = TFETI; N_s divisible by m)")
      ->capture_default_str();
  solve_cmd
      ->add_option("--glue", glue,
                   "primal gluing inside clusters: corners | averages | "
                   "corners+averages")
      ->capture_default_str();
  solve_cmd->add_option("--element", element, "q1 (bilinear) | p1 (linear triangles)")
      ->capture_default_str();
  solve_cmd->add_option("--rtol", opt.rtol, "relative precision eps, in (0, 1)")
      ->capture_default_str();
  solve_cmd
      ->add_option("--max-it", opt.max_iterations,
                   "iteration limit: PCG iterations, or SMALBE-M outer iterations (0: 1000 / 200)")
      ->capture_default_str();
  solve_cmd
      ->add_option("--ordering", ordering,
                   "fill-reducing ordering of subdomain factors: amd | metis")
      ->capture_default_str();
  solve_cmd
      ->add_option("--dual-operator", dual_operator,
                   "how F is applied: implicit (sparse solves), explicit (dense local blocks "
                   "from Schur complements), auto (explicit from 25 nodes per subdomain)")
      ->capture_default_str();
  solve_cmd->add_flag("--keep-factors", opt.feti.keep_factors,
                      "explicit operator: always keep the subdomain factors during the iterations "
                      "(by default they are freed, and rebuilt for the reconstruction, when they "
                      "would take more than 4 GiB per rank)");
  solve_cmd
      ->add_option("--rho-factor", opt.smalbe.rho_factor, "SMALBE-M penalty rho = factor * ||PFP||")
      ->capture_default_str();
  solve_cmd
      ->add_option("--M0-factor", opt.smalbe.M0_factor, "SMALBE-M initial M = factor * ||PFP||")
      ->capture_default_str();
  solve_cmd->add_option("--eta-factor", opt.smalbe.eta_factor, "SMALBE-M eta = factor * ||b||")
      ->capture_default_str();
  solve_cmd
      ->add_option("--beta", opt.smalbe.beta, "SMALBE-M: M is divided by beta on a failed test")
      ->capture_default_str();
  solve_cmd->add_option("--gamma", opt.smalbe.gamma, "MPRGP proportioning parameter Gamma")
      ->capture_default_str();
  solve_cmd->add_option("--report", report, "write the report JSON here")->capture_default_str();
  solve_cmd->add_flag("--no-report", no_report, "do not write a report");
  solve_cmd
      ->add_option("--vtu", vtu,
                   "write the solution for ParaView here (.vtu, or .pvtu with "
                   "several ranks)")
      ->capture_default_str();
  solve_cmd->add_flag("--no-vtu", no_vtu, "do not write VTU output");
  solve_cmd->add_flag("--progress", opt.progress, "print one line per (outer) iteration");

  auto* spec_cmd = app.add_subcommand(
      "spectrum",
      "extreme non-zero eigenvalues of the Schur complement of one floating cluster "
      "of m x m subdomains joined by edge averages, and the estimate (19) (Table 1)");
  int spec_m = 2, spec_n = 64;
  std::string spec_element = "p1";
  bool spec_json = false;
  spec_cmd->add_option("--cluster-size,-m", spec_m, "m: subdomains per cluster side")
      ->capture_default_str();
  spec_cmd->add_option("--elements,-n", spec_n, "n: elements per cluster side (h = 1/n)")
      ->capture_default_str();
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

  try {
    opt.decomposition.problem = parse_problem(problem);
    opt.decomposition.element = parse_element(element);
    opt.decomposition.glue = parse_glue(glue);
    opt.feti.ordering = parse_ordering(ordering);
    opt.feti.dual_operator = parse_dual_operator(dual_operator);
    validate(opt);
  } catch (const std::invalid_argument& e) {
    return fail(comm, e.what(), 2);
  }

  SolveOutput out = htfeti::solve(opt, comm);
  if (comm.rank() == 0) print_summary(out.report);
  if (!no_vtu) {
    const std::string where = write_vtu(vtu, *out.model, *out.dual, out.u, out.lambda);
    if (comm.rank() == 0) std::printf("  solution: %s\n", where.c_str());
  }
  if (!no_report && comm.rank() == 0) {
    write_atomically(report, out.report.dump(2));
    std::printf("  report:   %s\n", report.c_str());
  }
  return out.converged ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  init_threads();
  int code = 0;
  {
    const Comm comm(MPI_COMM_WORLD);
    try {
      code = run(argc, argv, comm);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "htfeti: error on rank %d: %s\n", comm.rank(), e.what());
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
  }
  MPI_Finalize();
  return code;
}
