// TFETI for the linear problem against the undecomposed solution; runs under mpiexec -n 1, 2, 4.
#include <gtest/gtest.h>

#include "helpers.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

struct Case {
  int n, ns, m;
  const char* glue;
  ElementKind element;
};

class LinearAgainstUndecomposed : public ::testing::TestWithParam<Case> {};

TEST_P(LinearAgainstUndecomposed, Poisson2d) {
  const Case c = GetParam();
  Comm comm;
  SolveOptions opt;
  opt.decomposition = {ProblemKind::poisson2d, c.element, c.n, c.ns, c.m, parse_glue(c.glue)};
  opt.rtol = 1e-12;
  auto out = solve(opt, comm);
  ASSERT_TRUE(out.converged);
  const auto ref = solve_undecomposed(ProblemKind::poisson2d, c.element, c.n);
  EXPECT_LT(test::relative_error(*out.model, *out.dual, out.u, ref.u), 1e-8);
  const double energy = out.report["objective"];
  EXPECT_NEAR(energy, ref.energy, 1e-8 * std::abs(ref.energy));
  EXPECT_LT(out.report["kkt"]["equality_residual"].get<double>(), 1e-8);
}

INSTANTIATE_TEST_SUITE_P(Tfeti, LinearAgainstUndecomposed,
                         ::testing::Values(Case{8, 2, 1, "averages", ElementKind::q1},
                                           Case{12, 3, 1, "averages", ElementKind::q1},
                                           Case{24, 4, 1, "averages", ElementKind::q1},
                                           Case{16, 8, 1, "averages", ElementKind::p1},
                                           Case{20, 5, 1, "averages", ElementKind::q1}));

INSTANTIATE_TEST_SUITE_P(HTfetiDp, LinearAgainstUndecomposed,
                         ::testing::Values(Case{16, 4, 2, "averages", ElementKind::q1},
                                           Case{24, 6, 3, "averages", ElementKind::q1},
                                           Case{16, 4, 2, "corners", ElementKind::q1},
                                           Case{24, 4, 2, "corners+averages", ElementKind::p1},
                                           Case{32, 8, 4, "averages", ElementKind::q1},
                                           Case{32, 8, 8, "corners", ElementKind::q1}));

}  // namespace
