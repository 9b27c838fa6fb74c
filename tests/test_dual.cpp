// The dual operators on small cases, TFETI and H-TFETI-DP: the coarse factor inverts G~ G~^T
// (so G = L^{-1} G~ has orthonormal rows), P is a symmetric idempotent projector onto Ker G~,
// F is symmetric positive semidefinite and positive definite on Ker G~. A failure on one rank
// during setup is thrown on every rank. Runs under mpiexec -n 1, 2, 4.
#include <gtest/gtest.h>

#include <optional>

#include "helpers.hpp"
#include "htfeti/feti/dual_reducer.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/feti/operator_cost.hpp"

using namespace htfeti;

namespace {

struct Case {
  ProblemKind problem;
  int n, ns, m;
  Glue glue;
};

class DualOperators : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    const Case c = GetParam();
    dec = std::make_unique<Decomposition>(
        DecompositionOptions{c.problem, ElementKind::q1, c.n, c.ns, c.m, c.glue});
    model = make_builtin_model(dec->options());
    dual = test::make_dual(*model, comm);
  }
  double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return comm.sum(a.dot(b)); }
  // The columns of G~^T, from unit coarse vectors.
  std::vector<Eigen::VectorXd> gt_columns() {
    const int nc = dual->coarse_dimension();
    std::vector<Eigen::VectorXd> cols(nc);
    for (int c = 0; c < nc; ++c) {
      Eigen::VectorXd e = Eigen::VectorXd::Zero(nc);
      e[c] = 1;
      dual->apply_Gt(e, cols[c]);
    }
    return cols;
  }
  Comm comm;
  std::unique_ptr<Decomposition> dec;
  std::unique_ptr<Model> model;
  std::unique_ptr<DualProblem> dual;
};

TEST_P(DualOperators, CoarseFactorInvertsGGt) {
  // The dense G~ G~^T from the dot products of the columns of G~^T.
  const int nc = dual->coarse_dimension();
  const std::vector<Eigen::VectorXd> cols = gt_columns();
  Eigen::MatrixXd GGt(nc, nc);
  for (int a = 0; a < nc; ++a)
    for (int b = 0; b < nc; ++b) GGt(a, b) = dot(cols[a], cols[b]);
  Eigen::VectorXd z = Eigen::VectorXd::LinSpaced(nc, 1.0, 2.0), w = GGt * z;
  dual->coarse_solve(w);
  EXPECT_LT((w - z).norm(), 1e-10 * z.norm());
  // (The coarse factor comes from the owners' summed products, GGt here from dot products of
  // apply_Gt columns: two code paths. A former check that L^{-1} GGt L^{-T} = I with L from
  // GGt itself held by construction and was removed.)
  EXPECT_EQ(dual->unrestrained_rigid_motions(), 0);
  // apply_G is the transpose of apply_Gt.
  const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0);
  Eigen::VectorXd gx;
  dual->apply_G(x, gx);
  for (int c = 0; c < nc; ++c) EXPECT_NEAR(gx[c], dot(cols[c], x), 1e-12);
}

TEST_P(DualOperators, FaceCorrectionEqualsTheDenseFaceMatrix) {
  // set_face forms G~ D G~^T from a fixed part (the rows never held) kept from its first call
  // and the bounded rows times free: its correction G~^T (G~ D G~^T)^{-1} G~ v must be the one
  // of the dense matrix formed from apply_Gt's columns, for a face with held contact rows and
  // then (the kept fixed part reused) for the face with none held, where it is v - P v.
  const auto bounds = dual->constraint_set();
  const auto* lb = dynamic_cast<const qp::LowerBounds*>(bounds.get());
  if (!lb) GTEST_SKIP() << "no contact rows";
  const int n = dual->n_owned(), nc = dual->coarse_dimension();
  const std::vector<Eigen::VectorXd> cols = gt_columns();
  Eigen::VectorXd held_some = Eigen::VectorXd::Ones(n);
  int bounded = 0;
  for (int i = 0; i < n; ++i)
    if (lb->lower()[i] > -1e300 && bounded++ % 3 == 0) held_some[i] = 0.0;  // a contact row
  const Eigen::VectorXd v = test::pseudo_random(*dual, 3.0);
  for (const Eigen::VectorXd& free : {held_some, Eigen::VectorXd(Eigen::VectorXd::Ones(n))}) {
    Eigen::MatrixXd GDGt(nc, nc);
    for (int a = 0; a < nc; ++a)
      for (int b = 0; b < nc; ++b) GDGt(a, b) = dot(cols[a], free.cwiseProduct(cols[b]));
    if (GDGt.ldlt().rcond() < 1e-12) continue;  // a rigid motion held by held rows alone
    ASSERT_TRUE(dual->set_face(free));
    Eigen::VectorXd y, gv, ref;
    dual->face_correction(v, y);
    dual->apply_G(v, gv);
    const Eigen::VectorXd z = GDGt.ldlt().solve(gv);
    dual->apply_Gt(z, ref);
    EXPECT_LT(std::sqrt(dot(y - ref, y - ref)), 1e-10 * std::sqrt(dot(ref, ref)));
    if (comm.sum(static_cast<double>((free.array() == 0.0).count())) == 0) {
      // no row held (on any rank): the projector's complement
      Eigen::VectorXd pv;
      dual->project(v, pv);
      EXPECT_LT(std::sqrt(dot(y - (v - pv), y - (v - pv))), 1e-10 * std::sqrt(dot(v, v)));
    }
  }
}

