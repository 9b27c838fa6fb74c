#include "htfeti/spectrum.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "htfeti/model/decomposition.hpp"
#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/constraints.hpp"
#include "htfeti/parallel/memory.hpp"

extern "C" void dsyevd_(const char* jobz, const char* uplo, const int* n, double* a, const int* lda,
                        double* w, double* work, const int* lwork, int* iwork, const int* liwork,
                        int* info);

namespace htfeti {

namespace {

Eigen::VectorXd symmetric_eigenvalues(Eigen::MatrixXd A) {
  const int n = static_cast<int>(A.rows());
  Eigen::VectorXd w(n);
  int info = 0, lwork = -1, liwork = -1, iwq = 0;
  double wq = 0;
  dsyevd_("N", "U", &n, A.data(), &n, w.data(), &wq, &lwork, &iwq, &liwork, &info);
  lwork = static_cast<int>(wq);
  liwork = iwq;
  std::vector<double> work(lwork);
  std::vector<int> iwork(liwork);
  dsyevd_("N", "U", &n, A.data(), &n, w.data(), work.data(), &lwork, iwork.data(), &liwork, &info);
  if (info != 0) throw std::runtime_error("dsyevd failed");
  return w;  // ascending
}

// Smallest eigenvalue above the round-off zero of a matrix with a known 1-dimensional kernel.
double smallest_nonzero(const Eigen::VectorXd& w) { return w[1]; }

}  // namespace

ClusterSpectrum cluster_spectrum(int m, int n, ElementKind element) {
  if (m < 1 || n < 1) throw std::invalid_argument("--cluster-size and --elements must be positive");
  if (n % m != 0)
    throw std::invalid_argument("--elements " + std::to_string(n) + " is not divisible by " +
                                "--cluster-size " + std::to_string(m));
  const int H = n / m;
  if (H < 2) throw std::invalid_argument("need at least 2 elements per subdomain side");
  {
    // The subdomain stiffness is formed densely ((H+1)^2 rows and columns, a few copies):
    // refuse before allocating what cannot fit.
    const double rows = static_cast<double>(H + 1) * (H + 1);
    const double need_mb = 3.0 * 8.0 * rows * rows / 1048576.0, have_mb = available_memory_mb();
    if (have_mb > 0 && need_mb > have_mb)
      throw std::invalid_argument(
          "the dense subdomain matrices of H_s/h = " + std::to_string(H) + " need about " +
          std::to_string(static_cast<long long>(need_mb / 1024)) + " GB, more than the " +
          std::to_string(static_cast<long long>(have_mb / 1024)) +
          " GB available (use a larger --cluster-size or fewer --elements)");
  }
  ClusterSpectrum res;
  res.m = m;
  res.n = n;
  res.H_over_h = H;

  // One subdomain's Schur complement on its boundary nodes.
  Decomposition dec({ProblemKind::poisson2d, element, n, m, 1, Glue::averages});
  Physics laplace;
  const Eigen::MatrixXd K(assemble_stiffness(dec.grid().mesh(0), laplace));
  const int np = H + 1;
  std::vector<int> bnd, inner, bindex(np * np, -1);
  for (int k = 0; k < np * np; ++k) {
    const int a = k % np, b = k / np;
    if (a == 0 || b == 0 || a == H || b == H) {
      bindex[k] = static_cast<int>(bnd.size());
      bnd.push_back(k);
    } else {
      inner.push_back(k);
    }
  }
  const int nb = static_cast<int>(bnd.size()), ni = static_cast<int>(inner.size());
  Eigen::MatrixXd Kbb(nb, nb), Kbi(nb, ni), Kii(ni, ni);
  for (int r = 0; r < nb; ++r) {
    for (int c = 0; c < nb; ++c) Kbb(r, c) = K(bnd[r], bnd[c]);
    for (int c = 0; c < ni; ++c) Kbi(r, c) = K(bnd[r], inner[c]);
  }
  for (int r = 0; r < ni; ++r)
    for (int c = 0; c < ni; ++c) Kii(r, c) = K(inner[r], inner[c]);
  const Eigen::MatrixXd S = Kbb - Kbi * Kii.llt().solve(Kbi.transpose());
  const Eigen::VectorXd ws = symmetric_eigenvalues(S);
  res.subdomain_lambda_max = ws[nb - 1];
  res.subdomain_lambda_min = smallest_nonzero(ws);

  // Z: columns over the stacked boundary dofs of the m*m subdomains (cluster-local order).
  const int N = m * m * nb, p = H - 1;
  auto edge_dof = [&](int sub, int side, int t) {  // t-th interior node (t = 1..H-1) of an edge
    int a = 0, b = 0;
    switch (side) {
      case 0:
        a = t, b = 0;
        break;  // bottom
      case 1:
        a = H, b = t;
        break;  // right
      case 2:
        a = t, b = H;
        break;  // top
      case 3:
        a = 0, b = t;
        break;  // left
    }
    return sub * nb + bindex[b * np + a];
  };
  std::vector<Eigen::Triplet<double>> zt;
  int col = 0;
  const auto helmert = orthonormal_complement(std::vector<double>(p, 1.0));
  for (int sub = 0; sub < m * m; ++sub) {
    const int lx = sub % m, ly = sub / m;
    for (int a : {0, H})
      for (int b : {0, H}) zt.emplace_back(sub * nb + bindex[b * np + a], col++, 1.0);
    for (int side = 0; side < 4; ++side) {
      const bool shared = (side == 0 && ly > 0) || (side == 1 && lx < m - 1) ||
                          (side == 2 && ly < m - 1) || (side == 3 && lx > 0);
      if (!shared) {
        for (int t = 1; t < H; ++t) zt.emplace_back(edge_dof(sub, side, t), col++, 1.0);
        continue;
      }
      for (const auto& h : helmert) {  // own fluctuations
        for (int t = 1; t < H; ++t) zt.emplace_back(edge_dof(sub, side, t), col, h[t - 1]);
        ++col;
      }
      if (side == 1 || side == 2) {  // joint average, once per shared edge (from the lower side)
        const int nbr = side == 1 ? sub + 1 : sub + m, nside = side == 1 ? 3 : 0;
        const double v = 1.0 / std::sqrt(2.0 * p);
        for (int t = 1; t < H; ++t) {
          zt.emplace_back(edge_dof(sub, side, t), col, v);
          zt.emplace_back(edge_dof(nbr, nside, t), col, v);
        }
        ++col;
      }
    }
  }
  Eigen::SparseMatrix<double> Z(N, col);
  Z.setFromTriplets(zt.begin(), zt.end());
  // S~ = Z' diag(S) Z, block by block.
  Eigen::MatrixXd SZ = Eigen::MatrixXd::Zero(N, col);
  const Eigen::MatrixXd Zd(Z);
  for (int sub = 0; sub < m * m; ++sub)
    SZ.middleRows(sub * nb, nb).noalias() = S * Zd.middleRows(sub * nb, nb);
  const Eigen::MatrixXd St = Zd.transpose() * SZ;
  res.dimension = col;
  const Eigen::VectorXd w = symmetric_eigenvalues(St);
  res.lambda_max = w[col - 1];
  res.lambda_min = smallest_nonzero(w);
  const double ne = H - 1, ns = 4.0 * H, s = std::sin(M_PI / (2.0 * m));
  res.lambda_min_estimate = 2.0 * ne / ns * res.subdomain_lambda_min * s * s;
  return res;
}

}  // namespace htfeti
