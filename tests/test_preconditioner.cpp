// The FETI preconditioners (feti/preconditioner.hpp), under mpiexec -n 1, 2:
//  - the local operators against an independent dense computation: lumped = K_bb, Dirichlet
//    S = K_bb - K_bi K_ii^{-1} K_ib (dense from the shifted factor and implicit alike);
//  - P M^{-1} P symmetric and positive definite on Ker G (dense eigenvalues on one rank, random
//    projected vectors on every rank count), for TFETI and H-TFETI-DP, 2D and 3D, with and
//    without contact, lumped and Dirichlet, multiplicity and stiffness scaling, on a problem
//    with a coefficient jump;
//  - the dense and the implicit Dirichlet preconditioner agree; the automatic storage by dimension;
//  - the layered Dirichlet operator S^(k) against the dense formula, between K_bb and S;
//  - preconditioned solves give the unpreconditioned solution (energy to 1e-8 at rtol 1e-10),
//    the layered Dirichlet one included.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <functional>
#include <limits>
#include <map>

#include "helpers.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

Eigen::VectorXd ramp(int n, double seed) {
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = std::sin(1.7 * i + seed) + 0.3 * std::cos(0.37 * i * i);
  return v;
}

// The cube-obstacle on a small mesh, optionally with a coefficient jump at x = 50.
std::shared_ptr<const Model> cube(int m, bool jump) {
  ProblemSpec spec = cube_obstacle_spec({4, 4, 4}, {2, 2, 2}, m);
  if (jump) spec.physics.coefficient = "x > 50 ? 1000 : 1";
  return std::shared_ptr<const Model>(make_model(spec));
}

std::shared_ptr<const Model> builtin(ProblemKind p, int n, int ns, int m, Glue glue) {
  return std::shared_ptr<const Model>(
      make_builtin_model(DecompositionOptions{p, ElementKind::q1, n, ns, m, glue}));
}

// The Schur complement K_bb - K_sb^T K_ss^{-1} K_sb of the dense Kd on the dofs b, over the
// interior dofs s (the rest of Kd left out: clamped).
Eigen::MatrixXd dense_schur(const Eigen::MatrixXd& Kd, const std::vector<int>& b,
                            const std::vector<int>& s) {
  const int nb = static_cast<int>(b.size()), ns = static_cast<int>(s.size());
  Eigen::MatrixXd Kbb(nb, nb), Ksb(ns, nb), Kss(ns, ns);
  for (int i = 0; i < nb; ++i)
    for (int j = 0; j < nb; ++j) Kbb(i, j) = Kd(b[i], b[j]);
  for (int i = 0; i < ns; ++i) {
    for (int j = 0; j < nb; ++j) Ksb(i, j) = Kd(s[i], b[j]);
    for (int j = 0; j < ns; ++j) Kss(i, j) = Kd(s[i], s[j]);
  }
  return Kbb - Ksb.transpose() * Kss.ldlt().solve(Ksb);
}

// The dofs of the nodes the subdomain shares (b, sorted) and the others (interior), of input in.
void shared_and_interior(const SubdomainInput& in, std::vector<int>& b,
                         std::vector<int>& interior) {
  const int dpn = in.system.dofs_per_node, n = static_cast<int>(in.system.K.rows());
  b.clear(), interior.clear();
  for (int k = 0; k < in.sharing.num_nodes(); ++k)
    if (in.sharing.num_copies(k) > 1)
      for (int d = 0; d < dpn; ++d) b.push_back(k * dpn + d);
  const int nb = static_cast<int>(b.size());
  for (int d = 0, j = 0; d < n; ++d)
    if (j < nb && b[j] == d)
      ++j;
    else
      interior.push_back(d);
}

// The matrix of a local preconditioner: its application to each unit vector.
Eigen::MatrixXd operator_matrix(LocalPreconditioner& p) {
  const int nb = p.size();
  Eigen::MatrixXd M(nb, nb);
  Eigen::VectorXd e(nb), y(nb);
  for (int j = 0; j < nb; ++j) {
    e.setZero();
    e[j] = 1;
    p.apply(e.data(), y.data());
    M.col(j) = y;
  }
  return M;
}

}  // namespace

