// 3D elastic contact with a rigid obstacle against independent solutions, under mpiexec -n 1, 2, 4:
// - the cube-obstacle problem (hex8 and tet4, small meshes) against the undecomposed problem
//   solved by a primal-dual active set method on the assembled KKT system (Dirichlet dofs
//   eliminated, Eigen's sparse LU), with full contact (amplitude 1) and partial contact (a deeper
//   obstacle), TFETI and H-TFETI-DP;
// - a column on a frictionless rigid plane under its own weight with lateral rollers against the
//   analytic solution u_z = -(rho g / M)(H z - z^2 / 2), M = E (1 - nu) / ((1 + nu)(1 - 2 nu)),
//   and the uniform contact pressure rho g H;
// - the subdomain matrices of a generated box are equal bit for bit, and the memory estimate
//   counts the factors they share once.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/SparseLU>
#include <algorithm>
#include <cstring>
#include <set>

#include "helpers.hpp"
#include "htfeti/memory_estimate.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

struct QpReference {
  Eigen::VectorXd u;  ///< per global dof
  double energy = 0;
  int active = 0, inactive = 0;
  int iterations = 0;
};

// min 1/2 u'Ku - f'u  s.t.  n_i . u_(node i) <= gap_i, by a primal-dual active set method.
QpReference solve_contact_directly(ProblemSpec spec) {
  spec.subdomains = {1, 1, 1};
  spec.cluster_size = 1;
  const auto model = make_model(spec);
  const SubdomainInput in = model->input(0);
  const SubdomainMesh mesh = model->mesh(0);
  const int dpn = model->physics().dofs_per_node();
  const test::EliminatedSystem sys = test::eliminate_dirichlet(in, dpn);
  const std::vector<double>& fixed = sys.fixed;
  const std::vector<int>& free_of = sys.free_of;
  const int nf = sys.nf;
  const Eigen::VectorXd& b = sys.b;
  const std::vector<Eigen::Triplet<double>>& kt = sys.trip;
  const double kmax = sys.kmax;
  // Constraint rows a_i . u_f <= g_i (fixed dofs moved to the right-hand side).
  const int m = static_cast<int>(in.contact.size());
  std::vector<std::vector<std::pair<int, double>>> a(m);
  Eigen::VectorXd g(m);
  for (int i = 0; i < m; ++i) {
    const auto& c = in.contact[i];
    g[i] = c.gap;
    for (int d = 0; d < dpn; ++d) {
      if (c.direction[d] == 0) continue;
      const int dof = c.node * dpn + d;
      if (free_of[dof] >= 0)
        a[i].push_back({free_of[dof], c.direction[d]});
      else
        g[i] -= c.direction[d] * fixed[dof];
    }
  }
  std::vector<char> active(m, 0);
  Eigen::VectorXd x, lambda = Eigen::VectorXd::Zero(m);
  QpReference ref;
  for (int it = 0; it < 200; ++it) {
    std::vector<int> act;
    for (int i = 0; i < m; ++i)
      if (active[i]) act.push_back(i);
    const int na = static_cast<int>(act.size());
    std::vector<Eigen::Triplet<double>> t = kt;
    Eigen::VectorXd rhs(nf + na);
    rhs.head(nf) = b;
    for (int j = 0; j < na; ++j) {
      for (const auto& [col, v] : a[act[j]]) {
        t.emplace_back(nf + j, col, v);
        t.emplace_back(col, nf + j, v);
      }
      rhs[nf + j] = g[act[j]];
    }
    Eigen::SparseMatrix<double> A(nf + na, nf + na);
    A.setFromTriplets(t.begin(), t.end());
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(A);
    EXPECT_EQ(lu.info(), Eigen::Success);
    Eigen::VectorXd sol = lu.solve(rhs);
    // Two steps of iterative refinement: the saddle-point matrix mixes K (E = 2.1e7) with unit
    // constraint rows, and LU alone leaves the energy about 1e-8 off.
    for (int r = 0; r < 2; ++r) sol += lu.solve(Eigen::VectorXd(rhs - A * sol));
    x = sol.head(nf);
    lambda.setZero();
    for (int j = 0; j < na; ++j) lambda[act[j]] = sol[nf + j];
    bool changed = false;
    for (int i = 0; i < m; ++i) {
      double ax = 0;
      for (const auto& [col, v] : a[i]) ax += v * x[col];
      const bool now = lambda[i] + kmax * (ax - g[i]) > 0;
      changed = changed || now != static_cast<bool>(active[i]);
      active[i] = now;
    }
    ref.iterations = it + 1;
    if (!changed) break;
  }
  const Eigen::VectorXd u = sys.expand(x);
  ref.energy = 0.5 * u.dot(in.system.K * u) - in.system.f.dot(u);
  ref.u.resize(static_cast<Eigen::Index>(model->num_nodes()) * dpn);
  for (int k = 0; k < mesh.num_nodes(); ++k)
    for (int d = 0; d < dpn; ++d) ref.u[mesh.global_node[k] * dpn + d] = u[k * dpn + d];
  for (int i = 0; i < m; ++i) (lambda[i] > 1e-12 * kmax ? ref.active : ref.inactive)++;
  return ref;
}

