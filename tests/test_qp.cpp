// Conformance suite for the QP solvers: on small random problems the result must match the exact
// solution found by enumerating active sets, and satisfy KKT (feasibility, non-negative bound
// multipliers, complementarity, small projected gradient). Failure paths are results, not throws.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <random>

#include "htfeti/linalg/nnls.hpp"
#include "htfeti/qp/cg_spectrum.hpp"
#include "htfeti/qp/mpgp.hpp"
#include "htfeti/qp/mprgp.hpp"
#include "htfeti/qp/pcg.hpp"
#include "htfeti/qp/power_norm.hpp"
#include "htfeti/qp/qp.hpp"
#include "htfeti/qp/smalbe.hpp"

using namespace htfeti;
using namespace htfeti::qp;

namespace {

const double inf = std::numeric_limits<double>::infinity();

class DenseOperator final : public Operator {
 public:
  explicit DenseOperator(Eigen::MatrixXd A) : A_(std::move(A)) {}

 protected:
  void do_apply(const Vec& x, Vec& y) override { y.noalias() = A_ * x; }

 private:
  Eigen::MatrixXd A_;
};

struct Qp {
  Eigen::MatrixXd A, G;  // G: orthonormal rows (may be empty)
  Vec b, l;
};

// The QP object of a test problem: A (not owned), b, the bounds l and, with equalities, the
// projector P = I - G'G onto Ker G (owned by the returned QP).
QuadraticProgram qp_of(Operator& A, const Qp& q, bool bounds = true) {
  QuadraticProgram out;
  out.hessian = borrow(A);
  out.linear = q.b;
  if (bounds) out.constraints = std::make_shared<LowerBounds>(q.l);
  const Eigen::Index n = q.b.size();
  out.equality_projector =
      std::make_shared<DenseOperator>(Eigen::MatrixXd::Identity(n, n) - q.G.transpose() * q.G);
  return out;
}

// Random QP: A = M'M + shift (or P M P + ... for the singular FETI-like case).
Qp random_qp(int n, int bounded, int equalities, unsigned seed, bool singular_off_kernel) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> N01;
  Qp q;
  Eigen::MatrixXd M(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) M(i, j) = N01(gen);
  q.A = M.transpose() * M / n + 0.1 * Eigen::MatrixXd::Identity(n, n);
  q.G.resize(equalities, n);
  for (int i = 0; i < equalities; ++i)
    for (int j = 0; j < n; ++j) q.G(i, j) = N01(gen);
  if (equalities > 0) {
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(q.G.transpose());
    q.G = Eigen::MatrixXd(qr.householderQ()).leftCols(equalities).transpose();
    if (singular_off_kernel) {  // A = P A P: singular, positive definite on Ker G only
      const Eigen::MatrixXd P = Eigen::MatrixXd::Identity(n, n) - q.G.transpose() * q.G;
      q.A = P * q.A * P;
    }
  }
  q.b.resize(n);
  q.l.resize(n);
  for (int i = 0; i < n; ++i) {
    q.b[i] = N01(gen);
    q.l[i] = i < bounded ? N01(gen) * 0.3 : -inf;
  }
  return q;
}

// Exact solution by enumerating the active sets of the bounded components.
Vec exact_solution(const Qp& q, int bounded) {
  const int n = static_cast<int>(q.b.size()), me = static_cast<int>(q.G.rows());
  for (int mask = 0; mask < (1 << bounded); ++mask) {
    std::vector<int> fr;
    for (int i = 0; i < n; ++i)
      if (!(i < bounded && (mask >> i & 1))) fr.push_back(i);
    const int nf = static_cast<int>(fr.size());
    Vec x = Vec::Zero(n);
    for (int i = 0; i < bounded; ++i)
      if (mask >> i & 1) x[i] = q.l[i];
    // KKT on the free set: [A_FF G_F'; G_F 0] [x_F; mu] = [b_F - A_FS x_S; -G_S x_S].
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nf + me, nf + me);
    Vec rhs(nf + me);
    const Vec Ax = q.A * x, Gx = me ? Vec(q.G * x) : Vec();
    for (int a = 0; a < nf; ++a) {
      for (int c = 0; c < nf; ++c) K(a, c) = q.A(fr[a], fr[c]);
      for (int e = 0; e < me; ++e) K(a, nf + e) = K(nf + e, a) = q.G(e, fr[a]);
      rhs[a] = q.b[fr[a]] - Ax[fr[a]];
    }
    for (int e = 0; e < me; ++e) rhs[nf + e] = -Gx[e];
    Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    if (!lu.isInvertible()) continue;
    const Vec sol = lu.solve(rhs);
    for (int a = 0; a < nf; ++a) x[fr[a]] = sol[a];
    Vec g = q.A * x - q.b;
    if (me) g += q.G.transpose() * sol.tail(me);
    bool ok = true;
    for (int i = 0; i < n; ++i) {
      if (x[i] < q.l[i] - 1e-12) ok = false;
      if (i < bounded && (mask >> i & 1) && g[i] < -1e-12) ok = false;  // multiplier >= 0
    }
    if (ok) return x;
  }
  ADD_FAILURE() << "no active set satisfies KKT";
  return Vec::Zero(n);
}

void expect_kkt(const Qp& q, const Vec& x, double tol) {
  const int me = static_cast<int>(q.G.rows());
  // Multipliers of the equalities by least squares on the free components.
  Vec g = q.A * x - q.b;
  if (me) {
    const Vec mu = q.G.transpose().colPivHouseholderQr().solve(-g);
    // only free components must vanish; use them to refit mu
    std::vector<int> fr;
    for (int i = 0; i < x.size(); ++i)
      if (x[i] > q.l[i] + 1e-9) fr.push_back(i);
    Eigen::MatrixXd Gf(fr.size(), me);
    Vec gf(fr.size());
    for (size_t a = 0; a < fr.size(); ++a) Gf.row(a) = q.G.col(fr[a]).transpose(), gf[a] = g[fr[a]];
    const Vec mu_f = Gf.colPivHouseholderQr().solve(-gf);
    g += q.G.transpose() * (fr.size() >= static_cast<size_t>(me) ? mu_f : mu);
    EXPECT_LT((q.G * x).norm(), tol);
  }
  for (int i = 0; i < x.size(); ++i) {
    EXPECT_GE(x[i], q.l[i] - 1e-14);  // feasibility
    if (q.l[i] > -inf) {
      EXPECT_GE(g[i], -tol);                             // multiplier >= 0
      EXPECT_LT(std::abs(g[i] * (x[i] - q.l[i])), tol);  // complementarity
    } else {
      EXPECT_LT(std::abs(g[i]), tol);  // stationarity
    }
  }
}

// A symmetric positive definite n x n matrix with eigenvalues spread from 1 to `spread`
// (logarithmically) in a random orthonormal basis: CG needs many steps on it.
Eigen::MatrixXd spread_spd(int n, double spread, unsigned seed) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> N01;
  Eigen::MatrixXd M(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) M(i, j) = N01(gen);
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(M).householderQ();
  Vec ev(n);
  for (int i = 0; i < n; ++i) ev[i] = std::pow(spread, static_cast<double>(i) / (n - 1));
  return Q * ev.asDiagonal() * Q.transpose();
}

}  // namespace

class MprgpConformance : public ::testing::TestWithParam<unsigned> {};

TEST_P(MprgpConformance, MatchesEnumeratedActiveSets) {
  const int n = 10, bounded = 7;
  const Qp q = random_qp(n, bounded, 0, GetParam(), false);
  DenseOperator A(q.A);
  SerialReducer red;
  MprgpOptions opt;
  const double normA = estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
  opt.alpha = 1.9 / normA;
  Vec x = Vec::Zero(n), g(n);
  const double tol = 1e-11 * q.b.norm();
  const auto r = mprgp(A, q.b, q.l, x, g, red, opt,
                       [&](const Vec&, const Vec&, double gp) { return gp <= tol; });
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_LT((x - exact_solution(q, bounded)).norm(), 1e-8);
  expect_kkt(q, x, 1e-9);
  EXPECT_EQ(r.cg_steps + r.expansion_steps + r.proportioning_steps, r.iterations);
  // Preconditioned in face (a non-diagonal SPD Z: the inverse of A's tridiagonal part, shifted):
  // the same solution.
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = std::max(0, i - 1); j <= std::min(n - 1, i + 1); ++j) T(i, j) = q.A(i, j);
  T.diagonal() += Vec::Constant(n, T.cwiseAbs().rowwise().sum().maxCoeff());  // diagonally dominant
  const Eigen::MatrixXd Zm = T.inverse();
  DenseOperator Z(0.5 * (Zm + Zm.transpose()));
  opt.preconditioner = &Z;
  Vec xp = Vec::Zero(n), gp(n);
  const auto rp = mprgp(A, q.b, q.l, xp, gp, red, opt,
                        [&](const Vec&, const Vec&, double gpn) { return gpn <= tol; });
  ASSERT_EQ(rp.reason, StopReason::converged);
  EXPECT_LT((xp - exact_solution(q, bounded)).norm(), 1e-8);
  expect_kkt(q, xp, 1e-9);
  EXPECT_GT(Z.count(), 0);
  // The preconditioned and the projected CG expansion steps, with Z and without: the same
  // solution.
  for (Expansion e : {Expansion::preconditioned, Expansion::projected_cg, Expansion::automatic})
    for (Operator* z : {static_cast<Operator*>(&Z), static_cast<Operator*>(nullptr)}) {
      opt.preconditioner = z;
      opt.expansion = e;
      Vec xe = Vec::Zero(n), ge(n);
      const auto re = mprgp(A, q.b, q.l, xe, ge, red, opt,
                            [&](const Vec&, const Vec&, double gpn) { return gpn <= tol; });
      ASSERT_EQ(re.reason, StopReason::converged);
      EXPECT_LT((xe - exact_solution(q, bounded)).norm(), 1e-8);
      expect_kkt(q, xe, 1e-9);
      EXPECT_LE(re.expansion_cost_increases, re.expansion_steps);
    }
}

INSTANTIATE_TEST_SUITE_P(Random, MprgpConformance, ::testing::Range(1u, 9u));