TEST(LocalPreconditioner, MatchesTheDenseSchurComplement) {
  Comm comm;
  if (comm.rank() != 0) return;
  for (const auto& model :
       {builtin(ProblemKind::poisson2d, 8, 2, 1, Glue::averages), cube(1, true)}) {
    const SubdomainInput in = model->input(0);
    const Eigen::SparseMatrix<double>& K = in.system.K;
    std::vector<int> b, interior;  // the dofs of shared nodes, and the others
    shared_and_interior(in, b, interior);
    const int n = static_cast<int>(K.rows()), nb = static_cast<int>(b.size());
    ASSERT_GT(nb, 0);
    ASSERT_LT(nb, n);
    const Eigen::MatrixXd Kd(K);
    Eigen::MatrixXd Kbb(nb, nb);
    for (int i = 0; i < nb; ++i)
      for (int j = 0; j < nb; ++j) Kbb(i, j) = Kd(b[i], b[j]);
    const Eigen::MatrixXd S = dense_schur(Kd, b, interior);
    const Eigen::VectorXd x = ramp(nb, 0.5);
    Eigen::VectorXd y(nb);
    LocalPreconditioner lumped(K, b, PreconditionerKind::lumped, false, Ordering::amd);
    lumped.apply(x.data(), y.data());
    EXPECT_LT((y - Kbb * x).norm(), 1e-13 * (Kbb * x).norm());
    {  // K_bb in the order of an interface given unsorted (reversed): P K_bb P^T
      const std::vector<int> rb(b.rbegin(), b.rend());
      LocalPreconditioner reversed(K, rb, PreconditionerKind::lumped, false, Ordering::amd);
      reversed.apply(x.data(), y.data());
      const Eigen::VectorXd expect = (Kbb * x.reverse()).reverse();
      EXPECT_LT((y - expect).norm(), 1e-13 * expect.norm());
    }
    for (bool dense : {true, false}) {
      LocalPreconditioner dir(K, b, PreconditionerKind::dirichlet, dense, Ordering::amd);
      EXPECT_EQ(dir.dense(), dense);
      dir.apply(x.data(), y.data());
      // The dense S comes from L L^T - sigma I with sigma = max diag K_bb: round-off relative to
      // sigma, not to ||S x||.
      EXPECT_LT((y - S * x).norm(), 1e-11 * Kbb.diagonal().maxCoeff() * x.norm()) << dense;
      // With the kernel: S + tau Q Q^T, Q spanning the rigid motions on the interface, which S
      // annihilates: positive definite.
      LocalPreconditioner reg(K, b, PreconditionerKind::dirichlet, dense, Ordering::amd,
                              &in.system.R);
      const Eigen::MatrixXd Sr = operator_matrix(reg);
      Eigen::MatrixXd Rb(nb, in.system.R.cols());
      for (int i = 0; i < nb; ++i) Rb.row(i) = in.system.R.row(b[i]);
      EXPECT_LT((S * Rb).norm(), 1e-9 * Kbb.diagonal().maxCoeff() * Rb.norm());
      // On the complement of R_b unchanged; on R_b tau times the identity.
      const Eigen::VectorXd xc = x - Rb * Rb.colPivHouseholderQr().solve(x);
      EXPECT_LT((Sr * xc - S * xc).norm(), 1e-10 * Kbb.diagonal().maxCoeff() * x.norm()) << dense;
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (Sr + Sr.transpose()));
      EXPECT_GT(eig.eigenvalues().minCoeff(), 1e-8 * eig.eigenvalues().maxCoeff()) << dense;
    }
  }
}

// The implicit Dirichlet operator with single-precision solves (the default, with every factor
// precision but double): within single-precision round-off of the exact S (relative to the
// largest diagonal entry of K_bb, as the dense form), not the same bits as the double solves
// (so the copy is what is read), and its factor held in fewer bytes, the doubles freed.
TEST(LocalPreconditioner, SinglePrecisionSolvesOfTheImplicitForm) {
  Comm comm;
  if (comm.rank() != 0) return;
  const auto model = cube(1, true);
  const SubdomainInput in = model->input(0);
  const Eigen::SparseMatrix<double>& K = in.system.K;
  std::vector<int> b, interior;
  shared_and_interior(in, b, interior);
  const int nb = static_cast<int>(b.size());
  ASSERT_GT(nb, 0);
  ASSERT_GT(interior.size(), 0u);
  const Eigen::MatrixXd Kd(K);
  const Eigen::MatrixXd S = dense_schur(Kd, b, interior);
  const double scale = Kd.diagonal().maxCoeff();
  LocalPreconditioner dbl(K, b, PreconditionerKind::dirichlet, false, Ordering::metis, nullptr,
                          nullptr, 0, false);
  LocalPreconditioner sgl(K, b, PreconditionerKind::dirichlet, false, Ordering::metis, nullptr,
                          nullptr, 0, true);
  EXPECT_FALSE(dbl.single());
  EXPECT_TRUE(sgl.single());
  const Eigen::MatrixXd Md = operator_matrix(dbl), Ms = operator_matrix(sgl);
  EXPECT_LT((Md - S).norm(), 1e-11 * scale * std::sqrt(nb));
  EXPECT_LT((Ms - S).norm(), 1e-5 * scale * std::sqrt(nb));
  EXPECT_GT((Ms - Md).norm(), 0.0);
  EXPECT_LT(sgl.bytes(), dbl.bytes());
  // Symmetric up to the same round-off, and positive semidefinite as S is (S >= 0 holds to it).
  EXPECT_LT((Ms - Ms.transpose()).norm(), 1e-5 * scale * std::sqrt(nb));
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (Ms + Ms.transpose()));
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-5 * scale);
}

