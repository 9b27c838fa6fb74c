#include "htfeti/feti/cluster.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "htfeti/feti/constraints.hpp"

namespace htfeti {

DualOperator parse_dual_operator(const std::string& name) {
  if (name == "implicit") return DualOperator::implicit;
  if (name == "explicit") return DualOperator::explicit_;
  if (name == "auto") return DualOperator::automatic;
  throw std::invalid_argument("unknown dual operator '" + name +
                              "' (expected implicit, explicit or auto)");
}

std::string to_string(DualOperator kind) {
  switch (kind) {
    case DualOperator::implicit:
      return "implicit";
    case DualOperator::explicit_:
      return "explicit";
    case DualOperator::automatic:
      return "auto";
  }
  return "?";
}

Cluster::Cluster(const Decomposition& dec, int id, std::vector<Subdomain*> subs, Ordering ordering,
                 std::vector<std::vector<Subdomain::BEntry>> b, std::vector<int> nmult,
                 bool explicit_F)
    : id_(id), subs_(std::move(subs)), b_(std::move(b)), explicit_(explicit_F) {
  const int s = static_cast<int>(subs_.size());
  long total = 0;
  if (explicit_)
    F_.resize(s), V_.resize(s);
  else
    xw_.resize(s);
  std::string error;
  // Parallel over the cluster's subdomains when the caller is not already parallel (few large
  // clusters per rank); nested inside a parallel loop over clusters this runs serially.
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    try {
      if (explicit_) {
        std::vector<int> dofs;
        for (const auto& e : b_[i]) dofs.push_back(e.dof);
        std::sort(dofs.begin(), dofs.end());
        dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
        subs_[i]->factorize_with_interface_last(dofs);
        F_[i] = subs_[i]->dual_block(b_[i], nmult[i]);
        V_[i] = Eigen::VectorXd::Zero(nmult[i]);
        for (const auto& e : b_[i]) V_[i][e.mult] += e.value * subs_[i]->kernel()[e.dof];
      } else {
        subs_[i]->factorize(ordering);
        xw_[i] = Eigen::VectorXd::Zero(subs_[i]->size());
      }
    } catch (const std::exception& e) {
#pragma omp critical
      error = e.what();
    }
  }
  if (!error.empty()) throw std::runtime_error(error);
  for (int i = 0; i < s; ++i) total += subs_[i]->size();
  kernel_value_ = 1.0 / std::sqrt(static_cast<double>(total));
  const auto rows = cluster_primal_constraints(dec, id);
  nc_ = static_cast<int>(rows.size());
  if (nc_ == 0) {
    rhs_.resize(0);
    sol_.resize(0);
    if (explicit_) b_ = {};  // the explicit blocks replace the rows of B~ here
    return;
  }

  const auto t0 = std::chrono::steady_clock::now();
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
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    W_[i] = Eigen::MatrixXd::Zero(subs_[i]->size(), static_cast<int>(cols.size()));
    for (const auto& e : c_of_sub_[i]) {
      const int col =
          static_cast<int>(std::lower_bound(cols.begin(), cols.end(), e.constraint) - cols.begin());
      W_[i](e.dof, col) += e.value;
    }
    for (int col = 0; col < W_[i].cols(); ++col)
      subs_[i]->apply_pinv(W_[i].col(col).data(), W_[i].col(col).data());
  }
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    // (C K^+ C^T)_{j, cols[col]} += C_i[j] . W_i[:, col]
    for (const auto& e : c_of_sub_[i])
      for (int col = 0; col < W_[i].cols(); ++col)
        S(e.constraint, cols[col]) += e.value * W_[i](e.dof, col);
    if (i > 0) {
      const Eigen::VectorXd& R = subs_[i]->kernel();
      for (const auto& e : c_of_sub_[i]) {
        S(e.constraint, nc_ + i - 1) -= e.value * R[e.dof];
        S(nc_ + i - 1, e.constraint) -= e.value * R[e.dof];
      }
    }
  }
  if (explicit_) {  // U_i = B_i W_i
    for (int i = 0; i < s; ++i) {
      U_.push_back(Eigen::MatrixXd::Zero(nmult[i], W_[i].cols()));
      for (const auto& e : b_[i]) U_[i].row(e.mult) += e.value * W_[i].row(e.dof);
    }
  }
  lu_.compute(S);
  if (explicit_) b_ = {};  // the explicit blocks replace the rows of B~ here
  setup_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double rcond = lu_.rcond();
  if (!(rcond > 1e-14))
    throw std::runtime_error("cluster " + std::to_string(id) +
                             ": the primal constraints do not remove the subdomain kernels "
                             "(singular cluster system)");
  rhs_.resize(dim);
  sol_.resize(dim);
}