struct Case {
  const char* name;
  CellType cell;
  double amplitude;
  std::vector<int> subdomains;
  int cluster_size;
  bool partial;
};

class CubeObstacle : public ::testing::TestWithParam<Case> {};

TEST_P(CubeObstacle, MatchesTheActiveSetSolution) {
  const Case c = GetParam();
  Comm comm;
  const ProblemSpec spec =
      cube_obstacle_spec({12, 6, 6}, c.subdomains, c.cluster_size, c.amplitude, c.cell);
  std::shared_ptr<const Model> model = make_model(spec);
  SolveOptions opt;
  // A tight precision is attainable (issue 28): SMALBE-M's test is in the units of the load, so
  // lambda ~ 1e9 (E = 2.1e7) no longer keeps ||G lambda|| above it; the energy then agrees with
  // the undecomposed active-set solution to 1e-10.
  opt.rtol = 1e-10;
  opt.max_iterations = 2000;
  const QpReference ref = solve_contact_directly(spec);
  for (int steps : {2, 1}) {  // both forms of the Hessian product through the same checks
    SCOPED_TRACE("coarse steps per product: " + std::to_string(steps));
    opt.coarse_steps_per_product = steps;
    const auto out = solve(model, opt, comm);
    ASSERT_TRUE(out.converged) << out.report["stop_reason"];
    EXPECT_EQ(out.report["coarse_steps_per_product"].get<int>(), steps);
    ASSERT_GT(ref.active, 0);
    if (c.partial) {
      ASSERT_GT(ref.inactive, 0) << "the case should have partial contact";
    } else {
      ASSERT_EQ(ref.inactive, 0) << "the case should have full contact";
    }
    const double energy = out.report["objective"];
    EXPECT_NEAR(energy, ref.energy, 1e-10 * std::abs(ref.energy));
    EXPECT_LT(test::relative_error(*model, *out.dual, out.u, ref.u), 1e-8);
    const auto& kkt = out.report["kkt"];
    const double umax = ref.u.cwiseAbs().maxCoeff();
    EXPECT_LT(kkt["max_violation"].get<double>(), 1e-6 * umax);
    EXPECT_GE(kkt["min_multiplier"].get<double>(), -1e-8 * std::abs(energy) / umax);
    EXPECT_EQ(out.report["coarse_dimension"].get<int>(), 6 * model->num_clusters());
  }
}

