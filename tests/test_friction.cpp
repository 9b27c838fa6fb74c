// Tresca friction in 2D against a rigid plane: a block pressed on the plane y = 0 by a
// traction p on its top, whose top is dragged by a prescribed horizontal displacement d. The
// tangential multipliers live in boxes |lambda_t| <= g A (qp::BoxBounds, MPRGP inside SMALBE-M).
// Checked against what does not depend on the solver: full slip transmits exactly g L (L the
// contact length); a bound that nothing reaches is the same problem as a bottom held in x by a
// Dirichlet condition (equality rows instead of boxes); a zero bound is frictionless contact.
// Runs under mpiexec -n 1 and 2.
#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <cmath>

#include "helpers.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

constexpr double kLength = 4.0, kPressure = 10.0;

// The block [0, 4] x [0, 1], 40 x 10 quad4 in 4 x 2 subdomains, E = 1000, in contact with the
// plane y = 0; slip_bound < 0: frictionless; bottom_fixed_x: the bottom held in x instead.
ProblemSpec block_on_plane(double poisson, double drag, double slip_bound,
                           bool bottom_fixed_x = false) {
  ProblemSpec s;
  s.box.dim = 2;
  s.box.cell = CellType::quad4;
  s.box.size = {kLength, 1.0, 0.0};
  s.box.elements = {40, 10, 0};
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.material = {1000.0, poisson};
  s.dirichlet.push_back({"y1", {drag, 0, 0}, {0}});
  if (bottom_fixed_x) s.dirichlet.push_back({"y0", {0, 0, 0}, {0}});
  s.loads.push_back({"y1", ProblemSpec::Load::traction, {0, -kPressure, 0}});
  ProblemSpec::Contact c;
  c.group = "y0";
  c.direction = {0, -1, 0};
  c.gap = "0";
  c.slip_bound = slip_bound;
  s.contact.push_back(c);
  s.subdomains = {4, 2};
  return s;
}

SolveOutput run(const ProblemSpec& spec, const Comm& comm) {
  SolveOptions opt;
  opt.rtol = 1e-10;
  opt.max_iterations = 20000;
  return solve(std::shared_ptr<const Model>(make_model(spec)), opt, comm);
}

}  // namespace

