// Tiny hand-checkable cases: element matrices, loads, subdomain generalized inverses, B~ and the
// cluster generalized inverse.
#include <SuiteSparse_config.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <thread>

#include "helpers.hpp"
#include "htfeti/fem/element.hpp"
#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/cluster.hpp"
#include "htfeti/feti/constraints.hpp"
#include "htfeti/linalg/orthonormal.hpp"
#include "htfeti/linalg/packed_symmetric.hpp"
#include "htfeti/parallel/fresh_pages.hpp"

using namespace htfeti;

TEST(Element, Q1StiffnessIsTheTextbookMatrix) {
  const auto k = square_stiffness(ElementKind::q1);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(k[i][i], 2.0 / 3.0, 1e-15);
    EXPECT_NEAR(k[i][(i + 1) % 4], -1.0 / 6.0, 1e-15);
    EXPECT_NEAR(k[i][(i + 2) % 4], -1.0 / 3.0, 1e-15);
  }
}

TEST(Element, P1StiffnessOfTwoRightTriangles) {
  // Diagonal 0-2: edges of the square get -1/2, the diagonal 0-2 gets 0 (right angles at 1 and 3)
  // and 1-3 are not connected.
  const auto k = square_stiffness(ElementKind::p1);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(k[i][i], 1.0, 1e-15);
    EXPECT_NEAR(k[i][(i + 1) % 4], -0.5, 1e-15);
    EXPECT_NEAR(k[i][(i + 2) % 4], 0.0, 1e-15);
  }
}

TEST(Element, Q1StiffnessOfTheUnitCube) {
  // Trilinear Laplace on [0,1]^3: 1/3 on the diagonal, 0 along an edge, -1/12 across a face
  // diagonal and across the body diagonal (rows sum to zero).
  const double x[24] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  const Eigen::MatrixXd k = laplace_stiffness(CellType::hex8, x);
  for (int a = 0; a < 8; ++a)
    for (int b = 0; b < 8; ++b) {
      int differ = 0;
      for (int d = 0; d < 3; ++d) differ += x[3 * a + d] != x[3 * b + d];
      const double expect = differ == 0 ? 1.0 / 3 : differ == 1 ? 0.0 : -1.0 / 12;
      EXPECT_NEAR(k(a, b), expect, 1e-15) << a << " " << b;
    }
}

namespace {
// B^T D B of linear elasticity integrated by the test's own quadrature: the 3D cells' element
// matrices against an independent evaluation (hex8 2 x 2 x 2 Gauss points, tet4 one point).
Eigen::MatrixXd reference_elasticity(CellType t, const double* x, double E, double nu) {
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6, 6);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) += 2 * mu;
    D(3 + i, 3 + i) = mu;
  }
  const int n = t == CellType::hex8 ? 8 : 4;
  std::vector<std::array<double, 4>> pts;  // xi, eta, zeta, weight
  const double g = 1 / std::sqrt(3.0);
  if (n == 8) {
    for (double a : {-g, g})
      for (double b : {-g, g})
        for (double c : {-g, g}) pts.push_back({a, b, c, 1.0});
  } else {
    pts.push_back({0.25, 0.25, 0.25, 1.0 / 6});
  }
  const int s[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                       {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (const auto& p : pts) {
    Eigen::MatrixXd dN(n, 3);
    if (n == 8) {
      for (int a = 0; a < 8; ++a)
        for (int k = 0; k < 3; ++k) {
          double v = s[a][k] / 8.0;
          for (int m = 0; m < 3; ++m)
            if (m != k) v *= 1 + s[a][m] * p[m];
          dN(a, k) = v;
        }
    } else {
      dN << -1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    }
    Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
    for (int a = 0; a < n; ++a)
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) J(i, k) += x[3 * a + i] * dN(a, k);
    const Eigen::MatrixXd G = dN * J.inverse();
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(6, 3 * n);
    for (int a = 0; a < n; ++a) {
      B(0, 3 * a) = B(3, 3 * a + 1) = B(5, 3 * a + 2) = G(a, 0);
      B(1, 3 * a + 1) = B(3, 3 * a) = B(4, 3 * a + 2) = G(a, 1);
      B(2, 3 * a + 2) = B(4, 3 * a + 1) = B(5, 3 * a) = G(a, 2);
    }
    K += p[3] * std::abs(J.determinant()) * B.transpose() * D * B;
  }
  return K;
}
}  // namespace

TEST(Element, ElasticityOf3DCellsIsBTransposeDBAndKillsRigidMotions) {
  // A distorted hex8 (no two faces parallel) and a tet4 of negative orientation.
  const double hex[24] = {0.0,  0.0,  0.0, 1.1, 0.1, -0.05, 1.2, 0.9, 0.1, -0.1, 1.0, 0.0,
                          0.05, -0.1, 0.9, 1.0, 0.0, 1.2,   1.3, 1.1, 1.0, 0.0,  0.8, 1.1};
  const double tet[12] = {0, 0, 0, 0, 1.0, 0.2, 0.9, 0.1, 0, 0.2, 0.3, 1.1};
  const Material m{2.1e5, 0.3};
  for (auto [t, x] : {std::pair{CellType::hex8, hex}, std::pair{CellType::tet4, tet}}) {
    const int n = t == CellType::hex8 ? 8 : 4;
    const Eigen::MatrixXd k = elasticity_stiffness(t, x, m);
    const Eigen::MatrixXd r = reference_elasticity(t, x, m.young, m.poisson);
    ASSERT_EQ(k.rows(), 3 * n);
    EXPECT_LT((k - r).norm(), 1e-13 * r.norm()) << to_string(t);
    EXPECT_EQ((k - k.transpose()).norm(), 0.0) << to_string(t);
    // The six rigid body motions are in the kernel.
    Eigen::MatrixXd R = Eigen::MatrixXd::Zero(3 * n, 6);
    for (int a = 0; a < n; ++a) {
      const double* p = x + 3 * a;
      for (int d = 0; d < 3; ++d) R(3 * a + d, d) = 1;
      R(3 * a + 0, 3) = -p[1], R(3 * a + 1, 3) = p[0];
      R(3 * a + 1, 4) = -p[2], R(3 * a + 2, 4) = p[1];
      R(3 * a + 2, 5) = -p[0], R(3 * a + 0, 5) = p[2];
    }
    EXPECT_LT((k * R).norm(), 1e-12 * k.norm()) << to_string(t);
    // The tet's volume, and the shape integrals summing to the measure.
    if (t == CellType::tet4) {
      Eigen::Matrix3d e;
      for (int i = 0; i < 3; ++i)
        for (int d = 0; d < 3; ++d) e(d, i) = x[3 * (i + 1) + d] - x[d];
      EXPECT_NEAR(cell_measure(t, x), std::abs(e.determinant()) / 6, 1e-15);
      EXPECT_NEAR(shape_integrals(t, x)[0], std::abs(e.determinant()) / 24, 1e-15);
    }
    EXPECT_NEAR(shape_integrals(t, x).sum(), cell_measure(t, x), 1e-14);
  }
  // A box: the measure is exact.
  const double box[24] = {0, 0, 0,   2, 0, 0,   2, 3, 0,   0, 3, 0,
                          0, 0, 0.5, 2, 0, 0.5, 2, 3, 0.5, 0, 3, 0.5};
  EXPECT_NEAR(cell_measure(CellType::hex8, box), 3.0, 1e-14);
  for (int a = 0; a < 8; ++a) EXPECT_NEAR(shape_integrals(CellType::hex8, box)[a], 3.0 / 8, 1e-15);
  EXPECT_THROW(elasticity_stiffness(CellType::tet4, std::array<double, 12>{}.data(), m),
               std::invalid_argument);
}