TEST_P(DualOperators, WeightedCoarseSolveEqualsTheDenseMatrix) {
  // solve_weighted forms G~ W G~^T from the fixed part that factor() keeps plus the bounded
  // rows' products where W is 1 off the contact rows (the reconstruction's mask), and from all of
  // G~'s items otherwise: both must solve with the dense matrix of apply_Gt's columns.
  const int n = dual->n_owned(), nc = dual->coarse_dimension();
  const std::vector<Eigen::VectorXd> cols = gt_columns();
  const auto bounds = dual->constraint_set();
  const auto* lb = dynamic_cast<const qp::LowerBounds*>(bounds.get());
  std::vector<double> masked(n, 1.0), other(n, 1.0);
  int bounded = 0;
  for (int i = 0; i < n; ++i) {
    if (lb && lb->lower()[i] > -1e300 && bounded++ % 3 == 0) masked[i] = 0.0;  // a contact row
    if (!(lb && lb->lower()[i] > -1e300) && i % 5 == 1) other[i] = 0.5;        // an equality row
  }
  for (const std::vector<double>& weight : {masked, other}) {
    const Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(weight.data(), n);
    Eigen::MatrixXd GWGt(nc, nc);
    for (int a = 0; a < nc; ++a)
      for (int b = 0; b < nc; ++b) GWGt(a, b) = dot(cols[a], w.cwiseProduct(cols[b]));
    if (GWGt.ldlt().rcond() < 1e-12) continue;  // a rigid motion held by masked rows alone
    const Eigen::VectorXd z = Eigen::VectorXd::LinSpaced(nc, 1.0, 2.0);
    Eigen::VectorXd y = GWGt * z;
    EXPECT_EQ(dual->coarse_solve_weighted(weight, y), 0);
    EXPECT_LT((y - z).norm(), 1e-10 * z.norm());
  }
}

TEST_P(DualOperators, ProjectorIsSymmetricIdempotentOntoKerG) {
  const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0), y = test::pseudo_random(*dual, 2.0);
  Eigen::VectorXd px, ppx, py, gpx;
  dual->project(x, px);
  dual->project(px, ppx);
  dual->project(y, py);
  const double nx = std::sqrt(dot(x, x));
  EXPECT_LT(std::sqrt(dot(ppx - px, ppx - px)), 1e-12 * nx);
  EXPECT_NEAR(dot(px, y), dot(x, py), 1e-12 * nx * std::sqrt(dot(y, y)));
  dual->apply_G(px, gpx);
  EXPECT_LT(gpx.norm(), 1e-12 * nx);
  // lambda~ satisfies G~ lambda = e~.
  Eigen::VectorXd gl;
  dual->apply_G(dual->lambda_tilde(), gl);
  EXPECT_LT((gl - dual->e()).norm(), 1e-12 * (1 + dual->e().norm()));
}

