#include "htfeti/feti/preconditioner.hpp"

#include <algorithm>
#include <limits>
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

namespace {

// The layered Dirichlet preconditioner keeps the interface and the dofs within `layers` steps
// of it in the graph of K (breadth first over K's columns); kept[d] is d's index among the kept
// dofs (in K's order) or -1. Returns how many are kept.
int keep_layers(const Eigen::SparseMatrix<double>& K, const std::vector<int>& interface, int layers,
                std::vector<int>& kept) {
  const int n = static_cast<int>(K.rows());
  kept.assign(n, -1);
  std::vector<int> front(interface), next;
  for (int d : interface) kept[d] = 0;
  for (int l = 0; l < layers && !front.empty(); ++l) {
    next.clear();
    for (int c : front)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
        if (kept[it.row()] < 0) kept[it.row()] = 0, next.push_back(static_cast<int>(it.row()));
    front.swap(next);
  }
  int nk = 0;
  for (int d = 0; d < n; ++d)
    if (kept[d] == 0) kept[d] = nk++;
  return nk;
}

// K's rows and columns of the kept dofs (kept: keep_layers), straight into compressed columns.
Eigen::SparseMatrix<double> kept_block(const Eigen::SparseMatrix<double>& K,
                                       const std::vector<int>& kept, int nk) {
  Eigen::Index nnz = 0;
  for (int c = 0; c < K.outerSize(); ++c)
    if (kept[c] >= 0)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
        nnz += kept[it.row()] >= 0;
  Eigen::SparseMatrix<double> A;
  resize_resident(A, nk, nk, nnz);
  int* outer = A.outerIndexPtr();
  int* inner = A.innerIndexPtr();
  double* value = A.valuePtr();
  Eigen::Index k = 0;
  outer[0] = 0;
  for (int c = 0; c < K.outerSize(); ++c) {
    if (kept[c] < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
      if (kept[it.row()] >= 0) inner[k] = kept[it.row()], value[k++] = it.value();
    outer[kept[c] + 1] = static_cast<int>(k);
  }
  return A;
}

}  // namespace

LocalPreconditioner::LocalPreconditioner(const Eigen::SparseMatrix<double>& K,
                                         std::vector<int> interface, PreconditionerKind kind,
                                         bool dense, Ordering ordering,
                                         const Eigen::MatrixXd* kernel, SubdomainCache* cache,
                                         int layers, bool single)
    : interface_(std::move(interface)), kind_(kind) {
  if (kind == PreconditionerKind::none) throw std::logic_error("LocalPreconditioner: no kind");
  if (layers < 0) throw std::invalid_argument("LocalPreconditioner: layers must be >= 0");
  const int n = static_cast<int>(K.rows()), nb = size();
  const std::vector<int>& iface = interface_;
  // Layered Dirichlet: kept[d] >= 0 for the interface and the interior dofs of its layers; the
  // other dofs are clamped. Where the layers reach every dof nothing is clamped (S_i exact).
  std::vector<int> kept;
  int n_kept = n;
  if (kind == PreconditionerKind::dirichlet && layers > 0 && nb > 0)
    n_kept = keep_layers(K, iface, layers, kept);
  const bool clamped = n_kept < n;
  constexpr int kClamped = std::numeric_limits<int>::min();
  // pos: interface position (>= 0), -(interior position) - 2, or kClamped.
  std::vector<int> pos(n, -1);
  for (int i = 0; i < nb; ++i) pos[iface[i]] = i;
  int ni = 0;
  for (int d = 0; d < n; ++d)
    if (pos[d] < 0) pos[d] = clamped && kept[d] < 0 ? kClamped : -(ni++) - 2;
  // K_bb straight into its compressed columns (no list of triplets: its growth touched fresh
  // pages for every subdomain), in two passes over the interface columns: count, then fill.
  // Within a column the rows come in K's order; the interface positions follow it where the
  // interface is sorted (the caller's), else the column is sorted by insertion.
  double sigma = 0;
  {
    Eigen::Index nnz = 0;
    for (int pc = 0; pc < nb; ++pc)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, iface[pc]); it; ++it)
        if (pos[it.row()] >= 0) ++nnz;
    resize_resident(Kbb_, nb, nb, nnz);  // (parallel/fresh_pages.hpp)
    int* outer = Kbb_.outerIndexPtr();
    int* inner = Kbb_.innerIndexPtr();
    double* value = Kbb_.valuePtr();
    Eigen::Index k = 0;
    outer[0] = 0;
    for (int pc = 0; pc < nb; ++pc) {
      const Eigen::Index first = k;
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, iface[pc]); it; ++it) {
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
  // The clamped dofs make S_i^(k) positive definite: no kernel term (that is for S_i, which
  // vanishes on the rigid motions).
  if (clamped) kernel = nullptr;
  if (kernel && kernel->cols() > 0) {  // Q: orthonormal basis of R restricted to the interface
    Eigen::MatrixXd Rb(nb, kernel->cols());
    for (int i = 0; i < nb; ++i) Rb.row(i) = kernel->row(iface[i]);
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
    // (layered: K's block of the kept dofs, the interface renumbered with it)
    std::vector<int> b_kept;
    if (clamped)
      for (int d : iface) b_kept.push_back(kept[d]);
    Eigen::SparseMatrix<double> A = clamped ? kept_block(K, kept, n_kept) : K;
    for (int d : clamped ? b_kept : iface) A.coeffRef(d, d) += sigma;
    SparseCholesky chol;
    try {
      chol.factorize(A, clamped ? b_kept : iface, cache);
    } catch (const std::runtime_error&) {
      throw std::runtime_error(
          "Dirichlet preconditioner: the interface does not restrain a subdomain (K_ii is "
          "singular); use --preconditioner lumped");
    }
    Eigen::MatrixXd L;
    std::vector<int> order;
    chol.schur_factor(L, order);
    // The interface position of a dof of A (layered: A numbers the kept dofs).
    std::vector<int> kept_pos;
    if (clamped) {
      kept_pos.resize(n_kept);
      for (int d = 0; d < n; ++d)
        if (kept[d] >= 0) kept_pos[kept[d]] = pos[d];
    }
    const auto pos_of = [&](int d) { return clamped ? kept_pos[d] : pos[d]; };
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
        const int i = pos_of(order[nb - 1 - a]), j = pos_of(order[nb - 1 - b]);
        S_(i, j) = S_(j, i) = U(a, b);
      }
    S_.diagonal().array() -= sigma;
    if (Q_.cols() > 0) S_.noalias() += tau_ * Q_ * Q_.transpose();
    Q_ = Eigen::MatrixXd();
    Kbb_ = Eigen::SparseMatrix<double>();
    return;
  }
  // K_ib and the upper triangle of K_ii (CHOLMOD reads it) straight into compressed columns,
  // two passes each (count, fill), as K_bb above; interior positions follow K's order.
  const auto fill = [&](Eigen::SparseMatrix<double>& M, int rows, int cols, const auto& column,
                        const auto& keep) {
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::Index k = 0;
      for (int c = 0; c < cols; ++c) {
        const Eigen::Index first = k;
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, column(c)); it; ++it) {
          const int pr = pos[it.row()];
          if (pr >= 0 || pr == kClamped || !keep(-pr - 2, c)) continue;
          if (pass == 0) {
            ++k;
            continue;
          }
          int* inner = M.innerIndexPtr();
          double* value = M.valuePtr();
          Eigen::Index q = k++;
          for (; q > first && inner[q - 1] > -pr - 2; --q)
            inner[q] = inner[q - 1], value[q] = value[q - 1];
          inner[q] = -pr - 2, value[q] = it.value();
        }
        if (pass == 1) M.outerIndexPtr()[c + 1] = static_cast<int>(k);
      }
      if (pass == 0) {
        resize_resident(M, rows, cols, k);
        M.outerIndexPtr()[0] = 0;
      }
    }
  };
  std::vector<int> interior(ni);  // the interior dofs in position order
  for (int d = 0; d < n; ++d)
    if (pos[d] < 0 && pos[d] != kClamped) interior[-pos[d] - 2] = d;
  fill(
      Kib_, ni, nb, [&](int c) { return iface[c]; }, [](int, int) { return true; });
  if (ni > 0) {
    Eigen::SparseMatrix<double> Kii;
    fill(
        Kii, ni, ni, [&](int c) { return interior[c]; }, [](int r, int c) { return r <= c; });
    Kii_ = SparseCholesky(ordering);
    try {
      const KeptAllocations kept;  // (kept for the run: no larger block than it needs)
      Kii_.factorize(Kii, cache);
    } catch (const std::runtime_error&) {
      throw std::runtime_error(
          "Dirichlet preconditioner: the interface does not restrain a subdomain (K_ii is "
          "singular); use --preconditioner lumped");
    }
    if (single) {  // half the bytes per application; the double values freed
      Kii_.make_single();
      Kii_.drop_double();
      single_ = true;
    }
  }
  work_.resize(ni);
  // One solve here makes the factor's solve workspace (CHOLMOD's dense work arrays, kept between
  // solves), so that apply(), which runs in the dual problem's parallel loops, allocates
  // nothing from its first call on: an allocation failure happens in the setup, where it is
  // reported ("out of memory", exit 2), not inside a loop that cannot pass it on.
  if (ni > 0) {
    work_.setZero();
    solve_interior();
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
    solve_interior();
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
  if (!dense_ && work_.size() > 0) b += Kii_.held_bytes();
  return b;
}

}  // namespace htfeti
