#include "htfeti/feti/preconditioner.hpp"

#include <algorithm>
#include <stdexcept>

#include "htfeti/parallel/fresh_pages.hpp"

extern "C" void dlauum_(const char* uplo, const int* n, double* a, const int* lda, int* info);

namespace htfeti {

PreconditionerKind parse_preconditioner(const std::string& name) {
  return parse_name(kPreconditionerNames, name, "preconditioner");
}

std::string to_string(PreconditionerKind value) { return name_of(kPreconditionerNames, value); }

Scaling parse_scaling(const std::string& name) {
  return parse_name(kScalingNames, name, "scaling");
}

std::string to_string(Scaling value) { return name_of(kScalingNames, value); }

LocalPreconditioner::LocalPreconditioner(const Eigen::SparseMatrix<double>& K,
                                         std::vector<int> interface, PreconditionerKind kind,
                                         bool dense, Ordering ordering,
                                         const Eigen::MatrixXd* kernel, SubdomainCache* cache)
    : interface_(std::move(interface)), kind_(kind) {
  if (kind == PreconditionerKind::none) throw std::logic_error("LocalPreconditioner: no kind");
  const int n = static_cast<int>(K.rows()), nb = size();
  std::vector<int> pos(n, -1);  // interface position (>= 0) or -(interior position) - 2
  for (int i = 0; i < nb; ++i) pos[interface_[i]] = i;
  int ni = 0;
  for (int d = 0; d < n; ++d)
    if (pos[d] < 0) pos[d] = -(ni++) - 2;
  // K_bb straight into its compressed columns (no list of triplets: its growth touched fresh
  // pages for every subdomain), in two passes over the interface columns: count, then fill.
  // Within a column the rows come in K's order; the interface positions follow it where the
  // interface is sorted (the caller's), else the column is sorted by insertion.
  double sigma = 0;
  {
    Eigen::Index nnz = 0;
    for (int pc = 0; pc < nb; ++pc)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, interface_[pc]); it; ++it)
        if (pos[it.row()] >= 0) ++nnz;
    resize_resident(Kbb_, nb, nb, nnz);  // (parallel/fresh_pages.hpp)
    int* outer = Kbb_.outerIndexPtr();
    int* inner = Kbb_.innerIndexPtr();
    double* value = Kbb_.valuePtr();
    Eigen::Index k = 0;
    outer[0] = 0;
    for (int pc = 0; pc < nb; ++pc) {
      const Eigen::Index first = k;
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, interface_[pc]); it; ++it) {
        const int pr = pos[it.row()];
        if (pr < 0) continue;
        Eigen::Index q = k++;
        for (; q > first && inner[q - 1] > pr; --q)
          inner[q] = inner[q - 1], value[q] = value[q - 1];
        inner[q] = pr, value[q] = it.value();
        if (pr == pc) sigma = std::max(sigma, it.value());
      }
      outer[pc + 1] = static_cast<int>(k);
    }
  }
  // Lumped needs K_bb only; the other kinds also K_ib and K_ii.
  const bool lumped = kind == PreconditionerKind::lumped || nb == 0;
  if (lumped) return;
  std::vector<Eigen::Triplet<double>> tib, tii;
  for (int col = 0; col < n; ++col) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it) {
      const int row = static_cast<int>(it.row());
      const int pr = pos[row], pc = pos[col];
      if (pr < 0 && pc >= 0) {
        tib.emplace_back(-pr - 2, pc, it.value());
      } else if (pr < 0 && pc < 0 && row <= col) {
        tii.emplace_back(-pr - 2, -pc - 2, it.value());  // upper triangle (CHOLMOD reads it)
      }
    }
  }
  if (kernel && kernel->cols() > 0) {  // Q: orthonormal basis of R restricted to the interface
    Eigen::MatrixXd Rb(nb, kernel->cols());
    for (int i = 0; i < nb; ++i) Rb.row(i) = kernel->row(interface_[i]);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Rb);
    qr.setThreshold(1e-10);
    const int rank = static_cast<int>(qr.rank());
    // The first `rank` columns of Q only: forming all of Q costs 8 n_b^2 bytes and about
    // 4 n_b^2 k flops per subdomain (80^3 cube, 512 METIS parts: the preconditioner's setup took
    // 50.1 core-s with all of Q, 14.2 with the columns; docs/performance.md).
    Q_ = qr.householderQ() * Eigen::MatrixXd::Identity(nb, rank);
    qwork_.resize(rank);
    tau_ = Kbb_.diagonal().mean();
  }
  if (dense) {
    // K + sigma I_b with the interface last: the trailing factor block gives S + sigma I.
    dense_ = true;
    Eigen::SparseMatrix<double> A = K;
    for (int d : interface_) A.coeffRef(d, d) += sigma;
    SparseCholesky chol;
    try {
      chol.factorize(A, interface_, cache);
    } catch (const std::runtime_error&) {
      throw std::runtime_error(
          "Dirichlet preconditioner: the interface does not restrain a subdomain (K_ii is "
          "singular); use --preconditioner lumped");
    }
    Eigen::MatrixXd L;
    std::vector<int> order;
    chol.schur_factor(L, order);
    // L L^T by LAPACK's dlauum (n_b^3 / 3 flops; a rank update with L as a full matrix costs
    // n_b^3): dlauum forms U U^T of an upper triangle U, here U = J L J (J reverses the order),
    // so that U U^T = J L L^T J.
    Eigen::MatrixXd U = L.reverse();
    int info = 0;
    if (nb > 0) dlauum_("U", &nb, U.data(), &nb, &info);
    if (info != 0) throw std::logic_error("Dirichlet preconditioner: dlauum failed");
    S_.resize(nb, nb);
    for (int b = 0; b < nb; ++b)
      for (int a = 0; a <= b; ++a) {
        const int i = pos[order[nb - 1 - a]], j = pos[order[nb - 1 - b]];
        S_(i, j) = S_(j, i) = U(a, b);
      }
    S_.diagonal().array() -= sigma;
    if (Q_.cols() > 0) S_.noalias() += tau_ * Q_ * Q_.transpose();
    Q_ = Eigen::MatrixXd();
    Kbb_ = Eigen::SparseMatrix<double>();
    return;
  }
  Kib_.resize(ni, nb);
  Kib_.setFromTriplets(tib.begin(), tib.end());
  if (ni > 0) {
    Eigen::SparseMatrix<double> Kii(ni, ni);
    Kii.setFromTriplets(tii.begin(), tii.end());
    Kii_ = SparseCholesky(ordering);
    try {
      Kii_.factorize(Kii, cache);
    } catch (const std::runtime_error&) {
      throw std::runtime_error(
          "Dirichlet preconditioner: the interface does not restrain a subdomain (K_ii is "
          "singular); use --preconditioner lumped");
    }
  }
  work_.resize(ni);
  // One solve here makes the factor's solve workspace (CHOLMOD's dense work arrays, kept between
  // solves), so that apply(), which runs in the dual problem's parallel loops, allocates
  // nothing from its first call on: an allocation failure happens in the setup, where it is
  // reported ("out of memory", exit 2), not inside a loop that cannot pass it on.
  if (ni > 0) {
    work_.setZero();
    Kii_.solve(work_.data(), work_.data());
  }
}