// By hand: min 1/2 x'Ax - b'x, x_1 >= 0, A = [1 -0.92; -0.92 1], b = (0, -0.8), from (1.2, 0.9).
// The first CG step (along g = (2.028, -0.504) in this form) leaves the bound after 3.23 of its
// 5.76 length; projected, the whole step costs 1.18, the half step -0.30, so it is undone and the
// fixed-length step is taken from the half step. The solution is (0, -0.8) (g_1 = 0.736 >= 0). The
// tracked image T x follows through the undone step.
TEST(Mprgp, ProjectedCgExpansionIsUndoneWhereItRaisesTheCost) {
  Eigen::MatrixXd Am(2, 2);
  Am << 1.0, -0.92, -0.92, 1.0;
  const Vec b = (Vec(2) << 0.0, -0.8).finished();
  const Vec l = (Vec(2) << 0.0, -inf).finished();
  const Eigen::MatrixXd Tm = (Eigen::MatrixXd(1, 2) << 0.3, -1.7).finished();
  Vec last(1);
  FunctionOperator A([&](const Vec& v, Vec& y) {
    y = Am * v;
    last = Tm * v;
  });
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.9 / 1.92;  // ||A|| = 1.92
  opt.expansion = Expansion::projected_cg;
  TrackedImage image;
  image.last = &last;
  opt.image = &image;
  Vec x = (Vec(2) << 1.2, 0.9).finished(), g(2);
  double worst = 0, first_f = 0;
  int tests = 0;
  const auto r = mprgp(A, b, l, x, g, red, opt, [&](const Vec& xx, const Vec& gg, double gp) {
    worst = std::max(worst, (image.tx - Tm * xx).norm());
    if (tests++ == 1) first_f = 0.5 * xx.dot(gg - b);
    return gp <= 1e-12;
  });
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_GE(r.expansion_cost_increases, 1);
  EXPECT_LT((x - (Vec(2) << 0.0, -0.8).finished()).norm(), 1e-10);
  // automatic tries the same step: it would move x by 5.76, more than twice the fixed-length
  // step's alpha ||phi|| = 2.07.
  opt.expansion = Expansion::automatic;
  Vec xa = (Vec(2) << 1.2, 0.9).finished(), ga(2);
  const auto ra = mprgp(A, b, l, xa, ga, red, opt,
                        [&](const Vec&, const Vec&, double gp) { return gp <= 1e-12; });
  ASSERT_EQ(ra.reason, StopReason::converged);
  EXPECT_GE(ra.projected_cg_expansions, 1);
  EXPECT_GE(ra.expansion_cost_increases, 1);
  EXPECT_LT((xa - (Vec(2) << 0.0, -0.8).finished()).norm(), 1e-10);
  EXPECT_LT(worst, 1e-12);
  // After the first iteration the cost is below the half step's -0.2952 (the undone step's 1.18
  // would be above it).
  EXPECT_LT(first_f, -0.2952);
}

// The preconditioned and the projected CG expansion steps are taken in these random cases, and
// the runs end at the enumerated solution.
//  - preconditioned: a step that raised the cost is counted (kept), at most one per expansion
//    step; one product per iteration, one more per expansion step and per preconditioned one.
//  - projected CG (the whole CG step, projected): kept when it lowers the cost below the feasible
//    half step's, undone otherwise, so the cost never rises from one stop test to the next; an
//    expansion step costs one product more than a CG step, two when undone.
TEST(Mprgp, ExpansionVariantsAreTakenAndReachTheSolution) {
  const int n = 10, bounded = 7;
  for (Expansion e : {Expansion::preconditioned, Expansion::projected_cg, Expansion::automatic}) {
    int taken = 0, kept = 0, tried = 0;
    for (unsigned seed = 1; seed < 17; ++seed) {
      Qp q = random_qp(n, bounded, 0, seed, false);
      q.b *= 2.0;
      DenseOperator A(q.A);
      SerialReducer red;
      MprgpOptions opt;
      opt.alpha = 1.9 / estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
      DenseOperator Z(Eigen::MatrixXd(q.A.diagonal().cwiseInverse().asDiagonal()));
      if (e == Expansion::preconditioned || seed % 2) opt.preconditioner = &Z;
      opt.expansion = e;
      Vec x = Vec::Zero(n), g(n);
      double last = std::numeric_limits<double>::infinity(), rise = 0;
      const long before = A.count();
      const auto r =
          mprgp(A, q.b, q.l, x, g, red, opt, [&](const Vec& xx, const Vec& gg, double gp) {
            const double f = 0.5 * xx.dot(gg - q.b);
            rise = std::max(rise, f - last);
            last = f;
            return gp <= 1e-11 * q.b.norm();
          });
      const std::string what = to_string(e) + ", seed " + std::to_string(seed);
      ASSERT_EQ(r.reason, StopReason::converged) << what;
      EXPECT_LT((x - exact_solution(q, bounded)).norm(), 1e-8) << what;
      EXPECT_LE(r.expansion_cost_increases, r.expansion_steps) << what;
      const long products = A.count() - before;
      if (e == Expansion::preconditioned) {
        EXPECT_LE(products, 1 + r.iterations + 2 * r.expansion_steps) << what;
      } else {
        EXPECT_LE(rise, 1e-12 * std::abs(last)) << what;
        EXPECT_EQ(products, 1 + r.iterations + r.expansion_steps + r.expansion_cost_increases)
            << what;
      }
      if (e != Expansion::preconditioned)
        EXPECT_LE(r.expansion_cost_increases, r.projected_cg_expansions) << what;
      if (e == Expansion::projected_cg) EXPECT_EQ(r.projected_cg_expansions, r.expansion_steps);
      taken += r.expansion_steps;
      kept += r.expansion_steps - r.expansion_cost_increases;
      tried += r.projected_cg_expansions;
    }
    EXPECT_GT(taken, 0) << to_string(e);
    EXPECT_GT(kept, 0) << to_string(e);
    // automatic takes both kinds of expansion step in these cases.
    if (e == Expansion::automatic) {
      EXPECT_GT(tried, 0);
      EXPECT_LT(tried, taken);
    }
  }
}

// By hand: min 1/2 x'x - b'x, x_1 >= 0, b = (-10, 0), from (0.5, 0). g = (10.5, 0) = phi, the CG
// step along p = phi has length a_cg = 1 and leaves the bound after 0.5 / 10.5 of it: an
// expansion step. The whole CG step moves x by a_cg ||p|| = 10.5, the fixed-length step by
// alpha ||phi|| = 19.95 (alpha = 1.9, ||A|| = 1): less than twice as far, so automatic takes the
// fixed-length step (x = P(0 - 1.9 * 0) = 0 after the half step) and projected_cg tries the CG
// step. The solution is (0, 0) (g_1 = 10 >= 0).
TEST(Mprgp, AutomaticExpansionTakesTheProjectedCgStepOnlyWhereItIsLong) {
  const Vec b = (Vec(2) << -10.0, 0.0).finished();
  const Vec l = (Vec(2) << 0.0, -inf).finished();
  DenseOperator A(Eigen::MatrixXd::Identity(2, 2));
  SerialReducer red;
  for (Expansion e : {Expansion::automatic, Expansion::projected_cg}) {
    MprgpOptions opt;
    opt.alpha = 1.9;
    opt.expansion = e;
    Vec x = (Vec(2) << 0.5, 0.0).finished(), g(2);
    const auto r = mprgp(A, b, l, x, g, red, opt,
                         [&](const Vec&, const Vec&, double gp) { return gp <= 1e-12; });
    ASSERT_EQ(r.reason, StopReason::converged) << to_string(e);
    EXPECT_LT(x.norm(), 1e-12) << to_string(e);
    EXPECT_EQ(r.expansion_steps, 1) << to_string(e);
    EXPECT_EQ(r.projected_cg_expansions, e == Expansion::projected_cg ? 1 : 0) << to_string(e);
  }
}

class SmalbeConformance : public ::testing::TestWithParam<std::tuple<unsigned, bool>> {};

TEST_P(SmalbeConformance, MatchesEnumeratedActiveSets) {
  const auto [seed, singular] = GetParam();
  const int n = 10, bounded = 6, me = 2;
  const Qp q = random_qp(n, bounded, me, seed, singular);
  DenseOperator A(q.A);
  const Eigen::MatrixXd Qm = q.G.transpose() * q.G;
  SerialReducer red;
  SmalbeOptions opt;
  opt.rtol = 1e-11;
  const double normA = estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
  Vec x = Vec::Zero(n);
  const auto r = smalbe(qp_of(A, q), normA, x, red, opt);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_LT((x - exact_solution(q, bounded)).norm(), 1e-7);
  expect_kkt(q, x, 1e-8);
  // The combined penalized operator gives the same iterates (with SMALBE-M's arithmetic:
  // A v + rho (v - P v)).
  Vec x2 = Vec::Zero(n);
  const Eigen::MatrixXd Pq = Eigen::MatrixXd::Identity(n, n) - Qm;
  const PenalizedHessian combined = [&](const Vec& v, double rho, Vec& y, Vec& qv) {
    qv = v - Pq * v;
    y = q.A * v;
    y += rho * qv;
  };
  SmalbeHooks fused;
  fused.fused_hessian = combined;
  const auto r2 = smalbe(qp_of(A, q), normA, x2, red, opt, fused);
  ASSERT_EQ(r2.reason, StopReason::converged);
  EXPECT_EQ(r2.inner_iterations, r.inner_iterations);
  EXPECT_LT((x2 - x).norm(), 1e-10);
  // Preconditioned in face with Z_rho = P D^{-1} P + Q / rho (D = diag A, P = I - Q): the same
  // solution.
  const Eigen::MatrixXd Pm = Eigen::MatrixXd::Identity(n, n) - Qm;
  const Eigen::MatrixXd Dinv = q.A.diagonal().cwiseInverse().asDiagonal();
  const PenalizedApply Zrho = [&](const Vec& v, double rho, Vec& y) {
    y = Pm * (Dinv * (Pm * v)) + Qm * v / rho;
  };
  Vec x3 = Vec::Zero(n);
  SmalbeHooks preconditioned;
  preconditioned.preconditioner = Zrho;
  const auto r3 = smalbe(qp_of(A, q), normA, x3, red, opt, preconditioned);
  ASSERT_EQ(r3.reason, StopReason::converged);
  EXPECT_LT((x3 - exact_solution(q, bounded)).norm(), 1e-7);
  expect_kkt(q, x3, 1e-8);
}

INSTANTIATE_TEST_SUITE_P(Random, SmalbeConformance,
                         ::testing::Combine(::testing::Range(1u, 7u), ::testing::Bool()));

static Vec box_upper(Qp& q, int bounded, unsigned seed);
static Vec exact_box_solution(const Qp& q, const Vec& u, int bounded);

// The face of the bounds for a dense G (orthonormal rows): G D G' factored densely; singular
// when its smallest eigenvalue is below 1e-12 of its largest.
struct DenseFace {
  Eigen::MatrixXd G;
  Eigen::LLT<Eigen::MatrixXd> llt;
  int sets = 0;
  FaceHooks hooks() {
    FaceHooks h;
    h.set = [this](const Vec& free) {
      ++sets;
      const Eigen::MatrixXd M = G * free.asDiagonal() * G.transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(M);
      if (!(eig.eigenvalues().minCoeff() > 1e-12 * eig.eigenvalues().cwiseAbs().maxCoeff()))
        return false;
      llt.compute(M);
      return true;
    };
    h.correction = [this](const Vec& v, Vec& y) { y = G.transpose() * llt.solve(G * v); };
    return h;
  }
};

