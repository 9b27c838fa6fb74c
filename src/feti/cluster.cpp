#include "htfeti/feti/cluster.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "htfeti/feti/constraints.hpp"

namespace htfeti {

Cluster::Cluster(const Decomposition& dec, int id, std::vector<Subdomain*> subs, Ordering ordering)
    : id_(id), subs_(std::move(subs)) {
  const int s = static_cast<int>(subs_.size());
  long total = 0;
  for (auto* sd : subs_) {
    sd->factorize(ordering);
    total += sd->size();
  }
  kernel_value_ = 1.0 / std::sqrt(static_cast<double>(total));
  const auto rows = cluster_primal_constraints(dec, id);
  nc_ = static_cast<int>(rows.size());
  if (nc_ == 0) return;

  const int first = subs_.front()->id();
  c_of_sub_.assign(s, {});
  cols_of_sub_.assign(s, {});
  for (int j = 0; j < nc_; ++j)
    for (const auto& e : rows[j]) {
      const int i = e.subdomain - first;
      c_of_sub_[i].push_back({j, e.dof, e.value});
      if (cols_of_sub_[i].empty() || cols_of_sub_[i].back() != j) cols_of_sub_[i].push_back(j);
    }
  // W_i = K_i^+ C_i^T, and the dense saddle-point matrix.
  const int dim = nc_ + s - 1;
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(dim, dim);
  W_.resize(s);
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    const int n = subs_[i]->size();
    W_[i] = Eigen::MatrixXd::Zero(n, static_cast<int>(cols.size()));
    for (const auto& e : c_of_sub_[i]) {
      const int col = static_cast<int>(std::lower_bound(cols.begin(), cols.end(), e.constraint) -
                                       cols.begin());
      W_[i](e.dof, col) += e.value;
    }
    for (int col = 0; col < W_[i].cols(); ++col) subs_[i]->apply_pinv(W_[i].col(col).data(),
                                                                        W_[i].col(col).data());
    // (C K^+ C^T)_{j, cols[col]} += C_i[j] . W_i[:, col]
    for (const auto& e : c_of_sub_[i])
      for (int col = 0; col < W_[i].cols(); ++col) S(e.constraint, cols[col]) += e.value * W_[i](e.dof, col);
    if (i > 0) {
      const Eigen::VectorXd& R = subs_[i]->kernel();
      for (const auto& e : c_of_sub_[i]) {
        S(e.constraint, nc_ + i - 1) -= e.value * R[e.dof];
        S(nc_ + i - 1, e.constraint) -= e.value * R[e.dof];
      }
    }
  }
  lu_.compute(S);
  const double rcond = lu_.rcond();
  if (!(rcond > 1e-14))
    throw std::runtime_error("cluster " + std::to_string(id) +
                             ": the primal constraints do not remove the subdomain kernels "
                             "(singular cluster system)");
  rhs_.resize(dim);
  sol_.resize(dim);
}

long Cluster::dense_doubles() const {
  long n = 0;
  for (const auto& w : W_) n += w.size();
  return n + lu_.matrixLU().size();
}

void Cluster::solve(std::vector<Eigen::VectorXd>& x) {
  const int s = static_cast<int>(subs_.size());
  if (nc_ == 0) {
    for (int i = 0; i < s; ++i) subs_[i]->apply_pinv(x[i].data(), x[i].data());
    return;
  }
  rhs_.setZero();
  for (int i = 1; i < s; ++i) rhs_[nc_ + i - 1] = -subs_[i]->kernel().dot(x[i]);
  for (int i = 0; i < s; ++i) {
    subs_[i]->apply_pinv(x[i].data(), x[i].data());  // x_i <- K_i^+ x_i
    for (const auto& e : c_of_sub_[i]) rhs_[e.constraint] += e.value * x[i][e.dof];
  }
  sol_.noalias() = lu_.solve(rhs_);
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      x[i].noalias() -= sol_[cols[col]] * W_[i].col(col);
    if (i > 0) x[i].noalias() += sol_[nc_ + i - 1] * subs_[i]->kernel();
  }
}

}  // namespace htfeti
