#include "htfeti/feti/subdomain.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>

#include "htfeti/clock.hpp"

namespace htfeti {

namespace {
// Moves a SubdomainSystem without copying K (Eigen's SparseMatrix copies on "move").
SubdomainSystem take(SubdomainSystem& s) {
  Eigen::SparseMatrix<double> K;
  K.swap(s.K);
  SubdomainSystem out = std::move(s);
  out.K.swap(K);
  return out;
}
}  // namespace

Subdomain::Subdomain(SubdomainSystem system,
                     std::shared_ptr<const Eigen::SparseMatrix<double>> pooled)
    : sys_(take(system)), shared_K_(std::move(pooled)) {
  const int n = size();
  if (shared_K_ && (shared_K_->rows() != n || sys_.K.size() != 0))
    throw std::logic_error("Subdomain: the pooled K and f sizes differ, or K was given twice");
  if (K().rows() != n && !sys_.assemble) throw std::logic_error("Subdomain: K and f sizes differ");
  if (sys_.R.rows() != n) throw std::logic_error("Subdomain: R and f sizes differ");
  if (static_cast<int>(sys_.fixed_dofs.size()) != sys_.R.cols())
    throw std::logic_error("Subdomain " + std::to_string(sys_.id) +
                           ": the number of fixed dofs differs from the kernel dimension");
  reduced_.assign(n, 0);
  for (int d : sys_.fixed_dofs) reduced_.at(d) = -1;
  for (int d = 0, r = 0; d < n; ++d)
    if (reduced_[d] == 0) reduced_[d] = r++;
}

double Subdomain::energy(const Eigen::VectorXd& u) const {
  const Eigen::SparseMatrix<double>& K = this->K();
  if (K.rows() == size()) return 0.5 * u.dot(K.selfadjointView<Eigen::Lower>() * u) - sys_.f.dot(u);
  if (sys_.quadratic_form) return 0.5 * sys_.quadratic_form(u) - sys_.f.dot(u);
  const Eigen::SparseMatrix<double> A = sys_.assemble();
  return 0.5 * u.dot(A * u) - sys_.f.dot(u);
}

void Subdomain::release_factor() {
  chol_ = SparseCholesky();
  work_ = Eigen::VectorXd();
}

void Subdomain::factorize(Ordering ordering, SubdomainCache* cache, SingleCopy single) {
  factorize_impl(ordering, nullptr, cache, single);
}

void Subdomain::factorize_with_interface_last(const std::vector<int>& interface_dofs,
                                              SubdomainCache* cache, Ordering ordering) {
  factorize_impl(ordering, &interface_dofs, cache);
}

namespace {
// dual_block()'s dense work arrays, kept per thread between subdomains.
struct DualBlockWork {
  std::vector<double> w, f;
};
thread_local DualBlockWork dual_block_work;
}  // namespace

void Subdomain::release_dual_block_work() {
  std::vector<double>().swap(dual_block_work.w);
  std::vector<double>().swap(dual_block_work.f);
}

PackedSymmetric Subdomain::dual_block(const std::vector<BEntry>& b, int nmult,
                                      Precision precision) const {
  const auto inverse = chol_.schur_inverse();  // S^{-1} (shared by equal matrices)
  const Eigen::MatrixXd& S = inverse->S;
  const std::vector<int>& order = inverse->order;
  // order[i]: reduced index of the dof standing for row i of L_s.
  std::vector<int> dof_of_reduced(size() - sys_.fixed_dofs.size());
  for (int d = 0; d < size(); ++d)
    if (reduced_[d] >= 0) dof_of_reduced[reduced_[d]] = d;
  std::vector<int> pos(size(), -1);
  for (size_t i = 0; i < order.size(); ++i) pos[dof_of_reduced[order[i]]] = static_cast<int>(i);
  struct Entry {
    int mult, p;
    double value;
  };
  std::vector<Entry> entries;  // B_i on the interface positions, by multiplier
  entries.reserve(b.size());
  for (const auto& e : b) {
    if (reduced_[e.dof] < 0) continue;  // K^+ vanishes on fixed dofs
    if (pos[e.dof] < 0)
      throw std::logic_error("dual_block: a row of B touches a non-interface dof");
    entries.push_back({e.mult, pos[e.dof], e.value});
  }
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& x, const Entry& y) { return x.mult < y.mult; });
  const int nb = static_cast<int>(S.rows());
  // (K_rr^{-1}) on the interface is S^{-1} = (L_s L_s^T)^{-1} (SparseCholesky::schur_inverse:
  // LAPACK's dpotri, 2/3 n_b^3 flops).
  // W = S^{-1} B_i^T (one column per multiplier: n_b flops per entry of B_i), then the lower
  // half of F_i = B_i W (n_mult flops per entry), packed. W and F live in this thread's work
  // arrays (DualBlockWork), which keep their pages from one subdomain to the next.
  DualBlockWork& work = dual_block_work;
  work.w.assign(static_cast<size_t>(nb) * nmult, 0.0);
  work.f.assign(static_cast<size_t>(nmult) * nmult, 0.0);
  Eigen::Map<Eigen::MatrixXd> W(work.w.data(), nb, nmult), F(work.f.data(), nmult, nmult);
  for (const auto& e : entries) W.col(e.mult) += e.value * S.col(e.p);
  size_t first = 0;  // first entry with mult >= col
  for (int col = 0; col < nmult; ++col) {
    while (first < entries.size() && entries[first].mult < col) ++first;
    const double* w = W.col(col).data();
    double* f = F.col(col).data();
    for (size_t k = first; k < entries.size(); ++k)
      f[entries[k].mult] += entries[k].value * w[entries[k].p];
  }
  return PackedSymmetric(F, precision);  // the lower half
}