// face_cg from a point of the exact solution's face (the free entries perturbed): CG on that
// face with G x = 0 reaches the solution, and the face's multiplier nu gives g + nu >= 0 on the
// held rows (the solution's bound multipliers) and 0 on the free ones.
TEST(FaceCg, ReachesTheSolutionFromItsFace) {
  int faces = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const int n = 10, bounded = 6, me = 2;
    const Qp q = random_qp(n, bounded, me, seed, seed % 2 == 0);
    const Vec xs = exact_solution(q, bounded);
    DenseOperator A(q.A);
    SerialReducer red;
    DenseFace face{q.G, {}, 0};
    std::mt19937 gen(seed);
    std::uniform_real_distribution<double> U(0.0, 0.1);
    Vec x = xs;
    bool held = false;
    // The free entries move by a small part of their distance from the bound, so that the CG
    // path stays inside (CG's iterates need not approach the solution entry by entry).
    for (int i = 0; i < n; ++i)
      if (xs[i] > q.l[i] + 1e-9)
        x[i] += U(gen) * std::min(1.0, 0.01 * (xs[i] - q.l[i]));
      else
        held = true;
    Vec g = q.A * x - q.b, nu;
    FaceWorkspace work;
    const FaceResult r =
        face_cg(A, q.b, q.l, Vec(), x, g, nu, face.hooks(), nullptr, red, 1e-12, 1.0, 100, work);
    ASSERT_EQ(r.outcome, FaceOutcome::converged) << seed;
    EXPECT_LT((x - xs).norm(), 1e-9) << seed;
    EXPECT_LT((q.G * x).norm(), 1e-12) << seed;
    EXPECT_LT((g - (q.A * x - q.b)).norm(), 1e-9) << seed;
    const Vec gl = g + nu;
    for (int i = 0; i < n; ++i) {
      if (xs[i] > q.l[i] + 1e-9)
        EXPECT_NEAR(gl[i], 0.0, 1e-9) << seed << " " << i;
      else
        EXPECT_GT(gl[i], -1e-9) << seed << " " << i;
    }
    EXPECT_LT((nu - q.G.transpose() * (q.G * nu)).norm(), 1e-12);  // nu in Im G'
    faces += held;
  }
  EXPECT_GT(faces, 0);  // some solutions have held rows: the face is not the whole space
}

// On a wrong face face_cg ends without claiming a solution (declined, released or at a
// bound); where G D G' is singular it is not taken and x is unchanged.
TEST(FaceCg, LeavesAWrongFaceAndRefusesASingularOne) {
  int wrong = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const int n = 10, bounded = 6, me = 2;
    const Qp q = random_qp(n, bounded, me, seed, false);
    const Vec xs = exact_solution(q, bounded);
    // Held where the solution is free, free (slightly above the bound) where it is held.
    Vec x = q.l.cwiseMax(Vec::Constant(n, -1.0));
    bool differs = false;
    for (int i = 0; i < bounded; ++i) {
      const bool free_at_solution = xs[i] > q.l[i] + 1e-9;
      x[i] = free_at_solution ? q.l[i] : q.l[i] + 1e-3;
      differs = true;
    }
    for (int i = bounded; i < n; ++i) x[i] = xs[i];
    ASSERT_TRUE(differs);
    DenseOperator A(q.A);
    SerialReducer red;
    DenseFace face{q.G, {}, 0};
    Vec g = q.A * x - q.b, nu;
    FaceWorkspace work;
    const FaceResult r =
        face_cg(A, q.b, q.l, Vec(), x, g, nu, face.hooks(), nullptr, red, 1e-12, 1.0, 100, work);
    if (r.outcome == FaceOutcome::converged) {
      // Possible only where the wrong face still holds the solution's KKT point.
      EXPECT_LT((x - xs).norm(), 1e-8) << seed;
    } else {
      ++wrong;
    }
  }
  EXPECT_GT(wrong, 0);
  // G D G' singular: every row of G lives on the held entries.
  Qp q = random_qp(6, 6, 2, 3, false);
  q.G = Eigen::MatrixXd::Zero(2, 6);
  q.G(0, 0) = q.G(1, 1) = 1.0;
  DenseOperator A(q.A);
  SerialReducer red;
  DenseFace face{q.G, {}, 0};
  Vec x = q.l;
  x.tail(4).array() += 1.0;
  const Vec x0 = x;
  Vec g = q.A * x - q.b, nu;
  FaceWorkspace work;
  const FaceResult r =
      face_cg(A, q.b, q.l, Vec(), x, g, nu, face.hooks(), nullptr, red, 1e-12, 1.0, 100, work);
  EXPECT_EQ(r.outcome, FaceOutcome::singular);
  EXPECT_FALSE(r.taken());
  EXPECT_EQ(x, x0);
}

// With changes of the face allowed (step 3 of face_cg.hpp), face_cg started with every row
// free (x_i = l_i + 1) holds rows at the bounds it reaches (and frees held rows), and reaches
// the enumerated solution for most seeds (without changes it would stop at the first bound);
// whatever the outcome, x stays inside the bounds with G x = 0, g = A x - b, and the cost does
// not rise above that at the start (after step 1) by more than round-off. (A start on a wrong
// face is declined before any step: LeavesAWrongFaceAndRefusesASingularOne.)
TEST(FaceCg, ChangesItsFaceOnTheWayToTheSolution) {
  int solved = 0, changed = 0, held_at_solution = 0, went_on = 0;
  for (unsigned seed = 1; seed <= 24; ++seed) {
    const int n = 10, bounded = 6, me = 2;
    const Qp q = random_qp(n, bounded, me, seed, false);
    const Vec xs = exact_solution(q, bounded);
    Vec x = q.l.cwiseMax(Vec::Constant(n, -1.0));
    for (int i = 0; i < bounded; ++i) x[i] = q.l[i] + 1.0;
    for (int i = bounded; i < n; ++i) x[i] = xs[i];
    const Vec x0 = x;
    for (int i = 0; i < bounded; ++i) held_at_solution += !(xs[i] > q.l[i] + 1e-9);
    // Step 1's point (G x = 0 by the free entries), whose cost the solve must not exceed.
    Vec d(n);
    for (int i = 0; i < n; ++i) d[i] = x[i] > q.l[i] ? 1.0 : 0.0;
    const Eigen::MatrixXd GD = q.G * d.asDiagonal();
    const Vec x1 =
        x - d.cwiseProduct(q.G.transpose() * (GD * q.G.transpose()).ldlt().solve(q.G * x));
    const auto cost = [&](const Vec& v) { return 0.5 * v.dot(q.A * v) - q.b.dot(v); };
    DenseOperator A(q.A);
    SerialReducer red;
    DenseFace face{q.G, {}, 0};
    Vec g = q.A * x - q.b, nu;
    FaceWorkspace work;
    const FaceResult r = face_cg(A, q.b, q.l, Vec(), x, g, nu, face.hooks(), nullptr, red, 1e-12,
                                 1.0, 200, work, 50);
    if (!r.taken()) continue;
    EXPECT_GE(r.changes, 0);
    EXPECT_LE(r.changes, 50);
    EXPECT_EQ(face.sets, 1 + r.changes) << seed;  // one coarse factorization per change
    EXPECT_TRUE((x.array() >= q.l.array()).all()) << seed;
    EXPECT_LT((q.G * x).norm(), 1e-10) << seed;
    EXPECT_LT((g - (q.A * x - q.b)).norm(), 1e-9) << seed;
    EXPECT_LE(cost(x), cost(x1) + 1e-10 * (1 + std::abs(cost(x1)))) << seed;
    changed += r.changes > 0;
    if (r.outcome == FaceOutcome::converged) {
      ++solved;
      EXPECT_LT((x - xs).norm(), 1e-8) << seed;
      const Vec gl = g + nu;  // the bound multipliers on the held rows
      for (int i = 0; i < n; ++i)
        if (!(x[i] > q.l[i])) EXPECT_GT(gl[i], -1e-8) << seed << " " << i;
    }
    // Loose (1e-2), going on to 1e-12 where that is met (FaceGoOn), changing the face on the way
    // as it needs: it converges where the tight run does, to the same solution, or, where it
    // cannot go on, ends converged for 1e-2 at the point where it went on.
    Vec xg = x0, gg = q.A * x0 - q.b, nug;
    DenseFace face_g{q.G, {}, 0};
    int asked = 0;
    const FaceResult rg =
        face_cg(A, q.b, q.l, Vec(), xg, gg, nug, face_g.hooks(), nullptr, red, 1e-2, 1.0, 200, work,
                50, [&](const Vec&, double) { return ++asked == 1 ? 1e-12 : 0.0; });
    if (rg.outcome == FaceOutcome::converged && asked > 0) {
      EXPECT_LE(rg.free_gradient, rg.go_on_failed ? 1e-2 : 1e-12) << seed;
      if (!rg.go_on_failed) {
        ++went_on;
        EXPECT_LT((xg - xs).norm(), 1e-8) << seed;
      }
    }
    EXPECT_TRUE((xg.array() >= q.l.array()).all()) << seed;
    EXPECT_LT((q.G * xg).norm(), 1e-10) << seed;
  }
  EXPECT_GT(went_on, 6);
  EXPECT_GT(held_at_solution, 12);
  EXPECT_GT(changed, 12);
  EXPECT_GT(solved, 12);
}

// The face solve goes on (FaceGoOn): on the solution's face of a QP with a spread spectrum,
// asked at tol 1e-4 to go on to 1e-11, face_cg continues its CG: the result is that of a run
// asked for 1e-11 from the start, to the bit. Asked for an unattainable tol, it ends where it
// went on: the point of a run without going on, to the bit, converged, go_on_failed.
TEST(FaceCg, GoesOnToASmallerTolOnItsFace) {
  const int n = 60, bounded = 6, me = 2;
  Qp q = random_qp(n, bounded, me, 3, false);
  q.A = spread_spd(n, 1e3, 3);
  const Vec xs = exact_solution(q, bounded);
  DenseOperator A(q.A);
  SerialReducer red;
  Vec start = xs;
  int held = 0;
  for (int i = 0; i < n; ++i)
    if (xs[i] > q.l[i] + 1e-9)
      start[i] += 1e-3 * std::min(1.0, xs[i] - q.l[i]) * std::sin(3.0 * i);
    else
      ++held;
  const auto run = [&](double tol, const FaceGoOn& go_on, Vec& x) {
    DenseFace face{q.G, {}, 0};
    x = start;
    Vec g = q.A * x - q.b, nu;
    FaceWorkspace work;
    return face_cg(A, q.b, q.l, Vec(), x, g, nu, face.hooks(), nullptr, red, tol, 1.0, 1000, work,
                   0, go_on);
  };
  Vec direct, loose, on, vain;
  const FaceResult rd = run(1e-11, {}, direct);
  ASSERT_EQ(rd.outcome, FaceOutcome::converged);
  EXPECT_GT(rd.iterations, 20);
  const FaceResult rl = run(1e-4, {}, loose);
  ASSERT_EQ(rl.outcome, FaceOutcome::converged);
  EXPECT_LT(rl.iterations, rd.iterations);
  int calls = 0;
  const FaceResult ro = run(
      1e-4,
      [&](const Vec& x, double gp) {
        if (++calls > 1) return 0.0;  // asked again where 1e-11 is met: stop there
        EXPECT_EQ(x, loose);          // asked first where the loose run ended
        EXPECT_GE(gp, rl.free_gradient);
        return 1e-11;
      },
      on);
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(ro.outcome, FaceOutcome::converged);
  EXPECT_EQ(ro.go_ons, 1);
  EXPECT_FALSE(ro.go_on_failed);
  EXPECT_EQ(on, direct);
  EXPECT_EQ(ro.iterations, rd.iterations);
  EXPECT_LT((on - xs).norm(), 1e-8);
  const FaceResult rv = run(
      1e-4, [](const Vec&, double) { return 1e-300; }, vain);
  EXPECT_EQ(rv.outcome, FaceOutcome::converged);
  EXPECT_TRUE(rv.go_on_failed);
  EXPECT_EQ(vain, loose);
  EXPECT_EQ(rv.free_gradient, rl.free_gradient);
  EXPECT_GT(rv.iterations, rl.iterations);
  EXPECT_GT(held, 0);
}

