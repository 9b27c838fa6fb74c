// TFETI and H-TFETI-DP for the membranes variational inequality against the undecomposed
// problem solved by a primal-dual active set method, with two coarse steps per Hessian product
// and with one; runs under mpiexec -n 1, 2, 4.
#include <gtest/gtest.h>

#include "helpers.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

struct Case {
  ProblemKind problem;
  int n, ns, m;
  const char* glue;
};

class ContactAgainstUndecomposed : public ::testing::TestWithParam<Case> {};

TEST_P(ContactAgainstUndecomposed, EnergyAndContactDisplacements) {
  const Case c = GetParam();
  Comm comm;
  SolveOptions opt;
  opt.decomposition = {c.problem, ElementKind::q1, c.n, c.ns, c.m, parse_glue(c.glue)};
  opt.rtol = 1e-10;
  const auto ref = solve_undecomposed(c.problem, ElementKind::q1, c.n);
  // Both forms of SMALBE-M's Hessian product through the same checks.
  for (int steps : {2, 1}) {
    SCOPED_TRACE("coarse steps per product: " + std::to_string(steps));
    opt.coarse_steps_per_product = steps;
    auto out = solve(opt, comm);
    ASSERT_TRUE(out.converged) << out.report["stop_reason"];
    EXPECT_EQ(out.report["coarse_steps_per_product"].get<int>(), steps);
    // The coercive membranes' least-squares lambda~ has negative contact entries, and their
    // Dirichlet rows restrain every rigid motion: lambda~ from the equality rows alone. The
    // floating membranes have no such lambda~ (the right one is held by contact alone).
    EXPECT_EQ(out.report["lambda_tilde"],
              c.problem == ProblemKind::membranes_coercive ? "equality rows" : "least squares");
    const double energy = out.report["objective"];
    EXPECT_NEAR(energy, ref.energy, 1e-6 * std::abs(ref.energy));
    EXPECT_LT(test::relative_error(*out.model, *out.dual, out.u, ref.u), 1e-5);
    const auto& contact = out.report["contact"];
    ASSERT_EQ(contact["y"].size(), ref.contact_y.size());
    double umax = 0, fmax = 0;
    for (size_t j = 0; j < ref.contact_y.size(); ++j) {
      umax = std::max({umax, std::abs(ref.u_left[j]), std::abs(ref.u_right[j])});
      fmax = std::max(fmax, std::abs(ref.multiplier[j]));
    }
    for (size_t j = 0; j < ref.contact_y.size(); ++j) {
      EXPECT_NEAR(contact["y"][j].get<double>(), ref.contact_y[j], 1e-14);
      EXPECT_NEAR(contact["u_left"][j].get<double>(), ref.u_left[j], 1e-5 * umax) << "node " << j;
      EXPECT_NEAR(contact["u_right"][j].get<double>(), ref.u_right[j], 1e-5 * umax) << "node " << j;
      EXPECT_NEAR(contact["multiplier"][j].get<double>(), ref.multiplier[j], 1e-4 * fmax)
          << "node " << j;
    }
    // KKT conditions of the primal solution, each on its own scale (min_multiplier >= 0 holds by
    // construction of lambda and is not checked here): feasibility, complementarity
    // |force x gap| per contact node, and the equality rows B_E u = c_E.
    const auto& kkt = out.report["kkt"];
    EXPECT_LT(kkt["max_violation"].get<double>(), 1e-6 * umax);
    EXPECT_LE(kkt["complementarity"].get<double>(), 1e-6 * umax * fmax);
    EXPECT_LT(kkt["equality_residual"].get<double>(), 1e-6 * umax);
  }
}

INSTANTIATE_TEST_SUITE_P(Tfeti, ContactAgainstUndecomposed,
                         ::testing::Values(Case{ProblemKind::membranes, 8, 2, 1, "averages"},
                                           Case{ProblemKind::membranes, 24, 4, 1, "averages"},
                                           Case{ProblemKind::membranes, 30, 5, 1, "averages"},
                                           Case{ProblemKind::membranes_coercive, 16, 4, 1,
                                                "averages"}));