INSTANTIATE_TEST_SUITE_P(
    Small, CubeObstacle,
    ::testing::Values(Case{"hex8_full_tfeti", CellType::hex8, 1.0, {2, 2, 2}, 1, false},
                      Case{"hex8_full_htfeti", CellType::hex8, 1.0, {4, 2, 2}, 2, false},
                      Case{"hex8_partial_tfeti", CellType::hex8, 40.0, {2, 2, 2}, 1, true},
                      Case{"hex8_partial_htfeti", CellType::hex8, 40.0, {4, 2, 2}, 2, true},
                      Case{"tet4_full_tfeti", CellType::tet4, 1.0, {2, 2, 2}, 1, false},
                      Case{"tet4_partial_htfeti", CellType::tet4, 40.0, {4, 2, 2}, 2, true}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Column, OwnWeightOnARigidPlaneIsTheAnalyticSolution) {
  Comm comm;
  const double E = 1000, nu = 0.25, rho = 2, g = 3, H = 10;
  ProblemSpec s;
  s.box.dim = 3;
  s.box.cell = CellType::hex8;
  s.box.size = {1, 1, H};
  s.box.elements = {2, 2, 10};
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.dim = 3;
  s.physics.material = {E, nu};
  s.physics.density = rho;
  s.physics.gravity = {0, 0, -g};
  for (const char* f : {"x0", "x1"}) s.dirichlet.push_back({f, {0, 0, 0}, {0}});  // rollers
  for (const char* f : {"y0", "y1"}) s.dirichlet.push_back({f, {0, 0, 0}, {1}});
  s.contact.push_back({"z0", {0, 0, -1}, "0"});
  s.subdomains = {1, 1, 5};
  s.cluster_size = 1;
  std::shared_ptr<const Model> model = make_model(s);
  SolveOptions opt;
  opt.rtol = 1e-10;
  const auto out = solve(model, opt, comm);
  ASSERT_TRUE(out.converged);
  const double M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu));
  double err = 0, scale = 0;
  for (size_t i = 0; i < out.u.size(); ++i) {
    const SubdomainMesh m = model->mesh(out.dual->subdomains()[i]->id());
    for (int k = 0; k < m.num_nodes(); ++k) {
      const double z = m.coords[3 * k + 2];
      const double exact = -(rho * g / M) * (H * z - z * z / 2);
      err = std::max(err, std::abs(out.u[i][3 * k + 2] - exact));
      err = std::max({err, std::abs(out.u[i][3 * k]), std::abs(out.u[i][3 * k + 1])});
      scale = std::max(scale, std::abs(exact));
    }
  }
  EXPECT_LT(comm.max(err), 1e-8 * comm.max(scale));
  // Uniform pressure rho g H: nodal forces are the pressure times each node's share of the area.
  const auto& c = out.report["contact"];
  ASSERT_EQ(c["multiplier"].size(), 9u);
  double total = 0;
  for (size_t j = 0; j < 9; ++j) {
    const double x = c["x"][j], y = c["y"][j];
    const double share = (x == 0.5 ? 0.5 : 0.25) * (y == 0.5 ? 0.5 : 0.25);
    EXPECT_NEAR(c["multiplier"][j].get<double>(), rho * g * H * share, 1e-8 * rho * g * H) << j;
    total += c["multiplier"][j].get<double>();
  }
  EXPECT_NEAR(total, rho * g * H * 1.0, 1e-8 * rho * g * H);
}

}  // namespace

// A generated box gives every subdomain the same element matrices, kernel and fixed dofs
// (computed on the nodes' offsets in whole grid spacings, not on their rounded coordinates), so
// the subdomain matrices of a box with one material are equal bit for bit: equal subdomains
// share one factor (numeric cache), and the memory estimate counts the shared factors once.
TEST(Box, SubdomainMatricesAreEqualBitForBit) {
  for (CellType cell : {CellType::hex8, CellType::tet4}) {
    const auto model = make_model(cube_obstacle_spec({12, 12, 12}, {3, 3, 3}, 1, 1.0, cell));
    const SubdomainSystem first = model->input(0).system;
    const Eigen::SparseMatrix<double>& K0 = first.K;
    ASSERT_TRUE(K0.isCompressed());
    for (int s = 1; s < model->num_subdomains(); ++s) {
      const SubdomainSystem sys = model->input(s).system;
      EXPECT_EQ(sys.fixed_dofs, first.fixed_dofs) << "subdomain " << s;
      ASSERT_EQ(sys.R.size(), first.R.size());
      EXPECT_EQ(std::memcmp(sys.R.data(), first.R.data(), sizeof(double) * sys.R.size()), 0)
          << "subdomain " << s;
      const Eigen::SparseMatrix<double>& K = sys.K;
      ASSERT_TRUE(K.isCompressed());
      ASSERT_EQ(K.rows(), K0.rows());
      ASSERT_EQ(K.nonZeros(), K0.nonZeros());
      EXPECT_TRUE(
          std::equal(K.outerIndexPtr(), K.outerIndexPtr() + K.outerSize() + 1, K0.outerIndexPtr()));
      EXPECT_TRUE(
          std::equal(K.innerIndexPtr(), K.innerIndexPtr() + K.nonZeros(), K0.innerIndexPtr()));
      EXPECT_EQ(std::memcmp(K.valuePtr(), K0.valuePtr(), sizeof(double) * K.nonZeros()), 0)
          << "subdomain " << s << " of " << to_string(cell);
    }
  }
}

