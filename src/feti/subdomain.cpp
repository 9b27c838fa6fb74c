#include "htfeti/feti/subdomain.hpp"

#include <vector>

namespace htfeti {

Subdomain::Subdomain(const Decomposition& dec, int id)
    : id_(id), pos_(dec.position(id)), H_(dec.H()), h_(1.0 / dec.n()) {
  const int np = H_ + 1, nn = np * np;
  const auto ke = square_stiffness(dec.options().element);
  const Problem problem = dec.problem();
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(16 * H_ * H_);
  f_ = Eigen::VectorXd::Zero(nn);
  for (int b = 0; b < H_; ++b)
    for (int a = 0; a < H_; ++a) {
      const int nodes[4] = {dec.local_node(a, b), dec.local_node(a + 1, b),
                            dec.local_node(a + 1, b + 1), dec.local_node(a, b + 1)};
      const double x0 = pos_.q + (pos_.sx * H_ + a) * h_, y0 = (pos_.sy * H_ + b) * h_;
      const auto fe = square_load(problem, dec.options().element, x0, y0, h_);
      for (int i = 0; i < 4; ++i) {
        f_[nodes[i]] += fe[i];
        for (int j = 0; j < 4; ++j)
          if (ke[i][j] != 0.0) trip.emplace_back(nodes[i], nodes[j], ke[i][j]);
      }
    }
  K_.resize(nn, nn);
  K_.setFromTriplets(trip.begin(), trip.end());
  R_ = Eigen::VectorXd::Constant(nn, 1.0 / std::sqrt(static_cast<double>(nn)));
  fixed_ = dec.local_node(H_ / 2, H_ / 2);
}

double Subdomain::x_of(int k) const { return pos_.q + (pos_.sx * H_ + k % (H_ + 1)) * h_; }
double Subdomain::y_of(int k) const { return (pos_.sy * H_ + k / (H_ + 1)) * h_; }

void Subdomain::factorize(Ordering ordering) {
  const int nn = size();
  // K_rr: drop the fixed node's row and column (indices above it shift down by one).
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(K_.nonZeros());
  for (int col = 0; col < nn; ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K_, col); it; ++it) {
      const int row = static_cast<int>(it.row());
      if (row == fixed_ || col == fixed_ || row > col) continue;
      trip.emplace_back(row - (row > fixed_), col - (col > fixed_), it.value());
    }
  Eigen::SparseMatrix<double> Krr(nn - 1, nn - 1);
  Krr.setFromTriplets(trip.begin(), trip.end());
  chol_ = SparseCholesky(ordering);
  chol_.factorize(Krr);
  work_.resize(nn - 1);
}

void Subdomain::apply_pinv(const double* x, double* y) {
  const int nn = size();
  double* w = work_.data();
  for (int k = 0, r = 0; k < nn; ++k)
    if (k != fixed_) w[r++] = x[k];
  chol_.solve(w, w);
  for (int k = nn - 1, r = nn - 2; k >= 0; --k) y[k] = (k == fixed_) ? 0.0 : w[r--];
}

}  // namespace htfeti