// SMALBE-M with the face solve reaches the enumerated solutions (bounds and boxes, with and
// without a preconditioner), and across the suite some runs end by a face solve.
TEST(Smalbe, FaceSolveReachesTheEnumeratedSolutions) {
  int finished = 0, taken = 0;
  for (unsigned seed = 1; seed <= 12; ++seed)
    for (int box = 0; box < 2; ++box) {
      const int n = 10, bounded = 6, me = 2;
      Qp q = random_qp(n, bounded, me, seed, seed % 2 == 0);
      Vec u;
      if (box) {
        q.b *= 2.0;
        u = box_upper(q, bounded, seed);
      }
      const Vec xs = box ? exact_box_solution(q, u, bounded) : exact_solution(q, bounded);
      DenseOperator A(q.A);
      SerialReducer red;
      const double normA = estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
      QuadraticProgram qp = qp_of(A, q, !box);
      if (box) qp.constraints = std::make_shared<BoxBounds>(q.l, u);
      const Eigen::MatrixXd Qm = q.G.transpose() * q.G;
      const Eigen::MatrixXd Pm = Eigen::MatrixXd::Identity(n, n) - Qm;
      const Eigen::MatrixXd Dinv = q.A.diagonal().cwiseInverse().asDiagonal();
      for (int pre = 0; pre < 2; ++pre) {
        DenseFace face{q.G, {}, 0};
        SmalbeHooks hooks;
        hooks.face = face.hooks();
        if (pre)
          hooks.preconditioner = [&](const Vec& v, double rho, Vec& y) {
            y = Pm * (Dinv * (Pm * v)) + Qm * v / rho;
          };
        SmalbeOptions opt;
        opt.rtol = 1e-11;
        Vec x = Vec::Zero(n);
        const auto r = smalbe(qp, normA, x, red, opt, hooks);
        ASSERT_EQ(r.reason, StopReason::converged) << seed << box << pre;
        EXPECT_LT((x - xs).norm(), 1e-7) << seed << box << pre;
        EXPECT_LT((q.G * x).norm(), 1e-8) << seed << box << pre;
        if (!box) expect_kkt(q, x, 1e-8);
        EXPECT_LE(r.face_converged, 1);
        EXPECT_LE(r.face_solves, kMaxFaceSolves);
        finished += r.face_converged;
        taken += r.face_solves;
        // Off: no face solve, the same solution.
        opt.face_solve = false;
        Vec x2 = Vec::Zero(n);
        const auto r2 = smalbe(qp, normA, x2, red, opt, hooks);
        ASSERT_EQ(r2.reason, StopReason::converged);
        EXPECT_EQ(r2.face_solves, 0);
        EXPECT_LT((x2 - xs).norm(), 1e-7);
      }
    }
  EXPECT_GT(finished, 0);
  EXPECT_GE(taken, finished);
}

// One problem of the face-solve suites below: a random QP with lower bounds on 6 of 10 entries
// and 2 equalities, its enumerated solution, and SMALBE-M's hooks with a dense face (built in
// place: the hooks point into it).
struct FaceCase {
  static constexpr int n = 10, bounded = 6, me = 2;
  Qp q;
  Vec xs;
  DenseOperator A;
  SerialReducer red;
  double normA;
  QuadraticProgram qp;
  DenseFace face;
  SmalbeHooks hooks;
  SmalbeOptions opt;
  explicit FaceCase(unsigned seed)
      : q(random_qp(n, bounded, me, seed, seed % 2 == 0)),
        xs(exact_solution(q, bounded)),
        A(q.A),
        normA(estimate_norm(A, Vec::Ones(n), red, 200, 1e-10)),
        qp(qp_of(A, q, true)),
        face{q.G, {}, 0} {
    hooks.face = face.hooks();
    opt.rtol = 1e-10;
  }
  FaceCase(const FaceCase&) = delete;
  FaceCase& operator=(const FaceCase&) = delete;
};

// A face is tried on the active set of every inner exit, not only once two exits in a row
// agree: a cold start whose first inner solve already ends on the solution's face can finish
// there by the face solve, after one outer iteration (with the rule of two equal exits, a face
// could end a solve at the second outer iteration at the earliest). Every run reaches the
// enumerated solution.
TEST(Smalbe, FaceIsTriedAtTheFirstInnerExit) {
  int first = 0;
  for (unsigned seed = 1; seed <= 12; ++seed) {
    FaceCase c(seed);
    Vec x = Vec::Zero(FaceCase::n);
    const auto r = smalbe(c.qp, c.normA, x, c.red, c.opt, c.hooks);
    ASSERT_EQ(r.reason, StopReason::converged) << seed;
    EXPECT_LT((x - c.xs).norm(), 1e-7) << seed;
    expect_kkt(c.q, x, 1e-7);
    EXPECT_GE(r.face_tries, r.outer_iterations > 1 ? 1 : 0) << seed;
    if (r.outer_iterations == 1 && r.face_converged == 1) ++first;
  }
  EXPECT_GT(first, 0);
}

// A warm start (a multiplier given) tries the face solve first: started at the solution, with
// any multiplier, the face solve finds the face's own multiplier and ends the solve before any
// inner solve; started at zero, the same solution as a cold start. A face solve that stops on a
// bound is kept (the outer loop restarts there): across the suite some are, and every run still
// reaches the enumerated solution.
TEST(Smalbe, WarmStartTriesTheFaceFirst) {
  int at_start = 0, kept = 0;
  for (unsigned seed = 1; seed <= 24; ++seed) {
    FaceCase c(seed);
    // Half the seeds without changes of the face, where a face solve stops at its first bound
    // or release more often, and SMALBE-M restarts from the face's point (kept).
    if (seed > 12) c.opt.face_changes = 0;
    for (int start = 0; start < 2; ++start) {
      Vec x = start ? c.xs : Vec::Zero(FaceCase::n);
      Vec mu = Vec::Zero(FaceCase::n);
      const auto r = smalbe(c.qp, c.normA, x, c.red, c.opt, c.hooks, {}, &mu);
      ASSERT_EQ(r.reason, StopReason::converged) << seed << start;
      EXPECT_LT((x - c.xs).norm(), 1e-7) << seed << start;
      expect_kkt(c.q, x, 1e-7);
      if (start && r.outer_iterations == 0) {
        ++at_start;
        EXPECT_EQ(r.face_converged, 1);
        EXPECT_EQ(r.inner_iterations, 0);
      }
      kept += r.face_solves - r.face_converged;
    }
  }
  EXPECT_GT(at_start, 12);  // strict complementarity holds for most seeds
  EXPECT_GT(kept, 0);
}

// SmalbeHooks::tighten: asked where a face solve's point passes the test at rtol 1e-4, it asks
// for 1e-11; where the face solve ends the solve, the solve meets 1e-11 (SmalbeResult::rtol and
// its tolerance: the face solve went on, or its point met 1e-11 already) and reaches the
// enumerated solution, as a solve asked for 1e-11 does. The callback is asked with a feasible x,
// at most twice per face solve (where 1e-4 is met and where 1e-11 is).
TEST(Smalbe, FaceSolveGoesOnToTheRtolAsked) {
  int tightened = 0;
  for (unsigned seed = 1; seed <= 12; ++seed) {
    FaceCase c(seed);
    c.opt.rtol = 1e-4;
    int calls = 0;
    c.hooks.tighten = [&](const Vec& x, double rtol) {
      ++calls;
      EXPECT_TRUE((x.array() >= c.q.l.array()).all()) << seed;
      return rtol > 1e-11 ? 1e-11 : rtol;
    };
    Vec x = Vec::Zero(FaceCase::n);
    const auto r = smalbe(c.qp, c.normA, x, c.red, c.opt, c.hooks);
    ASSERT_EQ(r.reason, StopReason::converged) << seed;
    EXPECT_LE(calls, 2 * r.face_solves) << seed;
    EXPECT_LE(r.go_ons, 1) << seed;
    EXPECT_EQ(r.go_ons_failed, 0) << seed;
    EXPECT_LE(r.projected_gradient, r.tolerance) << seed;
    if (r.face_converged == 1 && calls > 0) {
      ++tightened;
      EXPECT_EQ(r.rtol, 1e-11) << seed;
      EXPECT_LE(r.tolerance, std::max(1e-11 * c.red.norm(c.q.b), 1e-12)) << seed;
      EXPECT_LT((x - c.xs).norm(), 1e-8) << seed;
      expect_kkt(c.q, x, 1e-8);
    } else {
      EXPECT_EQ(r.rtol, 1e-4) << seed;
    }
  }
  EXPECT_GT(tightened, 6);
}

// A continuation (the accuracy refinement): a loose solve, then SMALBE-M again from its x, its
// equality multiplier, its rho and its M with a tight rtol, reaches the solution; M never grows
// and rho never falls from where the continuation started (so the start values were taken).
TEST(Smalbe, ContinuesFromTheLastSolvesPenaltyAndM) {
  for (unsigned seed = 1; seed <= 6; ++seed) {
    const int n = 10, bounded = 6, me = 2;
    const Qp q = random_qp(n, bounded, me, seed, seed % 2 == 0);
    DenseOperator A(q.A);
    SerialReducer red;
    const double normA = estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
    SmalbeOptions opt;
    opt.rtol = 1e-3;
    Vec x = Vec::Zero(n), nu;
    const auto loose = smalbe(qp_of(A, q), normA, x, red, opt, {}, {}, &nu);
    ASSERT_EQ(loose.reason, StopReason::converged) << seed;
    opt.rtol = 1e-11;
    opt.rho_start = loose.rho;
    opt.M_start = loose.M;
    const auto tight = smalbe(qp_of(A, q), normA, x, red, opt, {}, {}, &nu);
    ASSERT_EQ(tight.reason, StopReason::converged) << seed;
    EXPECT_LT((x - exact_solution(q, bounded)).norm(), 1e-7) << seed;
    expect_kkt(q, x, 1e-8);
    EXPECT_LE(tight.M, loose.M) << seed;
    EXPECT_GE(tight.rho, loose.rho) << seed;
  }
  const Qp q = random_qp(10, 6, 2, 1, false);
  DenseOperator A(q.A);
  SerialReducer red;
  Vec x = Vec::Zero(10);
  SmalbeOptions bad;
  bad.M_start = -1;
  EXPECT_THROW(smalbe(qp_of(A, q), 1.0, x, red, bad), std::invalid_argument);
  bad.M_start = 0;
  bad.rho_start = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(smalbe(qp_of(A, q), 1.0, x, red, bad), std::invalid_argument);
}

// Box constraints l <= x <= u (BoxBounds): the random QP above with upper bounds on its first
// `bounded` components: a lower bound only (i % 3 == 1), an upper bound only (i % 3 == 0), or
// both (i % 3 == 2), around 0 so that both sides are active at some solutions.
static Vec box_upper(Qp& q, int bounded, unsigned seed) {
  std::mt19937 gen(seed + 1000);
  std::normal_distribution<double> N01;
  const Eigen::Index n = q.b.size();
  Vec u = Vec::Constant(n, inf);
  for (int i = 0; i < bounded; ++i) {
    q.l[i] = i % 3 == 0 ? -inf : -0.1 - 0.3 * std::abs(N01(gen));
    if (i % 3 != 1) u[i] = 0.1 + 0.3 * std::abs(N01(gen));
  }
  return u;
}