TEST(Load, TotalLoadIsTheIntegralOfF) {
  for (auto element : {ElementKind::q1, ElementKind::p1}) {
    Decomposition dec({ProblemKind::membranes, element, 8, 2, 1, Glue::averages});
    const auto model = make_builtin_model(dec.options());
    double total = 0;
    for (int s = 0; s < dec.num_subdomains(); ++s)
      total += test::make_subdomain(*model, s).f().sum();
    EXPECT_NEAR(total, -3.0 * 0.25 - 1.0 * 0.25, 1e-14);
    Decomposition p({ProblemKind::poisson2d, element, 6, 3, 1, Glue::averages});
    const auto pm = make_builtin_model(p.options());
    total = 0;
    for (int s = 0; s < p.num_subdomains(); ++s) total += test::make_subdomain(*pm, s).f().sum();
    EXPECT_NEAR(total, 1.0, 1e-14);
  }
}

TEST(Subdomain, GeneralizedInverseAndKernel) {
  for (auto element : {ElementKind::q1, ElementKind::p1}) {
    Decomposition dec({ProblemKind::poisson2d, element, 10, 2, 1, Glue::averages});
    const auto model = make_builtin_model(dec.options());
    Subdomain sd = test::make_subdomain(*model, 3);
    sd.factorize(Ordering::amd);
    const Eigen::MatrixXd K = Eigen::MatrixXd(sd.K());
    Eigen::MatrixXd KpK(K.rows(), K.cols());
    for (int j = 0; j < K.cols(); ++j) {
      Eigen::VectorXd col = K.col(j);
      sd.apply_pinv(col.data(), KpK.col(j).data());
    }
    EXPECT_LT((K * KpK - K).norm(), 1e-12 * K.norm());  // K K^+ K = K
    // All columns at once (one multi-column solve) give the single solves up to round-off.
    Eigen::MatrixXd many = K.leftCols(5);
    sd.apply_pinv_many(many);
    EXPECT_LT((many - KpK.leftCols(5)).norm(), 1e-13 * KpK.leftCols(5).norm());
    EXPECT_GT(many.norm(), 0.0);
    EXPECT_LT((K * sd.kernel()).norm(), 1e-13);  // K R = 0
    EXPECT_NEAR(sd.kernel().norm(), 1.0, 1e-14);
    const Eigen::VectorXd u = Eigen::VectorXd::LinSpaced(K.rows(), -1.0, 2.0);
    EXPECT_NEAR(sd.energy(u), 0.5 * u.dot(K * u) - sd.f().dot(u), 1e-12);  // element-wise energy
  }
}

// populate() (parallel/fresh_pages.hpp) makes pages resident and leaves what they hold as it
// was: a block written before, unaligned at both ends, read back the same; blocks below the
// threshold and empty ranges are left alone. The factors of a matrix given uncompressed and
// with explicit entries below the diagonal (the upper triangle is copied into resident arrays)
// solve as those of the same matrix compressed.
TEST(FreshPages, PopulateKeepsTheContents) {
  const std::size_t bytes = 3 * kPopulateBytes + 123;
  std::vector<unsigned char> block(bytes + 7);
  for (std::size_t i = 0; i < block.size(); ++i) block[i] = static_cast<unsigned char>(i * 31 + 7);
  const std::vector<unsigned char> copy = block;
  populate(block.data() + 3, bytes);
  populate(block.data() + 1, 100);
  populate(block.data(), 0);
  EXPECT_EQ(block, copy);
  std::vector<double> fresh;
  fresh.reserve(kPopulateBytes);  // not written yet: made resident, then written
  populate(fresh.data(), kPopulateBytes * sizeof(double));
  fresh.assign(kPopulateBytes, 2.5);
  EXPECT_EQ(std::count(fresh.begin(), fresh.end(), 2.5), static_cast<long>(kPopulateBytes));
}

TEST(FreshPages, UncompressedMatrixFactorsAsCompressed) {
  const int n = 40;
  Eigen::SparseMatrix<double> A(n, n);  // a 1D Laplacian plus the identity, built by insert
  A.reserve(Eigen::VectorXi::Constant(n, 4));
  for (int j = 0; j < n; ++j) {
    A.insert(j, j) = 3.0;
    if (j > 0) A.insert(j - 1, j) = -1.0, A.insert(j, j - 1) = -1.0;
  }
  ASSERT_FALSE(A.isCompressed());
  Eigen::SparseMatrix<double> C = A;
  C.makeCompressed();
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n, -1.0, 1.0);
  SparseCholesky a, c;
  a.factorize(A);
  c.factorize(C);
  Eigen::VectorXd xa = b, xc = b;
  a.solve(xa.data(), xa.data());
  c.solve(xc.data(), xc.data());
  EXPECT_EQ(xa, xc);
  EXPECT_LT((C * xc - b).norm(), 1e-13 * b.norm());
}

// CHOLMOD's large blocks go through the block pool (populate_cholmod_allocations): a freed block
// serves the next allocation; its contents survive a realloc that grows it, and calloc hands
// back zeros from a block that held other values.
TEST(FreshPages, PooledBlocksKeepTheirContents) {
  populate_cholmod_allocations();
  const std::size_t n = 2 * kPopulateBytes / sizeof(double);
  auto* a = static_cast<double*>(SuiteSparse_config.malloc_func(n * sizeof(double)));
  ASSERT_NE(a, nullptr);
  for (std::size_t i = 0; i < n; ++i) a[i] = static_cast<double>(i);
  auto* b = static_cast<double*>(SuiteSparse_config.realloc_func(a, 3 * n * sizeof(double)));
  ASSERT_NE(b, nullptr);
  bool same = true;
  for (std::size_t i = 0; i < n; ++i) same = same && b[i] == static_cast<double>(i);
  EXPECT_TRUE(same);
  for (std::size_t i = 0; i < 3 * n; ++i) b[i] = 1.5;
  SuiteSparse_config.free_func(b);
  auto* c = static_cast<double*>(SuiteSparse_config.calloc_func(3 * n, sizeof(double)));
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(std::count(c, c + 3 * n, 0.0), static_cast<long>(3 * n));
  SuiteSparse_config.free_func(c);
  release_idle_blocks();
}