TEST_P(DualOperators, FusedReductionsEqualTheSeparateOnes) {
  // DualProblem::dots forms several dot products and sums in one allreduce; each must be the
  // number dot() and sum() give, bit for bit (MPRGP's counts and results must not move), also
  // with more terms than the work array holds at first (kDotsReserved).
  const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0), y = test::pseudo_random(*dual, 2.0);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(dual->n_owned());
  const int terms = kDotsReserved + 2;
  std::vector<const Eigen::VectorXd*> a(terms), b(terms);
  for (int k = 0; k < terms; ++k) {
    a[k] = k % 2 ? &x : &y;
    b[k] = k % 3 == 2 ? nullptr : (k % 2 ? &y : &x);
  }
  b[1] = &ones;
  std::vector<double> out(terms);
  dual->dots(terms, a.data(), b.data(), out.data());
  for (int k = 0; k < terms; ++k)
    EXPECT_EQ(out[k], b[k] ? dual->dot(*a[k], *b[k]) : dual->sum(*a[k])) << "term " << k;
  // A hand-checkable one: ones'ones and the entries of ones sum to the dual dimension.
  const Eigen::VectorXd* oa[2] = {&ones, &ones};
  const Eigen::VectorXd* ob[2] = {&ones, nullptr};
  double counts[2];
  dual->dots(2, oa, ob, counts);
  EXPECT_EQ(counts[0], static_cast<double>(dual->dual_dimension()));
  EXPECT_EQ(counts[1], static_cast<double>(dual->dual_dimension()));
  // Through the reducer MPRGP uses.
  const DualReducer red(comm, *dual);
  double via[2];
  red.dots(2, oa, ob, via);
  EXPECT_EQ(via[0], counts[0]);
  EXPECT_EQ(via[1], counts[1]);
}

TEST_P(DualOperators, FIsSymmetricPositiveSemidefinite) {
  Eigen::VectorXd fx, fy;
  for (double seed : {1.0, 2.0, 3.0}) {
    const Eigen::VectorXd x = test::pseudo_random(*dual, seed),
                          y = test::pseudo_random(*dual, seed + 10);
    dual->apply_F(x, fx);
    dual->apply_F(y, fy);
    const double scale = std::sqrt(dot(fx, fx) * dot(y, y));
    EXPECT_NEAR(dot(fx, y), dot(x, fy), 1e-12 * scale);
    // F is positive definite on Ker G~ (B~ has full row rank): for a random projected x,
    // x'Fx is positive on the scale of ||Fx|| ||x||, not merely >= 0.
    Eigen::VectorXd px, fpx;
    dual->project(x, px);
    dual->apply_F(px, fpx);
    EXPECT_GT(dot(fpx, px), 1e-8 * std::sqrt(dot(fpx, fpx) * dot(px, px)));
  }
  if (comm.size() == 1) {  // all eigenvalues of the dense F are >= 0
    const int n = dual->n_owned();
    Eigen::MatrixXd F(n, n);
    Eigen::VectorXd e, col;
    for (int j = 0; j < n; ++j) {
      e = Eigen::VectorXd::Zero(n);
      e[j] = 1;
      dual->apply_F(e, col);
      F.col(j) = col;
    }
    EXPECT_LT((F - F.transpose()).norm(), 1e-12 * F.norm());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (F + F.transpose()));
    EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-12 * eig.eigenvalues().maxCoeff());
  }
}

// The implicit operator with the factors (double sweeps) equals the explicit one to round-off;
// with the factors' single-precision copies (the automatic precision for TFETI) it differs by
// their rounding (visible, and small), and set_single_sweeps(false) gives the double sweeps
// back bit for bit. d is formed with the factors either way.
TEST_P(DualOperators, ExplicitEqualsImplicit) {
  FetiOptions imp, exp, sgl;
  imp.dual_operator = sgl.dual_operator = DualOperator::implicit;
  imp.factor_precision = FactorPrecision::double_;
  exp.dual_operator = DualOperator::explicit_;
  auto pa = test::make_dual(*model, comm, imp), pb = test::make_dual(*model, comm, exp);
  auto pc = test::make_dual(*model, comm, sgl);
  DualProblem &a = *pa, &b = *pb, &c = *pc;
  ASSERT_FALSE(a.explicit_operator());
  ASSERT_TRUE(b.explicit_operator());
  EXPECT_FALSE(a.single_sweeps());
  EXPECT_EQ(c.single_sweeps(), GetParam().m == 1);  // TFETI only
  Eigen::VectorXd fa, fb, fc;
  for (double seed : {1.0, 5.0}) {
    const Eigen::VectorXd x = test::pseudo_random(a, seed);
    a.apply_F(x, fa);
    b.apply_F(x, fb);
    EXPECT_LT(std::sqrt(dot(fa - fb, fa - fb)), 1e-11 * std::sqrt(dot(fa, fa)));
    c.apply_F(x, fc);
    const double diff = std::sqrt(dot(fc - fa, fc - fa)) / std::sqrt(dot(fa, fa));
    EXPECT_LT(diff, 1e-5);
    if (c.single_sweeps()) {
      EXPECT_GT(diff, 1e-12);
      c.set_single_sweeps(false);
      c.apply_F(x, fc);
      EXPECT_EQ(dot(fc - fa, fc - fa), 0.0);
      c.set_single_sweeps(true);
    }
  }
  EXPECT_LT((a.d() - b.d()).norm(), 1e-11 * (1 + a.d().norm()));
  EXPECT_EQ(dot(a.d() - c.d(), a.d() - c.d()), 0.0);
}