// Exact solution with box constraints by enumerating, for each bounded component, free / at
// its lower bound / at its upper bound (3^bounded cases), KKT solved on the free set.
static Vec exact_box_solution(const Qp& q, const Vec& u, int bounded) {
  const int n = static_cast<int>(q.b.size()), me = static_cast<int>(q.G.rows());
  int cases = 1;
  for (int i = 0; i < bounded; ++i) cases *= 3;
  for (int c = 0; c < cases; ++c) {
    std::vector<int> state(n, 0), fr;  // 0 free, 1 at l, 2 at u
    bool possible = true;
    for (int i = 0, r = c; i < bounded; ++i, r /= 3) {
      state[i] = r % 3;
      if ((state[i] == 1 && q.l[i] == -inf) || (state[i] == 2 && u[i] == inf)) possible = false;
    }
    if (!possible) continue;
    Vec x = Vec::Zero(n);
    for (int i = 0; i < n; ++i) {
      if (state[i] == 0) fr.push_back(i);
      if (state[i] == 1) x[i] = q.l[i];
      if (state[i] == 2) x[i] = u[i];
    }
    const int nf = static_cast<int>(fr.size());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nf + me, nf + me);
    Vec rhs(nf + me);
    const Vec Ax = q.A * x, Gx = me ? Vec(q.G * x) : Vec();
    for (int a = 0; a < nf; ++a) {
      for (int b = 0; b < nf; ++b) K(a, b) = q.A(fr[a], fr[b]);
      for (int e = 0; e < me; ++e) K(a, nf + e) = K(nf + e, a) = q.G(e, fr[a]);
      rhs[a] = q.b[fr[a]] - Ax[fr[a]];
    }
    for (int e = 0; e < me; ++e) rhs[nf + e] = -Gx[e];
    Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    if (!lu.isInvertible()) continue;
    const Vec sol = lu.solve(rhs);
    for (int a = 0; a < nf; ++a) x[fr[a]] = sol[a];
    Vec g = q.A * x - q.b;
    if (me) g += q.G.transpose() * sol.tail(me);
    bool ok = true;
    for (int i = 0; i < n; ++i) {
      if (x[i] < q.l[i] - 1e-12 || x[i] > u[i] + 1e-12) ok = false;
      if (state[i] == 1 && g[i] < -1e-12) ok = false;  // pushed against l: multiplier >= 0
      if (state[i] == 2 && g[i] > 1e-12) ok = false;   // pushed against u
    }
    if (ok) return x;
  }
  ADD_FAILURE() << "no active set satisfies KKT";
  return Vec::Zero(n);
}

TEST(MprgpBox, HandCheckableTwoByTwo) {
  // A = I: the solution is b clamped to the box.
  DenseOperator A(Eigen::MatrixXd::Identity(2, 2));
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.0;
  const Vec l = Vec::Constant(2, -1.0), u = Vec::Constant(2, 1.0);
  const auto stop = [](const Vec&, const Vec&, double gp) { return gp <= 1e-14; };
  for (const auto& [b, expected] : {std::pair<Vec, Vec>{Vec{{3.0, -3.0}}, Vec{{1.0, -1.0}}},
                                    std::pair<Vec, Vec>{Vec{{0.5, -0.25}}, Vec{{0.5, -0.25}}},
                                    std::pair<Vec, Vec>{Vec{{-7.0, 0.0}}, Vec{{-1.0, 0.0}}}}) {
    Vec x = Vec::Zero(2), g(2);
    const auto r = mprgp(A, b, l, u, x, g, red, opt, stop);
    ASSERT_EQ(r.reason, StopReason::converged);
    EXPECT_EQ(x, expected);
    Vec gp;
    projected_gradient(x, g, l, gp, u);
    EXPECT_EQ(gp.norm(), 0.0);
  }
  // A fixed component (l = u) stays at its value and has no projected gradient.
  const Vec lf{{-1.0, 0.25}}, uf{{1.0, 0.25}};
  Vec x = Vec::Zero(2), g(2);
  const auto r = mprgp(A, Vec{{0.5, 9.0}}, lf, uf, x, g, red, opt, stop);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_EQ(x, (Vec{{0.5, 0.25}}));
  // Upper bounds of the wrong size are refused.
  EXPECT_THROW(mprgp(A, Vec::Zero(2), l, Vec::Zero(3), x, g, red, opt, stop),
               std::invalid_argument);
}

class MprgpBoxConformance : public ::testing::TestWithParam<unsigned> {};

TEST_P(MprgpBoxConformance, MatchesEnumeratedActiveSets) {
  const int n = 10, bounded = 7;
  Qp q = random_qp(n, bounded, 0, GetParam(), false);
  q.b *= 2.0;  // push more components onto their bounds
  const Vec u = box_upper(q, bounded, GetParam());
  DenseOperator A(q.A);
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.9 / estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
  const double tol = 1e-11 * q.b.norm();
  const auto stop = [&](const Vec&, const Vec&, double gp) { return gp <= tol; };
  const Vec exact = exact_box_solution(q, u, bounded);
  int at_upper = 0;
  for (int i = 0; i < n; ++i) at_upper += exact[i] == u[i];
  Vec x = Vec::Zero(n), g(n);
  const auto r = mprgp(A, q.b, q.l, u, x, g, red, opt, stop);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_LT((x - exact).norm(), 1e-8) << at_upper << " components at an upper bound";
  for (int i = 0; i < n; ++i) EXPECT_TRUE(x[i] >= q.l[i] && x[i] <= u[i]);
  // Preconditioned in face (Jacobi): the same solution.
  DenseOperator Z(Eigen::MatrixXd(q.A.diagonal().cwiseInverse().asDiagonal()));
  opt.preconditioner = &Z;
  Vec xp = Vec::Zero(n), gp(n);
  ASSERT_EQ(mprgp(A, q.b, q.l, u, xp, gp, red, opt, stop).reason, StopReason::converged);
  EXPECT_LT((xp - exact).norm(), 1e-8);
  // With the preconditioned, the projected CG and the automatic expansion steps: the same
  // solution.
  for (Expansion e : {Expansion::preconditioned, Expansion::projected_cg, Expansion::automatic}) {
    opt.expansion = e;
    Vec xe = Vec::Zero(n), ge(n);
    ASSERT_EQ(mprgp(A, q.b, q.l, u, xe, ge, red, opt, stop).reason, StopReason::converged);
    EXPECT_LT((xe - exact).norm(), 1e-8) << to_string(e);
    for (int i = 0; i < n; ++i) EXPECT_TRUE(xe[i] >= q.l[i] && xe[i] <= u[i]);
  }
}

INSTANTIATE_TEST_SUITE_P(Random, MprgpBoxConformance, ::testing::Range(1u, 13u));

TEST(MprgpBox, UpperBoundsEnteredAtSomeSolution) {
  // The random cases above are not all decided by lower bounds: some solution of the suite has
  // a component on its upper bound (else the upper-bound code would be untested).
  int at_upper = 0;
  for (unsigned seed = 1; seed < 13; ++seed) {
    Qp q = random_qp(10, 7, 0, seed, false);
    q.b *= 2.0;
    const Vec u = box_upper(q, 7, seed);
    const Vec x = exact_box_solution(q, u, 7);
    for (int i = 0; i < 10; ++i) at_upper += x[i] == u[i];
  }
  EXPECT_GT(at_upper, 3);
}

TEST(MprgpBox, InfiniteUpperBoundsGiveTheLowerBoundIterates) {
  // u = +infinity everywhere: bit for bit the iterates of the lower-bound form.
  const Qp q = random_qp(10, 7, 0, 5, false);
  DenseOperator A(q.A);
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.9 / estimate_norm(A, Vec::Ones(10), red, 200, 1e-10);
  const auto stop = [&](const Vec&, const Vec&, double gp) { return gp <= 1e-12; };
  Vec x1 = Vec::Zero(10), g1(10), x2 = Vec::Zero(10), g2(10);
  const auto r1 = mprgp(A, q.b, q.l, x1, g1, red, opt, stop);
  const auto r2 = mprgp(A, q.b, q.l, Vec::Constant(10, inf), x2, g2, red, opt, stop);
  EXPECT_EQ(r1.iterations, r2.iterations);
  EXPECT_EQ(x1, x2);
  EXPECT_EQ(g1, g2);
}

class SmalbeBoxConformance : public ::testing::TestWithParam<std::tuple<unsigned, bool>> {};

TEST_P(SmalbeBoxConformance, MatchesEnumeratedActiveSets) {
  const auto [seed, singular] = GetParam();
  const int n = 10, bounded = 6, me = 2;
  Qp q = random_qp(n, bounded, me, seed, singular);
  q.b *= 2.0;
  const Vec u = box_upper(q, bounded, seed);
  DenseOperator A(q.A);
  SerialReducer red;
  SmalbeOptions opt;
  opt.rtol = 1e-11;
  const double normA = estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
  QuadraticProgram qp = qp_of(A, q, false);
  qp.constraints = std::make_shared<BoxBounds>(q.l, u);
  Vec x = Vec::Zero(n);
  const auto r = smalbe(qp, normA, x, red, opt);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_LT((x - exact_box_solution(q, u, bounded)).norm(), 1e-7);
  EXPECT_LT((q.G * x).norm(), 1e-8);
  // Homogenized at x0 (the box moves with it, BoxBounds::shifted): SMALBE-M then solves for y
  // in min 1/2 y'Ay - (b - A x0)'y, l - x0 <= y <= u - x0, G y = 0, checked against the
  // enumeration of that problem.
  const Vec x0 = Vec::Constant(n, 0.05);
  const QuadraticProgram h = homogenize(qp, x0);
  Vec y = Vec::Zero(n);
  ASSERT_EQ(smalbe(h, normA, y, red, opt).reason, StopReason::converged);
  Qp qs = q;
  qs.b = q.b - q.A * x0;
  qs.l = q.l - x0;
  EXPECT_LT((y - exact_box_solution(qs, u - x0, bounded)).norm(), 1e-7);
}

INSTANTIATE_TEST_SUITE_P(Random, SmalbeBoxConformance,
                         ::testing::Combine(::testing::Range(1u, 7u), ::testing::Bool()));

// MPGP on bounds alone (a SeparableSet without discs): the boxes of the MPRGP suite, the same
// enumerated solutions, with and without preconditioning in face.
class MpgpBoxConformance : public ::testing::TestWithParam<unsigned> {};

