// The options table (options.hpp). Each row binds a problem-file key and a flag to one member of
// RunOptions; the builders below keep a row to its name, help and range.
#include "htfeti/options.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace htfeti {

namespace {

constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;

[[noreturn]] void refuse(const std::string& msg) { throw std::invalid_argument(msg); }

double as_number(const OptionValue& v) {
  if (const double* d = std::get_if<double>(&v)) return *d;
  if (const long long* i = std::get_if<long long>(&v)) return static_cast<double>(*i);
  refuse("must be a number");
}

long long as_integer(const OptionValue& v) {
  if (const long long* i = std::get_if<long long>(&v)) return *i;
  refuse("must be an integer");
}

bool as_bool(const OptionValue& v) {
  if (const bool* b = std::get_if<bool>(&v)) return *b;
  refuse("must be true or false");
}

const std::string& as_text(const OptionValue& v) {
  if (const std::string* s = std::get_if<std::string>(&v)) return *s;
  refuse("must be a string");
}

// A number option stored as a double member; `check` returns an error message or nullptr.
using NumberRef = double& (*)(RunOptions&);
using NumberCheck = const char* (*)(double);

OptionSpec number(const char* key, const char* flag, const char* help, NumberRef ref,
                  NumberCheck check) {
  return {"solver",
          key,
          flag,
          "",
          OptionType::number,
          "",
          help,
          {},
          [ref, check](RunOptions& r, const OptionValue& v) {
            const double x = as_number(v);
            if (!std::isfinite(x)) refuse("must be a finite number");
            if (const char* msg = check(x)) refuse(msg);
            ref(r) = x;
          },
          [ref](const RunOptions& r) { return nlohmann::json(ref(const_cast<RunOptions&>(r))); }};
}

// A memory size in GB (GiB: 2^30 bytes) stored in bytes.
OptionSpec gigabytes(const char* key, const char* flag, const char* help, NumberRef bytes) {
  return {"solver",
          key,
          flag,
          "",
          OptionType::number,
          "GB",
          help,
          {},
          [bytes](RunOptions& r, const OptionValue& v) {
            const double x = as_number(v);
            if (!std::isfinite(x) || x < 0) refuse("must be a non-negative number of GB");
            if (x > 1e9) refuse("must be at most 1e9 GB");
            bytes(r) = x * kGiB;
          },
          [bytes](const RunOptions& r) {
            return nlohmann::json(bytes(const_cast<RunOptions&>(r)) / kGiB);
          }};
}

using IntRef = int& (*)(RunOptions&);

OptionSpec integer(const char* key, const char* flag, const char* help, IntRef ref, long long lo,
                   long long hi, const char* section = "solver") {
  return {section,
          key,
          flag,
          "",
          OptionType::integer,
          "",
          help,
          {},
          [ref, lo, hi](RunOptions& r, const OptionValue& v) {
            const long long x = as_integer(v);
            if (x < lo || x > hi)
              refuse("must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                     " (got " + std::to_string(x) + ")");
            ref(r) = static_cast<int>(x);
          },
          [ref](const RunOptions& r) { return nlohmann::json(ref(const_cast<RunOptions&>(r))); }};
}

using BoolRef = bool& (*)(RunOptions&);

OptionSpec boolean(const char* section, const char* key, const char* flag,
                   const char* negative_flag, const char* help, BoolRef ref) {
  return {section,
          key,
          flag,
          negative_flag,
          OptionType::boolean,
          "",
          help,
          {},
          [ref](RunOptions& r, const OptionValue& v) { ref(r) = as_bool(v); },
          [ref](const RunOptions& r) { return nlohmann::json(ref(const_cast<RunOptions&>(r))); }};
}

template <class E, size_t N>
OptionSpec choice(const char* section, const char* key, const char* flag, const char* help,
                  const std::array<EnumName<E>, N>& names, E& (*ref)(RunOptions&)) {
  return {section,
          key,
          flag,
          "",
          OptionType::choice,
          "",
          help,
          names_of(names),
          [ref, &names, key](RunOptions& r, const OptionValue& v) {
            ref(r) = parse_name(names, as_text(v), key);
          },
          [ref, &names](const RunOptions& r) {
            return nlohmann::json(name_of(names, ref(const_cast<RunOptions&>(r))));
          }};
}

// An output file: a name, or false (the --no- flag) for none.
OptionSpec path(const char* key, const char* flag, const char* negative_flag, const char* help,
                std::string& (*name)(RunOptions&), bool& (*write)(RunOptions&)) {
  return {"output",
          key,
          flag,
          negative_flag,
          OptionType::path,
          "",
          help,
          {},
          [name, write](RunOptions& r, const OptionValue& v) {
            if (const bool* b = std::get_if<bool>(&v)) {
              if (*b) refuse("give a file name or false");
              write(r) = false;
              return;
            }
            if (!std::holds_alternative<std::string>(v)) refuse("must be a file name or false");
            const std::string& s = std::get<std::string>(v);
            if (s.empty()) refuse("is empty (give a file name or false)");
            name(r) = s;
            write(r) = true;
          },
          [name, write](const RunOptions& r) {
            auto& rr = const_cast<RunOptions&>(r);
            return write(rr) ? nlohmann::json(name(rr)) : nlohmann::json(false);
          }};
}

enum class DirichletStorage { automatic, dense, implicit };
constexpr std::array<EnumName<DirichletStorage>, 3> kDirichletStorageNames{
    {{DirichletStorage::automatic, "auto"},
     {DirichletStorage::dense, "dense"},
     {DirichletStorage::implicit, "implicit"}}};

// The QP solvers: precision, limits, SMALBE-M and MPRGP parameters.
void add_qp_options(std::vector<OptionSpec>& t) {
  t.push_back(number(
      "rtol", "--rtol", "relative precision eps of PCG and SMALBE-M, in (0, 1) (the paper: 1e-4)",
      [](RunOptions& r) -> double& { return r.solve.rtol; },
      [](double x) -> const char* { return x > 0 && x < 1 ? nullptr : "must lie in (0, 1)"; }));
  t.push_back(integer(
      "max_iterations", "--max-it",
      "iteration limit: PCG iterations, or SMALBE-M outer iterations (0: 1000 / 200)",
      [](RunOptions& r) -> int& { return r.solve.max_iterations; }, 0, 100000000));
  t.push_back(number(
      "coulomb_rtol", "--coulomb-rtol",
      "Coulomb friction: the fixed point on the slip bound stops when the bounds change by at "
      "most this, relative",
      [](RunOptions& r) -> double& { return r.solve.coulomb_rtol; },
      [](double x) -> const char* { return x > 0 && x < 1 ? nullptr : "must lie in (0, 1)"; }));
  t.back().scope = OptionScope::coulomb;
  t.push_back(integer(
      "coulomb_max_iterations", "--coulomb-max-it",
      "Coulomb friction: at most this many Tresca solves in the fixed point",
      [](RunOptions& r) -> int& { return r.solve.coulomb_max_iterations; }, 1, 10000));
  t.back().scope = OptionScope::coulomb;
  t.push_back(choice(
      "solver", "mprgp_expansion", "--mprgp-expansion",
      "MPRGP's expansion step: gradient (fixed length 2 / ||H|| along the free gradient) | "
      "preconditioned (along the preconditioned free gradient with its optimal length, one "
      "more product) | projected-cg (the whole CG step, projected; undone, at one more "
      "product, where it would cost more than the feasible half step) | auto (projected-cg "
      "where the whole CG step moves the multipliers at least twice as far as the fixed-length "
      "step, else gradient). projected-cg and auto need fewer products where expansion steps are "
      "many (METIS-split contact problems: the report's solver.expansion_steps), projected-cg "
      "more on graded Hertz-like blocks (docs/performance.md). Friction in 3D runs MPGP, which "
      "has none of these: a variant asked for there is not used, and a warning says so",
      qp::kExpansionNames,
      +[](RunOptions& r) -> qp::Expansion& { return r.solve.smalbe.expansion; }));
  t.back().scope = OptionScope::contact;
  t.push_back(choice(
      "solver", "norm_estimate", "--norm-estimate",
      "SMALBE-M's estimate of ||PFP||: power (power method) | lanczos (largest Ritz value of the "
      "Lanczos process); at most 50 products, relative change 1e-3",
      qp::kNormEstimateNames,
      +[](RunOptions& r) -> qp::NormEstimate& { return r.solve.norm_estimate; }));
  t.back().scope = OptionScope::contact;
  t.push_back(integer(
      "coarse_steps_per_product", "--coarse-steps-per-product",
      "coarse steps per SMALBE-M Hessian product: 2 (P, F, P) | 1 (F, then one "
      "reduction with E = F G~^T formed in setup; memory and setup time, for "
      "many ranks)",
      [](RunOptions& r) -> int& { return r.solve.coarse_steps_per_product; }, 1, 2));
  t.back().scope = OptionScope::contact;
  auto positive = [](double x) -> const char* {
    return x > 0 && x <= 1e6 ? nullptr : "must lie in (0, 1e6]";
  };
  t.push_back(number(
      "perturb_load", "--perturb-load",
      "a robustness check of the iteration counts: every load entry times 1 + delta r, r in "
      "[-1, 1] fixed by its global dof (0: the load as given; bench/perturbation.py)",
      [](RunOptions& r) -> double& { return r.solve.perturb_load; },
      [](double x) -> const char* {
        return std::abs(x) <= 1e-3 ? nullptr : "must lie in [-1e-3, 1e-3]";
      }));
  t.push_back(number(
      "rho_factor", "--rho-factor", "SMALBE-M penalty rho = factor * ||PFP||",
      [](RunOptions& r) -> double& { return r.solve.smalbe.rho_factor; }, positive));
  t.back().scope = OptionScope::contact;
  t.push_back(number(
      "M0_factor", "--M0-factor", "SMALBE-M initial M = factor * ||PFP||",
      [](RunOptions& r) -> double& { return r.solve.smalbe.M0_factor; },
      [](double x) -> const char* {
        return x > 0 && x <= 1e12 ? nullptr : "must lie in (0, 1e12]";
      }));
  t.back().scope = OptionScope::contact;
  t.push_back(number(
      "eta_factor", "--eta-factor", "SMALBE-M eta = factor * ||b||",
      [](RunOptions& r) -> double& { return r.solve.smalbe.eta_factor; }, positive));
  t.back().scope = OptionScope::contact;
  t.push_back(number(
      "beta", "--beta", "SMALBE-M: M is divided by beta on a failed test (> 1)",
      [](RunOptions& r) -> double& { return r.solve.smalbe.beta; },
      [](double x) -> const char* {
        return x > 1 && x <= 1e6 ? nullptr : "must lie in (1, 1e6]";
      }));
  t.back().scope = OptionScope::contact;
  t.push_back(number(
      "rho_update_late", "--rho-update-late",
      "SMALBE-M: once only the equality test is left, rho is multiplied by this after each "
      "outer iteration (1: rho stays fixed)",
      [](RunOptions& r) -> double& { return r.solve.smalbe.rho_update_late; },
      [](double x) -> const char* {
        return x >= 1 && x <= 1e3 ? nullptr : "must lie in [1, 1e3]";
      }));
  t.back().scope = OptionScope::contact;
  t.push_back(boolean(
      "solver", "face_solve", "--face-solve", "--no-face-solve",
      "SMALBE-M: after an inner solve, on the active set where it ended (once per active set), "
      "and first in a continuation, solve on that face by projected CG with the equality held "
      "exactly (the coarse matrix of the free rows) and take the face's equality multiplier; "
      "where it stops short, SMALBE-M restarts from there (docs/method.md, \"The face solve\")",
      [](RunOptions& r) -> bool& { return r.solve.smalbe.face_solve; }));
  t.back().scope = OptionScope::contact;
  t.push_back(integer(
      "face_changes", "--face-changes",
      "SMALBE-M's face solve: how many times one face solve may change its face and go on "
      "(a CG step that would leave the bounds: the step onto the first bound, that row held; a "
      "held row to be freed: the held rows with a chopped gradient freed; each a new coarse "
      "matrix of the free rows and a CG restart) before it ends and SMALBE-M goes on; it also "
      "ends at the fourth bound in a row reached by the first CG step on its face (0: every "
      "face solve ends at the first bound or release)",
      [](RunOptions& r) -> int& { return r.solve.smalbe.face_changes; }, 0, 1000000));
  t.back().scope = OptionScope::contact;
  t.push_back(number(
      "gamma", "--gamma", "MPRGP proportioning parameter Gamma",
      [](RunOptions& r) -> double& { return r.solve.smalbe.gamma; }, positive));
  t.back().scope = OptionScope::contact;
  t.push_back(boolean("solver", "progress", "--progress", "",
                      "print one line per (outer) iteration (standard error, rank 0)",
                      [](RunOptions& r) -> bool& { return r.solve.progress; }));
}

// The FETI operators: dual operator, preconditioner, ordering, coarse space.
void add_feti_options(std::vector<OptionSpec>& t) {
  t.push_back(choice(
      "solver", "dual_operator", "--dual-operator",
      "how F is applied: implicit (sparse solves), explicit (dense local blocks from Schur "
      "complements), checked (explicit, compared with implicit at every product: the report's "
      "dual_operator_check; about twice the cost, factors kept), auto (explicit where a cost "
      "model of both operators' setup and F, counted on sampled subdomains, says it pays back "
      "within the expected applications of F and the blocks fit explicit_budget_gb, or when the "
      "implicit operator would not fit in memory; the report's dual_operator_model)",
      kDualOperatorNames,
      +[](RunOptions& r) -> DualOperator& { return r.solve.feti.dual_operator; }));
  t.push_back(choice(
      "solver", "explicit_precision", "--explicit-precision",
      "storage of the explicit F_i (lower triangle, packed): double | single (half the memory "
      "and bytes per F; values rounded to single precision, sums in double)",
      kPrecisionNames,
      +[](RunOptions& r) -> Precision& { return r.solve.feti.explicit_precision; }));
  t.back().scope = OptionScope::explicit_operator;
  t.push_back(choice(
      "solver", "factor_precision", "--factor-precision",
      "what the implicit operator's factor sweeps read: double (the subdomain factors) | single "
      "(single-precision copies of the factors, sums in double: half the bytes per F for 50% "
      "more factor memory; the converged solve is then checked with the factors, one product, "
      "and finished with them if the check fails, so the result meets rtol for the exact "
      "operator) | auto (single for TFETI's implicit operator; H-TFETI-DP's clusters with "
      "corners or averages and the explicit operator: double)",
      kFactorPrecisionNames,
      +[](RunOptions& r) -> FactorPrecision& { return r.solve.feti.factor_precision; }));
  t.push_back(choice(
      "solver", "ordering", "--ordering",
      "fill-reducing ordering of subdomain factors: amd | metis (METIS's nested dissection) | "
      "nesdis (CHOLMOD's nested dissection: METIS's separators, constrained AMD on parts of 200 "
      "rows: 2-3% smaller factors in 3D, a slower analysis) | auto (METIS, except AMD for the "
      "implicit operator in 2D); "
      "the explicit operator orders the interface last and the rest by constrained AMD (amd) "
      "or nested dissection (metis, nesdis)",
      kOrderingNames, +[](RunOptions& r) -> Ordering& { return r.solve.feti.ordering; }));
  t.push_back(choice(
      "solver", "preconditioner", "--preconditioner",
      "FETI preconditioner: none | lumped (B_D K B_D^T) | dirichlet (B_D S B_D^T, S the "
      "subdomain Schur complement on the interface) | auto (Dirichlet with a coefficient field; "
      "elasticity: lumped; otherwise none); used by "
      "PCG and, in face, by MPRGP inside SMALBE-M",
      kPreconditionerNames,
      +[](RunOptions& r) -> PreconditionerKind& { return r.solve.feti.preconditioner; }));
  t.push_back(choice(
      "solver", "scaling", "--scaling",
      "B_D of the preconditioner: multiplicity | stiffness (weights by the diagonal of K, for "
      "coefficient jumps between subdomains) | auto (stiffness with a coefficient field)",
      kScalingNames, +[](RunOptions& r) -> Scaling& { return r.solve.feti.scaling; }));
  t.back().scope = OptionScope::preconditioned;
  t.push_back(choice(
      "solver", "pcg_projector", "--pcg-projector",
      "the projector in PCG's preconditioner (no contact): orthogonal (P M^-1 P) | weighted "
      "(P_Q M^-1 P_Q^T, Q the stiffness of each multiplier's copies: for coefficient jumps "
      "between subdomains; needs stiffness scaling) | auto (weighted with stiffness scaling "
      "where no subdomain's coefficient varies by more than 10 times, else orthogonal)",
      kPcgProjectorNames, +[](RunOptions& r) -> PcgProjector& { return r.solve.pcg_projector; }));
  t.back().scope = OptionScope::pcg;
  t.push_back({"solver", "dirichlet_storage", "--dirichlet-storage", "", OptionType::choice, "",
               "Dirichlet preconditioner: dense (S_i stored, 8 n_b^2 bytes per subdomain) | "
               "implicit (applied with a factor of K_ii) | auto (3D: implicit; 2D: dense when "
               "all fit dirichlet_budget_gb per rank)",
               names_of(kDirichletStorageNames),
               [](RunOptions& r, const OptionValue& v) {
                 r.solve.feti.dirichlet_storage = static_cast<int>(
                     parse_name(kDirichletStorageNames, as_text(v), "dirichlet storage"));
               },
               [](const RunOptions& r) {
                 return nlohmann::json(
                     name_of(kDirichletStorageNames,
                             static_cast<DirichletStorage>(r.solve.feti.dirichlet_storage)));
               }});
  t.back().scope = OptionScope::dirichlet;
  t.push_back(integer(
      "dirichlet_layers", "--dirichlet-layers",
      "Dirichlet preconditioner: 0 the Schur complement on the whole interior of each "
      "subdomain; k >= 1 only the k layers of interior dofs next to the interface, the rest "
      "clamped (an approximate Dirichlet preconditioner: a smaller setup and application, "
      "iterations between lumped and Dirichlet)",
      [](RunOptions& r) -> int& { return r.solve.feti.dirichlet_layers; }, 0, 1000000));
  t.back().scope = OptionScope::dirichlet;
  t.push_back(gigabytes(
      "dirichlet_budget_gb", "--dirichlet-budget",
      "GB per rank: with dirichlet_storage = auto in 2D the Dirichlet preconditioner stores its "
      "S_i dense when they fit this, else applies them with a factor of K_ii",
      [](RunOptions& r) -> double& { return r.solve.feti.dirichlet_dense_budget_bytes; }));
}

// Memory: limits, budgets and caches (GB).
void add_memory_options(std::vector<OptionSpec>& t) {
  t.push_back({"solver",
               "explicit_budget_gb",
               "--explicit-budget",
               "",
               OptionType::number,
               "GB",
               "GB per rank: --dual-operator auto takes the explicit operator only when its F_i "
               "fit this, or when the implicit operator would not fit in memory (default "
               "automatic: the F_i fit when the memory check estimates the whole run with them at "
               "most 3/4 of each machine's memory; 4 GB with --no-memory-check)",
               {},
               [](RunOptions& r, const OptionValue& v) {
                 const double x = as_number(v);
                 if (!std::isfinite(x) || x < 0) refuse("must be a non-negative number of GB");
                 if (x > 1e9) refuse("must be at most 1e9 GB");
                 r.solve.feti.explicit_budget_bytes = x * kGiB;
               },
               [](const RunOptions& r) {
                 const double b = r.solve.feti.explicit_budget_bytes;
                 return b >= 0 ? nlohmann::json(b / kGiB) : nlohmann::json(nullptr);
               }});
  t.back().scope = OptionScope::automatic_operator;
  t.push_back({"solver",
               "memory_limit_gb",
               "--memory-limit",
               "",
               OptionType::number,
               "GB",
               "GB the solve may use on each machine (default none: the machine's available "
               "memory); the memory check, the automatic dual operator and the factor release "
               "count with it",
               {},
               [](RunOptions& r, const OptionValue& v) {
                 const double x = as_number(v);
                 if (!std::isfinite(x) || !(x > 0)) refuse("must be a positive number of GB");
                 if (x > 1e9) refuse("must be at most 1e9 GB");
                 r.solve.feti.memory_limit_mb = x * 1024.0;
               },
               [](const RunOptions& r) {
                 const double mb = r.solve.feti.memory_limit_mb;
                 return mb != 0 ? nlohmann::json(mb / 1024.0) : nlohmann::json(nullptr);
               }});
  t.push_back(boolean("solver", "memory_check", "", "--no-memory-check",
                      "estimate the memory before setup, and stop with exit 2 when the estimate "
                      "exceeds the available memory (--no-memory-check: skip the estimate)",
                      [](RunOptions& r) -> bool& { return r.solve.check_memory; }));
  t.push_back(boolean(
      "solver", "keep_factors", "--keep-factors", "",
      "explicit operator: always keep the subdomain factors during the iterations (by default a "
      "cluster frees them after its setup, and they are rebuilt for the reconstruction, once the "
      "available memory, less what the clusters still to be set up will allocate, has fallen "
      "below 30% of what it was when the factorizations began)",
      [](RunOptions& r) -> bool& { return r.solve.feti.keep_factors; }));
  t.push_back(
      {"solver",
       "release_factors",
       "--release-factors",
       "",
       OptionType::boolean,
       "",
       "explicit operator: every cluster frees its subdomain factors right after its "
       "setup and factors again for the reconstruction (the least memory; by default "
       "factors are freed only once memory runs short)",
       {},
       [](RunOptions& r, const OptionValue& v) {
         r.solve.feti.factor_budget_bytes = as_bool(v) ? 0.0 : -1.0;
       },
       [](const RunOptions& r) { return nlohmann::json(r.solve.feti.factor_budget_bytes == 0); }});
  t.push_back(integer(
      "coarse_ranks", "--coarse-ranks",
      "ranks that hold the coarse factor (G G^T): 0 every rank; K splits the ranks into K groups "
      "of consecutive ranks, the first of each factors and solves and sends the solution to the "
      "rest (memory: one factor per group, e.g. per machine; the same solution bit for bit)",
      [](RunOptions& r) -> int& { return r.solve.feti.coarse_ranks; }, 0, 1000000000));
  t.push_back(integer(
      "symbolic_cache", "--symbolic-cache",
      "subdomain factorizations share the symbolic analysis (ordering, supernodes) of "
      "subdomains with the same sparsity pattern; at most this many patterns are kept per rank "
      "(0: analyse every subdomain anew); the factors are the same either way",
      [](RunOptions& r) -> int& { return r.solve.feti.symbolic_cache_patterns; }, 0, 1000000));
  t.push_back(gigabytes(
      "numeric_cache_gb", "--numeric-cache",
      "GB per rank of numeric factors kept for subdomains whose matrix repeats a kept one entry "
      "for entry (generated boxes): such a subdomain shares the kept factor instead of "
      "factoring; the factors are the same either way (0: off; needs symbolic_cache > 0)",
      [](RunOptions& r) -> double& { return r.solve.feti.numeric_cache_bytes; }));
}

// Output: the report and the VTU file.
void add_output_options(std::vector<OptionSpec>& t) {
  t.push_back(path(
      "report", "--report", "--no-report", "the report JSON (false: none)",
      [](RunOptions& r) -> std::string& { return r.output.report; },
      [](RunOptions& r) -> bool& { return r.output.write_report; }));
  t.push_back(path(
      "vtu", "--vtu", "--no-vtu",
      "the solution for ParaView (.vtu, or .pvtu with several ranks; binary; false: "
      "none)",
      [](RunOptions& r) -> std::string& { return r.output.vtu; },
      [](RunOptions& r) -> bool& { return r.output.write_vtu; }));
  t.push_back(path(
      "xdmf", "--xdmf", "--no-xdmf",
      "the solution as XDMF + HDF5 for ParaView (FILE.xdmf and FILE.h5 beside it: one HDF5 file "
      "written by all ranks through MPI-IO, for large runs; false: none, the default)",
      [](RunOptions& r) -> std::string& { return r.output.xdmf; },
      [](RunOptions& r) -> bool& { return r.output.write_xdmf; }));
  t.push_back(boolean("output", "vtu_ascii", "--vtu-ascii", "", "write the VTU as ASCII",
                      [](RunOptions& r) -> bool& { return r.output.vtu_ascii; }));
  t.back().scope = OptionScope::vtu_output;
  t.push_back(choice(
      "output", "vtu_io", "--vtu-io",
      "how the binary VTU reaches the disk: buffered (through the page cache), direct (whole 4 "
      "KiB blocks by direct I/O from the writer's buffers, the rest through the page cache; "
      "buffered where the file system refuses it) or auto (direct for a piece of 256 MiB and "
      "more)",
      kVtuIoNames, +[](RunOptions& r) -> VtuIo& { return r.output.vtu_io; }));
  t.back().scope = OptionScope::vtu_output;
  t.push_back(integer(
      "report_contact_rows", "--report-contact-rows",
      "the report's per-row contact arrays (`contact`: coordinates, displacements, gaps, forces) "
      "are written up to this many contact rows; above it the report has their count and the "
      "summary per condition only (the arrays are gathered on rank 0 and shared with every rank, "
      "memory proportional to the rows on each; the VTU has the values per node); 0: never",
      [](RunOptions& r) -> int& { return r.solve.report_contact_rows; }, 0, 1000000000, "output"));
}

// The table, one row per option, in the order of --help (grouped as the four parts above).
std::vector<OptionSpec> build_table() {
  std::vector<OptionSpec> t;
  add_qp_options(t);
  add_feti_options(t);
  add_memory_options(t);
  add_output_options(t);
  return t;
}

}  // namespace

const std::vector<OptionSpec>& option_table() {
  static const std::vector<OptionSpec> table = build_table();
  return table;
}

const OptionSpec* find_option(const std::string& section, const std::string& key) {
  for (const auto& o : option_table())
    if (section == o.section && key == o.key) return &o;
  return nullptr;
}

OptionValue parse_option_text(const OptionSpec& spec, const std::string& text) {
  switch (spec.type) {
    case OptionType::boolean:
      if (text == "true") return true;
      if (text == "false") return false;
      refuse("'" + text + "' is not true or false");
    case OptionType::integer: {
      long long v = 0;
      const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
      const bool digits = !text.empty() && (text[0] >= '0' && text[0] <= '9');
      if (!digits || r.ec != std::errc() || r.ptr != text.data() + text.size())
        refuse("'" + text + "' is not a non-negative decimal integer (or it is too large)");
      return v;
    }
    case OptionType::number: {
      double v = 0;
      const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
      if (text.empty() || r.ec != std::errc() || r.ptr != text.data() + text.size())
        refuse("'" + text + "' is not a number");
      if (!std::isfinite(v)) refuse("'" + text + "' is not a finite number");
      return v;
    }
    case OptionType::choice:
    case OptionType::path:
      return text;
  }
  refuse("unknown option type");
}

void set_option(RunOptions& run, const OptionSpec& spec, const OptionValue& value,
                const std::string& where) {
  try {
    spec.set(run, value);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(where + ": " + e.what());
  }
  if (std::find(run.given.begin(), run.given.end(), &spec) == run.given.end())
    run.given.push_back(&spec);
}

std::vector<UnusedOption> unused_options(const RunOptions& run, const nlohmann::json& report) {
  // What the run turned out to be, from the report's resolved settings.
  const auto text = [&](const nlohmann::json& j, const char* key) {
    return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
  };
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& solver = report.contains("solver") ? report["solver"] : none;
  const std::string algorithm = text(solver, "algorithm");
  const bool contact = algorithm.rfind("smalbe", 0) == 0;
  const bool coulomb = solver.contains("coulomb");
  const std::string preconditioner = text(report, "preconditioner");
  const std::string op = text(report, "dual_operator");
  const std::string op_reason = text(report, "dual_operator_reason");
  const RunOptions defaults;
  std::vector<UnusedOption> out;
  for (const OptionSpec* o : run.given) {
    if (o->get(run) == o->get(defaults)) continue;  // the default: nothing was asked
    std::string why;
    switch (o->scope) {
      case OptionScope::every_run:
        break;
      case OptionScope::contact:
        if (!contact) why = "the problem has no contact rows: PCG solves it, not SMALBE-M";
        break;
      case OptionScope::coulomb:
        if (!coulomb) why = "the problem has no Coulomb friction";
        break;
      case OptionScope::pcg:
        if (contact) why = "the problem has contact rows: SMALBE-M solves it, not PCG";
        break;
      case OptionScope::preconditioned:
        if (preconditioner == "none") why = "no preconditioner is built (preconditioner none)";
        break;
      case OptionScope::dirichlet:
        if (preconditioner != "dirichlet")
          why = "the preconditioner is " + preconditioner + ", not dirichlet";
        break;
      case OptionScope::vtu_output:
        if (!run.output.write_vtu) why = "no VTU is written (--no-vtu, output.vtu = false)";
        break;
      case OptionScope::explicit_operator:
        if (op != "explicit") why = "the dual operator is " + op + ", not explicit";
        break;
      case OptionScope::automatic_operator:
        if (op_reason == "requested")
          why = "the dual operator " + op + " is requested, not chosen by --dual-operator auto";
        break;
    }
    if (!why.empty())
      out.push_back({std::string(o->section) + "." + o->key, o->flag, std::move(why)});
  }
  const bool clusters = report.contains("clusters") && report.contains("subdomains") &&
                        report["clusters"] != report["subdomains"];
  for (const std::string& key : run.given_decomposition)
    if (!clusters)
      out.push_back({"decomposition." + key, key == "glue" ? "--glue" : "--cluster-split",
                     "every cluster is one subdomain (TFETI): there is nothing to glue inside "
                     "clusters, nor clusters to form"});
  return out;
}

void check_option_combinations(const RunOptions& run) {
  if (run.solve.feti.keep_factors && run.solve.feti.factor_budget_bytes == 0)
    refuse(
        "solver.keep_factors (--keep-factors) and solver.release_factors (--release-factors) "
        "contradict each other");
  if (run.solve.pcg_projector == PcgProjector::weighted &&
      (run.solve.feti.preconditioner == PreconditionerKind::none ||
       run.solve.feti.scaling == Scaling::multiplicity))
    refuse(
        "solver.pcg_projector = weighted (--pcg-projector) weights by the stiffness scaling: it "
        "needs a preconditioner (--preconditioner lumped or dirichlet) and --scaling stiffness "
        "(or auto with a coefficient field)");
}

nlohmann::json options_json(const RunOptions& run) {
  nlohmann::json j = {{"solver", nlohmann::json::object()}, {"output", nlohmann::json::object()}};
  for (const auto& o : option_table()) j[o.section][o.key] = o.get(run);
  return j;
}

std::string options_toml(const RunOptions& run) {
  std::ostringstream s;
  for (const char* section : {"solver", "output"}) {
    s << "[" << section << "]\n";
    for (const auto& o : option_table()) {
      if (std::string(o.section) != section) continue;
      const nlohmann::json v = o.get(run);
      if (v.is_null())
        s << "# " << o.key << " = (none)\n";
      else
        s << o.key << " = " << v.dump() << "\n";
    }
  }
  return s.str();
}

}  // namespace htfeti