INSTANTIATE_TEST_SUITE_P(
    HTfetiDp, ContactAgainstUndecomposed,
    ::testing::Values(Case{ProblemKind::membranes, 16, 4, 2, "averages"},
                      Case{ProblemKind::membranes, 24, 6, 3, "corners"},
                      Case{ProblemKind::membranes, 32, 8, 4, "corners+averages"},
                      Case{ProblemKind::membranes_coercive, 24, 4, 2, "averages"}));

// SMALBE-M's face solve (qp/face_cg.hpp) on and off: both reach the undecomposed solution, the
// face solve ends the TFETI solves where it is on (both coarse-step forms; on the H-TFETI-DP
// clusters here SMALBE-M converges before an inner solve has ended twice on one active set), and
// off it is never taken. Under mpiexec -n 1, 2, 4 like the suite above.
TEST(FaceSolve, OnAndOffReachTheUndecomposedSolution) {
  Comm comm;
  const auto ref = solve_undecomposed(ProblemKind::membranes, ElementKind::q1, 24);
  for (int m : {1, 2})
    for (int steps : {2, 1}) {
      SCOPED_TRACE("m " + std::to_string(m) + ", steps " + std::to_string(steps));
      SolveOptions opt;
      opt.rtol = 1e-10;
      opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 24, 4, m, Glue::averages};
      opt.coarse_steps_per_product = steps;
      const auto on = solve(opt, comm);
      opt.smalbe.face_solve = false;
      const auto off = solve(opt, comm);
      ASSERT_TRUE(on.converged);
      ASSERT_TRUE(off.converged);
      if (m == 1) EXPECT_GE(on.report["solver"]["face_converged"].get<int>(), 1);
      EXPECT_EQ(off.report["solver"]["face_solves"].get<int>(), 0);
      for (const auto* out : {&on, &off}) {
        EXPECT_NEAR(out->report["objective"].get<double>(), ref.energy,
                    1e-8 * std::abs(ref.energy));
        EXPECT_LT(test::relative_error(*out->model, *out->dual, out->u, ref.u), 1e-6);
      }
      // Ended by the face solve, G lambda = e holds to round-off.
      if (on.report["solver"]["face_converged"].get<int>() > 0)
        EXPECT_LT(on.report["solver"]["equality_residual"].get<double>(),
                  1e-12 * on.report["solver"]["multiplier_norm"].get<double>());
    }
}