// End to end: the solve holds the box's equal matrices once and shares their factor.
TEST(Box, EqualSubdomainsShareMatrixAndFactor) {
  Comm comm;
  std::shared_ptr<const Model> model = make_model(cube_obstacle_spec({12, 12, 12}, {3, 3, 3}, 1));
  SolveOptions opt;
  opt.feti.dual_operator = DualOperator::implicit;
  const auto out = solve(model, opt, comm);
  ASSERT_TRUE(out.converged);
  const int n = model->num_subdomains();
  // Per rank, every K_i but the rank's first is a shared one.
  EXPECT_GE(out.report["memory"]["shared_matrices"].get<long>(), n - comm.size());
  // The numeric cache keeps a factor from a pattern's second factorization on; each thread of
  // each rank may factor the first two itself.
  EXPECT_GE(out.report["factorization"]["numeric_reuses"].get<long>(),
            n - 2 * comm.size() * omp_get_max_threads());
  // In memory: those factored before a factor was kept, and the kept one (equal sizes).
  const double all = out.report["memory"]["factor_mb"], each = all / n;
  EXPECT_LE(out.report["memory"]["distinct_factor_mb"].get<double>(),
            (1e-9 + comm.size() * (2 * omp_get_max_threads() + 1)) * each);
}

// H-TFETI-DP on a box: subdomains at the same place in their clusters have equal K_i and equal
// face-average constraints C_i (the rigid motions of a face taken on its grid offsets), so their
// K_i^+ C_i^T is computed once and held once; the solution is the one computed per subdomain,
// bit for bit.
TEST(Box, EqualSubdomainsShareTheirClusterSolves) {
  Comm comm;
  std::shared_ptr<const Model> model = make_model(cube_obstacle_spec({12, 12, 12}, {4, 4, 4}, 2));
  SolveOptions opt;
  opt.feti.dual_operator = DualOperator::implicit;
  const auto shared = solve(model, opt, comm);
  opt.feti.numeric_cache_bytes = 0;  // a factor per subdomain: nothing shared
  const auto own = solve(model, opt, comm);
  ASSERT_TRUE(shared.converged && own.converged);
  EXPECT_EQ(shared.report["objective"], own.report["objective"]);
  EXPECT_EQ(shared.report["matvecs"], own.report["matvecs"]);
  ASSERT_EQ(shared.u.size(), own.u.size());
  for (size_t i = 0; i < own.u.size(); ++i) EXPECT_TRUE(shared.u[i] == own.u[i]) << i;
  EXPECT_EQ(own.report["factorization"]["solve_reuses"], 0);
  // 8 places in a cluster of 2 x 2 x 2; each rank holds whole clusters, and each place is
  // solved at most twice per rank (a factor is kept from a pattern's second factorization on).
  const long places = 8, clusters = model->num_clusters();
  EXPECT_GE(shared.report["factorization"]["solve_reuses"].get<long>(),
            (clusters - 2 * comm.size()) * places);
  EXPECT_LT(shared.report["memory"]["cluster_dense_mb"].get<double>(),
            own.report["memory"]["cluster_dense_mb"].get<double>());
}

