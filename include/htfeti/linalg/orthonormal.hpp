// Small dense orthonormalization shared by the fem stage (subdomain kernels) and the FETI stage
// (kernels restricted to interface objects).
#pragma once

#include <Eigen/Dense>

namespace htfeti {

/// Orthonormal basis of the column space of A (modified Gram-Schmidt twice, columns dropped when
/// their remaining norm is below tol times their original norm). Deterministic.
inline Eigen::MatrixXd orthonormal_columns(const Eigen::MatrixXd& A, double tol = 1e-10) {
  Eigen::MatrixXd Q(A.rows(), A.cols());
  int r = 0;
  for (int j = 0; j < A.cols(); ++j) {
    Eigen::VectorXd v = A.col(j);
    const double n0 = v.norm();
    if (n0 == 0) continue;
    for (int pass = 0; pass < 2; ++pass)
      for (int i = 0; i < r; ++i) v -= Q.col(i).dot(v) * Q.col(i);
    const double n1 = v.norm();
    if (n1 <= tol * n0) continue;
    Q.col(r++) = v / n1;
  }
  return Q.leftCols(r);
}

}  // namespace htfeti
