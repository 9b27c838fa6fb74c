#include "reference.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>
#include <stdexcept>

namespace htfeti {

ReferenceSolution solve_undecomposed(ProblemKind kind, ElementKind element, int n) {
  const Problem problem{kind};
  const int np = n + 1, per = np * np, N = problem.squares() * per;
  const double h = 1.0 / n;
  const auto ke = square_stiffness(element);
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(N);
  for (int q = 0; q < problem.squares(); ++q)
    for (int b = 0; b < n; ++b)
      for (int a = 0; a < n; ++a) {
        const int nodes[4] = {q * per + b * np + a, q * per + b * np + a + 1,
                              q * per + (b + 1) * np + a + 1, q * per + (b + 1) * np + a};
        const auto fe = square_load(problem, element, q + a * h, b * h, h);
        for (int i = 0; i < 4; ++i) {
          f[nodes[i]] += fe[i];
          for (int j = 0; j < 4; ++j) trip.emplace_back(nodes[i], nodes[j], ke[i][j]);
        }
      }
  Eigen::SparseMatrix<double> K(N, N);
  K.setFromTriplets(trip.begin(), trip.end());

  // Free (non-Dirichlet) nodes.
  std::vector<int> free_of(N, -1), node_of;
  for (int q = 0; q < problem.squares(); ++q)
    for (int gy = 0; gy <= n; ++gy)
      for (int gx = 0; gx <= n; ++gx)
        if (!problem.dirichlet(q, gx, gy, n)) {
          free_of[q * per + gy * np + gx] = static_cast<int>(node_of.size());
          node_of.push_back(q * per + gy * np + gx);
        }
  const int nf = static_cast<int>(node_of.size());
  std::vector<Eigen::Triplet<double>> tf;
  for (int col = 0; col < N; ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it)
      if (free_of[it.row()] >= 0 && free_of[col] >= 0)
        tf.emplace_back(free_of[it.row()], free_of[col], it.value());
  Eigen::VectorXd ff(nf);
  for (int i = 0; i < nf; ++i) ff[i] = f[node_of[i]];

  ReferenceSolution ref;
  Eigen::VectorXd uf;
  if (!problem.has_contact()) {
    Eigen::SparseMatrix<double> Kf(nf, nf);
    Kf.setFromTriplets(tf.begin(), tf.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kf);
    if (ldlt.info() != Eigen::Success) throw std::runtime_error("reference: factorization failed");
    uf = ldlt.solve(ff);
  } else {
    // Contact pairs: left node (0, n, j) and right node (1, 0, j); g_j = u_left - u_right <= 0.
    std::vector<int> left(np), right(np);
    for (int j = 0; j <= n; ++j) {
      left[j] = free_of[j * np + n];
      right[j] = free_of[per + j * np];
    }
    std::vector<char> active(np, 1), previous;
    Eigen::VectorXd lam = Eigen::VectorXd::Zero(np);
    for (int iter = 0; iter < 100; ++iter) {
      ref.active_set_iterations = iter + 1;
      std::vector<int> act;
      for (int j = 0; j <= n; ++j)
        if (active[j]) act.push_back(j);
      const int na = static_cast<int>(act.size());
      std::vector<Eigen::Triplet<double>> ts = tf;
      for (int r = 0; r < na; ++r) {
        const int j = act[r];
        ts.emplace_back(nf + r, left[j], 1.0);
        ts.emplace_back(nf + r, right[j], -1.0);
        ts.emplace_back(left[j], nf + r, 1.0);
        ts.emplace_back(right[j], nf + r, -1.0);
      }
      Eigen::SparseMatrix<double> S(nf + na, nf + na);
      S.setFromTriplets(ts.begin(), ts.end());
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nf + na);
      rhs.head(nf) = ff;
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
      lu.compute(S);
      if (lu.info() != Eigen::Success)
        throw std::runtime_error("reference: KKT system is singular");
      const Eigen::VectorXd sol = lu.solve(rhs);
      uf = sol.head(nf);
      lam.setZero();
      for (int r = 0; r < na; ++r) lam[act[r]] = sol[nf + r];
      previous = active;
      for (int j = 0; j <= n; ++j) active[j] = lam[j] + (uf[left[j]] - uf[right[j]]) > 0;
      if (active == previous) break;
    }
    for (int j = 0; j <= n; ++j) {
      ref.contact_y.push_back(static_cast<double>(j) / n);
      ref.u_left.push_back(uf[left[j]]);
      ref.u_right.push_back(uf[right[j]]);
      ref.multiplier.push_back(lam[j]);
    }
  }
  ref.u = Eigen::VectorXd::Zero(N);
  for (int i = 0; i < nf; ++i) ref.u[node_of[i]] = uf[i];
  ref.energy = 0.5 * ref.u.dot(K * ref.u) - f.dot(ref.u);
  return ref;
}

}  // namespace htfeti
