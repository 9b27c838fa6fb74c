#include "htfeti/feti/subdomain.hpp"

#include <stdexcept>
#include <vector>

namespace htfeti {

Subdomain::Subdomain(const Decomposition& dec, int id)
    : id_(id), pos_(dec.position(id)), H_(dec.H()), h_(1.0 / dec.n()) {
  const int np = H_ + 1, nn = np * np;
  ke_ = square_stiffness(dec.options().element);
  const Problem problem = dec.problem();
  f_ = Eigen::VectorXd::Zero(nn);
  for (int b = 0; b < H_; ++b)
    for (int a = 0; a < H_; ++a) {
      const int n0 = b * np + a, nodes[4] = {n0, n0 + 1, n0 + np + 1, n0 + np};
      const double x0 = pos_.q + (pos_.sx * H_ + a) * h_, y0 = (pos_.sy * H_ + b) * h_;
      const auto fe = square_load(problem, dec.options().element, x0, y0, h_);
      for (int i = 0; i < 4; ++i) f_[nodes[i]] += fe[i];
    }
  assemble();
  R_ = Eigen::VectorXd::Constant(nn, 1.0 / std::sqrt(static_cast<double>(nn)));
  fixed_ = dec.local_node(H_ / 2, H_ / 2);
}

void Subdomain::assemble() {
  const int np = H_ + 1, nn = np * np;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(16 * H_ * H_);
  for (int b = 0; b < H_; ++b)
    for (int a = 0; a < H_; ++a) {
      const int n0 = b * np + a, nodes[4] = {n0, n0 + 1, n0 + np + 1, n0 + np};
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          if (ke_[i][j] != 0.0) trip.emplace_back(nodes[i], nodes[j], ke_[i][j]);
    }
  K_.resize(nn, nn);
  K_.setFromTriplets(trip.begin(), trip.end());
}

void Subdomain::release_factor() {
  chol_ = SparseCholesky();
  work_ = Eigen::VectorXd();
}

double Subdomain::energy(const Eigen::VectorXd& u) const {
  const int np = H_ + 1;
  double q = 0;
  for (int b = 0; b < H_; ++b)
    for (int a = 0; a < H_; ++a) {
      const int n0 = b * np + a;
      const double ue[4] = {u[n0], u[n0 + 1], u[n0 + np + 1], u[n0 + np]};
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) q += 0.5 * ue[i] * ke_[i][j] * ue[j];
    }
  return q - f_.dot(u);
}

double Subdomain::x_of(int k) const { return pos_.q + (pos_.sx * H_ + k % (H_ + 1)) * h_; }
double Subdomain::y_of(int k) const { return (pos_.sy * H_ + k / (H_ + 1)) * h_; }

void Subdomain::factorize(Ordering ordering) { factorize_impl(ordering, nullptr); }

void Subdomain::factorize_with_interface_last(const std::vector<int>& interface_dofs) {
  factorize_impl(Ordering::amd, &interface_dofs);
}

Eigen::MatrixXd Subdomain::dual_block(const std::vector<BEntry>& b, int nmult) const {
  Eigen::MatrixXd L;
  std::vector<int> order;
  chol_.schur_factor(L, order);
  std::vector<int> pos(size(), -1);
  for (size_t i = 0; i < order.size(); ++i)
    pos[order[i] + (order[i] >= fixed_)] = static_cast<int>(i);
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(L.rows(), nmult);  // B_i^T on the interface
  for (const auto& e : b) {
    if (pos[e.dof] < 0)
      throw std::logic_error("dual_block: a row of B touches a non-interface dof");
    T(pos[e.dof], e.mult) += e.value;
  }
  L.triangularView<Eigen::Lower>().solveInPlace(T);  // T = L_s^{-1} B_i^T
  Eigen::MatrixXd F(nmult, nmult);
  F.setZero();
  F.selfadjointView<Eigen::Lower>().rankUpdate(T.transpose());  // F = T^T T (lower half)
  return F.selfadjointView<Eigen::Lower>();
}

void Subdomain::factorize_impl(Ordering ordering, const std::vector<int>* interface_dofs) {
  const int nn = size();
  if (K_.rows() != nn) assemble();  // released earlier
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
  if (interface_dofs) {
    std::vector<int> last;
    for (int d : *interface_dofs) {
      if (d == fixed_) throw std::logic_error("the fixed node lies on the interface");
      last.push_back(d - (d > fixed_));
    }
    chol_.factorize(Krr, last);
  } else {
    chol_.factorize(Krr);
  }
  factor_nonzeros_ = chol_.factor_nonzeros();
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