TEST(TrescaFriction, FullSlipTransmitsTheBoundTimesTheLength) {
  Comm comm;
  const double g = 1.0;
  const auto out = run(block_on_plane(0.3, 0.1, g), comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const auto& f = out.report["friction"];
  EXPECT_EQ(f["slip_rows"].get<long long>(), 41);
  EXPECT_EQ(f["stick_rows"].get<long long>(), 0);
  const auto& r = out.report;
  EXPECT_EQ(r["friction_rows"].get<long long>(), 41);
  EXPECT_EQ(r["inequalities"].get<long long>(), 41);
  EXPECT_EQ(r["equalities"].get<long long>() + 82, r["dual_dimension"].get<long long>());
  // The plane holds the block back (-x) with g per unit length over the whole contact.
  EXPECT_NEAR(f["tangential_force"].get<double>(), -g * kLength, 1e-8 * g * kLength);
  // The normal force balances the load.
  EXPECT_LT(out.report["kkt"]["max_violation"].get<double>(), 1e-8);
  // The nodal contact force of the VTU (-B_I^T lambda, normal and tangential rows) sums to the
  // same tangential force in x and to the load in y.
  const auto forces = out.dual->contact_forces(out.lambda);
  double fx = 0, fy = 0;
  for (const auto& f_s : forces)
    for (Eigen::Index i = 0; i < f_s.size(); i += 2) fx += f_s[i], fy += f_s[i + 1];
  fx = comm.sum(fx), fy = comm.sum(fy);
  EXPECT_NEAR(fx, -g * kLength, 1e-8 * g * kLength);
  EXPECT_NEAR(fy, kPressure * kLength, 1e-8 * kPressure * kLength);
}

TEST(TrescaFriction, SmallDragSticksEverywhere) {
  Comm comm;
  const double g = 1.0;
  const auto out = run(block_on_plane(0.0, 1e-4, g), comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const auto& f = out.report["friction"];
  EXPECT_EQ(f["stick_rows"].get<long long>(), 41);
  EXPECT_EQ(f["slip_rows"].get<long long>(), 0);
  const double t = f["tangential_force"];
  EXPECT_LT(t, 0.0);
  EXPECT_LT(std::abs(t), 0.1 * g * kLength);
}

TEST(TrescaFriction, UnreachedBoundIsTheBottomHeldInX) {
  // Stick everywhere: the tangential rows hold as equalities, the problem of a bottom held in
  // x by a Dirichlet condition (solved with equality rows, no boxes).
  Comm comm;
  const auto fr = run(block_on_plane(0.3, 1e-3, 1e6), comm);
  const auto held = run(block_on_plane(0.3, 1e-3, -1, true), comm);
  ASSERT_TRUE(fr.converged && held.converged);
  EXPECT_EQ(fr.report["friction"]["slip_rows"].get<long long>(), 0);
  const double e1 = fr.report["objective"], e2 = held.report["objective"];
  EXPECT_NEAR(e1, e2, 1e-8 * std::abs(e2));
}

TEST(TrescaFriction, ZeroBoundIsFrictionless) {
  Comm comm;
  const auto fr = run(block_on_plane(0.3, 1e-3, 0.0), comm);
  const auto none = run(block_on_plane(0.3, 1e-3, -1), comm);
  ASSERT_TRUE(fr.converged && none.converged);
  EXPECT_NEAR(fr.report["friction"]["tangential_force"].get<double>(), 0.0, 1e-12);
  const double e1 = fr.report["objective"], e2 = none.report["objective"];
  EXPECT_NEAR(e1, e2, 1e-8 * std::abs(e2));
}

TEST(TrescaFriction, NoTangentialRowWhereDirichletFixesTheTangent) {
  // The left side held in x: at the corner node (0, 0) the condition already fixes t.u, and a
  // tangential row there would repeat it (a dependent row of B~: the split of the reaction
  // between the two would not be unique). The normal row stays.
  Comm comm;
  ProblemSpec spec = block_on_plane(0.3, 0.002, 1.0);
  spec.dirichlet.push_back({"x0", {0, 0, 0}, {0}});
  const auto out = run(spec, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  EXPECT_EQ(out.report["friction_rows"].get<long long>(), 40);
  EXPECT_EQ(out.report["inequalities"].get<long long>(), 41);
}

// Coulomb in 2D: the fixed point on the slip bound (mu times the normal pressure of the last
// solve). A large drag slips everywhere: the plane holds the block back with exactly mu N,
// N = p L the load.
TEST(CoulombFriction, FullSlipTransmitsMuTimesTheLoad) {
  Comm comm;
  ProblemSpec spec = block_on_plane(0.3, 0.1, -1);
  spec.contact[0].friction_coefficient = 0.2;
  SolveOptions opt;
  opt.rtol = 1e-10;
  opt.coulomb_rtol = 1e-12;
  const auto out = solve(std::shared_ptr<const Model>(make_model(spec)), opt, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  ASSERT_TRUE(out.report["solver"]["coulomb"]["converged"].get<bool>());
  const auto& c = out.report["contact_summary"][0];
  EXPECT_EQ(c["slip_nodes"].get<long long>(), 41);
  EXPECT_NEAR(c["tangential_force"].get<double>(), -0.2 * kPressure * kLength,
              1e-8 * kPressure * kLength);
  EXPECT_NEAR(c["normal_force"].get<double>(), kPressure * kLength, 1e-8 * kPressure * kLength);
}

TEST(CoulombFriction, SmallDragSticksAndTheFixedPointConverges) {
  Comm comm;
  ProblemSpec spec = block_on_plane(0.0, 1e-4, -1);
  spec.contact[0].friction_coefficient = 0.5;
  SolveOptions opt;
  opt.rtol = 1e-10;
  const auto out = solve(std::shared_ptr<const Model>(make_model(spec)), opt, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const auto& cf = out.report["solver"]["coulomb"];
  EXPECT_TRUE(cf["converged"].get<bool>());
  EXPECT_GE(cf["solves"].get<int>(), 2);  // frictionless first, then mu p
  const auto& c = out.report["contact_summary"][0];
  EXPECT_EQ(c["stick_nodes"].get<long long>(), 41);
  EXPECT_LT(std::abs(c["tangential_force"].get<double>()), 0.5 * kPressure * kLength);
}

namespace {

// The 3D block [0, 2] x [0, 2] x [0, 1] of 4 x 4 x 2 hex8 in 2 x 2 x 1 subdomains, nu = 0 (no
// spreading: a full slip is along the drag exactly), pressed on the plane z = 0 by p on its top
// and dragged by d in x there; friction: Tresca's g or Coulomb's mu.
constexpr double kSide = 2.0;
ProblemSpec block3d_on_plane(double drag, double slip_bound, double mu = -1) {
  ProblemSpec s;
  s.box.dim = 3;
  s.box.cell = CellType::hex8;
  s.box.size = {kSide, kSide, 1.0};
  s.box.elements = {4, 4, 2};
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.dim = 3;
  s.physics.material = {1000.0, 0.0};
  s.dirichlet.push_back({"z1", {drag, 0, 0}, {0, 1}});
  s.loads.push_back({"z1", ProblemSpec::Load::traction, {0, 0, -kPressure}});
  ProblemSpec::Contact c;
  c.group = "z0";
  c.direction = {0, 0, -1};
  c.gap = "0";
  c.slip_bound = slip_bound;
  c.friction_coefficient = mu;
  s.contact.push_back(c);
  s.subdomains = {2, 2, 1};
  return s;
}

}  // namespace

// Tresca in 3D: a disc |lambda_t| <= g A per node (MPGP inside SMALBE-M).
TEST(TrescaFriction3D, FullSlipTransmitsTheBoundTimesTheArea) {
  Comm comm;
  const double g = 1.0, area = kSide * kSide;
  const auto out = run(block3d_on_plane(0.1, g), comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  EXPECT_EQ(out.report["solver"]["algorithm"], "smalbe-m+mpgp");
  EXPECT_EQ(out.report["friction_rows"].get<long long>(), 2 * 25);
  const auto& c = out.report["contact_summary"][0];
  EXPECT_EQ(c["slip_nodes"].get<long long>(), 25);
  const auto t = c["tangential_force"].get<std::vector<double>>();
  ASSERT_EQ(t.size(), 3u);
  EXPECT_NEAR(t[0], -g * area, 1e-8 * g * area);
  EXPECT_NEAR(t[1], 0.0, 1e-8 * g * area);
  EXPECT_NEAR(t[2], 0.0, 1e-8 * g * area);
  EXPECT_NEAR(c["resultant"][2].get<double>(), kPressure * area, 1e-8 * kPressure * area);
}

// The same block on rollers at y = 0 (a symmetry plane): its 5 nodes on the bottom edge there
// can only slip along x. They keep one tangential row each, along x (an interval, not a disc:
// a second row along y would repeat the roller, and as half of a disc would take an arbitrary
// share of the bound), so the full slip still transmits g A.
TEST(TrescaFriction3D, NodesOnARollerPlaneSlipAlongIt) {
  Comm comm;
  const double g = 1.0, area = kSide * kSide;
  ProblemSpec spec = block3d_on_plane(0.1, g);
  spec.dirichlet.push_back({"y0", {0, 0, 0}, {1}});
  const auto out = run(spec, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  EXPECT_EQ(out.report["friction_rows"].get<long long>(), 2 * 20 + 5);
  const auto& c = out.report["contact_summary"][0];
  EXPECT_EQ(c["slip_nodes"].get<long long>(), 25);
  const auto t = c["tangential_force"].get<std::vector<double>>();
  EXPECT_NEAR(t[0], -g * area, 1e-8 * g * area);
  // On rollers at x = 0 as well, the corner node (0, 0, 0) cannot slip: no tangential row.
  spec.dirichlet.push_back({"x0", {0, 0, 0}, {0}});
  spec.dirichlet[0].value = {0, 0, 0};  // the drag would fight the roller at x = 0
  const auto held = run(spec, comm);
  ASSERT_TRUE(held.converged) << held.report["stop_reason"];
  EXPECT_EQ(held.report["friction_rows"].get<long long>(), 2 * 16 + 8);
}

TEST(TrescaFriction3D, SmallDragSticksAndAZeroBoundIsFrictionless) {
  Comm comm;
  const auto stuck = run(block3d_on_plane(1e-5, 1.0), comm);
  ASSERT_TRUE(stuck.converged) << stuck.report["stop_reason"];
  EXPECT_EQ(stuck.report["contact_summary"][0]["stick_nodes"].get<long long>(), 25);
  const auto zero = run(block3d_on_plane(1e-3, 0.0), comm);
  const auto none = run(block3d_on_plane(1e-3, -1), comm);
  ASSERT_TRUE(zero.converged && none.converged);
  const double e1 = zero.report["objective"], e2 = none.report["objective"];
  EXPECT_NEAR(e1, e2, 1e-8 * std::abs(e2));
}

TEST(TrescaFriction3D, UnreachedBoundIsTheBottomHeldInPlane) {
  // Stick everywhere: the problem of a bottom held in x and y by Dirichlet conditions.
  Comm comm;
  const auto fr = run(block3d_on_plane(1e-3, 1e6), comm);
  ProblemSpec held = block3d_on_plane(1e-3, -1);
  held.dirichlet.push_back({"z0", {0, 0, 0}, {0, 1}});
  const auto h = run(held, comm);
  ASSERT_TRUE(fr.converged && h.converged);
  const double e1 = fr.report["objective"], e2 = h.report["objective"];
  EXPECT_NEAR(e1, e2, 1e-8 * std::abs(e2));
}

TEST(CoulombFriction3D, FullSlipTransmitsMuTimesTheLoad) {
  Comm comm;
  const double mu = 0.3, area = kSide * kSide;
  SolveOptions opt;
  opt.rtol = 1e-10;
  opt.coulomb_rtol = 1e-12;
  const auto out =
      solve(std::shared_ptr<const Model>(make_model(block3d_on_plane(0.1, -1, mu))), opt, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const auto& c = out.report["contact_summary"][0];
  EXPECT_EQ(c["slip_nodes"].get<long long>(), 25);
  const auto t = c["tangential_force"].get<std::vector<double>>();
  EXPECT_NEAR(t[0], -mu * kPressure * area, 1e-8 * kPressure * area);
  EXPECT_NEAR(t[1], 0.0, 1e-8 * kPressure * area);
}

namespace {

// The undecomposed Tresca problem of a spec, solved by an independent method: the stiffness
// with the Dirichlet dofs eliminated (sparse LDL'), the dense dual operator of the contact and
// friction rows (one normal row n.u <= gap and two tangential rows t.u per contact node, with
// the node's force as the multiplier), and FISTA projected gradient (its own projections onto
// lambda_n >= 0 and the discs |lambda_t| <= g A) run until its iterate stops moving.
struct TrescaReference {
  Eigen::VectorXd u;  ///< per global dof
  double energy = 0;
  double projected_gradient = 0;  ///< of the dual QP at the solution, relative to ||d||
};

TrescaReference solve_tresca_directly(ProblemSpec spec, double g) {
  spec.subdomains = {1, 1, 1};
  spec.cluster_size = 1;
  const auto model = make_model(spec);
  const SubdomainInput in = model->input(0);
  const SubdomainMesh mesh = model->mesh(0);
  const int dpn = 3;
  const test::EliminatedSystem sys = test::eliminate_dirichlet(in, dpn);
  Eigen::SparseMatrix<double> K(sys.nf, sys.nf);
  K.setFromTriplets(sys.trip.begin(), sys.trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(K);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  // Rows: per contact node n, t1, t2 (all its dofs are free here), on the free dofs.
  const int nodes = static_cast<int>(in.contact.size()), m = 3 * nodes;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, sys.nf);
  Eigen::VectorXd c = Eigen::VectorXd::Zero(m), radius(nodes);
  for (int i = 0; i < nodes; ++i) {
    const ContactRow& r = in.contact[i];
    const auto& n = r.direction;
    const auto& t = r.tangent;
    const std::array<double, 3> t2{n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2],
                                   n[0] * t[1] - n[1] * t[0]};
    for (int d = 0; d < 3; ++d) {
      const int col = sys.free_of[r.node * dpn + d];
      EXPECT_GE(col, 0);
      A(3 * i, col) = n[d];
      A(3 * i + 1, col) = t[d];
      A(3 * i + 2, col) = t2[d];
    }
    c[3 * i] = r.gap;
    radius[i] = g * r.area;
  }
  const Eigen::MatrixXd KiAt = ldlt.solve(Eigen::MatrixXd(A.transpose()));
  const Eigen::MatrixXd F = A * KiAt;
  const Eigen::VectorXd d = A * ldlt.solve(sys.b) - c;
  const double L = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(F).eigenvalues().maxCoeff();
  auto project = [&](Eigen::VectorXd& x) {
    for (int i = 0; i < nodes; ++i) {
      x[3 * i] = std::max(x[3 * i], 0.0);
      const double len = std::hypot(x[3 * i + 1], x[3 * i + 2]);
      if (len > radius[i]) x[3 * i + 1] *= radius[i] / len, x[3 * i + 2] *= radius[i] / len;
    }
  };
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m), y = x, prev = x;
  double tk = 1;
  for (int it = 0; it < 2000000; ++it) {
    prev = x;
    x = y - (F * y - d) / L;
    project(x);
    const double tn = 0.5 * (1 + std::sqrt(1 + 4 * tk * tk));
    y = x + ((tk - 1) / tn) * (x - prev);
    tk = tn;
    if ((x - prev).dot(y - x) > 0) y = x, tk = 1;  // adaptive restart
    if ((x - prev).norm() <= 1e-16 * x.norm() && it > 10) break;
  }
  // The gradient mapping at x (zero exactly at the solution).
  Eigen::VectorXd step = x - (F * x - d) / L;
  project(step);
  TrescaReference ref;
  ref.projected_gradient = (L * (x - step)).norm() / d.norm();
  const Eigen::VectorXd u = sys.expand(ldlt.solve(sys.b - A.transpose() * x));
  ref.energy = 0.5 * u.dot(in.system.K * u) - in.system.f.dot(u);
  ref.u.resize(static_cast<Eigen::Index>(model->num_nodes()) * dpn);
  for (int k = 0; k < mesh.num_nodes(); ++k)
    for (int dd = 0; dd < dpn; ++dd) ref.u[mesh.global_node[k] * dpn + dd] = u[k * dpn + dd];
  return ref;
}

}  // namespace

// Tresca friction on the paper's cube-obstacle (a coarse mesh, g = 1e6: some nodes stick, the
// others slip) against the independent dual solver above: the same displacement and energy.
TEST(TrescaFriction3D, CubeObstacleMatchesAnIndependentSolver) {
  Comm comm;
  const double g = 1e6;
  ProblemSpec spec = cube_obstacle_spec({8, 4, 4}, {2, 1, 1}, 1);
  spec.contact[0].slip_bound = g;
  const TrescaReference ref = solve_tresca_directly(spec, g);
  EXPECT_LT(ref.projected_gradient, 1e-12);
  SolveOptions opt;
  opt.rtol = 1e-11;
  for (auto [sub, m] : {std::pair<std::vector<int>, int>{{2, 1, 1}, 1}, {{4, 2, 2}, 2}}) {
    spec.subdomains = sub;
    spec.cluster_size = m;
    std::shared_ptr<const Model> model = make_model(spec);
    const auto out = solve(model, opt, comm);
    ASSERT_TRUE(out.converged) << out.report["stop_reason"];
    const auto& s = out.report["contact_summary"][0];
    EXPECT_GT(s["stick_nodes"].get<long long>(), 0);
    EXPECT_GT(s["slip_nodes"].get<long long>(), 0);
    EXPECT_LT(test::relative_error(*model, *out.dual, out.u, ref.u), 1e-8) << "m = " << m;
    EXPECT_NEAR(out.report["objective"].get<double>(), ref.energy, 1e-9 * std::abs(ref.energy));
  }
}