// The layered Dirichlet operator S^(k) = K_bb - K_bs K_ss^{-1} K_sb (s: the interior dofs within
// k steps of the interface in K's graph, the rest clamped) against the same formula in dense
// algebra with its own breadth-first search; and the order S <= S^(2) <= S^(1) <= K_bb, with
// S^(k) = S once the layers reach every dof. A 2 x 2 x 2 split of 8^3 hex8 cells: 4^3 cells
// per part, so one layer leaves interior nodes clamped.
TEST(LocalPreconditioner, LayeredDirichletBetweenLumpedAndDirichlet) {
  Comm comm;
  if (comm.rank() != 0) return;
  const auto model =
      std::shared_ptr<const Model>(make_model(cube_obstacle_spec({8, 8, 8}, {2, 2, 2}, 1)));
  const SubdomainInput in = model->input(0);
  const Eigen::SparseMatrix<double>& K = in.system.K;
  const int dpn = in.system.dofs_per_node;
  std::vector<int> b;  // the dofs of shared nodes
  for (int k = 0; k < in.sharing.num_nodes(); ++k)
    if (in.sharing.num_copies(k) > 1)
      for (int d = 0; d < dpn; ++d) b.push_back(k * dpn + d);
  const int n = static_cast<int>(K.rows()), nb = static_cast<int>(b.size());
  const Eigen::MatrixXd Kd(K);
  // The Schur complement on b of K's block of the dofs `keep` (b first in it).
  const auto schur = [&](const std::vector<int>& keep) {
    std::vector<int> s;
    for (int d : keep)
      if (!std::binary_search(b.begin(), b.end(), d)) s.push_back(d);
    return std::make_pair(dense_schur(Kd, b, s), static_cast<int>(s.size()));
  };
  // The dofs within k steps of b in the dense matrix's nonzero pattern.
  const auto within = [&](int k) {
    std::vector<int> depth(n, -1);
    for (int d : b) depth[d] = 0;
    for (int l = 1; l <= k; ++l)
      for (int i = 0; i < n; ++i)
        if (depth[i] < 0)
          for (int j = 0; j < n; ++j)
            if (depth[j] == l - 1 && Kd(i, j) != 0.0) {
              depth[i] = l;
              break;
            }
    std::vector<int> keep;
    for (int i = 0; i < n; ++i)
      if (depth[i] >= 0) keep.push_back(i);
    return keep;
  };
  const auto [S, n_interior] = schur(within(n));
  ASSERT_GT(n_interior, 0);
  const auto min_eigenvalue = [](const Eigen::MatrixXd& A) {
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (A + A.transpose()))
        .eigenvalues()
        .minCoeff();
  };
  const double scale = Kd.diagonal().maxCoeff();
  LocalPreconditioner lumped(K, b, PreconditionerKind::lumped, false, Ordering::amd);
  Eigen::MatrixXd previous = operator_matrix(lumped);  // K_bb
  for (int k : {1, 2}) {
    const auto [Sk, ns] = schur(within(k));
    ASSERT_GT(ns, 0) << k;
    ASSERT_LT(ns, n_interior) << k;  // some interior dofs are clamped
    for (bool dense : {false, true}) {
      LocalPreconditioner p(K, b, PreconditionerKind::dirichlet, dense, Ordering::amd, &in.system.R,
                            nullptr, k);
      const Eigen::MatrixXd M = operator_matrix(p);
      EXPECT_LT((M - Sk).norm(), 1e-10 * scale * nb) << k << " " << dense;
    }
    // S <= S^(k) <= S^(k-1): the differences are positive semidefinite, and not zero.
    EXPECT_GT(min_eigenvalue(Sk - S), -1e-9 * scale) << k;
    EXPECT_GT(min_eigenvalue(previous - Sk), -1e-9 * scale) << k;
    EXPECT_GT((previous - Sk).norm(), 1e-3 * scale) << k;
    EXPECT_GT(min_eigenvalue(Sk), 0.0) << k;  // positive definite: dofs are clamped
    previous = Sk;
  }
  // Layers that reach every dof: the Dirichlet operator itself.
  LocalPreconditioner all(K, b, PreconditionerKind::dirichlet, false, Ordering::amd, nullptr,
                          nullptr, n);
  EXPECT_LT((operator_matrix(all) - S).norm(), 1e-10 * scale * nb);
}

