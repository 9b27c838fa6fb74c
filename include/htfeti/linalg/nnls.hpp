// Nonnegative least squares, min ||M x - b|| subject to x >= 0, by the active-set method of
// Lawson and Hanson ("Solving Least Squares Problems", 1974, ch. 23): columns enter the passive
// set by the largest gradient entry and leave when an interpolation step reaches zero. For the
// small dense problems of the setup checks (M: k x n with k <= a few dozen rows, n up to the
// contact rows): each iteration solves a least-squares problem on at most k passive columns
// (QR, O(k^3)) and forms M^T r (O(k n)). Deterministic: ties are broken by the lower index.
#pragma once

#include <Eigen/Dense>

namespace htfeti {

struct NnlsResult {
  Eigen::VectorXd x;  ///< the minimizer, x >= 0
  Eigen::VectorXd r;  ///< the residual b - M x; M^T r <= tol at the solution (Farkas: if r != 0,
                      ///< then M^T r <= 0 and b^T r = ||r||^2 > 0)
  bool converged = false;
};

/// tol: the gradient M^T r below which a column does not enter (relative to ||M|| ||b||).
NnlsResult nnls(const Eigen::MatrixXd& M, const Eigen::VectorXd& b, double tol = 1e-12,
                int max_iterations = 0);

}  // namespace htfeti