// A block to be kept for the run (KeptAllocations) takes only its own size from a larger idle
// block; the rest stays idle and serves the next allocation. Other blocks take the idle block
// whole (the next allocation is then new).
TEST(FreshPages, KeptBlocksTakeOnlyTheirSize) {
  populate_cholmod_allocations();
  release_idle_blocks();
  const std::size_t big = 8 * kPopulateBytes, small = 2 * kPopulateBytes;
  auto* a = static_cast<char*>(SuiteSparse_config.malloc_func(big));
  ASSERT_NE(a, nullptr);
  SuiteSparse_config.free_func(a);
  void* again = SuiteSparse_config.malloc_func(big);
  SuiteSparse_config.free_func(again);
  if (again != a) GTEST_SKIP() << "no block pool (a sanitizer build)";
  char* head = nullptr;
  {
    const KeptAllocations kept;
    head = static_cast<char*>(SuiteSparse_config.malloc_func(small));
  }
  auto* tail = static_cast<char*>(SuiteSparse_config.malloc_func(big - small));
  EXPECT_EQ(head, a);
  EXPECT_EQ(tail, a + small);
  std::memset(head, 1, small);  // both usable to their ends
  std::memset(tail, 2, big - small);
  EXPECT_EQ(head[small - 1], 1);
  EXPECT_EQ(tail[0], 2);
  SuiteSparse_config.free_func(tail);
  SuiteSparse_config.free_func(head);
  release_idle_blocks();
  a = static_cast<char*>(SuiteSparse_config.malloc_func(big));
  SuiteSparse_config.free_func(a);
  head = static_cast<char*>(SuiteSparse_config.malloc_func(small));  // the whole block
  tail = static_cast<char*>(SuiteSparse_config.malloc_func(big - small));
  EXPECT_EQ(head, a);
  EXPECT_NE(tail, a + small);
  SuiteSparse_config.free_func(tail);
  SuiteSparse_config.free_func(head);
  release_idle_blocks();
}

// rand() and srand() have one state per thread (sparse_cholesky.cpp: METIS orders on several
// threads at once): the C library's sequence for a seed (glibc's first values for seed 1), and
// two threads drawing at once each get their seed's sequence.
TEST(SparseCholesky, RandomNumbersPerThreadFollowTheirSeed) {
  std::srand(1);
  EXPECT_EQ(std::rand(), 1804289383);
  EXPECT_EQ(std::rand(), 846930886);
  const auto draws = [](unsigned seed) {
    std::srand(seed);
    std::vector<int> v(1000000);  // long enough for the two threads to overlap
    for (int& x : v) x = std::rand();
    return v;
  };
  const std::vector<int> a = draws(4321), b = draws(77);
  std::vector<int> ta, tb;
  std::thread t1([&] { ta = draws(4321); }), t2([&] { tb = draws(77); });
  t1.join(), t2.join();
  EXPECT_EQ(ta, a);
  EXPECT_EQ(tb, b);
  EXPECT_NE(a, b);
}

TEST(Subdomain, NotPositiveDefiniteIsAnError) {
  SparseCholesky chol;
  Eigen::SparseMatrix<double> A(2, 2);
  A.insert(0, 0) = 1.0;
  A.insert(0, 1) = 2.0;
  A.insert(1, 0) = 2.0;
  A.insert(1, 1) = 1.0;
  EXPECT_THROW(chol.factorize(A), std::runtime_error);
}

// The symbolic cache: the same pattern reuses the analysis and gives the factor of its own
// analysis bit for bit (other values, same pattern); another pattern or another set ordered last
// is analysed anew; a full cache analyses without keeping.
// Two interface-last factors have the same trailing Schur factor, bit for bit, in the same order;
// returns it.
Eigen::MatrixXd expect_same_schur_factor(const SparseCholesky& a, const SparseCholesky& b) {
  Eigen::MatrixXd La, Lb;
  std::vector<int> oa, ob;
  a.schur_factor(La, oa);
  b.schur_factor(Lb, ob);
  EXPECT_EQ(oa, ob);
  EXPECT_EQ((La - Lb).cwiseAbs().maxCoeff(), 0.0);
  return Lb;
}

