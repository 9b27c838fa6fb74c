#include "htfeti/feti/sparse_cholesky.hpp"

#include <cholmod.h>

#include <cstring>
#include <stdexcept>

namespace htfeti {

Ordering parse_ordering(const std::string& name) {
  if (name == "amd") return Ordering::amd;
  if (name == "metis") return Ordering::metis;
  throw std::invalid_argument("unknown ordering '" + name + "' (expected amd or metis)");
}

std::string to_string(Ordering ordering) { return ordering == Ordering::amd ? "amd" : "metis"; }

struct SparseCholesky::Impl {
  cholmod_common common;
  cholmod_factor* factor = nullptr;
  cholmod_dense* x = nullptr;  // solve work arrays, reused (cholmod_solve2)
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;
  int n = 0;

  explicit Impl(Ordering ordering) {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    common.supernodal = CHOLMOD_SUPERNODAL;
    common.nmethods = 1;
    common.method[0].ordering = ordering == Ordering::amd ? CHOLMOD_AMD : CHOLMOD_METIS;
    common.postorder = 1;
  }
  ~Impl() {
    cholmod_free_dense(&x, &common);
    cholmod_free_dense(&y, &common);
    cholmod_free_dense(&e, &common);
    cholmod_free_factor(&factor, &common);
    cholmod_finish(&common);
  }
};

SparseCholesky::SparseCholesky(Ordering ordering) : impl_(std::make_unique<Impl>(ordering)) {}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

void SparseCholesky::factorize(const Eigen::SparseMatrix<double>& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("SparseCholesky: matrix is not square");
  auto& c = impl_->common;
  Eigen::SparseMatrix<double> upper = A.triangularView<Eigen::Upper>();
  upper.makeCompressed();
  cholmod_sparse view{};
  view.nrow = view.ncol = static_cast<size_t>(A.rows());
  view.nzmax = static_cast<size_t>(upper.nonZeros());
  view.p = upper.outerIndexPtr();
  view.i = upper.innerIndexPtr();
  view.x = upper.valuePtr();
  view.stype = 1;  // upper triangle stored
  view.itype = CHOLMOD_INT;
  view.xtype = CHOLMOD_REAL;
  view.dtype = CHOLMOD_DOUBLE;
  view.sorted = 1;
  view.packed = 1;
  cholmod_free_factor(&impl_->factor, &c);
  impl_->factor = cholmod_analyze(&view, &c);
  if (!impl_->factor) throw std::runtime_error("CHOLMOD analysis failed");
  cholmod_factorize(&view, impl_->factor, &c);
  if (c.status == CHOLMOD_NOT_POSDEF || impl_->factor->minor < impl_->factor->n)
    throw std::runtime_error("CHOLMOD: matrix is not positive definite");
  if (c.status < 0) throw std::runtime_error("CHOLMOD factorization failed");
  impl_->n = static_cast<int>(A.rows());
  cholmod_free_work(&c);  // the analysis workspace is O(n) per factor: do not keep it
}

void SparseCholesky::solve(const double* b, double* out) {
  auto& c = impl_->common;
  cholmod_dense rhs{};
  rhs.nrow = rhs.d = rhs.nzmax = static_cast<size_t>(impl_->n);
  rhs.ncol = 1;
  rhs.x = const_cast<double*>(b);
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  if (!cholmod_solve2(CHOLMOD_A, impl_->factor, &rhs, nullptr, &impl_->x, nullptr, &impl_->y,
                      &impl_->e, &c))
    throw std::runtime_error("CHOLMOD solve failed");
  std::memcpy(out, impl_->x->x, sizeof(double) * impl_->n);
}

int SparseCholesky::rows() const { return impl_->n; }

long SparseCholesky::factor_nonzeros() const {
  const cholmod_factor* L = impl_->factor;
  if (!L) return 0;
  if (L->is_super) return static_cast<long>(L->xsize);
  return static_cast<long>(L->nzmax);
}

}  // namespace htfeti