namespace {

struct Case {
  std::string name;
  std::function<std::shared_ptr<const Model>()> model;
};

class Preconditioners
    : public ::testing::TestWithParam<std::tuple<Case, PreconditionerKind, Scaling>> {};

}  // namespace

TEST_P(Preconditioners, SymmetricPositiveDefiniteOnKerG) {
  const auto& [c, kind, scaling] = GetParam();
  Comm comm;
  const auto model = c.model();
  FetiOptions opt;
  opt.preconditioner = kind;
  opt.scaling = scaling;
  auto dual = test::make_dual(*model, comm, opt);
  auto dot = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return dual->dot(a, b); };
  auto Z = [&](const Eigen::VectorXd& x) {
    Eigen::VectorXd px, mx, y;
    dual->project(x, px);
    dual->apply_preconditioner(px, mx);
    dual->project(mx, y);
    return y;
  };
  for (double seed : {1.0, 2.0, 3.0}) {
    const Eigen::VectorXd x = test::pseudo_random(*dual, seed),
                          y = test::pseudo_random(*dual, seed + 7);
    const Eigen::VectorXd zx = Z(x), zy = Z(y);
    const double scale = std::sqrt(dot(zx, zx) * dot(y, y));
    EXPECT_NEAR(dot(zx, y), dot(x, zy), 1e-12 * scale) << c.name;
    Eigen::VectorXd px;
    dual->project(x, px);
    EXPECT_GT(dot(Z(px), px), 1e-8 * std::sqrt(dot(zx, zx) * dot(px, px))) << c.name;
  }
  if (comm.size() == 1) {
    // Dense: Z + s (I - P) (s = ||Z||) is positive definite iff Z is on Ker G = Im P.
    const int n = dual->n_owned();
    Eigen::MatrixXd Zd(n, n), Pd(n, n);
    for (int j = 0; j < n; ++j) {
      Eigen::VectorXd e = Eigen::VectorXd::Zero(n), pe;
      e[j] = 1;
      Zd.col(j) = Z(e);
      dual->project(e, pe);
      Pd.col(j) = pe;
    }
    EXPECT_LT((Zd - Zd.transpose()).norm(), 1e-12 * Zd.norm()) << c.name;
    const double s = Zd.norm();
    const Eigen::MatrixXd A =
        0.5 * (Zd + Zd.transpose()) + s * (Eigen::MatrixXd::Identity(n, n) - Pd);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 1e-10 * eig.eigenvalues().maxCoeff()) << c.name;
  }
  if (kind == PreconditionerKind::dirichlet) {
    // Dense and implicit S_i agree (the implicit one's solves with K_ii in double); with the
    // default single-precision copies of those factors to single-precision round-off.
    FetiOptions dense = opt, imp = opt;
    dense.dirichlet_storage = 1;
    imp.dirichlet_storage = 2;
    FetiOptions single = imp;
    imp.factor_precision = FactorPrecision::double_;
    dual = test::make_dual(*model, comm, dense);
    auto other = test::make_dual(*model, comm, imp);
    auto rounded = test::make_dual(*model, comm, single);
    EXPECT_TRUE(dual->preconditioner_dense());
    EXPECT_FALSE(other->preconditioner_dense());
    EXPECT_FALSE(other->preconditioner_single());
    EXPECT_TRUE(comm.max(rounded->preconditioner_single() ? 1.0 : 0.0) > 0);
    const Eigen::VectorXd x = test::pseudo_random(*dual, 4.0);
    Eigen::VectorXd a, b, r;
    dual->apply_preconditioner(x, a);
    other->apply_preconditioner(x, b);
    rounded->apply_preconditioner(x, r);
    EXPECT_LT(std::sqrt(dot(a - b, a - b)), 1e-9 * std::sqrt(dot(a, a))) << c.name;
    EXPECT_LT(std::sqrt(dot(a - r, a - r)), 1e-5 * std::sqrt(dot(a, a))) << c.name;
  }
}