TEST(SubdomainCache, SharesAnalysesOnlyBetweenEqualPatterns) {
  const auto grid = [](int n, double shift) {  // 5-point Laplacian on n x n, diagonal shifted
    std::vector<Eigen::Triplet<double>> t;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int i = y * n + x;
        t.emplace_back(i, i, 4.0 + shift + 0.01 * i);
        if (x + 1 < n) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
        if (y + 1 < n) t.emplace_back(i, i + n, -1.0), t.emplace_back(i + n, i, -1.0);
      }
    Eigen::SparseMatrix<double> A(n * n, n * n);
    A.setFromTriplets(t.begin(), t.end());
    return A;
  };
  const Eigen::SparseMatrix<double> A1 = grid(12, 0.0), A2 = grid(12, 0.5), A3 = grid(13, 0.0);
  std::vector<int> last;
  for (int i = 0; i < 12; ++i) last.push_back(i);  // one side of the grid
  std::vector<int> other_last = last;
  other_last.back() = 12 * 12 - 1;
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(144, -1.0, 1.0);
  const auto solve = [&](SparseCholesky& c) {
    Eigen::VectorXd x(144);
    c.solve(b.data(), x.data());
    return x;
  };
  for (Ordering ordering : {Ordering::amd, Ordering::metis, Ordering::nesdis}) {
    SubdomainCache cache;
    SparseCholesky plain(ordering), shared1(ordering), shared2(ordering), other(ordering);
    plain.factorize(A2);
    shared1.factorize(A1, &cache);
    shared2.factorize(A2, &cache);  // reuses A1's analysis
    other.factorize(A3, &cache);
    EXPECT_EQ(cache.analyses(), 2);
    EXPECT_EQ(cache.reuses(), 1);
    EXPECT_EQ(cache.patterns(), 2);
    const Eigen::VectorXd x_plain = solve(plain), x_shared = solve(shared2);
    EXPECT_EQ((x_plain - x_shared).cwiseAbs().maxCoeff(), 0.0);  // the same factor
    EXPECT_EQ(plain.factor_nonzeros(), shared2.factor_nonzeros());
    EXPECT_LT((A2 * x_shared - b).norm(), 1e-12 * b.norm());
  }
  {  // the set ordered last is part of the key; a Schur factor from a reused analysis is exact
    SubdomainCache cache;
    SparseCholesky p1, p2, p3, plain;
    p1.factorize(A1, last, &cache);
    p2.factorize(A2, last, &cache);
    p3.factorize(A2, other_last, &cache);
    plain.factorize(A2, last);
    EXPECT_EQ(cache.analyses(), 2);
    EXPECT_EQ(cache.reuses(), 1);
    expect_same_schur_factor(p2, plain);
  }
  {  // numeric factors: kept for a repeated pattern, copied for an equal matrix only
    SubdomainCache cache(64, 1e9);
    SparseCholesky f1, f2, f3, f4, f5, plain;
    f1.factorize(A1, last, &cache);        // analysed
    f2.factorize(A1, last, &cache);        // analysis reused; its numeric factor kept
    f3.factorize(A1, last, &cache);        // copies f2's factor
    f4.factorize(A2, last, &cache);        // the same pattern, other values: factored
    f5.factorize(A1, other_last, &cache);  // another set ordered last: analysed
    plain.factorize(A1, last);
    EXPECT_EQ(cache.analyses(), 2);
    EXPECT_EQ(cache.reuses(), 2);
    EXPECT_EQ(cache.numeric_reuses(), 1);
    EXPECT_EQ(cache.matrices(), 2);
    EXPECT_EQ(f3.numeric_seconds(), 0.0);
    const Eigen::MatrixXd L2 = expect_same_schur_factor(f3, plain);  // the same, bit for bit
    EXPECT_EQ((solve(f3) - solve(plain)).cwiseAbs().maxCoeff(), 0.0);
    // S^{-1}: computed once for f2 and f3 (shared), equal to the plain factor's, and the inverse
    // of S = L_s L_s^T.
    const auto s2 = f2.schur_inverse(), s3 = f3.schur_inverse(), sp = plain.schur_inverse();
    EXPECT_EQ(s2.get(), s3.get());
    EXPECT_NE(sp.get(), s3.get());
    EXPECT_EQ(s3->order, sp->order);
    EXPECT_EQ((s3->S - sp->S).cwiseAbs().maxCoeff(), 0.0);
    const Eigen::MatrixXd Sm = L2 * L2.transpose();
    EXPECT_LT((Sm * sp->S - Eigen::MatrixXd::Identity(Sm.rows(), Sm.cols())).norm(), 1e-10);
    EXPECT_GT((solve(f4) - solve(plain)).cwiseAbs().maxCoeff(), 0.0);
    // Multi-column solves: f3 finds f2's solve of an equal right-hand side (sharing the factor)
    // and gives what the plain factor's solve gives, bit for bit; another right-hand side, or a
    // factor outside the numeric cache (f4), is solved.
    Eigen::MatrixXd X0 = Eigen::MatrixXd::Zero(144, 3);
    for (int k = 0; k < 12; ++k) X0(k, 0) = 1.0 / 12, X0(12 * k, 1) = 0.5, X0(143 - k, 2) = -1.0;
    Eigen::MatrixXd X2 = X0, X3 = X0, Xp = X0, X4 = X0, Y3 = X0;
    Y3(5, 2) = 0.25;
    f2.solve_many(X2.data(), 3);
    EXPECT_EQ(cache.solve_reuses(), 0);
    f3.solve_many(X3.data(), 3);
    EXPECT_EQ(cache.solve_reuses(), 1);
    plain.solve_many(Xp.data(), 3);
    EXPECT_EQ((X3 - Xp).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ((X2 - Xp).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_LT((A1 * Xp - X0).norm(), 1e-12 * X0.norm());
    f3.solve_many(Y3.data(), 3);
    f4.solve_many(X4.data(), 3);
    EXPECT_EQ(cache.solve_reuses(), 1);
    Eigen::MatrixXd Y3in = X0;
    Y3in(5, 2) = 0.25;
    EXPECT_LT((A1 * Y3 - Y3in).norm(), 1e-12 * Y3in.norm());  // its own right-hand side
    EXPECT_LT((A2 * X4 - X0).norm(), 1e-12 * X0.norm());
    // Single solves with a shared factor go through the same memo: b, solved with f3 above, is
    // found for f2 and f3, bit for bit the plain factor's solution.
    const long before = cache.solve_reuses();
    const Eigen::VectorXd x2 = solve(f2), x3 = solve(f3);
    EXPECT_EQ(cache.solve_reuses(), before + 2);
    EXPECT_EQ((x3 - solve(plain)).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ((x2 - x3).cwiseAbs().maxCoeff(), 0.0);
    SubdomainCache small(64, 1.0);  // a byte budget too small for any factor: none kept
    SparseCholesky g1, g2, g3;
    g1.factorize(A1, &small);
    g2.factorize(A1, &small);
    g3.factorize(A1, &small);
    EXPECT_EQ(small.numeric_reuses(), 0);
    EXPECT_EQ(small.matrices(), 0);
  }
  {  // capacity 1: the second pattern is analysed but not kept, the first is still reused
    SubdomainCache cache(1);
    SparseCholesky a, b2, c;
    a.factorize(A1, &cache);
    b2.factorize(A3, &cache);
    c.factorize(A2, &cache);
    EXPECT_EQ(cache.patterns(), 1);
    EXPECT_EQ(cache.analyses(), 2);
    EXPECT_EQ(cache.reuses(), 1);
  }
}

// A numeric factor found in the cache is shared, not copied: it lives as long as any of its
// holders (the cache itself included), refactoring one holder leaves the others as they were,
// and holders in different threads solve with it at the same time (each with its own work
// arrays), all giving the plain factor's solution bit for bit.
// Equal assembled matrices are held once: the pool hands back the held matrix for an equal one
// (pattern and values compared), a matrix differing in one bit of one value is held on its own,
// and a matrix is freed with its last holder (the pool remembers it by weak_ptr only).
TEST(SubdomainCache, EqualMatricesAreHeldOnce) {
  auto make = [](double last) {
    Eigen::SparseMatrix<double> K(3, 3);
    std::vector<Eigen::Triplet<double>> t{
        {0, 0, 2.0}, {1, 0, -1.0}, {1, 1, 2.0}, {2, 1, -1.0}, {2, 2, last}};
    K.setFromTriplets(t.begin(), t.end());
    return K;
  };
  SubdomainCache pool;  // its matrix level
  Eigen::SparseMatrix<double> a = make(2.0), b = make(2.0), c = make(std::nextafter(2.0, 3.0));
  auto A = pool.intern_matrix(a);
  EXPECT_EQ(a.nonZeros(), 0);  // the storage moved into the pool's matrix
  ASSERT_EQ(A->nonZeros(), 5);
  auto B = pool.intern_matrix(b);
  EXPECT_EQ(B.get(), A.get());
  EXPECT_EQ(b.nonZeros(), 0);
  const auto C = pool.intern_matrix(c);
  EXPECT_NE(C.get(), A.get());
  EXPECT_EQ(pool.matrix_reuses(), 1);
  std::weak_ptr<const Eigen::SparseMatrix<double>> w = A;
  const Eigen::SparseMatrix<double> copy = *A;
  // Subdomains holding the pool's matrix read it through K(); releasing drops their hold.
  SubdomainSystem sys;
  Eigen::SparseMatrix<double> k = make(2.0);
  sys.f = Eigen::VectorXd::Zero(3);
  sys.R = Eigen::MatrixXd::Zero(3, 0);
  Subdomain sub(std::move(sys), pool.intern_matrix(k));  // as the setup hands over an assembled K_i
  EXPECT_EQ(&sub.K(), A.get());
  EXPECT_EQ(pool.matrix_reuses(), 2);
  sub.release_matrix();
  EXPECT_EQ(sub.K().nonZeros(), 0);
  EXPECT_FALSE(w.expired());
  A.reset();
  B.reset();
  EXPECT_TRUE(w.expired()) << "the pool must not keep a matrix alive";
  Eigen::SparseMatrix<double> d = make(2.0);
  const auto D = pool.intern_matrix(d);
  EXPECT_EQ(pool.matrix_reuses(), 2);  // the freed one is not found again
  EXPECT_EQ(std::memcmp(D->valuePtr(), copy.valuePtr(), 5 * sizeof(double)), 0);
}

TEST(SubdomainCache, SharedNumericFactorOutlivesItsOtherHolders) {
  const int n = 14;
  std::vector<Eigen::Triplet<double>> t;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int i = y * n + x;
      t.emplace_back(i, i, 4.0 + 0.02 * i);
      if (x + 1 < n) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
      if (y + 1 < n) t.emplace_back(i, i + n, -1.0), t.emplace_back(i + n, i, -1.0);
    }
  Eigen::SparseMatrix<double> A(n * n, n * n), A2;
  A.setFromTriplets(t.begin(), t.end());
  A2 = A * 2.0;
  SparseCholesky plain;
  plain.factorize(A);
  const int holders = 8;
  std::vector<SparseCholesky> f(holders);
  {
    SubdomainCache cache(64, 1e9);
    for (auto& c : f) c.factorize(A, &cache);
    EXPECT_EQ(cache.matrices(), 1);
    EXPECT_EQ(cache.numeric_reuses(), holders - 2);  // the first analyses, the second is kept
  }                         // the cache is gone; its factor lives on in the holders
  f[1] = SparseCholesky();  // the holder that factored the kept matrix
  f[2].factorize(A2);       // another holder refactored with other values
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n * n, -1.0, 2.0);
  Eigen::VectorXd x_plain(n * n);
  plain.solve(b.data(), x_plain.data());
  std::vector<Eigen::VectorXd> x(holders, Eigen::VectorXd::Zero(n * n));
#pragma omp parallel for schedule(static, 1) num_threads(2)
  for (int k = 0; k < 4 * holders; ++k) {
    const int h = k % holders;
    if (h == 1) continue;
    for (int rep = 0; rep < 50; ++rep) f[h].solve(b.data(), x[h].data());
  }
  for (int h = 0; h < holders; ++h) {
    if (h == 1) continue;
    if (h == 2) {
      EXPECT_LT((A2 * x[h] - b).norm(), 1e-12 * b.norm());
      continue;
    }
    EXPECT_EQ((x[h] - x_plain).cwiseAbs().maxCoeff(), 0.0) << "holder " << h;
  }
}