TEST_P(MpgpBoxConformance, MatchesEnumeratedActiveSets) {
  const int n = 10, bounded = 7;
  Qp q = random_qp(n, bounded, 0, GetParam(), false);
  q.b *= 2.0;
  const Vec u = box_upper(q, bounded, GetParam());
  DenseOperator A(q.A);
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.9 / estimate_norm(A, Vec::Ones(n), red, 200, 1e-10);
  const double tol = 1e-11 * q.b.norm();
  const auto stop = [&](const Vec&, const Vec&, double gp) { return gp <= tol; };
  const Vec exact = exact_box_solution(q, u, bounded);
  const SeparableSet set(q.l, u, {}, Vec(), Vec());
  for (bool jacobi : {false, true}) {
    DenseOperator Z(Eigen::MatrixXd(q.A.diagonal().cwiseInverse().asDiagonal()));
    opt.preconditioner = jacobi ? &Z : nullptr;
    Vec x = Vec::Zero(n), g(n);
    ASSERT_EQ(mpgp(A, q.b, set, x, g, red, opt, stop).reason, StopReason::converged);
    EXPECT_LT((x - exact).norm(), 1e-8) << (jacobi ? "preconditioned" : "");
  }
}

INSTANTIATE_TEST_SUITE_P(Random, MpgpBoxConformance, ::testing::Range(1u, 13u));

namespace {

// A random QP with discs on the entries (0, 1), (2, 3), (4, 5), lower bounds on 6, 7 and 8, 9
// free; b large enough that some discs are active at the solution.
struct DiscQp {
  Qp q;
  std::shared_ptr<SeparableSet> set;
};
DiscQp disc_qp(unsigned seed) {
  DiscQp d;
  d.q = random_qp(10, 0, 0, seed, false);
  d.q.b *= 2.0;
  std::mt19937 gen(seed + 100);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Vec l = Vec::Constant(10, -inf), u = Vec::Constant(10, inf);
  for (int i = 6; i < 8; ++i) l[i] = 0.3 * (U(gen) - 0.5);
  Vec c(6), r(3);
  for (int k = 0; k < 6; ++k) c[k] = 0.2 * (U(gen) - 0.5);
  for (int k = 0; k < 3; ++k)  // disc 1 wide (often inactive), disc 2 a point in a third
    r[k] = k == 2 && seed % 3 == 0 ? 0.0 : k == 1 ? 0.5 + 3.0 * U(gen) : 0.1 + 0.4 * U(gen);
  d.set = std::make_shared<SeparableSet>(
      l, u, std::vector<SeparableSet::Pair>{{0, 1}, {2, 3}, {4, 5}}, c, r);
  return d;
}

// The reference: plain projected gradient with step 1/||A||, an independent and slow method,
// run until its iterate stops moving (linear convergence, rate 1 - 1/cond(A)).
Vec projected_gradient_reference(const Eigen::MatrixXd& A, const Vec& b, const SeparableSet& set) {
  const double L = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues().maxCoeff();
  Vec x = Vec::Zero(b.size());
  set.project(x);
  for (int it = 0; it < 200000; ++it) {
    Vec y = x - (A * x - b) / L;
    set.project(y);
    const double step = (y - x).norm();
    x = y;
    if (step < 1e-16 * (1 + x.norm())) break;
  }
  return x;
}

}  // namespace

class MpgpDiscConformance : public ::testing::TestWithParam<unsigned> {};