// PCG's estimate of the preconditioned operator's extreme eigenvalues (qp/cg_spectrum.hpp,
// the report's solver.spectrum_estimate), against the dense eigenvalues of P M^{-1} P F on
// Ker G (one rank): the extreme Ritz values of a solve to rtol 1e-10 lie within its spectrum;
// the largest is one of its eigenvalues to 1e-5 (the first run uses the factors'
// single-precision copies), the smallest, in the cluster near 1 that FETI's preconditioned
// operators have, where Ritz values settle later, to 1e-3. With contact, the face solves'
// estimate is there and positive.
TEST_P(Preconditioners, CgSpectrumEstimateIsInTheDenseSpectrum) {
  const auto& [c, kind, scaling] = GetParam();
  Comm comm;
  if (comm.size() != 1) GTEST_SKIP() << "dense eigenvalues on one rank";
  const auto model = c.model();
  SolveOptions o;
  o.rtol = 1e-10;
  o.check_memory = false;
  o.feti.preconditioner = kind;
  o.feti.scaling = scaling;
  const SolveOutput out = solve(model, o, comm);
  ASSERT_TRUE(out.converged) << c.name;
  const auto& solver = out.report["solver"];
  if (solver["algorithm"] != "pcg") {
    ASSERT_TRUE(solver.contains("face_spectrum_estimate")) << c.name;
    const auto& e = solver["face_spectrum_estimate"];
    if (!e.is_null()) {
      EXPECT_GT(e["min"].get<double>(), 0.0) << c.name;
      EXPECT_LE(e["min"].get<double>(), e["max"].get<double>()) << c.name;
      EXPECT_GT(e["cg_steps"].get<int>(), 0) << c.name;
    }
    return;
  }
  ASSERT_FALSE(solver["spectrum_estimate"].is_null()) << c.name;
  const double lo = solver["spectrum_estimate"]["min"], hi = solver["spectrum_estimate"]["max"];
  if (solver["pcg_projector"] != "orthogonal") GTEST_SKIP() << "the weighted projector's operator";
  FetiOptions fo = o.feti;
  fo.factor_precision = FactorPrecision::double_;
  auto dual = test::make_dual(*model, comm, fo);
  const int n = dual->n_owned();
  Eigen::MatrixXd ZFP(n, n);
  for (int j = 0; j < n; ++j) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(n), pe, fe, pf, me, y;
    e[j] = 1;
    dual->project(e, pe);
    dual->apply_F(pe, fe);
    dual->project(fe, pf);
    dual->apply_preconditioner(pf, me);
    dual->project(me, y);
    ZFP.col(j) = y;
  }
  // Z F P maps Ker G into itself and Im G~' to 0: its nonzero eigenvalues are those of Z F on
  // Ker G (real and positive: Z is symmetric positive definite there).
  const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(ZFP, false).eigenvalues();
  std::vector<double> theta;
  double top = 0;
  for (int i = 0; i < n; ++i) top = std::max(top, std::abs(ev[i]));
  for (int i = 0; i < n; ++i)
    if (std::abs(ev[i]) > 1e-9 * top) theta.push_back(ev[i].real());
  ASSERT_FALSE(theta.empty()) << c.name;
  const double tmin = *std::min_element(theta.begin(), theta.end()),
               tmax = *std::max_element(theta.begin(), theta.end());
  const auto nearest = [&](double x) {
    double d = std::numeric_limits<double>::infinity();
    for (double t : theta) d = std::min(d, std::abs(t - x));
    return d / x;
  };
  EXPECT_LT(nearest(lo), 1e-3) << c.name << ": " << lo << " (smallest " << tmin << ")";
  EXPECT_LT(nearest(hi), 1e-5) << c.name << ": " << hi << " (largest " << tmax << ")";
  EXPECT_GE(lo, tmin * (1 - 1e-6)) << c.name;
  EXPECT_LE(hi, tmax * (1 + 1e-6)) << c.name;
}

namespace {
const Case kCases[] = {
    {"poisson2d TFETI", [] { return builtin(ProblemKind::poisson2d, 12, 3, 1, Glue::averages); }},
    {"membranes H-TFETI-DP averages",
     [] { return builtin(ProblemKind::membranes, 16, 4, 2, Glue::averages); }},
    {"poisson2d H-TFETI-DP corners",
     [] { return builtin(ProblemKind::poisson2d, 12, 4, 2, Glue::corners); }},
    {"cube TFETI jump", [] { return cube(1, true); }},
    {"cube H-TFETI-DP", [] { return cube(2, false); }},
};
}  // namespace