void Cluster::release_factors() {
  for (auto* sd : subs_) {
    sd->release_factor();
    sd->release_matrix();
  }
}

void Cluster::refactor(Ordering ordering) {
  const int s = static_cast<int>(subs_.size());
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    subs_[i]->factorize(ordering);
    subs_[i]->release_matrix();
  }
}

long Cluster::explicit_doubles() const {
  long n = 0;
  for (const auto& f : F_) n += f.size();
  for (const auto& u : U_) n += u.size();
  for (const auto& v : V_) n += v.size();
  return n;
}

void Cluster::apply_dual(const std::vector<Eigen::VectorXd>& lam,
                         std::vector<Eigen::VectorXd>& out) {
  const int s = static_cast<int>(subs_.size());
  if (!explicit_) {
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
    for (int i = 0; i < s; ++i) {
      xw_[i].setZero();
      for (const auto& e : b_[i]) xw_[i][e.dof] += e.value * lam[i][e.mult];  // B_i^T lam_i
    }
    solve(xw_);  // K~^+ B~^T lam
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
    for (int i = 0; i < s; ++i) {
      out[i].setZero();
      for (const auto& e : b_[i]) out[i][e.mult] += e.value * xw_[i][e.dof];  // B_i x_i
    }
    return;
  }
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i)
    out[i].noalias() = F_[i].selfadjointView<Eigen::Lower>() * lam[i];  // the bottleneck
  if (nc_ == 0) return;
  rhs_.setZero();
  for (int i = 0; i < s; ++i) {  // fixed order
    const auto& cols = cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      rhs_[cols[col]] += U_[i].col(col).dot(lam[i]);    // C K^+ B^T lam
    if (i > 0) rhs_[nc_ + i - 1] = -V_[i].dot(lam[i]);  // -R'^T B^T lam
  }
  sol_.noalias() = lu_.solve(rhs_);
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      out[i].noalias() -= sol_[cols[col]] * U_[i].col(col);
    if (i > 0) out[i].noalias() += sol_[nc_ + i - 1] * V_[i];
  }
}

long Cluster::dense_doubles() const {
  long n = 0;
  for (const auto& w : W_) n += w.size();
  return n + lu_.matrixLU().size();
}

void Cluster::solve(std::vector<Eigen::VectorXd>& x) {
  const int s = static_cast<int>(subs_.size());
  if (nc_ == 0) {
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
    for (int i = 0; i < s; ++i) subs_[i]->apply_pinv(x[i].data(), x[i].data());
    return;
  }
  rhs_.setZero();
  for (int i = 1; i < s; ++i) rhs_[nc_ + i - 1] = -subs_[i]->kernel().dot(x[i]);
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) subs_[i]->apply_pinv(x[i].data(), x[i].data());  // x_i <- K_i^+ x_i
  for (int i = 0; i < s; ++i)  // C K^+ x, summed in a fixed order
    for (const auto& e : c_of_sub_[i]) rhs_[e.constraint] += e.value * x[i][e.dof];
  sol_.noalias() = lu_.solve(rhs_);
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      x[i].noalias() -= sol_[cols[col]] * W_[i].col(col);
    if (i > 0) x[i].noalias() += sol_[nc_ + i - 1] * subs_[i]->kernel();
  }
}

}  // namespace htfeti