// shared_result: holders of one shared factor get one result per key (key and tag compared in
// full); a key whose first holder's computation throws is computed by each waiting holder.
TEST(SubdomainCache, SharedResultOncePerKeyAndAfterAFailure) {
  const int n = 10;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 3.0);
    if (i + 1 < n) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  SubdomainCache cache(64, 1e9);
  std::vector<SparseCholesky> f(3);
  for (auto& c : f) c.factorize(A, &cache);  // f[1] keeps the factor, f[2] copies it
  const Eigen::MatrixXd key = Eigen::MatrixXd::Identity(n, 2);
  int computed = 0;
  const auto compute = [&] {
    ++computed;
    return Eigen::MatrixXd(key * 2.0);
  };
  const auto r1 = f[1].shared_result(key, {7}, compute);
  const auto r2 = f[2].shared_result(key, {7}, compute);
  const auto r3 = f[2].shared_result(key, {8}, compute);  // another tag: another result
  EXPECT_EQ(r1.get(), r2.get());
  EXPECT_NE(r1.get(), r3.get());
  EXPECT_EQ(computed, 2);
  EXPECT_EQ(*r1, key * 2.0);
  // The first holder throws after the second has begun to wait for the same key.
  std::atomic<bool> first_in{false};
  std::atomic<int> waiter_computed{0};
  const Eigen::MatrixXd key2 = Eigen::MatrixXd::Constant(n, 1, 0.5);
  std::shared_ptr<const Eigen::MatrixXd> got;
  bool threw = false;
  std::thread first([&] {
    try {
      f[1].shared_result(key2, {}, [&]() -> Eigen::MatrixXd {
        first_in = true;
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
        throw std::runtime_error("no memory");
      });
    } catch (const std::runtime_error&) {
      threw = true;
    }
  });
  while (!first_in) std::this_thread::yield();
  got = f[2].shared_result(key2, {}, [&] {
    ++waiter_computed;
    return Eigen::MatrixXd(key2 * 3.0);
  });
  first.join();
  EXPECT_TRUE(threw);
  EXPECT_EQ(waiter_computed, 1);
  EXPECT_EQ(*got, key2 * 3.0);
}

// The packed lower triangle: the product equals the dense symmetric product (double: to
// rounding; single: to the rounding of the values, 2^-24 relative), entries read back, and half
// the bytes (a quarter in single precision). Every n mod 4 and short and long columns: the
// product takes four columns at a time, then the last n mod 4 one by one.
TEST(PackedSymmetric, ProductAndStorage) {
  for (int n : {1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 64, 65, 66, 67}) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, n);
    A = (A + A.transpose()).eval();
    A.triangularView<Eigen::StrictlyUpper>().setConstant(1e30);  // not read
    const Eigen::MatrixXd S = A.selfadjointView<Eigen::Lower>();
    const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);
    const Eigen::VectorXd ref = S * x;
    for (Precision p : {Precision::double_, Precision::single}) {
      const PackedSymmetric P(A, p);
      Eigen::VectorXd y = Eigen::VectorXd::Constant(n, 7.0);  // overwritten
      P.multiply(x.data(), y.data());
      const double tol =
          (p == Precision::double_ ? 1e-14 : 2e-7) * (S.cwiseAbs() * x.cwiseAbs()).maxCoeff();
      EXPECT_LT((y - ref).cwiseAbs().maxCoeff(), tol) << n;
      EXPECT_EQ(P.bytes(), (p == Precision::double_ ? 8L : 4L) * n * (n + 1) / 2);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
          EXPECT_NEAR(P(i, j), S(i, j), p == Precision::double_ ? 0.0 : 1e-7 * std::abs(S(i, j)));
    }
  }
}

// The single-precision product on AVX2 runs a hand-vectorized tile kernel with the portable
// code's operations in the order in which the Release build (-O3) compiles them: there the two
// must agree bit for bit, so that the kernel a machine takes does not change its results. Other
// flags (the sanitizer job's -O1) contract the portable code's sums into fused multiply-adds
// differently; there they agree to rounding. Whole tiles, partial tiles, the last n mod 4 columns.
TEST(PackedSymmetric, VectorizedSingleProductEqualsThePortableOne) {
  for (int n : {4, 5, 12, 13, 19, 20, 37, 396}) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, n);
    A = (A + A.transpose()).eval();
    const Eigen::VectorXd x = Eigen::VectorXd::Random(n);
    const Eigen::VectorXd scale = A.cwiseAbs() * x.cwiseAbs();
    for (Precision p : {Precision::double_, Precision::single}) {
      const PackedSymmetric P(A, p);
      Eigen::VectorXd y(n), z(n);
      P.multiply(x.data(), y.data());
      P.multiply_portable(x.data(), z.data());
      for (int i = 0; i < n; ++i) {
#ifdef NDEBUG
        EXPECT_EQ(y[i], z[i]) << "n " << n << " row " << i;
#else
        EXPECT_NEAR(y[i], z[i], 1e-14 * scale[i]) << "n " << n << " row " << i;
#endif
      }
    }
  }
}

namespace {

struct Dense {
  Eigen::MatrixXd B, C;
};

Dense dense_constraints(const Decomposition& dec, bool gluing_only) {
  const auto model = make_builtin_model(dec.options());
  const auto d = test::dense_constraints(*model, gluing_only);
  return {d.B, d.C};
}

}  // namespace

class Constraints : public ::testing::TestWithParam<std::tuple<int, int, int, Glue, ProblemKind>> {
};