// The checked operator applies the explicit one (bit for bit what the explicit operator gives)
// and measures it against the implicit one at every product: within round-off in double
// precision, the rounding of the blocks in single precision (visible, and small).
TEST_P(DualOperators, CheckedMeasuresTheExplicitAgainstTheImplicit) {
  for (Precision precision : {Precision::double_, Precision::single}) {
    FetiOptions exp, chk;
    exp.dual_operator = DualOperator::explicit_;
    chk.dual_operator = DualOperator::checked;
    exp.explicit_precision = chk.explicit_precision = precision;
    auto pe = test::make_dual(*model, comm, exp), pc = test::make_dual(*model, comm, chk);
    DualProblem &e = *pe, &c = *pc;
    EXPECT_EQ(c.dual_operator_name(), "checked");
    EXPECT_EQ(e.dual_operator_name(), "explicit");
    EXPECT_EQ(c.dual_operator_check().applications, 0);
    Eigen::VectorXd fe, fc;
    for (double seed : {1.0, 5.0, 9.0}) {
      const Eigen::VectorXd x = test::pseudo_random(e, seed);
      e.apply_F(x, fe);
      c.apply_F(x, fc);
      if (fe.size() > 0) EXPECT_EQ((fe - fc).cwiseAbs().maxCoeff(), 0.0);
    }
    const DualProblem::OperatorCheck check = c.dual_operator_check();
    EXPECT_EQ(check.applications, 3);
    if (precision == Precision::double_) {
      EXPECT_LT(check.max_relative_difference, 1e-11);
    } else {
      EXPECT_GT(check.max_relative_difference, 1e-10);
      EXPECT_LT(check.max_relative_difference, 1e-5);
    }
  }
}

// The coarse image: E = F G~^T column by column (each from its own G~^T and F application,
// against the colour-at-a-time construction), and the Hessian product with one coarse step
// against P F P v + rho Q v with two projections.
TEST_P(DualOperators, CoarseImageGivesTheHessianWithOneCoarseStep) {
  dual->build_coarse_image();
  const auto& st = dual->coarse_image_stats();
  EXPECT_GT(st.colours, 0);
  EXPECT_LE(st.F_applications, st.colours * 3);
  const int nc = dual->coarse_dimension();
  Eigen::VectorXd e, w, fw, ew;
  double scale = 0, err = 0;
  for (int a = 0; a < nc; ++a) {
    e = Eigen::VectorXd::Zero(nc);
    e[a] = 1;
    dual->apply_Gt(e, w);
    dual->apply_F(w, fw);
    dual->apply_coarse_image(e, ew);
    scale = std::max(scale, std::sqrt(dot(fw, fw)));
    err = std::max(err, std::sqrt(dot(fw - ew, fw - ew)));
  }
  EXPECT_LE(err, 1e-13 * scale);
  for (double seed : {1.0, 4.0}) {
    const Eigen::VectorXd v = test::pseudo_random(*dual, seed);
    const double rho = 1.7;
    Eigen::VectorXd pv, y, fv, y1, q1;
    dual->project(v, pv);
    dual->apply_F(pv, y);
    dual->project(y, y);
    y += rho * (v - pv);
    dual->apply_F(v, fv);
    dual->hessian_from_Fv(v, fv, rho, y1, q1);
    EXPECT_LE(std::sqrt(dot(y1 - y, y1 - y)), 1e-12 * std::sqrt(dot(y, y)));
    const Eigen::VectorXd q = v - pv;
    EXPECT_LE(std::sqrt(dot(q1 - q, q1 - q)), 1e-12 * std::sqrt(dot(v, v)));
  }
}