// Single-precision sweeps (FetiOptions::factor_precision) with the implicit operator: TFETI's
// solve reads the factors' single-precision copies, then is checked and, where the check fails,
// finished with the factors, so it reaches the undecomposed solution as the double sweeps do.
// At rtol 1e-10 the copies' operator cannot pass the exact operator's test (its perturbation is
// far above 1e-10), so the check must go on with the factors: more than the one product of a
// check that passes. H-TFETI-DP's clusters (corners or averages) keep the double sweeps. The
// same for PCG without contact. Under mpiexec -n 1, 2, 4 like the suites above.
TEST(FactorPrecision, SingleSweepsAreCheckedAndFinishedWithTheFactors) {
  Comm comm;
  for (ProblemKind kind : {ProblemKind::membranes, ProblemKind::poisson2d}) {
    const auto ref = solve_undecomposed(kind, ElementKind::q1, 24);
    for (int m : {1, 2})
      for (double rtol : {1e-10, 1e-5})
        for (FactorPrecision fp : {FactorPrecision::automatic, FactorPrecision::double_}) {
          SCOPED_TRACE(to_string(kind) + ", m " + std::to_string(m) + ", rtol " +
                       std::to_string(rtol) + ", " + name_of(kFactorPrecisionNames, fp));
          SolveOptions opt;
          opt.rtol = rtol;
          opt.decomposition = {kind, ElementKind::q1, 24, 4, m, Glue::averages};
          opt.feti.dual_operator = DualOperator::implicit;
          opt.feti.factor_precision = fp;
          const auto out = solve(opt, comm);
          ASSERT_TRUE(out.converged) << out.report["stop_reason"];
          const bool single = fp == FactorPrecision::automatic && m == 1;
          EXPECT_EQ(out.report["factor_precision"], single ? "single" : "double");
          const auto& sv = out.report["solver"];
          EXPECT_EQ(sv.contains("single_sweeps"), single);
          if (single) {
            EXPECT_GT(out.report["memory"]["single_factor_mb"].get<double>(), 0.0);
            const long check = sv["single_sweeps"]["check_products"].get<long>();
            if (rtol < 1e-8)
              EXPECT_GE(check, 2);
            else
              EXPECT_GE(check, 1);
          }
          if (rtol < 1e-8) {
            EXPECT_NEAR(out.report["objective"].get<double>(), ref.energy,
                        1e-8 * std::abs(ref.energy));
            EXPECT_LT(test::relative_error(*out.model, *out.dual, out.u, ref.u), 1e-6);
          } else {
            EXPECT_NEAR(out.report["objective"].get<double>(), ref.energy,
                        1e-4 * std::abs(ref.energy));
          }
        }
  }
}

TEST(FactorsReleased, SameSolutionWhenFactorsAreRebuiltForTheReconstruction) {
  Comm comm;
  SolveOptions opt;
  opt.rtol = 1e-10;
  opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 32, 4, 2, Glue::averages};
  const auto kept = solve(opt, comm);
  opt.feti.factor_budget_bytes = 0;  // force: free after setup, refactor for u
  const auto released = solve(opt, comm);
  EXPECT_FALSE(kept.report["factors_released"].get<bool>());
  EXPECT_TRUE(released.report["factors_released"].get<bool>());
  // The iterations use only the explicit F_i: the same iterates. The reconstruction factors
  // again without the interface last (a plain factor): the same u to round-off.
  EXPECT_EQ(kept.report["matvecs"], released.report["matvecs"]);
  EXPECT_EQ(kept.report["solver"]["projected_gradient"],
            released.report["solver"]["projected_gradient"]);
  const double e0 = kept.report["objective"], e1 = released.report["objective"];
  EXPECT_NEAR(e1, e0, 1e-13 * std::abs(e0));
  ASSERT_EQ(kept.u.size(), released.u.size());
  double diff = 0, norm = 0;
  for (size_t s = 0; s < kept.u.size(); ++s)
    diff = std::max(diff, (kept.u[s] - released.u[s]).cwiseAbs().maxCoeff()),
    norm = std::max(norm, kept.u[s].cwiseAbs().maxCoeff());
  EXPECT_LT(diff, 1e-12 * norm);
  EXPECT_TRUE(kept.lambda == released.lambda);
}

