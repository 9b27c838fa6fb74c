#include "htfeti/qp/power_norm.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>

namespace htfeti::qp {

NormEstimate parse_norm_estimate(const std::string& name) {
  return parse_name(kNormEstimateNames, name, "norm estimate");
}

std::string to_string(NormEstimate value) { return name_of(kNormEstimateNames, value); }

double estimate_norm(Operator& A, const Vec& start, const Reducer& red, int max_iterations,
                     double rtol) {
  Vec x = start, y(start.size());
  double nx = red.norm(x), estimate = 0;
  if (nx == 0) return 0;
  x /= nx;
  for (int it = 0; it < max_iterations; ++it) {
    A.apply(x, y);
    const double rq = red.dot(x, y);  // Rayleigh quotient x'Ax, x of unit norm
    const double ny = red.norm(y);
    const bool done = it > 0 && std::abs(rq - estimate) <= rtol * rq;
    estimate = rq;
    if (ny == 0 || done) break;
    x = y / ny;
  }
  return estimate;
}

double estimate_norm_lanczos(Operator& A, const Vec& start, const Reducer& red, int max_iterations,
                             double rtol) {
  const double n0 = red.norm(start);
  if (n0 == 0) return 0;
  Vec q = start / n0, q_prev = Vec::Zero(start.size()), w(start.size());
  Eigen::VectorXd alpha(max_iterations), beta(max_iterations);
  double estimate = 0, b = 0;
  for (int k = 0; k < max_iterations; ++k) {
    A.apply(q, w);  // w = A q_k - beta_{k-1} q_{k-1} - alpha_k q_k
    alpha[k] = red.dot(q, w);
    w -= alpha[k] * q + b * q_prev;
    b = red.norm(w);
    beta[k] = b;
    // The largest eigenvalue of T_k (diagonal alpha_0..k, off-diagonal beta_0..k-1).
    double theta = alpha[0];
    if (k > 0) {
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
      es.computeFromTridiagonal(alpha.head(k + 1), beta.head(k), Eigen::EigenvaluesOnly);
      theta = es.eigenvalues().maxCoeff();
    }
    const bool done = k > 0 && std::abs(theta - estimate) <= rtol * theta;
    estimate = theta;
    // b = 0: the Krylov space is invariant, theta is exact on it.
    if (done || !(b > 1e-14 * std::abs(theta))) break;
    q_prev.swap(q);
    q = w / b;
  }
  return estimate;
}

}  // namespace htfeti::qp