TEST_P(MpgpDiscConformance, MatchesProjectedGradientAndKkt) {
  const DiscQp d = disc_qp(GetParam());
  DenseOperator A(d.q.A);
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.9 / estimate_norm(A, Vec::Ones(10), red, 200, 1e-10);
  const double tol = 1e-12 * d.q.b.norm();
  const auto stop = [&](const Vec&, const Vec&, double gp) { return gp <= tol; };
  const Vec ref = projected_gradient_reference(d.q.A, d.q.b, *d.set);
  for (bool jacobi : {false, true}) {
    DenseOperator Z(Eigen::MatrixXd(d.q.A.diagonal().cwiseInverse().asDiagonal()));
    opt.preconditioner = jacobi ? &Z : nullptr;
    Vec x = Vec::Zero(10), g(10);
    const auto r = mpgp(A, d.q.b, *d.set, x, g, red, opt, stop);
    ASSERT_EQ(r.reason, StopReason::converged);
    EXPECT_LT((x - ref).norm(), 1e-9) << (jacobi ? "preconditioned" : "");
    // KKT: feasible; on a disc's circle g = -mu (x - c) / r with mu >= 0, inside g = 0.
    Vec y = x;
    d.set->project(y);
    EXPECT_LT((y - x).norm(), 1e-14);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d off(x[2 * k] - d.set->centers()[2 * k],
                                x[2 * k + 1] - d.set->centers()[2 * k + 1]);
      const Eigen::Vector2d gk(g[2 * k], g[2 * k + 1]);
      const double rk = d.set->radii()[k];
      if (rk > 0 && off.norm() < rk * (1 - 1e-9)) {
        EXPECT_LT(gk.norm(), 1e-9);
      } else if (rk > 0) {
        EXPECT_LE(gk.dot(off), 1e-9);                                    // mu >= 0
        EXPECT_LT(std::abs(gk.x() * off.y() - gk.y() * off.x()), 1e-9);  // parallel
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Random, MpgpDiscConformance, ::testing::Range(1u, 13u));

TEST(MpgpDiscs, SomeDiscsAreActiveAndSomeFreeInTheSuite) {
  int active = 0, free = 0;
  for (unsigned seed = 1; seed < 13; ++seed) {
    const DiscQp d = disc_qp(seed);
    const Vec x = projected_gradient_reference(d.q.A, d.q.b, *d.set);
    for (int k = 0; k < 2; ++k) {
      const double len = std::hypot(x[2 * k] - d.set->centers()[2 * k],
                                    x[2 * k + 1] - d.set->centers()[2 * k + 1]);
      (len > d.set->radii()[k] * (1 - 1e-9) ? active : free) += 1;
    }
  }
  EXPECT_GT(active, 3);
  EXPECT_GT(free, 3);
}

TEST(MpgpDiscs, HandCheckableProjections) {
  // A = I: the solution is the projection of b onto the set. b = (3, 4) outside the disc of
  // radius 1 about 0: x = (0.6, 0.8); b = (0.3, 0.1) inside: x = b; a disc of radius 0: its
  // center.
  DenseOperator A(Eigen::MatrixXd::Identity(4, 4));
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.0;
  const auto stop = [&](const Vec&, const Vec&, double gp) { return gp <= 1e-14; };
  const SeparableSet set(Vec::Constant(4, -inf), Vec::Constant(4, inf), {{0, 1}, {2, 3}},
                         Vec{{0.0, 0.0, 1.0, 2.0}}, Vec{{1.0, 0.0}});
  for (const Vec& b : {Vec{{3.0, 4.0, 5.0, 5.0}}, Vec{{0.3, 0.1, -1.0, 0.0}}}) {
    Vec x = Vec::Zero(4), g(4);
    ASSERT_EQ(mpgp(A, b, set, x, g, red, opt, stop).reason, StopReason::converged);
    if (b[0] == 3.0) {
      EXPECT_NEAR(x[0], 0.6, 1e-14);
      EXPECT_NEAR(x[1], 0.8, 1e-14);
    } else {
      EXPECT_NEAR(x[0], 0.3, 1e-14);
      EXPECT_NEAR(x[1], 0.1, 1e-14);
    }
    EXPECT_EQ(x[2], 1.0);
    EXPECT_EQ(x[3], 2.0);
  }
}

// SMALBE-M hands a SeparableSet to MPGP: with the equality x_9 = 0 (G = e_9) the problem is the
// separable one on the other entries, solved by the reference.
TEST(MpgpDiscs, SmalbeTakesTheSeparableSet) {
  for (unsigned seed : {1u, 4u, 7u}) {
    const DiscQp d = disc_qp(seed);
    Qp q = d.q;
    q.G = Eigen::MatrixXd::Zero(1, 10);
    q.G(0, 9) = 1.0;
    DenseOperator A(q.A);
    SerialReducer red;
    SmalbeOptions opt;
    opt.rtol = 1e-12;
    QuadraticProgram qp = qp_of(A, q, false);
    qp.constraints = d.set;
    Vec x = Vec::Zero(10);
    ASSERT_EQ(smalbe(qp, estimate_norm(A, Vec::Ones(10), red, 200, 1e-10), x, red, opt).reason,
              StopReason::converged);
    // The reference on the first 9 entries (x_9 = 0 removes row and column 9).
    const Eigen::MatrixXd A9 = q.A.topLeftCorner(9, 9);
    const SeparableSet set9(d.set->lower().head(9), d.set->upper().head(9), d.set->discs(),
                            d.set->centers(), d.set->radii());
    const Vec ref = projected_gradient_reference(A9, q.b.head(9), set9);
    EXPECT_LT((x.head(9) - ref).norm(), 1e-8) << seed;
    EXPECT_LT(std::abs(x[9]), 1e-9);
  }
}

TEST(QpTransforms, SeparableSetRefusesBadDiscsAndShiftsItsCenters) {
  const Vec none = Vec::Constant(4, -inf), up = Vec::Constant(4, inf);
  EXPECT_THROW(SeparableSet(none, up, {{0, 1}}, Vec::Zero(2), Vec{{-1.0}}), std::invalid_argument);
  EXPECT_THROW(SeparableSet(none, up, {{0, 1}, {1, 2}}, Vec::Zero(4), Vec::Ones(2)),
               std::invalid_argument);
  Vec l = none;
  l[0] = 0.0;
  EXPECT_THROW(SeparableSet(l, up, {{0, 1}}, Vec::Zero(2), Vec::Ones(1)), std::invalid_argument);
  EXPECT_THROW(SeparableSet(none, up, {{0, 4}}, Vec::Zero(2), Vec::Ones(1)), std::invalid_argument);
  const SeparableSet s(none, up, {{2, 3}}, Vec{{1.0, 2.0}}, Vec{{0.5}});
  const auto t = s.shifted(Vec{{0.0, 0.0, 0.25, -1.0}});
  const auto& ts = dynamic_cast<const SeparableSet&>(*t);
  EXPECT_EQ(ts.centers()[0], 0.75);
  EXPECT_EQ(ts.centers()[1], 3.0);
}

TEST(QpTransforms, BoxBoundsRefuseEmptyIntervalsAndNan) {
  EXPECT_THROW(BoxBounds(Vec::Zero(2), Vec::Zero(3)), std::invalid_argument);
  EXPECT_THROW(BoxBounds(Vec{{0.0, 1.0}}, Vec{{1.0, 0.5}}), std::invalid_argument);
  EXPECT_THROW(BoxBounds(Vec{{0.0, std::nan("")}}, Vec{{1.0, 2.0}}), std::invalid_argument);
  const BoxBounds box(Vec{{-1.0, -inf}}, Vec{{1.0, 2.0}});
  Vec x{{5.0, -5.0}};
  box.project(x);
  EXPECT_EQ(x, (Vec{{1.0, -5.0}}));
  const auto moved = box.shifted(Vec{{1.0, 1.0}});
  Vec y{{5.0, 5.0}};
  moved->project(y);
  EXPECT_EQ(y, (Vec{{0.0, 1.0}}));
}

TEST(Pcg, EqualityConstrainedMatchesKkt) {
  const int n = 12, me = 3;
  const Qp q = random_qp(n, 0, me, 42, true);
  DenseOperator A(q.A);
  const Eigen::MatrixXd Pm = Eigen::MatrixXd::Identity(n, n) - q.G.transpose() * q.G;
  DenseOperator P(Pm);
  SerialReducer red;
  // G x = e with e = G x0 for a feasible start x0 = G' e.
  const Vec e = Vec::LinSpaced(me, 0.5, 1.5);
  Vec x = q.G.transpose() * e;
  PcgOptions opt;
  opt.rtol = 1e-12;
  QuadraticProgram pq;
  pq.hessian = borrow(A);
  pq.linear = q.b;
  pq.equality_projector = borrow(P);
  const auto r = projected_cg(pq, x, red, opt);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_LT((q.G * x - e).norm(), 1e-12);
  EXPECT_LT((Pm * (q.A * x - q.b)).norm(), 1e-10);
  EXPECT_EQ(A.count(), r.iterations + 1);  // one product per iteration plus the initial residual
  // Preconditioned (Z = P D^{-1}, D = diag A, applied to projected residuals): the same solution.
  const Eigen::MatrixXd Zm = Pm * q.A.diagonal().cwiseInverse().asDiagonal() * Pm;
  DenseOperator Z(Zm);
  Vec xz = q.G.transpose() * e;
  const auto rz = projected_cg(pq, xz, red, opt, {}, &Z);
  ASSERT_EQ(rz.reason, StopReason::converged);
  EXPECT_LT((q.G * xz - e).norm(), 1e-12);
  EXPECT_LT((xz - x).norm(), 1e-9 * x.norm());
  EXPECT_EQ(Z.count(), rz.iterations + 1);
}

// PcgOptions::tighten: asked once where PCG meets rtol 1e-3, it has PCG go on to 1e-9. Going on
// continues the recurrences, so the run is the one asked for 1e-9 from the start, to the bit,
// with no more products; the callback sees the point that met 1e-3. Asked for what round-off
// cannot give (1e-300), PCG ends, converged for the rtol it met, at its best iterate.
TEST(Pcg, GoesOnToASmallerRtolWithoutStartingOver) {
  const int n = 120, me = 4;
  Qp q = random_qp(n, 0, me, 7, false);
  const Eigen::MatrixXd Pm = Eigen::MatrixXd::Identity(n, n) - q.G.transpose() * q.G;
  q.A = spread_spd(n, 1e4, 7);
  DenseOperator A(q.A), P(Pm);
  SerialReducer red;
  QuadraticProgram pq;
  pq.hessian = borrow(A);
  pq.linear = q.b;
  pq.equality_projector = borrow(P);
  const Vec x0 = q.G.transpose() * Vec::LinSpaced(me, 0.5, 1.5);
  const double pb = (Pm * q.b).norm();
  const auto residual = [&](const Vec& x) { return (Pm * (q.b - q.A * x)).norm() / pb; };
  PcgOptions opt;
  opt.rtol = 1e-9;
  Vec direct = x0;
  const auto rd = projected_cg(pq, direct, red, opt);
  ASSERT_EQ(rd.reason, StopReason::converged);
  const long direct_products = A.count();
  opt.rtol = 1e-3;
  int calls = 0;
  opt.tighten = [&](const Vec& x, double rtol) {
    ++calls;
    EXPECT_EQ(rtol, calls == 1 ? 1e-3 : 1e-9);
    if (calls == 1) EXPECT_LE(residual(x), 1e-3 * (1 + 1e-8));
    return calls == 1 ? 1e-9 : rtol;
  };
  Vec x = x0;
  const auto r = projected_cg(pq, x, red, opt);
  ASSERT_EQ(r.reason, StopReason::converged);
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(r.go_ons, 1);
  EXPECT_FALSE(r.go_on_failed);
  EXPECT_EQ(r.rtol, 1e-9);
  EXPECT_EQ(x, direct);
  EXPECT_EQ(r.iterations, rd.iterations);
  EXPECT_EQ(A.count() - direct_products, direct_products);
  EXPECT_LE(residual(x), 1e-9 * (1 + 1e-6));
  EXPECT_GT(rd.iterations, 30);  // CG took many steps: the continuation is not trivial
  // Unattainable: back to the rtol met, converged, at least as good as where it went on.
  opt.tighten = [](const Vec&, double rtol) { return rtol > 1e-300 ? 1e-300 : rtol; };
  Vec y = x0;
  const auto rf = projected_cg(pq, y, red, opt);
  EXPECT_EQ(rf.reason, StopReason::converged);
  EXPECT_TRUE(rf.go_on_failed);
  EXPECT_EQ(rf.rtol, 1e-3);
  EXPECT_LE(residual(y), 1e-3);
  EXPECT_LE(rf.projected_residual, 1e-3 * pb);
}

TEST(Failures, NonConvergenceIsAResult) {
  const Qp q = random_qp(10, 5, 0, 3, false);
  DenseOperator A(q.A);
  SerialReducer red;
  MprgpOptions opt;
  opt.alpha = 1.0 / q.A.norm();
  opt.max_iterations = 1;
  Vec x = Vec::Zero(10), g(10);
  const auto r =
      mprgp(A, q.b, q.l, x, g, red, opt, [](const Vec&, const Vec&, double) { return false; });
  EXPECT_EQ(r.reason, StopReason::max_iterations);
  opt.alpha = 0;
  EXPECT_THROW(
      mprgp(A, q.b, q.l, x, g, red, opt, [](const Vec&, const Vec&, double) { return false; }),
      std::invalid_argument);
  // An indefinite operator is a breakdown, not a crash.
  DenseOperator negative(-Eigen::MatrixXd::Identity(4, 4));
  DenseOperator identity(Eigen::MatrixXd::Identity(4, 4));
  Vec y = Vec::Zero(4);
  PcgOptions po;
  QuadraticProgram nq;
  nq.hessian = borrow(negative);
  nq.linear = Vec::Ones(4);
  nq.equality_projector = borrow(identity);
  const auto rp = projected_cg(nq, y, red, po);
  EXPECT_EQ(rp.reason, StopReason::breakdown);
}

// The power-method estimate of ||A|| (used for MPRGP's step length and SMALBE-M's rho and M_0):
// a lower bound that converges to the largest eigenvalue; on diag(1..100) with a start that
// touches every eigenvector it is within 1e-3 of 100 and never above it.
TEST(NormEstimate, ConvergesFromBelowToTheLargestEigenvalue) {
  const int n = 100;
  DenseOperator A(Eigen::VectorXd::LinSpaced(n, 1.0, 100.0).asDiagonal().toDenseMatrix());
  SerialReducer red;
  const double est = estimate_norm(A, Vec::Ones(n), red, 500, 1e-12);
  EXPECT_LE(est, 100.0 * (1 + 1e-12));
  EXPECT_GT(est, 99.9);
  // Few products with a loose tolerance: still a lower bound, and counted by the operator.
  DenseOperator B(Eigen::VectorXd::LinSpaced(n, 1.0, 100.0).asDiagonal().toDenseMatrix());
  const double rough = estimate_norm(B, Vec::Ones(n), red, 5, 1e-3);
  EXPECT_LE(rough, est);
  EXPECT_LE(B.count(), 6);
}

// Lanczos: also a lower bound; after k products its Ritz value is at least the power method's
// (the Krylov space holds the power iterate), and it meets the same tolerance with fewer
// products. On a clustered top of the spectrum (diag(1..100) with 99, 99.5, 100) where the power
// method crawls.
TEST(NormEstimate, LanczosIsALowerBoundAndNeedsFewerProducts) {
  const int n = 100;
  Eigen::VectorXd d = Eigen::VectorXd::LinSpaced(n, 1.0, 100.0);
  d[98] = 99.5;
  const Eigen::MatrixXd D = d.asDiagonal().toDenseMatrix();
  SerialReducer red;
  for (int k : {2, 5, 10, 20}) {
    DenseOperator A(D), B(D);
    const double power = estimate_norm(A, Vec::Ones(n), red, k, 0.0);
    const double lanczos = estimate_norm_lanczos(B, Vec::Ones(n), red, k, 0.0);
    EXPECT_LE(lanczos, 100.0 * (1 + 1e-12)) << k;
    EXPECT_GE(lanczos, power * (1 - 1e-12)) << k;
    EXPECT_EQ(B.count(), k);
  }
  DenseOperator A(D), B(D);
  const double power = estimate_norm(A, Vec::Ones(n), red, 500, 1e-6);
  const double lanczos = estimate_norm_lanczos(B, Vec::Ones(n), red, 500, 1e-6);
  EXPECT_NEAR(lanczos, 100.0, 1e-4);
  EXPECT_LT(B.count(), A.count());
  EXPECT_LE(power, 100.0 * (1 + 1e-12));
  // An invariant Krylov space (an eigenvector as start): exact after one product.
  DenseOperator C(D);
  Vec e = Vec::Zero(n);
  e[n - 1] = 1;
  EXPECT_NEAR(estimate_norm_lanczos(C, e, red, 50, 1e-3), 100.0, 1e-12);
  EXPECT_EQ(C.count(), 1);
}

// SMALBE-M's iteration limit is a result with its reason and the iterate so far.
TEST(Failures, SmalbeIterationLimitIsAResult) {
  const Qp q = random_qp(10, 6, 2, 4, false);
  DenseOperator A(q.A);
  const Eigen::MatrixXd Qm = q.G.transpose() * q.G;
  SerialReducer red;
  SmalbeOptions opt;
  opt.rtol = 1e-12;
  opt.max_outer = 1;
  const double normA = estimate_norm(A, Vec::Ones(10), red, 200, 1e-10);
  Vec x = Vec::Zero(10);
  const auto r = smalbe(qp_of(A, q), normA, x, red, opt);
  EXPECT_EQ(r.reason, StopReason::max_iterations);
  EXPECT_EQ(r.outer_iterations, 1);
  EXPECT_TRUE(x.allFinite());
}

// The tracked image T x (SMALBE-M's Q x for the stopping test) equals T applied to x at every
// stop test, through CG, expansion and proportioning steps, and the iterates do not change.
TEST(Mprgp, TrackedImageEqualsAppliedImage) {
  const int n = 14, bounded = 10;
  int expansions = 0, proportionings = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const Qp q = random_qp(n, bounded, 0, seed, false);
    SerialReducer red;
    const Eigen::MatrixXd Tm = Eigen::MatrixXd::Random(5, n);
    Vec last(5);
    FunctionOperator A([&](const Vec& v, Vec& y) {
      y = q.A * v;
      last = Tm * v;
    });
    DenseOperator A0(q.A);
    MprgpOptions opt;
    opt.alpha = 1.9 / estimate_norm(A0, Vec::Ones(n), red, 200, 1e-10);
    opt.gamma = 0.3;  // small Gamma: proportioning steps happen
    TrackedImage image;
    image.last = &last;
    opt.image = &image;
    const double tol = 1e-11 * q.b.norm();
    double worst = 0;
    Vec x = Vec::Zero(n), g(n);
    const auto r = mprgp(A, q.b, q.l, x, g, red, opt, [&](const Vec& xx, const Vec&, double gp) {
      worst = std::max(worst, (image.tx - Tm * xx).norm() / std::max(1.0, (Tm * xx).norm()));
      return gp <= tol;
    });
    ASSERT_EQ(r.reason, StopReason::converged);
    EXPECT_LT(worst, 1e-12) << "seed " << seed;
    expansions += r.expansion_steps, proportionings += r.proportioning_steps;
    // Without tracking: the same iterates.
    MprgpOptions plain = opt;
    plain.image = nullptr;
    Vec x2 = Vec::Zero(n), g2(n);
    mprgp(A0, q.b, q.l, x2, g2, red, plain,
          [&](const Vec&, const Vec&, double gp) { return gp <= tol; });
    EXPECT_EQ(x2, x);
    // The projected CG expansion step, kept or undone: the image follows too.
    opt.expansion = Expansion::projected_cg;
    worst = 0;
    x.setZero();
    const auto rc = mprgp(A, q.b, q.l, x, g, red, opt, [&](const Vec& xx, const Vec&, double gp) {
      worst = std::max(worst, (image.tx - Tm * xx).norm() / std::max(1.0, (Tm * xx).norm()));
      return gp <= tol;
    });
    ASSERT_EQ(rc.reason, StopReason::converged);
    EXPECT_LT(worst, 1e-12) << "seed " << seed << ", projected CG expansion";
  }
  EXPECT_GT(expansions, 0);
  EXPECT_GT(proportionings, 0);
}

// MPRGP with the gradient given (SMALBE-M passes it between outer iterations): the same iterates
// and no product for the initial gradient.
TEST(Mprgp, GivenGradientPathMatchesComputedGradient) {
  const Qp q = random_qp(12, 7, 0, 5, false);
  SerialReducer red;
  MprgpOptions opt;
  DenseOperator A0(q.A);
  opt.alpha = 1.9 / estimate_norm(A0, Vec::Ones(12), red, 200, 1e-10);
  auto stop = [&](const Vec& x, const Vec& g, double) {
    Vec gp;
    projected_gradient(x, g, q.l, gp);
    return gp.norm() < 1e-10 * q.b.norm();
  };
  const Vec start = q.l.cwiseMax(Vec::Zero(12));  // feasible
  DenseOperator A1(q.A), A2(q.A);
  Vec x1 = start, g1(12), x2 = start, g2 = q.A * start - q.b;
  const auto r1 = mprgp(A1, q.b, q.l, x1, g1, red, opt, stop);
  const auto r2 = mprgp(A2, q.b, q.l, x2, g2, red, opt, stop, true);
  ASSERT_EQ(r1.reason, StopReason::converged);
  ASSERT_EQ(r2.reason, StopReason::converged);
  EXPECT_EQ(A2.count(), A1.count() - 1);
  EXPECT_LT((x1 - x2).norm(), 1e-12 * x1.norm());
  EXPECT_LT((x1 - exact_solution(q, 7)).norm(), 1e-8);
}

// The QP transforms (qp.hpp) on a small dense problem: homogenize shifts b, the bounds and the
// solution; enforce_by_projector gives P A P and P b; SMALBE-M on the transformed QP solves the
// original one; parts of the wrong size are refused.
TEST(QpTransforms, HomogenizeAndProjectGiveTheDualForm) {
  const int n = 8;
  const Qp q = random_qp(n, 4, 2, 11, false);
  DenseOperator A(q.A);
  QuadraticProgram base = qp_of(A, q);
  const Eigen::MatrixXd Pm = Eigen::MatrixXd::Identity(n, n) - q.G.transpose() * q.G;
  const Vec x0 = Vec::LinSpaced(n, -0.3, 0.4);
  const QuadraticProgram h = homogenize(base, x0);
  EXPECT_LT((h.linear - (q.b - q.A * x0)).norm(), 1e-14);
  const auto* hb = dynamic_cast<const LowerBounds*>(h.constraints.get());
  ASSERT_NE(hb, nullptr);
  EXPECT_EQ(hb->lower().head(4), (q.l - x0).head(4));
  EXPECT_TRUE(hb->lower().tail(4).array().isInf().all());
  EXPECT_EQ(h.shift, x0);
  const QuadraticProgram p = enforce_by_projector(h);
  EXPECT_LT((p.linear - Pm * h.linear).norm(), 1e-13);
  const Vec v = Vec::LinSpaced(n, 1.0, 2.0);
  Vec y(n);
  p.hessian->apply(v, y);
  EXPECT_LT((y - Pm * q.A * Pm * v).norm(), 1e-12);
  EXPECT_EQ(A.count(), 2);  // one in homogenize, one in the product above
  // A second homogenization adds to the shift.
  EXPECT_LT((homogenize(h, x0).shift - 2 * x0).norm(), 1e-15);
  // Wrong sizes are refused.
  QuadraticProgram bad = base;
  bad.constraints = std::make_shared<LowerBounds>(Vec::Zero(n + 1));
  EXPECT_THROW(bad.check(), std::invalid_argument);
  EXPECT_THROW(homogenize(base, Vec::Zero(n - 1)), std::invalid_argument);
  QuadraticProgram none;
  EXPECT_THROW(none.check(), std::invalid_argument);
  QuadraticProgram no_eq = base;
  no_eq.equality_projector = nullptr;
  EXPECT_THROW(enforce_by_projector(no_eq), std::invalid_argument);
  Vec x = Vec::Zero(n);
  SerialReducer red;
  EXPECT_THROW(smalbe(no_eq, 1.0, x, red, SmalbeOptions{}), std::invalid_argument);
  QuadraticProgram unbounded = base;
  unbounded.constraints = nullptr;
  EXPECT_THROW(smalbe(unbounded, 1.0, x, red, SmalbeOptions{}), std::invalid_argument);
  Vec short_x = Vec::Zero(n - 1);
  EXPECT_THROW(smalbe(base, 1.0, short_x, red, SmalbeOptions{}), std::invalid_argument);
  EXPECT_THROW(projected_cg(base, x, red, PcgOptions{}), std::invalid_argument);  // has bounds
}

// Nonnegative least squares (linalg/nnls.hpp), checked by hand: b inside the cone of M's columns
// is fitted exactly with x >= 0; b outside leaves the residual r of the nearest cone point, with
// M^T r <= 0 and b^T r = ||r||^2 (the Farkas certificate the contact check uses).
TEST(Nnls, FitsInsideTheConeAndCertifiesOutside) {
  Eigen::MatrixXd M(2, 3);
  M << 1, 0, 1,  //
      0, 1, 1;
  Eigen::VectorXd b(2);
  b << 2, 3;  // = 2 e1 + 3 e2 (or e1 + ... : any nonnegative combination)
  auto in = htfeti::nnls(M, b);
  ASSERT_TRUE(in.converged);
  EXPECT_LT(in.r.norm(), 1e-14);
  EXPECT_GE(in.x.minCoeff(), 0.0);
  EXPECT_LT((M * in.x - b).norm(), 1e-14);
  b << -1, 2;  // the nearest point of the cone {x >= 0, y >= 0} is (0, 2)
  auto out = htfeti::nnls(M, b);
  ASSERT_TRUE(out.converged);
  EXPECT_NEAR(out.r[0], -1.0, 1e-14);
  EXPECT_NEAR(out.r[1], 0.0, 1e-14);
  EXPECT_LE((M.transpose() * out.r).maxCoeff(), 1e-14);
  EXPECT_NEAR(b.dot(out.r), out.r.squaredNorm(), 1e-14);
}

// The Lanczos matrix of CG's coefficients (qp/cg_spectrum.hpp) by hand: alpha = (1, 1) and
// beta = 1 give T = [1 1; 1 2], eigenvalues (3 -+ sqrt 5) / 2; one step gives 1 / alpha; a
// coefficient that is not positive gives no estimate.
TEST(CgSpectrum, TheTridiagonalMatrixByHand) {
  CgLanczos l;
  l.start(10);
  EXPECT_TRUE(l.estimate().empty());
  l.step(0.5);
  EXPECT_DOUBLE_EQ(l.estimate().min, 2.0);
  EXPECT_DOUBLE_EQ(l.estimate().max, 2.0);
  l.start(10);
  l.step(1.0);
  l.direction(1.0);
  l.step(1.0);
  const SpectrumEstimate e = l.estimate();
  EXPECT_EQ(e.steps, 2);
  EXPECT_NEAR(e.min, (3 - std::sqrt(5.0)) / 2, 1e-14);
  EXPECT_NEAR(e.max, (3 + std::sqrt(5.0)) / 2, 1e-14);
  l.start(10);
  l.step(1.0);
  l.direction(1.0);
  l.step(-1.0);
  EXPECT_TRUE(l.estimate().empty());
  SpectrumEstimate merged = e;
  merged.merge(SpectrumEstimate{});
  EXPECT_EQ(merged.steps, 2);
  merged.merge(SpectrumEstimate{0.1, 9.0, 3});
  EXPECT_EQ(merged.min, 0.1);
  EXPECT_EQ(merged.max, 9.0);
  EXPECT_EQ(merged.steps, 5);
}

// PCG's estimate against known spectra: A = diag(1, ..., 40) without a preconditioner, and
// A = S Q diag(1, ..., 40) Q' S (Q a random orthogonal matrix, S a diagonal scaling over three
// decades) with Z = S^{-2}, so that Z A = S^{-1} Q diag Q' S has the eigenvalues 1, ..., 40.
// After 4 steps the Ritz values lie strictly inside [1, 40]; at convergence (b excites every
// eigenvector, and distinct eigenvalues take all 40 steps) they are 1 and 40.
TEST(CgSpectrum, PcgEstimatesTheExtremeEigenvalues) {
  const int n = 40;
  std::mt19937 gen(7);
  std::normal_distribution<double> N01;
  Eigen::MatrixXd R(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) R(i, j) = N01(gen);
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(R).householderQ();
  Eigen::VectorXd scale(n), diag(n);
  for (int i = 0; i < n; ++i) scale[i] = std::pow(10.0, 3.0 * i / n), diag[i] = i + 1;
  for (int preconditioned = 0; preconditioned < 2; ++preconditioned) {
    const Eigen::MatrixXd A = preconditioned
                                  ? Eigen::MatrixXd(scale.asDiagonal() * Q * diag.asDiagonal() *
                                                    Q.transpose() * scale.asDiagonal())
                                  : Eigen::MatrixXd(diag.asDiagonal());
    DenseOperator Aop(A),
        Z(Eigen::MatrixXd(scale.array().square().inverse().matrix().asDiagonal()));
    Qp q;
    q.A = A;
    q.b = (preconditioned ? Eigen::VectorXd(scale.asDiagonal() * Q * Eigen::VectorXd::Ones(n))
                          : Eigen::VectorXd::Ones(n));
    q.G.resize(0, n);
    const QuadraticProgram qp = qp_of(Aop, q, false);
    for (int steps : {4, 200}) {
      PcgOptions po;
      po.rtol = 1e-12;
      po.max_iterations = steps;
      Vec x = Vec::Zero(n);
      const PcgResult r =
          projected_cg(qp, x, SerialReducer(), po, {}, preconditioned ? &Z : nullptr);
      const SpectrumEstimate& e = r.spectrum;
      ASSERT_FALSE(e.empty());
      if (steps == 4) {
        EXPECT_EQ(e.steps, 4);
        EXPECT_GT(e.min, 1.01) << preconditioned;
        EXPECT_LT(e.max, 40 / 1.01) << preconditioned;
        continue;
      }
      EXPECT_EQ(r.reason, StopReason::converged);
      EXPECT_NEAR(e.min, 1.0, 1e-8) << preconditioned << ", " << e.steps << " steps";
      EXPECT_NEAR(e.max, 40.0, 1e-8 * 40) << preconditioned << ", " << e.steps << " steps";
    }
  }
}
