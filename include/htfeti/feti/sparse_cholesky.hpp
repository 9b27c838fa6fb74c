// Sparse Cholesky factorization of a symmetric positive definite matrix by CHOLMOD
// (supernodal, fill-reducing ordering), with solves that allocate nothing after the first call.
#pragma once

#include <Eigen/Sparse>
#include <memory>
#include <string>

namespace htfeti {

enum class Ordering { amd, metis };
Ordering parse_ordering(const std::string& name);
std::string to_string(Ordering ordering);

class SparseCholesky {
 public:
  explicit SparseCholesky(Ordering ordering = Ordering::amd);
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  /// Factors A (only its upper triangle is read). Throws std::runtime_error if A is not
  /// positive definite.
  void factorize(const Eigen::SparseMatrix<double>& A);
  /// x = A^{-1} b; x and b may alias. Work arrays are kept between calls, so a solve allocates
  /// nothing once the first one has run. Not safe to call concurrently on one object.
  void solve(const double* b, double* x);
  int rows() const;
  /// Nonzeros of the factor L (memory is about 8 bytes per nonzero plus the pattern).
  long factor_nonzeros() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace htfeti
