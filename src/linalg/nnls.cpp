#include "htfeti/linalg/nnls.hpp"

#include <vector>

namespace htfeti {

NnlsResult nnls(const Eigen::MatrixXd& M, const Eigen::VectorXd& b, double tol,
                int max_iterations) {
  const Eigen::Index n = M.cols();
  if (max_iterations <= 0) max_iterations = static_cast<int>(3 * n + 30);
  NnlsResult res;
  res.x = Eigen::VectorXd::Zero(n);
  res.r = b;
  const double scale = std::max(M.norm() * b.norm(), 1e-300);
  std::vector<char> passive(n, 0);
  Eigen::VectorXd w = M.transpose() * res.r;
  const auto solve_passive = [&](Eigen::VectorXd& z) {
    std::vector<Eigen::Index> cols;
    for (Eigen::Index j = 0; j < n; ++j)
      if (passive[j]) cols.push_back(j);
    Eigen::MatrixXd Mp(M.rows(), static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) Mp.col(static_cast<Eigen::Index>(c)) = M.col(cols[c]);
    const Eigen::VectorXd zp = Mp.colPivHouseholderQr().solve(b);
    z.setZero(n);
    for (size_t c = 0; c < cols.size(); ++c) z[cols[c]] = zp[static_cast<Eigen::Index>(c)];
  };
  Eigen::VectorXd z(n);
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::Index enter = -1;
    for (Eigen::Index j = 0; j < n; ++j)
      if (!passive[j] && w[j] > tol * scale && (enter < 0 || w[j] > w[enter])) enter = j;
    if (enter < 0) {
      res.converged = true;
      return res;
    }
    passive[enter] = 1;
    for (int inner = 0; inner <= n; ++inner) {
      solve_passive(z);
      bool positive = true;
      for (Eigen::Index j = 0; j < n; ++j)
        if (passive[j] && z[j] <= 0) positive = false;
      if (positive) break;
      double alpha = 1.0;
      for (Eigen::Index j = 0; j < n; ++j)
        if (passive[j] && z[j] <= 0) alpha = std::min(alpha, res.x[j] / (res.x[j] - z[j]));
      res.x += alpha * (z - res.x);
      for (Eigen::Index j = 0; j < n; ++j)
        if (passive[j] && res.x[j] <= 0) passive[j] = 0, res.x[j] = 0;
    }
    for (Eigen::Index j = 0; j < n; ++j) res.x[j] = passive[j] ? z[j] : 0.0;
    res.r = b - M * res.x;
    w = M.transpose() * res.r;
  }
  return res;
}

}  // namespace htfeti