TEST_P(Constraints, OrthonormalRowsAndTheRightKernel) {
  const auto [n, ns, m, glue, problem] = GetParam();
  Decomposition dec({problem, ElementKind::q1, n, ns, m, glue});
  const Dense all = dense_constraints(dec, false);
  const int rows = static_cast<int>(all.B.rows());
  EXPECT_LT((all.B * all.B.transpose() - Eigen::MatrixXd::Identity(rows, rows)).norm(), 1e-13);
  // Rows of B~ lie in Ker C (they are rows of B Z in the cluster variables): B~ C' = 0.
  if (all.C.rows() > 0) EXPECT_LT((all.B * all.C.transpose()).norm(), 1e-13);
  // Ker [B~_gluing; C] is exactly the continuous functions: one dimension per global node.
  const Dense glue_only = dense_constraints(dec, true);
  Eigen::MatrixXd stacked(glue_only.B.rows() + glue_only.C.rows(), glue_only.B.cols());
  stacked << glue_only.B, glue_only.C;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(stacked);
  const int global_nodes = dec.squares() * (n + 1) * (n + 1);
  EXPECT_EQ(stacked.cols() - lu.rank(), global_nodes);
}

INSTANTIATE_TEST_SUITE_P(
    AllGlues, Constraints,
    ::testing::Values(std::make_tuple(4, 2, 1, Glue::averages, ProblemKind::poisson2d),
                      std::make_tuple(6, 3, 1, Glue::averages, ProblemKind::membranes),
                      std::make_tuple(8, 4, 2, Glue::averages, ProblemKind::membranes),
                      std::make_tuple(8, 4, 2, Glue::corners, ProblemKind::membranes),
                      std::make_tuple(8, 4, 2, Glue::corners_averages, ProblemKind::poisson2d),
                      std::make_tuple(12, 4, 4, Glue::averages, ProblemKind::poisson2d),
                      std::make_tuple(12, 4, 4, Glue::corners, ProblemKind::membranes_coercive)));

// The sparse complement of an interface object's kernel: orthonormal rows, orthogonal to W,
// p dpn - rank W of them, O(p log p) nonzeros; Laplace constants on an edge, plane-strain rigid
// body motions on an edge, 3D rigid body motions on a face, on a curved face and on scattered
// points with a collinear subset.
class HierarchicalComplement : public ::testing::TestWithParam<std::tuple<PhysicsKind, int, int>> {
};

TEST_P(HierarchicalComplement, OrthonormalComplementOfTheObjectKernel) {
  const auto [kind, dim, shape] = GetParam();
  std::vector<double> xyz;
  if (shape == 0)  // a straight edge of 98 nodes (Table 3's edges at H_s/h = 99)
    for (int i = 0; i < 98; ++i) xyz.insert(xyz.end(), {0.25 * i, 1.0, 0.0});
  else if (shape == 1)  // a 9 x 9 face
    for (int j = 0; j < 9; ++j)
      for (int i = 0; i < 9; ++i) xyz.insert(xyz.end(), {1.0 * i, 2.0 * j, 5.0});
  else if (shape == 2)  // a curved 7 x 11 face
    for (int j = 0; j < 11; ++j)
      for (int i = 0; i < 7; ++i)
        xyz.insert(xyz.end(), {std::cos(0.1 * i), std::sin(0.1 * i), 0.3 * j});
  else {  // scattered points, 5 of them on one line
    for (int i = 0; i < 5; ++i) xyz.insert(xyz.end(), {1.0 * i, 0.0, 0.0});
    for (int i = 0; i < 40; ++i)
      xyz.insert(xyz.end(), {std::sin(1.3 * i), std::cos(2.1 * i), std::sin(0.7 * i + 1)});
  }
  const int p = static_cast<int>(xyz.size() / 3);
  Physics ph;
  ph.kind = kind;
  ph.dim = dim;
  const int dpn = ph.dofs_per_node();
  const Eigen::MatrixXd W = orthonormal_columns(physics_kernel(ph, xyz.data(), p));
  const SparseRows rows = hierarchical_complement(W, xyz.data(), p, dpn);
  const int m = p * dpn;
  ASSERT_EQ(static_cast<int>(rows.size()), m - W.cols());
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(static_cast<int>(rows.size()), m);
  long nnz = 0;
  for (size_t r = 0; r < rows.size(); ++r)
    for (const auto& [j, v] : rows[r]) B(static_cast<int>(r), j) += v, ++nnz;
  EXPECT_LT((B * B.transpose() - Eigen::MatrixXd::Identity(B.rows(), B.rows())).norm(), 1e-13);
  EXPECT_LT((B * W).norm(), 1e-13);
  // Far below the dense m (m - rank W), about m (dpn 2^d-ish leaf work + rank W log2 p).
  const double bound = m * (4.0 * dpn + W.cols() * (1 + std::log2(p)));
  EXPECT_LT(nnz, bound) << "dense: " << m * (m - W.cols());
  std::printf("  object of %d nodes x %d dofs: %zu rows, %ld nonzeros (dense: %ld)\n", p, dpn,
              rows.size(), nnz, static_cast<long>(rows.size()) * m);
}

INSTANTIATE_TEST_SUITE_P(Objects, HierarchicalComplement,
                         ::testing::Values(std::make_tuple(PhysicsKind::laplace, 2, 0),
                                           std::make_tuple(PhysicsKind::elasticity, 2, 0),
                                           std::make_tuple(PhysicsKind::laplace, 3, 1),
                                           std::make_tuple(PhysicsKind::elasticity, 3, 1),
                                           std::make_tuple(PhysicsKind::elasticity, 3, 2),
                                           std::make_tuple(PhysicsKind::elasticity, 3, 3)));

TEST(ObjectRowCache, GivesTheRowsOfHierarchicalComplementOncePerDistinctObject) {
  // Two 5 x 4 faces of a box at different places (the same kernel W in the box's frame, the same
  // tree), and a face of other proportions: the cache computes the first and the third and hands
  // the first's rows to the second, each equal to hierarchical_complement's bit for bit.
  Physics ph;
  ph.kind = PhysicsKind::elasticity;
  ph.dim = 3;
  const int dpn = ph.dofs_per_node();
  auto face = [](double x0, double y0, int nx, int ny) {
    std::vector<double> xyz;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) xyz.insert(xyz.end(), {x0 + 0.5 * i, y0 + 0.5 * j, 3.0});
    return xyz;
  };
  const std::vector<double> a = face(0, 0, 5, 4), b = face(8, 2, 5, 4), c = face(0, 0, 4, 5);
  std::vector<double> frame = face(0, 0, 5, 4);  // the box's frame: offsets from the first node
  const Eigen::MatrixXd W = orthonormal_columns(physics_kernel(ph, frame.data(), 20));
  const Eigen::MatrixXd Wc = orthonormal_columns(physics_kernel(ph, c.data(), 20));
  ObjectRowCache cache;
  const auto ra = cache.rows(W, a.data(), 20, dpn);
  const auto rb = cache.rows(W, b.data(), 20, dpn);
  const auto rc = cache.rows(Wc, c.data(), 20, dpn);
  EXPECT_EQ(cache.reuses(), 1);
  EXPECT_EQ(ra.get(), rb.get());
  EXPECT_NE(ra.get(), rc.get());
  EXPECT_EQ(*ra, hierarchical_complement(W, a.data(), 20, dpn));
  EXPECT_EQ(*rb, hierarchical_complement(W, b.data(), 20, dpn));
  EXPECT_EQ(*rc, hierarchical_complement(Wc, c.data(), 20, dpn));
  EXPECT_EQ(static_cast<int>(ra->size()), 20 * dpn - 6);
}

class ClusterInverse : public ::testing::TestWithParam<std::tuple<int, int, Glue>> {};