INSTANTIATE_TEST_SUITE_P(SmallCases, DualOperators,
                         ::testing::Values(Case{ProblemKind::poisson2d, 8, 4, 1, Glue::averages},
                                           Case{ProblemKind::membranes, 12, 3, 1, Glue::averages},
                                           Case{ProblemKind::membranes, 16, 4, 2, Glue::averages},
                                           Case{ProblemKind::poisson2d, 12, 4, 2, Glue::corners},
                                           Case{ProblemKind::membranes, 16, 4, 4,
                                                Glue::corners_averages}));

// The cost model of the automatic operator (operator_cost.hpp). Its arithmetic by hand: with
// c_sweep 1, c_supernode 2, c_packed 0.5, c_factor 3, c_unknown 5, c_dense 4,
// c_explicit_unknown 6, a subdomain of 10 unknowns whose factor has 100 values, 10 supernodes
// and 1000 flops, n_b = 2 and m = 3: implicit setup 3000 + 50 and F 16 * 100 + 2 * 10 = 1620;
// explicit setup 3050 + 4 * 2^3 + 6 * 10 = 3142 and F 0.5 * 8 * 3 * 4 / 2 = 24; break-even
// 92 / 1596 applications.
TEST(OperatorCost, ModelArithmetic) {
  OperatorCostConstants c;
  c.sweep_per_byte = 1, c.per_supernode = 2, c.packed_per_byte = 0.5, c.factor_per_flop = 3;
  c.dense_per_flop = 4;
  c.per_unknown = 5, c.explicit_per_unknown = 6;
  SubdomainCostSample m;
  m.factor_values = 100, m.factor_supernodes = 10, m.factor_flops = 1000, m.interface_dofs = 2;
  m.multipliers = 3, m.unknowns = 10;
  const OperatorCost o = operator_cost(m, 1, true, 8.0, c);
  EXPECT_DOUBLE_EQ(o.implicit_setup, 3050);
  EXPECT_DOUBLE_EQ(o.implicit_per_F, 1620);
  EXPECT_DOUBLE_EQ(o.explicit_setup, 3142);
  EXPECT_DOUBLE_EQ(o.explicit_per_F, 24);
  EXPECT_DOUBLE_EQ(o.break_even, 92.0 / 1596.0);
  EXPECT_EQ(o.expected_applications, kExpectedApplicationsContact);
  EXPECT_TRUE(o.explicit_cheaper());
  // Single precision halves the F_i's bytes; without contact the expected count is PCG's.
  const OperatorCost single = operator_cost(m, 1, false, 4.0, c);
  EXPECT_DOUBLE_EQ(single.explicit_per_F, 12);
  EXPECT_EQ(single.expected_applications, kExpectedApplicationsLinear);
  // F_i read slower than the factor: never worth forming.
  m.multipliers = 30;  // 0.5 * 8 * 30 * 31 / 2 = 1860 > 1620
  const OperatorCost never = operator_cost(m, 1, true, 8.0, c);
  EXPECT_TRUE(std::isinf(never.break_even));
  EXPECT_FALSE(never.explicit_cheaper());
  // Setup paid back only after more applications than expected.
  m.multipliers = 3, m.interface_dofs = 400;  // (4 * 400^3 + 60) / 1596 = 160,401 applications
  EXPECT_FALSE(operator_cost(m, 1, true, 8.0, c).explicit_cheaper());
}