INSTANTIATE_TEST_SUITE_P(
    SmallCases, Preconditioners,
    ::testing::Combine(::testing::ValuesIn(kCases),
                       ::testing::Values(PreconditionerKind::lumped, PreconditionerKind::dirichlet),
                       ::testing::Values(Scaling::multiplicity, Scaling::stiffness)),
    [](const auto& info) {
      std::string n = std::get<0>(info.param).name + "_" + to_string(std::get<1>(info.param)) +
                      "_" + to_string(std::get<2>(info.param));
      for (char& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return n;
    });

// Preconditioning changes the path, not the solution: the energy agrees to 1e-8 at rtol 1e-10
// (PCG for the linear problems, SMALBE-M + MPRGP in face with contact).
TEST(PreconditionedSolves, SameSolution) {
  Comm comm;
  const Case cases[] = {kCases[0], kCases[1], kCases[2], kCases[3], kCases[4]};
  for (const auto& c : cases) {
    const auto model = c.model();
    SolveOptions base;
    // All at rtol 1e-10, the stiff cube with the 1e3 jump (lambda ~ 1e9) too: SMALBE-M's test
    // is in the units of the load (qp/smalbe.hpp). (Comparing ||G lambda|| with ||b|| it could
    // not pass 1e-7 there without a preconditioner.)
    base.rtol = 1e-10;
    base.check_memory = false;
    const SolveOutput ref = solve(model, base, comm);
    ASSERT_TRUE(ref.converged) << c.name;
    const double e0 = ref.report["objective"];
    for (auto kind : {PreconditionerKind::lumped, PreconditionerKind::dirichlet})
      for (auto scaling : {Scaling::multiplicity, Scaling::stiffness}) {
        SolveOptions o = base;
        o.feti.preconditioner = kind;
        o.feti.scaling = scaling;
        const SolveOutput out = solve(model, o, comm);
        const std::string what = c.name + " " + to_string(kind) + " " + to_string(scaling);
        ASSERT_TRUE(out.converged) << what;
        EXPECT_NEAR(out.report["objective"].get<double>(), e0, 1e-8 * std::abs(e0)) << what;
        EXPECT_GT(out.report["preconditioner_applications"].get<long>(), 0) << what;
        EXPECT_EQ(out.report["preconditioner"], to_string(kind));
      }
    // The layered Dirichlet preconditioner (one layer) too.
    SolveOptions o = base;
    o.feti.preconditioner = PreconditionerKind::dirichlet;
    o.feti.scaling = Scaling::multiplicity;
    o.feti.dirichlet_layers = 1;
    const SolveOutput out = solve(model, o, comm);
    ASSERT_TRUE(out.converged) << c.name << " layered";
    EXPECT_NEAR(out.report["objective"].get<double>(), e0, 1e-8 * std::abs(e0)) << c.name;
    EXPECT_EQ(out.report["preconditioner"], "dirichlet") << c.name;
    EXPECT_EQ(out.report["preconditioner_layers"], 1) << c.name;
  }
}

// The layered Dirichlet preconditioner on parts of 4^3 hex8 cells, where one layer clamps
// interior nodes (its factor is smaller than the whole interior's) and two clamp fewer: the
// same solution as without a preconditioner, in fewer iterations than lumped.
TEST(PreconditionedSolves, LayeredDirichletClampsAndConverges) {
  Comm comm;
  const auto model =
      std::shared_ptr<const Model>(make_model(cube_obstacle_spec({8, 8, 8}, {2, 2, 2}, 1)));
  SolveOptions base;
  base.rtol = 1e-10;
  base.check_memory = false;
  const SolveOutput ref = solve(model, base, comm);
  ASSERT_TRUE(ref.converged);
  const double e0 = ref.report["objective"];
  double previous_mb = 0;
  long lumped_products = 0;
  {
    SolveOptions o = base;
    o.feti.preconditioner = PreconditionerKind::lumped;
    const SolveOutput out = solve(model, o, comm);
    ASSERT_TRUE(out.converged);
    lumped_products = out.report["matvecs"].get<long>();
  }
  for (int layers : {1, 2, 0}) {
    SolveOptions o = base;
    o.feti.preconditioner = PreconditionerKind::dirichlet;
    o.feti.dirichlet_storage = 2;  // implicit: the factor of the kept interior
    o.feti.dirichlet_layers = layers;
    const SolveOutput out = solve(model, o, comm);
    ASSERT_TRUE(out.converged) << layers;
    EXPECT_NEAR(out.report["objective"].get<double>(), e0, 1e-8 * std::abs(e0)) << layers;
    EXPECT_EQ(out.report["preconditioner_layers"], layers);
    EXPECT_EQ(out.report["preconditioner_storage"], "implicit");
    EXPECT_LT(out.report["matvecs"].get<long>(), lumped_products) << layers;
    const double mb = out.report["memory"]["preconditioner_mb"];
    EXPECT_GT(mb, previous_mb) << layers;  // 1 layer < 2 layers < the whole interior
    previous_mb = mb;
  }
}

// auto picks lumped for elasticity, H-TFETI-DP with contact included (Dirichlet's setup costs
// more than the products it saves: docs/results.md, "The default").
TEST(AutomaticPreconditioner, ElasticityGetsLumpedAlsoForHybridContact) {
  Comm comm;
  SolveOptions o;
  o.check_memory = false;
  o.max_iterations = 2;  // the choice is made in the setup
  for (const int m : {1, 2}) {
    const SolveOutput out = solve(cube(m, false), o, comm);
    EXPECT_EQ(out.report["preconditioner"], "lumped") << m;
    EXPECT_EQ(out.report["preconditioner_reason"], "automatic: elasticity") << m;
  }
}

// auto picks Dirichlet for a coefficient field. In 3D it applies S_i with a factor of K_ii
// whatever the dense budget (docs/performance.md, "The Dirichlet preconditioner's storage"); in
// 2D it stores S_i dense when they fit the budget, and when they do not it takes none, and the
// report says why (not only the rule that asked for Dirichlet).
TEST(AutomaticPreconditioner, DirichletStorageByDimension) {
  Comm comm;
  SolveOptions o;
  o.check_memory = false;
  o.max_iterations = 2;  // the choice is made in the setup
  const auto cube3d = cube(2, true);
  for (const double budget : {2.0 * (1LL << 30), 0.0}) {
    o.feti.dirichlet_dense_budget_bytes = budget;
    const SolveOutput out = solve(cube3d, o, comm);
    EXPECT_EQ(out.report["preconditioner"], "dirichlet") << budget;
    EXPECT_EQ(out.report["preconditioner_reason"], "automatic: a coefficient field") << budget;
    EXPECT_EQ(out.report["preconditioner_storage"], "implicit") << budget;
  }
  RunOptions run;
  const std::shared_ptr<const Model> square(
      make_model(read_problem_file(HTFETI_SOURCE_DIR "/examples/heterogeneous.toml", run)));
  ASSERT_EQ(square->physics().dim, 2);
  o.feti.dirichlet_dense_budget_bytes = 2.0 * (1LL << 30);
  const SolveOutput fits = solve(square, o, comm);
  EXPECT_EQ(fits.report["preconditioner"], "dirichlet");
  EXPECT_EQ(fits.report["preconditioner_reason"], "automatic: a coefficient field");
  EXPECT_EQ(fits.report["preconditioner_storage"], "dense");
  o.feti.dirichlet_dense_budget_bytes = 0;
  const SolveOutput over = solve(square, o, comm);
  EXPECT_EQ(over.report["preconditioner"], "none");
  EXPECT_EQ(over.report["preconditioner_reason"],
            "automatic: a coefficient field; Dirichlet's dense S_i exceed "
            "dirichlet_budget_gb: none");
  // Asked for by name, Dirichlet does not fall back: implicit S_i.
  o.feti.preconditioner = PreconditionerKind::dirichlet;
  const SolveOutput asked = solve(square, o, comm);
  EXPECT_EQ(asked.report["preconditioner"], "dirichlet");
  EXPECT_EQ(asked.report["preconditioner_storage"], "implicit");
}

// The weighted projector P_Q = I - Q G~^T (G~ Q G~^T)^{-1} G~ (Q: the stiffness scaling's row
// stiffness) on the cube with a jump of 1e3: it maps into Ker G~ (P y = y) and is a projection
// (P_Q y = y there); P_Q^T vanishes on Im G~^T = Im (I - P) and is P_Q's adjoint; with the jump
// it is not P. PCG's preconditioner P_Q M^{-1} P_Q^T is symmetric and positive on Ker G~.
TEST(WeightedProjector, ProjectsOntoKerGAlongTheStiffness) {
  Comm comm;
  const auto model = cube(1, true);
  FetiOptions opt;
  opt.preconditioner = PreconditionerKind::dirichlet;
  opt.scaling = Scaling::stiffness;
  auto dual = test::make_dual(*model, comm, opt);
  ASSERT_TRUE(dual->set_weighted_projector());
  auto dot = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return dual->dot(a, b); };
  auto norm = [&](const Eigen::VectorXd& a) { return std::sqrt(dot(a, a)); };
  for (double seed : {1.0, 2.0}) {
    const Eigen::VectorXd x = test::pseudo_random(*dual, seed),
                          z = test::pseudo_random(*dual, seed + 5);
    Eigen::VectorXd y, py, yy, px, v, qv, qz, p;
    dual->project_weighted(x, y, false);
    dual->project(y, py);
    EXPECT_LT(norm(py - y), 1e-10 * norm(y)) << "P_Q x in Ker G~";
    dual->project_weighted(y, yy, false);
    EXPECT_LT(norm(yy - y), 1e-10 * norm(y)) << "P_Q P_Q = P_Q";
    dual->project(x, px);
    EXPECT_GT(norm(y - px), 1e-3 * norm(px)) << "the jump weights P_Q away from P";
    v = x - px;  // in Im G~^T
    dual->project_weighted(v, qv, true);
    EXPECT_LT(norm(qv), 1e-10 * norm(v)) << "P_Q^T on Im G~^T";
    dual->project_weighted(z, qz, true);
    EXPECT_NEAR(dot(y, z), dot(x, qz), 1e-10 * norm(x) * norm(z)) << "P_Q^T is the adjoint";
    // The preconditioner: symmetric, positive on Ker G~.
    auto Z = [&](const Eigen::VectorXd& w) {
      Eigen::VectorXd a, b, c;
      dual->project_weighted(w, a, true);
      dual->apply_preconditioner(a, b);
      dual->project_weighted(b, c, false);
      return c;
    };
    Eigen::VectorXd pz;
    dual->project(z, pz);
    EXPECT_NEAR(dot(Z(px), pz), dot(px, Z(pz)), 1e-10 * norm(Z(px)) * norm(pz));
    EXPECT_GT(dot(Z(px), px), 1e-8 * norm(Z(px)) * norm(px));
  }
}

