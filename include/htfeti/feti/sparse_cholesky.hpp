// Sparse Cholesky factorization of a symmetric positive definite matrix by CHOLMOD
// (supernodal, fill-reducing ordering), with solves that allocate nothing after the first call.
#pragma once

#include <Eigen/Sparse>
#include <memory>
#include <string>
#include <vector>

namespace htfeti {

/// Fill-reducing ordering of the subdomain factors. automatic: AMD in 2D (the paper's tables were
/// measured with it), METIS nested dissection in 3D (27% fewer factor nonzeros on the
/// cube-obstacle subdomains, docs/performance.md); resolved by the FETI stage.
enum class Ordering { amd, metis, automatic };
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
  /// Factors A with the rows in `last` ordered after all others (constrained AMD, no
  /// postordering), so that the trailing block of the factor is the Cholesky factor of the Schur
  /// complement of A onto `last`. The ordering option of the constructor is not used.
  void factorize(const Eigen::SparseMatrix<double>& A, const std::vector<int>& last);
  /// After factorize(A, last): lower-triangular L_s (|last| x |last|) with L_s L_s^T the Schur
  /// complement, and order[i] = the row of A that row i of L_s stands for.
  void schur_factor(Eigen::MatrixXd& L, std::vector<int>& order) const;
  /// x = A^{-1} b; x and b may alias. Work arrays are kept between calls, so a solve allocates
  /// nothing once the first one has run. Not safe to call concurrently on one object.
  void solve(const double* b, double* x);
  int rows() const;
  /// Nonzeros of the factor L (memory is about 8 bytes per nonzero plus the pattern).
  long factor_nonzeros() const;
  /// Bytes held by the factor: values, row indices and the supernode/permutation arrays.
  long factor_bytes() const;
  /// The bytes factor_bytes() would report after factorize(A), from the symbolic analysis
  /// alone (ordering and supernodes; no numeric work).
  static long symbolic_factor_bytes(const Eigen::SparseMatrix<double>& A, Ordering ordering);

 private:
  void factorize_impl(const Eigen::SparseMatrix<double>& A, const std::vector<int>* last);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace htfeti