// A hand-made subdomain of 5 nodes with 2 dofs each (K tridiagonal): node 0 shared by 2
// subdomains and node 4 by 3 (2 + 4 multipliers), a contact row with friction keyed by node 3 and
// given to nodes 3 and 1 (one normal and one tangential row), a Dirichlet dof on node 2: m = 9;
// the dofs touched are those of nodes 0, 1, 3 and 4 and the Dirichlet dof, n_b = 9.
TEST(OperatorCost, CountsAHandMadeSubdomain) {
  const int nodes = 5, n = 2 * nodes;
  SubdomainInput in;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 2.0);
    if (i + 1 < n) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
  }
  in.system.dofs_per_node = 2;
  in.system.K.resize(n, n);
  in.system.K.setFromTriplets(t.begin(), t.end());
  in.system.f = Eigen::VectorXd::Zero(n);
  in.system.R = Eigen::MatrixXd(n, 0);  // K is positive definite: no kernel
  in.sharing.global_node = {0, 1, 2, 3, 4};
  in.sharing.coords.assign(3 * nodes, 0.0);
  in.sharing.copy_offset = {0, 2, 3, 4, 5, 8};
  in.sharing.copy_list = {0, 1, 0, 0, 0, 0, 1, 2};
  in.sharing.on_boundary.assign(nodes, 0);
  in.dirichlet = {{2, 0, 0.0}};
  for (int node : {3, 1}) {
    ContactRow r;
    r.node = node;
    r.node_a = 3;
    r.slip_bound = 1.0;
    in.contact.push_back(r);
  }
  const SubdomainCostSample s = sample_subdomain_cost(std::move(in), 2, Ordering::amd);
  EXPECT_EQ(s.unknowns, n);
  EXPECT_EQ(s.multipliers, 9);
  EXPECT_EQ(s.interface_dofs, 9);
  EXPECT_GE(s.factor_values, 2 * n - 1);  // no fill: the diagonal and the subdiagonal, at least
  EXPECT_GE(s.factor_supernodes, 1);
  EXPECT_GT(s.factor_flops, 0);
}

// The sample is the same on any number of ranks: subdomains 0, S / 2 and S - 1 wherever they
// are held, averaged in that order. Here every rank also counts them itself (a generated model
// builds any subdomain) and must find the collective result bit for bit.
TEST(OperatorCost, SameSampleOnEveryRankCount) {
  Comm comm;
  const auto model =
      make_builtin_model({ProblemKind::membranes, ElementKind::q1, 24, 4, 2, Glue::averages});
  FetiOptions options;
  const std::optional<OperatorCost> cost = estimate_operator_cost(*model, options, comm);
  ASSERT_TRUE(cost.has_value());
  const int S = model->num_subdomains();
  ASSERT_EQ(cost->samples, 3);
  SubdomainCostSample mine;
  for (int s : {0, S / 2, S - 1}) {
    const SubdomainCostSample x =
        sample_subdomain_cost(model->input(s), model->physics().dofs_per_node(), Ordering::amd);
    mine.unknowns += x.unknowns, mine.multipliers += x.multipliers;
    mine.interface_dofs += x.interface_dofs, mine.factor_values += x.factor_values;
    mine.factor_supernodes += x.factor_supernodes, mine.factor_flops += x.factor_flops;
  }
  EXPECT_EQ(cost->mean.unknowns, mine.unknowns / 3);
  EXPECT_EQ(cost->mean.multipliers, mine.multipliers / 3);
  EXPECT_EQ(cost->mean.interface_dofs, mine.interface_dofs / 3);
  EXPECT_EQ(cost->mean.factor_values, mine.factor_values / 3);
  EXPECT_EQ(cost->mean.factor_supernodes, mine.factor_supernodes / 3);
  EXPECT_EQ(cost->mean.factor_flops, mine.factor_flops / 3);
  // Membranes: contact, a 2D subdomain of 6 x 6 elements with a small interface.
  EXPECT_EQ(cost->expected_applications, kExpectedApplicationsContact);
  EXPECT_TRUE(cost->explicit_cheaper());
}

// A failure on one rank only (the input of the last subdomain, which the last rank owns) is
// agreed on: every rank throws the same exception type and message, nobody hangs.
TEST(Failures, OneRankFailingStopsEveryRank) {
  Comm comm;
  const auto model =
      make_builtin_model({ProblemKind::membranes, ElementKind::q1, 16, 4, 2, Glue::averages});
  const int last = model->num_subdomains() - 1;
  for (bool input_error : {true, false}) {
    std::string message;
    try {
      DualProblem dual(
          model->layout(),
          [&](int s) {
            if (s == last) {
              if (input_error) throw std::invalid_argument("bad subdomain " + std::to_string(s));
              throw std::runtime_error("broken subdomain " + std::to_string(s));
            }
            return model->input(s);
          },
          comm, FetiOptions{});
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(input_error);
      message = e.what();
    } catch (const std::runtime_error& e) {
      EXPECT_FALSE(input_error);
      message = e.what();
    }
    EXPECT_NE(message.find("subdomain " + std::to_string(last)), std::string::npos)
        << "rank " << comm.rank() << ": '" << message << "'";
  }
}

}  // namespace
