// The hot path allocates nothing: after one call of each (work arrays sized, solver workspace in
// place), applying F, P, G~, G~^T, the preconditioner and the Hessian product with one coarse
// step makes no heap allocation, and a SMALBE-M solve allocates as much when it runs twice as
// many inner iterations (nothing per iteration). Counted: malloc, calloc, realloc,
// posix_memalign and aligned_alloc called from htfeti's and Eigen's code (the linker wraps them
// for this program, tests/CMakeLists.txt) and every C++ operator new; not counted: what CHOLMOD
// and MPI allocate inside their own libraries. Runs under mpiexec -n 1, 2.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "helpers.hpp"
#include "htfeti/feti/dual_reducer.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/qp/pcg.hpp"
#include "htfeti/qp/smalbe.hpp"
#include "htfeti/solver.hpp"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
void count() {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
}
}  // namespace

extern "C" {
void* __real_malloc(size_t);
void* __real_calloc(size_t, size_t);
void* __real_realloc(void*, size_t);
int __real_posix_memalign(void**, size_t, size_t);
void* __real_aligned_alloc(size_t, size_t);
void* __wrap_malloc(size_t n) { return count(), __real_malloc(n); }
void* __wrap_calloc(size_t n, size_t s) { return count(), __real_calloc(n, s); }
void* __wrap_realloc(void* p, size_t n) { return count(), __real_realloc(p, n); }
int __wrap_posix_memalign(void** p, size_t a, size_t n) {
  return count(), __real_posix_memalign(p, a, n);
}
void* __wrap_aligned_alloc(size_t a, size_t n) { return count(), __real_aligned_alloc(a, n); }
}

void* operator new(size_t n) {
  count();
  if (void* p = __real_malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t) noexcept { std::free(p); }

using namespace htfeti;

namespace {

struct Counting {
  Counting() { g_allocations = 0, g_counting = true; }
  ~Counting() { g_counting = false; }
  long allocations() const { return g_allocations.load(); }
};

struct Case {
  const char* name;
  int m;
  DualOperator op;
  PreconditionerKind preconditioner;
};

class HotPath : public ::testing::TestWithParam<Case> {};

// The counting itself: an Eigen vector (malloc, wrapped) and a std::vector (operator new).
TEST(HotPath, CountingSeesAllocations) {
  long eigen = 0, vector = 0;
  {
    Counting counting;
    Eigen::VectorXd v = Eigen::VectorXd::Constant(1000, 1.0);
    eigen = counting.allocations();
    std::vector<double> w(1000, v[0]);
    vector = counting.allocations() - eigen;
    EXPECT_EQ(w[999], 1.0);
  }
  EXPECT_GE(eigen, 1);
  EXPECT_GE(vector, 1);
}

TEST_P(HotPath, OperatorsAllocateNothing) {
  const Case c = GetParam();
  Comm comm;
  const auto model =
      make_builtin_model({ProblemKind::membranes, ElementKind::q1, 32, 4, c.m, Glue::averages});
  FetiOptions o;
  o.dual_operator = c.op;
  o.preconditioner = c.preconditioner;
  auto dual = test::make_dual(*model, comm, o);
  dual->build_coarse_image();
  const int n = dual->n_owned(), nc = dual->coarse_dimension();
  const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0);
  Eigen::VectorXd y(n), z(n), fv(n), qv(n), g(nc), w(n);
  auto all = [&] {
    dual->apply_F(x, y);
    dual->project(x, z);
    dual->apply_G(x, g);
    dual->apply_Gt(g, w);
    dual->apply_F(x, fv);
    dual->hessian_from_Fv(x, fv, 1.5, y, qv);
    if (c.preconditioner != PreconditionerKind::none) dual->apply_preconditioner(x, z);
  };
  all();  // first calls: solver workspace
  Counting counting;
  for (int rep = 0; rep < 3; ++rep) all();
  EXPECT_EQ(counting.allocations(), 0) << c.name;
}

// The preconditioner allocates nothing from its first application on (the Dirichlet one's
// factor of K_ii makes its solve workspace in the setup): its loop over the subdomains cannot
// pass an allocation failure on.
TEST(HotPath, PreconditionerAllocatesNothingFromItsFirstApplication) {
  Comm comm;
  const auto model =
      make_builtin_model({ProblemKind::membranes, ElementKind::q1, 32, 4, 1, Glue::averages});
  for (const PreconditionerKind kind :
       {PreconditionerKind::lumped, PreconditionerKind::dirichlet}) {
    FetiOptions o;
    o.dual_operator = DualOperator::implicit;
    o.preconditioner = kind;
    o.dirichlet_storage = 2;  // implicit S_i: a sparse factor of K_ii
    auto dual = test::make_dual(*model, comm, o);
    const int n = dual->n_owned();
    const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0);
    Eigen::VectorXd z(n);
    Counting counting;
    dual->apply_preconditioner(x, z);
    EXPECT_EQ(counting.allocations(), 0) << to_string(kind);
    EXPECT_GT(z.norm(), 0.0);
  }
}