TEST_P(ClusterInverse, IsAGeneralizedInverseOfTheClusterStiffness) {
  // K~ = Z' K Z with Z an orthonormal basis of Ker C; the cluster solve returns Z K~^+ Z' x.
  const auto [H, m, glue] = GetParam();
  Decomposition dec({ProblemKind::poisson2d, ElementKind::q1, H * m, m, m, glue});
  const auto model = make_builtin_model(dec.options());
  const FetiLayout layout = model->layout();
  std::vector<SubdomainInput> inputs;
  std::vector<const SubdomainInput*> members;
  for (int s = 0; s < m * m; ++s) inputs.push_back(model->input(s));
  for (const auto& in : inputs) members.push_back(&in);
  const auto rows = cluster_primal_constraints(layout, 0, members);
  std::vector<std::unique_ptr<Subdomain>> subs;
  std::vector<Subdomain*> ptrs;
  for (int s = 0; s < m * m; ++s) {
    subs.push_back(std::make_unique<Subdomain>(inputs[s].system));
    ptrs.push_back(subs.back().get());
  }
  Cluster cluster(0, ptrs, rows, Ordering::amd);
  const int per = static_cast<int>(dec.nodes_per_subdomain()), N = m * m * per;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(N, N), C;
  for (int s = 0; s < m * m; ++s)
    K.block(s * per, s * per, per, per) = Eigen::MatrixXd(subs[s]->K());
  C = Eigen::MatrixXd::Zero(static_cast<int>(rows.size()), N);
  for (size_t r = 0; r < rows.size(); ++r)
    for (const auto& e : rows[r]) C(static_cast<int>(r), e.member * per + e.dof) += e.value;
  // Z: orthonormal basis of Ker C from the SVD.
  Eigen::MatrixXd Z = Eigen::MatrixXd::Identity(N, N);
  if (C.rows() > 0) {
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(C, Eigen::ComputeFullV);
    const int rank = static_cast<int>((svd.singularValues().array() > 1e-10).count());
    Z = svd.matrixV().rightCols(N - rank);
  }
  const Eigen::MatrixXd Kt = Z.transpose() * K * Z;
  // A = cluster solve applied to K Z (columns), then K~ K~^+ K~ = Z' K (A K Z).
  Eigen::MatrixXd AKZ(N, Z.cols());
  std::vector<Eigen::VectorXd> x(m * m);
  for (int j = 0; j < Z.cols(); ++j) {
    const Eigen::VectorXd kz = K * Z.col(j);
    for (int s = 0; s < m * m; ++s) x[s] = kz.segment(s * per, per);
    cluster.solve(x);
    for (int s = 0; s < m * m; ++s) AKZ.col(j).segment(s * per, per) = x[s];
  }
  EXPECT_LT((Z.transpose() * K * AKZ - Kt).norm(), 1e-10 * Kt.norm());
  // The result satisfies the primal constraints, and the cluster kernel is the constant.
  EXPECT_LT((C * AKZ).norm(), 1e-10 * AKZ.norm());
  ASSERT_EQ(cluster.kernel_dimension(), 1);
  Eigen::VectorXd R(N);
  for (int s = 0; s < m * m; ++s)
    for (int k = 0; k < per; ++k) R[s * per + k] = cluster.kernel_entry(s, k, 0);
  EXPECT_NEAR(R.norm(), 1.0, 1e-14);
  EXPECT_LT((Kt * (Z.transpose() * R)).norm(), 1e-12);
  EXPECT_LT((Z * (Z.transpose() * R) - R).norm(), 1e-12);  // R~ lies in the cluster space
  // The kernel of K~ is one-dimensional: the subdomains are really joined.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Kt);
  EXPECT_LT(std::abs(eig.eigenvalues()[0]), 1e-10);
  EXPECT_GT(eig.eigenvalues()[1], 1e-6);
  // The cluster's dual operator knows its sizes (no rows of B~ here: 0 multipliers each) and
  // refuses vectors of other sizes.
  std::vector<Eigen::VectorXd> lam(m * m, Eigen::VectorXd(0)), out(m * m, Eigen::VectorXd(0));
  EXPECT_NO_THROW(cluster.apply_dual(lam, out));
  lam[0] = Eigen::VectorXd::Zero(1);
  EXPECT_THROW(cluster.apply_dual(lam, out), std::logic_error);
  lam.pop_back();
  EXPECT_THROW(cluster.apply_dual(lam, out), std::logic_error);
}

INSTANTIATE_TEST_SUITE_P(AllGlues, ClusterInverse,
                         ::testing::Values(std::make_tuple(4, 1, Glue::averages),
                                           std::make_tuple(4, 2, Glue::averages),
                                           std::make_tuple(3, 2, Glue::corners),
                                           std::make_tuple(4, 2, Glue::corners_averages),
                                           std::make_tuple(3, 3, Glue::averages),
                                           std::make_tuple(2, 3, Glue::corners)));

TEST(Decomposition, BadSizesAreClearErrors) {
  auto make = [](int n, int ns, int m, Glue g) {
    return Decomposition({ProblemKind::poisson2d, ElementKind::q1, n, ns, m, g});
  };
  EXPECT_THROW(make(10, 3, 1, Glue::averages), std::invalid_argument);
  EXPECT_THROW(make(12, 4, 3, Glue::averages), std::invalid_argument);
  EXPECT_THROW(make(0, 1, 1, Glue::averages), std::invalid_argument);
  EXPECT_THROW(make(8, 8, 2, Glue::averages),
               std::invalid_argument);  // H = 1: empty edge interiors
  EXPECT_THROW(parse_problem("plate"), std::invalid_argument);
  EXPECT_THROW(parse_glue("faces"), std::invalid_argument);
}

TEST(Decomposition, ClusterMajorNumberingRoundTrips) {
  Decomposition dec({ProblemKind::membranes, ElementKind::q1, 24, 6, 3, Glue::averages});
  for (int s = 0; s < dec.num_subdomains(); ++s) {
    const auto p = dec.position(s);
    EXPECT_EQ(dec.subdomain_id(p.q, p.sx, p.sy), s);
  }
  for (int P : {1, 2, 3, 5}) {
    int covered = 0;
    for (int r = 0; r < P; ++r) {
      const auto [a, b] = dec.cluster_range(r, P);
      for (int c = a; c < b; ++c) EXPECT_EQ(dec.rank_of_cluster(c, P), r);
      covered += b - a;
    }
    EXPECT_EQ(covered, dec.num_clusters());
  }
}

// The single-precision copy of a factor (SparseCholesky::make_single): solve_single is the exact
// solve with the rounded factor L_s, so on a well-conditioned matrix its residual is of the order
// of single precision (not of double: the copy is read), its result agrees with solve() to that
// order, and holders of a factor shared through the numeric cache share one copy.
namespace {
// The 7-point stencil on an n^3 grid with diagonal `diagonal` + 0.01 (i % 7): positive definite
// for diagonal > 6.
Eigen::SparseMatrix<double> grid_matrix(int n, double diagonal) {
  std::vector<Eigen::Triplet<double>> t;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int i = (z * n + y) * n + x;
        t.emplace_back(i, i, diagonal + 0.01 * (i % 7));
        if (x + 1 < n) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
        if (y + 1 < n) t.emplace_back(i, i + n, -1.0), t.emplace_back(i + n, i, -1.0);
        if (z + 1 < n) t.emplace_back(i, i + n * n, -1.0), t.emplace_back(i + n * n, i, -1.0);
      }
  Eigen::SparseMatrix<double> A(n * n * n, n * n * n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}
}  // namespace