Eigen::SparseMatrix<double> Subdomain::reduced_matrix() {
  const int nn = size();
  if (K().rows() != nn) {  // released earlier
    shared_K_.reset();
    sys_.assemble().swap(sys_.K);
  }
  const Eigen::SparseMatrix<double>& K = this->K();
  const int nr = nn - static_cast<int>(sys_.fixed_dofs.size());
  // The upper triangle of K without the fixed rows and columns, written straight into compressed
  // storage: reduced_ is increasing, so the columns come in order and each keeps K's sorted rows
  // (no triplets, no sort; the same matrix entry for entry).
  long nnz = 0;
  for (int col = 0; col < nn; ++col) {
    if (reduced_[col] < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it)
      if (it.row() <= col && reduced_[it.row()] >= 0) ++nnz;
  }
  Eigen::SparseMatrix<double> Krr(nr, nr);
  Krr.makeCompressed();
  Krr.resizeNonZeros(nnz);
  int* outer = Krr.outerIndexPtr();
  int* inner = Krr.innerIndexPtr();
  double* value = Krr.valuePtr();
  long k = 0;
  outer[0] = 0;
  for (int col = 0; col < nn; ++col) {
    const int rc = reduced_[col];
    if (rc < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it) {
      const int row = static_cast<int>(it.row());
      if (row > col || reduced_[row] < 0) continue;
      inner[k] = reduced_[row];
      value[k] = it.value();
      ++k;
    }
    outer[rc + 1] = static_cast<int>(k);
  }
  return Krr;
}

void Subdomain::factorize_impl(Ordering ordering, const std::vector<int>* interface_dofs,
                               SubdomainCache* cache, SingleCopy single) {
  const double t0 = seconds_now();
  Eigen::SparseMatrix<double> Krr = reduced_matrix();
  const double t_reduce = seconds_now() - t0;
  chol_ = SparseCholesky(ordering);
  if (interface_dofs) {
    std::vector<int> last;
    for (int d : *interface_dofs)
      if (reduced_[d] >= 0) last.push_back(reduced_[d]);
    chol_.factorize(Krr, last, cache);
  } else {
    chol_.factorize(Krr, cache);
  }
  symbolic_seconds_ = t_reduce + chol_.symbolic_seconds();
  factor_nonzeros_ = chol_.factor_nonzeros();
  work_.resize(Krr.rows());
  if (single != SingleCopy::none) chol_.make_single();
  if (single == SingleCopy::instead_of_double) chol_.keep_single_only(std::move(Krr));
}

void Subdomain::apply_pinv_with(const double* x, double* y, bool single) {
  const int nn = size();
  double* w = work_.data();
  for (int k = 0; k < nn; ++k)
    if (reduced_[k] >= 0) w[reduced_[k]] = x[k];
  if (single)
    chol_.solve_single(w, w);
  else
    chol_.solve(w, w);
  for (int k = nn - 1; k >= 0; --k) y[k] = reduced_[k] < 0 ? 0.0 : w[reduced_[k]];
}

void Subdomain::apply_pinv_many(Eigen::MatrixXd& X) {
  const int nn = size(), nr = static_cast<int>(work_.size()), nc = static_cast<int>(X.cols());
  if (nc == 0) return;
  Eigen::MatrixXd W(nr, nc);
  for (int k = 0; k < nn; ++k)
    if (reduced_[k] >= 0) W.row(reduced_[k]) = X.row(k);
  chol_.solve_many(W.data(), nc);
  for (int k = 0; k < nn; ++k)
    if (reduced_[k] >= 0)
      X.row(k) = W.row(reduced_[k]);
    else
      X.row(k).setZero();
}

std::shared_ptr<const Eigen::MatrixXd> Subdomain::pinv_many_shared(const Eigen::MatrixXd& X) {
  return chol_.shared_result(X, sys_.fixed_dofs, [&] {
    Eigen::MatrixXd Y = X;
    apply_pinv_many(Y);
    return Y;
  });
}

std::shared_ptr<const Eigen::MatrixXd> Subdomain::pinv_many_shared(
    const Eigen::MatrixXd& X, const std::vector<std::vector<int>>& blocks) {
  return chol_.shared_result(X, sys_.fixed_dofs, [&] {
    Eigen::MatrixXd Y(X.rows(), X.cols());
    for (const auto& block : blocks) {
      Eigen::MatrixXd Xb(X.rows(), static_cast<Eigen::Index>(block.size()));
      for (size_t t = 0; t < block.size(); ++t)
        Xb.col(static_cast<Eigen::Index>(t)) = X.col(block[t]);
      const std::shared_ptr<const Eigen::MatrixXd> Yb = pinv_many_shared(Xb);
      for (size_t t = 0; t < block.size(); ++t)
        Y.col(block[t]) = Yb->col(static_cast<Eigen::Index>(t));
    }
    return Y;
  });
}

}  // namespace htfeti