// The weighted projector of PCG's preconditioner (both directions): nothing allocated from its
// first application on, as the orthogonal projector.
TEST(HotPath, WeightedProjectorAllocatesNothingFromItsFirstApplication) {
  Comm comm;
  ProblemSpec spec = cube_obstacle_spec({4, 4, 4}, {2, 2, 2}, 1);
  spec.physics.coefficient = "x > 50 ? 1000 : 1";
  const auto model = make_model(spec);
  FetiOptions o;
  o.preconditioner = PreconditionerKind::lumped;
  o.scaling = Scaling::stiffness;
  auto dual = test::make_dual(*model, comm, o);
  ASSERT_TRUE(dual->set_weighted_projector());
  const int n = dual->n_owned();
  const Eigen::VectorXd x = test::pseudo_random(*dual, 1.0);
  Eigen::VectorXd y(n), z(n);
  Counting counting;
  dual->project_weighted(x, y, true);
  dual->project_weighted(y, z, false);
  EXPECT_EQ(counting.allocations(), 0);
  EXPECT_GT(z.norm(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(
    Membranes, HotPath,
    ::testing::Values(
        Case{"tfeti_explicit", 1, DualOperator::explicit_, PreconditionerKind::none},
        Case{"tfeti_implicit_dirichlet", 1, DualOperator::implicit, PreconditionerKind::dirichlet},
        Case{"htfeti_explicit_lumped", 2, DualOperator::explicit_, PreconditionerKind::lumped},
        Case{"htfeti_implicit", 2, DualOperator::implicit, PreconditionerKind::none}),
    [](const auto& info) { return std::string(info.param.name); });

// SMALBE-M on the membranes: allocations of a solve capped at k inner iterations and at 2k are
// the same, for both forms of the Hessian product.
TEST(HotPath, SmalbeAllocatesNothingPerIteration) {
  Comm comm;
  for (int steps : {2, 1}) {
    long counts[2];
    for (int run = 0; run < 2; ++run) {
      SolveOptions opt;
      opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 32, 4, 1, Glue::averages};
      opt.coarse_steps_per_product = steps;
      const auto model = std::shared_ptr<const Model>(make_builtin_model(opt.decomposition));
      auto dual = test::make_dual(*model, comm);
      if (steps == 1) dual->build_coarse_image();
      const int n = dual->n_owned();
      Eigen::VectorXd px(n), fv(n), tmp(n), b(n), x = Eigen::VectorXd::Zero(n);
      qp::FunctionOperator F(
          [&](const Eigen::VectorXd& u, Eigen::VectorXd& v) { dual->apply_F(u, v); });
      qp::FunctionOperator P(
          [&](const Eigen::VectorXd& u, Eigen::VectorXd& v) { dual->project(u, v); });
      qp::FunctionOperator A([&](const Eigen::VectorXd& u, Eigen::VectorXd& v) {
        P.apply(u, tmp);
        F.apply(tmp, v);
        P.apply(v, v);
      });
      qp::SmalbeHooks hooks;
      hooks.fused_hessian = [&](const Eigen::VectorXd& v, double rho, Eigen::VectorXd& y,
                                Eigen::VectorXd& qv) {
        if (steps == 1) {
          F.apply(v, fv);
          dual->hessian_from_Fv(v, fv, rho, y, qv);
          return;
        }
        P.apply(v, px);
        F.apply(px, y);
        P.apply(y, y);
        qv = v - px;
        y += rho * qv;
      };
      F.apply(dual->lambda_tilde(), tmp);
      P.apply(dual->d() - tmp, b);
      qp::QuadraticProgram qp;
      qp.hessian = qp::borrow(A);
      qp.linear = b;
      qp.constraints = dual->constraint_set()->shifted(dual->lambda_tilde());
      qp.equality_projector = qp::borrow(P);
      DualReducer red(comm, *dual);
      qp::SmalbeOptions so;
      so.rtol = 1e-14;  // never met: the inner cap ends both runs
      so.max_inner = run == 0 ? 10 : 20;
      Counting counting;
      qp::smalbe(qp, 12.0, x, red, so, hooks);
      counts[run] = counting.allocations();
    }
    EXPECT_EQ(counts[1], counts[0]) << steps << " coarse steps per product";
  }
}

// Projected CG on the Poisson problem: 20 iterations allocate as much as 10.
TEST(HotPath, ProjectedCgAllocatesNothingPerIteration) {
  Comm comm;
  const auto model =
      make_builtin_model({ProblemKind::poisson2d, ElementKind::q1, 32, 4, 1, Glue::averages});
  auto dual = test::make_dual(*model, comm);
  const DualReducer red(comm, *dual);
  qp::FunctionOperator F(
      [&](const Eigen::VectorXd& u, Eigen::VectorXd& v) { dual->apply_F(u, v); });
  qp::FunctionOperator P(
      [&](const Eigen::VectorXd& u, Eigen::VectorXd& v) { dual->project(u, v); });
  long counts[2];
  for (int run = 0; run < 2; ++run) {
    Eigen::VectorXd x = dual->lambda_tilde();
    qp::PcgOptions po;
    po.rtol = 1e-300;  // never met: the iteration cap ends both runs
    po.max_iterations = run == 0 ? 10 : 20;
    qp::QuadraticProgram qp;
    qp.hessian = qp::borrow(F);
    qp.linear = dual->d();
    qp.equality_projector = qp::borrow(P);
    Counting counting;
    const auto r = qp::projected_cg(qp, x, red, po);
    counts[run] = counting.allocations();
    EXPECT_EQ(r.iterations, po.max_iterations);
  }
  EXPECT_EQ(counts[1], counts[0]);
}

}  // namespace