// PCG with the weighted projector: the same solution as with the orthogonal one; auto takes it
// where no subdomain straddles the jump (a square of 4 x 4 boxes, the jump on x = 0.5) and not
// where one does (3 x 3 boxes); refused without stiffness scaling.
TEST(WeightedProjector, SameSolutionAndTheAutomaticChoice) {
  Comm comm;
  for (const auto& [boxes, automatic] : {std::pair{4, "weighted"}, std::pair{3, "orthogonal"}}) {
    ProblemSpec spec;
    spec.box.dim = 2;
    spec.box.cell = CellType::quad4;
    spec.box.size = {1, 1, 0};
    spec.box.elements = {24, 24, 0};
    spec.subdomains = {boxes, boxes};
    spec.physics.kind = PhysicsKind::laplace;
    spec.physics.coefficient = "x > 0.5 ? 1e4 : 1";
    spec.source = "1";
    spec.dirichlet.push_back({"x0", {0, 0, 0}, {}});
    const std::shared_ptr<const Model> model = make_model(spec);
    SolveOptions o;
    o.rtol = 1e-10;
    o.check_memory = false;
    std::map<std::string, double> energy;
    for (auto projector :
         {PcgProjector::automatic, PcgProjector::orthogonal, PcgProjector::weighted}) {
      o.pcg_projector = projector;
      const SolveOutput out = solve(model, o, comm);
      const std::string name = name_of(kPcgProjectorNames, projector);
      ASSERT_TRUE(out.converged) << boxes << " " << name;
      const std::string used = out.report["solver"]["pcg_projector"];
      EXPECT_EQ(used, projector == PcgProjector::automatic ? std::string(automatic) : name);
      energy[name] = out.report["objective"].get<double>();
    }
    EXPECT_NEAR(energy["weighted"], energy["orthogonal"], 1e-9 * std::abs(energy["orthogonal"]));
    EXPECT_NEAR(energy["auto"], energy["orthogonal"], 1e-9 * std::abs(energy["orthogonal"]));
    o.pcg_projector = PcgProjector::weighted;
    o.feti.scaling = Scaling::multiplicity;
    EXPECT_THROW(solve(model, o, comm), std::invalid_argument);
  }
}