// The coarse factor on a subset of ranks (FetiOptions::coarse_ranks: the first rank of each
// group factors and solves, then broadcasts): the same solution bit for bit as with the factor on
// every rank, through every coarse solve: the projections (two coarse steps per product, and one
// with the coarse image), lambda~, H-TFETI-DP, and the reconstruction's weighted coarse problem
// on the membranes with one element per side, whose floating membrane has no contact force at
// the solution (a singular coarse matrix: the dense path on every rank).
TEST(CoarseRanks, SameSolutionBitForBitWithTheFactorOnFewerRanks) {
  Comm comm;
  struct C {
    int n, ns, m, steps;
  };
  for (const C c : {C{24, 4, 1, 2}, C{24, 4, 1, 1}, C{16, 4, 2, 2}, C{2, 1, 1, 2}}) {
    SCOPED_TRACE("n " + std::to_string(c.n) + ", m " + std::to_string(c.m) + ", steps " +
                 std::to_string(c.steps));
    SolveOptions opt;
    opt.rtol = 1e-8;
    opt.decomposition = {ProblemKind::membranes, ElementKind::q1, c.n, c.ns, c.m, Glue::averages};
    opt.coarse_steps_per_product = c.steps;
    const auto every = solve(opt, comm);
    ASSERT_TRUE(every.converged);
    EXPECT_EQ(every.report["memory"]["coarse_factor_ranks"].get<int>(), comm.size());
    if (c.n == 2) EXPECT_EQ(every.report["unrestrained_at_solution"].get<int>(), 1);
    for (int k : {1, 2}) {
      opt.feti.coarse_ranks = k;
      const auto subset = solve(opt, comm);
      EXPECT_EQ(subset.report["memory"]["coarse_factor_ranks"].get<int>(), std::min(k, comm.size()))
          << k;
      EXPECT_EQ(subset.report["memory"]["coarse_factor_nonzeros"],
                every.report["memory"]["coarse_factor_nonzeros"]);
      EXPECT_EQ(subset.report["objective"].get<double>(), every.report["objective"].get<double>())
          << k;
      EXPECT_EQ(subset.report["matvecs"], every.report["matvecs"]) << k;
      EXPECT_EQ(subset.report["unrestrained_at_solution"],
                every.report["unrestrained_at_solution"]);
      EXPECT_TRUE(subset.lambda == every.lambda) << k;
      ASSERT_EQ(subset.u.size(), every.u.size());
      for (size_t s = 0; s < every.u.size(); ++s) EXPECT_TRUE(subset.u[s] == every.u[s]) << k;
    }
  }
}

// Single-precision F_i: the values are rounded to 2^-24 relative, the sums stay in double; the
// contact solution moves by about that rounding (measured 2e-9 in energy on Table 3 reduced), so
// the energy agrees with the double-precision one to 1e-7, and the blocks take half the bytes.
TEST(ExplicitPrecision, SingleGivesTheDoubleSolutionToItsRounding) {
  Comm comm;
  for (int m : {1, 2}) {
    SolveOptions opt;
    opt.rtol = 1e-8;
    opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 32, 4, m, Glue::averages};
    opt.feti.dual_operator = DualOperator::explicit_;
    const auto d = solve(opt, comm);
    opt.feti.explicit_precision = Precision::single;
    const auto s = solve(opt, comm);
    ASSERT_TRUE(d.converged && s.converged) << m;
    EXPECT_EQ(s.report["explicit_precision"], "single");
    const double ed = d.report["objective"], es = s.report["objective"];
    EXPECT_NEAR(es, ed, 1e-7 * std::abs(ed)) << m;
    EXPECT_LT(s.report["kkt"]["max_violation"].get<double>(), 1e-6);
    EXPECT_LT(s.report["memory"]["explicit_mb"].get<double>(),
              0.6 * d.report["memory"]["explicit_mb"].get<double>());
  }
}