TEST(SparseCholesky, SingleCopySolvesWithTheRoundedFactor) {
  const int N = 12 * 12 * 12;
  const Eigen::SparseMatrix<double> A = grid_matrix(12, 7.0);
  for (Ordering ordering : {Ordering::amd, Ordering::metis, Ordering::nesdis}) {
    SCOPED_TRACE(to_string(ordering));
    SparseCholesky chol(ordering);
    chol.factorize(A);
    EXPECT_FALSE(chol.has_single());
    chol.make_single();
    ASSERT_TRUE(chol.has_single());
    EXPECT_GT(chol.single_bytes(), 0);
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(N, -1.0, 2.0).array().sin();
    Eigen::VectorXd xd(N), xs(N);
    chol.solve(b.data(), xd.data());
    chol.solve_single(b.data(), xs.data());
    const double rd = (A * xd - b).norm() / b.norm(), rs = (A * xs - b).norm() / b.norm();
    EXPECT_LT(rd, 1e-14);
    EXPECT_LT(rs, 1e-6);   // single precision (cond(A) < 3.5 here)
    EXPECT_GT(rs, 1e-10);  // and not double: the copy is what was read
    EXPECT_LT((xs - xd).norm(), 1e-6 * xd.norm());
    Eigen::VectorXd inplace = b;  // b == x allowed
    chol.solve_single(inplace.data(), inplace.data());
    EXPECT_EQ((inplace - xs).cwiseAbs().maxCoeff(), 0.0);
    chol.factorize(A * 2.0);  // a new factorization drops the copy
    EXPECT_FALSE(chol.has_single());
  }
  // Holders of one factor shared through the numeric cache share its copy.
  SubdomainCache cache(64, 1e9);
  std::vector<SparseCholesky> f(3);
  for (auto& c : f) c.factorize(A, &cache);
  for (auto& c : f) c.make_single();
  EXPECT_EQ(f[1].single_data(), f[2].single_data());
  EXPECT_NE(f[1].single_data(), nullptr);
}

namespace {
Eigen::SparseMatrix<double> upper_of(const Eigen::SparseMatrix<double>& A) {
  Eigen::SparseMatrix<double> U = A.triangularView<Eigen::Upper>();
  U.makeCompressed();
  return U;
}
}  // namespace

// The single-precision copy alone (SparseCholesky::keep_single_only): the double values are
// freed and solve() refines the single-precision solve with A to a double solve's residual. The
// result agrees with the double factor's solve to round-off, solve_many gives each column as
// solve() does, and a factor shared through the numeric cache keeps its double values.
TEST(SparseCholesky, SingleCopyAloneSolvesAsTheDoubleFactor) {
  const int N = 12 * 12 * 12;
  const Eigen::SparseMatrix<double> A = grid_matrix(12, 6.001);  // cond(A) about 70
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(N, -1.0, 2.0).array().sin();
  SparseCholesky chol(Ordering::metis);
  chol.factorize(A);
  Eigen::VectorXd xd(N);
  chol.solve(b.data(), xd.data());
  EXPECT_FALSE(chol.keep_single_only(upper_of(A)));  // no single-precision copy yet
  chol.make_single();
  EXPECT_EQ(chol.refinement_bytes(), 0);
  ASSERT_TRUE(chol.keep_single_only(upper_of(A)));
  EXPECT_FALSE(chol.has_double());
  EXPECT_TRUE(chol.has_single());
  EXPECT_TRUE(chol.refines());
  EXPECT_GT(chol.refinement_bytes(), 0);
  Eigen::VectorXd x = b;
  chol.solve(x.data(), x.data());                          // in place
  EXPECT_LE((A * x - b).norm(), 2 * (A * xd - b).norm());  // as accurate as the double solve
  EXPECT_LT((x - xd).norm(), 1e-14 * xd.norm());
  const SparseCholesky::RefinementStats st = chol.refinement_stats();
  EXPECT_EQ(st.solves, 1);
  EXPECT_GE(st.steps, 1);
  EXPECT_FALSE(st.refactored);
  Eigen::MatrixXd X(N, 3);
  X.col(0) = b, X.col(1) = b.array().cos(), X.col(2) = -b;
  Eigen::MatrixXd Y = X;
  chol.solve_many(Y.data(), 3);
  for (int j = 0; j < 3; ++j) {
    Eigen::VectorXd y(N);
    chol.solve(X.col(j).data(), y.data());
    EXPECT_EQ((Y.col(j) - y).cwiseAbs().maxCoeff(), 0.0);
  }
  EXPECT_FALSE(chol.refinement_stats().refactored);
  // A factor shared through the numeric cache keeps its values and refines all the same: its
  // solves are those of the unshared factor, bit for bit.
  SubdomainCache cache(64, 1e9);
  std::vector<SparseCholesky> f(3);
  for (auto& c : f) c.factorize(A, &cache);
  ASSERT_TRUE(f[2].factor_shared());
  for (auto& c : f) {
    c.make_single();
    ASSERT_TRUE(c.keep_single_only(upper_of(A)));
  }
  EXPECT_TRUE(f[2].has_double());
  EXPECT_FALSE(f[0].has_double());  // (its own factor: analysed, not kept by the cache)
  Eigen::VectorXd xf(N), x0(N);
  f[2].solve(b.data(), xf.data());
  f[0].solve(b.data(), x0.data());
  EXPECT_EQ((xf - x0).cwiseAbs().maxCoeff(), 0.0);
  chol.factorize(A);  // a new factorization holds double values again
  EXPECT_TRUE(chol.has_double());
  EXPECT_FALSE(chol.refines());
}

// Where single precision is too coarse for the matrix (a free 1D Laplacian of 1,000 unknowns
// shifted by 1e-12: cond(A) about 4e12, far beyond the 1 / 6e-8 a rounded factor resolves),
// the refinement does not converge and the matrix is factored again in double: the solve is
// then the double factor's, bit for bit.
TEST(SparseCholesky, SingleCopyAloneFactorsAgainWhereRefinementFails) {
  const int N = 1000;
  const double shift = 1e-12;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < N; ++i) {
    t.emplace_back(i, i, (i == 0 || i + 1 == N ? 1.0 : 2.0) + shift);
    if (i + 1 < N) t.emplace_back(i, i + 1, -1.0), t.emplace_back(i + 1, i, -1.0);
  }
  Eigen::SparseMatrix<double> A(N, N);
  A.setFromTriplets(t.begin(), t.end());
  SparseCholesky chol(Ordering::amd);
  chol.factorize(A);
  chol.make_single();
  ASSERT_TRUE(chol.keep_single_only(upper_of(A)));
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(N, -1.0, 2.0).array().sin();
  Eigen::VectorXd x(N), xd(N);
  chol.solve(b.data(), x.data());
  EXPECT_TRUE(chol.refinement_stats().refactored);
  EXPECT_TRUE(chol.has_double());
  EXPECT_FALSE(chol.refines());
  SparseCholesky plain(Ordering::amd);
  plain.factorize(A);
  plain.solve(b.data(), xd.data());
  EXPECT_EQ((x - xd).cwiseAbs().maxCoeff(), 0.0);
}