TEST(MemoryEstimate, EqualSubdomainsOfABoxShareTheirFactors) {
  Comm comm;
  ProblemSpec spec = cube_obstacle_spec({16, 16, 16}, {8, 8, 8}, 1);
  FetiOptions o;
  o.dual_operator = DualOperator::implicit;
  const FetiLayout layout = make_model(spec)->layout();
  const auto [c0, c1] = layout.cluster_range(comm.rank(), comm.size());
  const double mine = layout.cluster_first[c1] - layout.cluster_first[c0];
  auto model = make_model(spec);
  const MemoryEstimate shared = estimate_memory(*model, o, comm);
  o.numeric_cache_bytes = 0;  // no numeric cache: a factor per subdomain
  const MemoryEstimate own = estimate_memory(*model, o, comm);
  ASSERT_TRUE(shared.sampled && own.sampled);
  EXPECT_EQ(own.shared_factors, 0);
  ASSERT_GT(shared.shared_factors, 0);
  EXPECT_LT(shared.shared_factors, mine);
  // The same factor size, counted shared.shared_factors times instead of once per subdomain.
  EXPECT_NEAR(shared.factors_mb / shared.shared_factors, own.factors_mb / mine,
              1e-9 * own.factors_mb);
  EXPECT_EQ(shared.matrices_mb, own.matrices_mb);
  // A coefficient field makes the matrices differ: a factor per subdomain again.
  o.numeric_cache_bytes = 512.0 * (1 << 20);
  spec.physics.coefficient = "1 + x / 100";
  const MemoryEstimate field = estimate_memory(*make_model(spec), o, comm);
  EXPECT_EQ(field.shared_factors, 0);
}

// The implicit Dirichlet preconditioner's factors of K_ii are counted, as half of the
// subdomains' factors, and no more than it takes in the solve (the estimate errs low); the
// other preconditioners and storages are not counted.
TEST(MemoryEstimate, CountsTheImplicitDirichletPreconditioner) {
  Comm comm;
  ProblemSpec spec = cube_obstacle_spec({12, 12, 12}, {2, 2, 2}, 1);
  spec.physics.coefficient = "x > 50 ? 1000 : 1";
  std::shared_ptr<const Model> model = make_model(spec);
  FetiOptions o;
  o.dual_operator = DualOperator::implicit;
  o.preconditioner = PreconditionerKind::lumped;
  const MemoryEstimate lumped = estimate_memory(*model, o, comm);
  EXPECT_EQ(lumped.preconditioner_mb, 0);
  o.preconditioner = PreconditionerKind::dirichlet;  // automatic storage: implicit in 3D
  const MemoryEstimate dirichlet = estimate_memory(*model, o, comm);
  ASSERT_TRUE(dirichlet.sampled);
  EXPECT_GT(dirichlet.preconditioner_mb, 0);
  // Single-precision copies of the factors of K_ii (every precision but double), else double.
  EXPECT_DOUBLE_EQ(dirichlet.preconditioner_mb, 0.3 * dirichlet.factors_mb);
  o.factor_precision = FactorPrecision::double_;
  EXPECT_DOUBLE_EQ(estimate_memory(*model, o, comm).preconditioner_mb, 0.5 * dirichlet.factors_mb);
  o.factor_precision = FactorPrecision::automatic;
  EXPECT_GE(dirichlet.peak_mb(), lumped.peak_mb());
  o.dirichlet_storage = 1;  // dense S_i: bounded by the budget, not counted
  EXPECT_EQ(estimate_memory(*model, o, comm).preconditioner_mb, 0);
  o.dirichlet_storage = 0;
  o.dirichlet_layers = 1;  // the shell's factors: not counted
  EXPECT_EQ(estimate_memory(*model, o, comm).preconditioner_mb, 0);
  // What the solve holds (auto preconditioner: Dirichlet for the coefficient field, implicit).
  SolveOptions so;
  so.feti.dual_operator = DualOperator::implicit;
  so.max_iterations = 2;
  o.dirichlet_layers = 0;
  for (const FactorPrecision precision : {FactorPrecision::automatic, FactorPrecision::double_}) {
    so.feti.factor_precision = precision;
    o.factor_precision = precision;
    const SolveOutput out = solve(model, so, comm);
    EXPECT_EQ(out.report["preconditioner_storage"], "implicit");
    EXPECT_EQ(out.report["preconditioner_precision"],
              precision == FactorPrecision::double_ ? "double" : "single");
    const double counted = out.report["memory"]["estimate_mb"]["preconditioner"];
    EXPECT_NEAR(counted, comm.sum(estimate_memory(*model, o, comm).preconditioner_mb),
                1e-9 * counted);
    EXPECT_LE(counted, out.report["memory"]["preconditioner_mb"].get<double>());
  }
}