// Shared symbolic analyses change nothing but the setup time: identical reports with the cache
// on and off, for the implicit and the explicit operator, TFETI and H-TFETI-DP; the box's
// subdomains have few patterns.
TEST(SubdomainCache, SameResultsWithAndWithoutSharedAnalyses) {
  Comm comm;
  for (DualOperator op : {DualOperator::implicit, DualOperator::explicit_})
    for (int m : {1, 2}) {
      SolveOptions opt;
      opt.rtol = 1e-8;
      opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 32, 4, m, Glue::averages};
      opt.feti.dual_operator = op;
      opt.feti.symbolic_cache_patterns = 0;
      const auto off = solve(opt, comm);
      opt.feti.symbolic_cache_patterns = 64;
      opt.feti.numeric_cache_bytes = 0;
      const auto on = solve(opt, comm);
      opt.feti.numeric_cache_bytes = 512.0 * (1 << 20);  // equal matrices copy their factor
      const auto numeric = solve(opt, comm);
      for (const auto* r : {&on, &numeric}) {
        EXPECT_EQ(r->report["objective"], off.report["objective"]) << "m = " << m;
        EXPECT_EQ(r->report["matvecs"], off.report["matvecs"]);
        ASSERT_EQ(r->u.size(), off.u.size());
        for (size_t i = 0; i < off.u.size(); ++i) EXPECT_TRUE(r->u[i] == off.u[i]) << i;
      }
      EXPECT_EQ(off.report["factorization"]["symbolic_reuses"], 0);
      const long long subdomains = comm.sum(static_cast<long long>(on.u.size()));
      const long long reuses = on.report["factorization"]["symbolic_reuses"];
      const long long analyses = on.report["factorization"]["symbolic_analyses"];
      EXPECT_EQ(reuses + analyses, subdomains);
      EXPECT_LE(analyses, 9 * comm.size());  // corner, edge, interior types (+ contact sides)
      EXPECT_EQ(on.report["factorization"]["numeric_reuses"], 0);
      const auto& f = numeric.report["factorization"];
      EXPECT_GT(f["numeric_reuses"].get<long long>(), 0) << "m = " << m;
      EXPECT_EQ(f["numeric_reuses"].get<long long>() + f["symbolic_reuses"].get<long long>() +
                    f["symbolic_analyses"].get<long long>(),
                subdomains);
      // When the factors are shared (numeric cache), the clusters' K_i^+ C_i^T come from an
      // equal subdomain's solve and are held once (both operators), and so does K_i^+ f_i of d
      // with the explicit operator (interface-last factors), with the results above unchanged
      // bit for bit. The implicit operator without clusters (m = 1) has nothing to share.
      EXPECT_EQ(on.report["factorization"]["solve_reuses"], 0);
      if (op == DualOperator::explicit_ || m > 1)
        EXPECT_GT(f["solve_reuses"].get<long long>(), 0) << "m = " << m;
      else
        EXPECT_EQ(f["solve_reuses"], 0);
      if (m > 1)  // the shared K_i^+ C_i^T blocks are counted once
        EXPECT_LT(numeric.report["memory"]["cluster_dense_mb"].get<double>(),
                  on.report["memory"]["cluster_dense_mb"].get<double>())
            << "m = " << m;
    }
}

TEST(HTfetiDpEqualsTfeti, MembranesAndPoisson) {
  Comm comm;
  for (ProblemKind problem : {ProblemKind::poisson2d, ProblemKind::membranes}) {
    SolveOptions opt;
    opt.rtol = 1e-10;
    opt.decomposition = {problem, ElementKind::q1, 32, 8, 1, Glue::averages};
    const auto tfeti = solve(opt, comm);
    for (int m : {2, 4}) {
      opt.decomposition.cluster_size = m;
      const auto hybrid = solve(opt, comm);
      ASSERT_TRUE(hybrid.converged);
      const double e0 = tfeti.report["objective"], e1 = hybrid.report["objective"];
      EXPECT_NEAR(e1, e0, 1e-8 * std::abs(e0)) << "m = " << m;
      EXPECT_LT(hybrid.report["coarse_dimension"].get<int>(),
                tfeti.report["coarse_dimension"].get<int>());
      if (problem != ProblemKind::membranes) continue;
      const auto &c0 = tfeti.report["contact"], &c1 = hybrid.report["contact"];
      for (size_t j = 0; j < c0["y"].size(); ++j) {
        EXPECT_NEAR(c1["u_left"][j].get<double>(), c0["u_left"][j].get<double>(), 1e-6);
        EXPECT_NEAR(c1["u_right"][j].get<double>(), c0["u_right"][j].get<double>(), 1e-6);
      }
    }
  }
}

}  // namespace