void LocalPreconditioner::apply(const double* x, double* y) {
  const int nb = size();
  Eigen::Map<const Eigen::VectorXd> xv(x, nb);
  Eigen::Map<Eigen::VectorXd> yv(y, nb);
  if (dense_) {
    yv.noalias() = S_.selfadjointView<Eigen::Lower>() * xv;
    return;
  }
  yv.noalias() = Kbb_ * xv;
  if (kind_ == PreconditionerKind::lumped) return;
  if (work_.size() > 0) {
    work_.noalias() = Kib_ * xv;
    Kii_.solve(work_.data(), work_.data());
    yv.noalias() -= Kib_.transpose() * work_;
  }
  if (Q_.cols() > 0) {
    qwork_.noalias() = Q_.transpose() * xv;
    yv.noalias() += tau_ * (Q_ * qwork_);
  }
}

long LocalPreconditioner::bytes() const {
  auto sparse = [](const Eigen::SparseMatrix<double>& A) {
    return static_cast<long>(A.nonZeros()) * 12 + 4 * static_cast<long>(A.outerSize() + 1);
  };
  long b =
      8 * static_cast<long>(S_.size() + Q_.size()) + sparse(Kbb_) + sparse(Kib_) + 8 * work_.size();
  if (!dense_ && work_.size() > 0) b += Kii_.factor_bytes();
  return b;
}

}  // namespace htfeti
