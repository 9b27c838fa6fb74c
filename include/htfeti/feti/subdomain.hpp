// One subdomain of TFETI (paper, Section 4): stiffness K_i, load f_i, orthonormal kernel R_i and
// the generalized inverse K_i^+ obtained by fixing dim(Ker K_i) dofs chosen by the physics (one
// node for the Laplacian; dofs of well-separated nodes for elasticity, see fem/physics.hpp):
// K_rr (K without the fixed rows and columns) is factored by sparse Cholesky and
// K^+ = [K_rr^{-1} 0; 0 0]. Because as many dofs are fixed as the kernel has dimensions and R
// restricted to them is invertible, rank K_rr = rank K and K K^+ K = K (tested).
//
// Cost of one K^+ application: one forward and one backward triangular solve with the factor of
// K_rr (about 4 nnz(L) flops) plus two gathers of n_i values.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "htfeti/feti/input.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"
#include "htfeti/linalg/packed_symmetric.hpp"

namespace htfeti {

class Subdomain {
 public:
  /// Takes the assembled system; the factorization is separate (factorize()). With `pooled`
  /// (K_i as SubdomainCache::intern_matrix returned it), system.K is empty and K_i is the pooled
  /// one.
  explicit Subdomain(SubdomainSystem system,
                     std::shared_ptr<const Eigen::SparseMatrix<double>> pooled = nullptr);

  int id() const { return sys_.id; }
  int size() const { return static_cast<int>(sys_.f.size()); }
  int dofs_per_node() const { return sys_.dofs_per_node; }
  /// The assembled K_i; empty after release_matrix().
  const Eigen::SparseMatrix<double>& K() const { return shared_K_ ? *shared_K_ : sys_.K; }
  /// Frees K_i (the factor remains); energy() and factorize() rebuild it when needed.
  /// (Eigen 3.4's SparseMatrix has no move operations and keeps its storage on assignment from
  /// an empty matrix: swap is what frees it.)
  void release_matrix() {
    Eigen::SparseMatrix<double>().swap(sys_.K);
    shared_K_.reset();
  }
  /// q_i(u) = 1/2 u'K_i u - f_i'u (rebuilds K_i temporarily if it was freed).
  double energy(const Eigen::VectorXd& u) const;
  const Eigen::VectorXd& f() const { return sys_.f; }
  /// The orthonormal kernel basis R_i (one column for the Laplacian, 3 or 6 for elasticity).
  const Eigen::MatrixXd& kernel() const { return sys_.R; }
  int kernel_dimension() const { return static_cast<int>(sys_.R.cols()); }
  const std::vector<int>& fixed_dofs() const { return sys_.fixed_dofs; }

  /// What factorize() keeps for the solves: the double-precision factor; that and its
  /// single-precision copy (apply_pinv_single); or the copy alone with K_rr
  /// (SparseCholesky::keep_single_only: apply_pinv refines the single-precision solve to a double
  /// one; a factor shared with equal subdomains keeps its double values, and refines all the
  /// same, so that the result does not depend on which subdomains share).
  enum class SingleCopy { none, beside_double, instead_of_double };
  /// With a cache, the symbolic analysis is shared with subdomains of the same pattern.
  void factorize(Ordering ordering, SubdomainCache* cache = nullptr,
                 SingleCopy single = SingleCopy::none);
  /// Factors with the given dofs (the interface) ordered last, so that the Schur complement of
  /// K_rr onto them is available for dual_block() (explicit dual operator). Fixed dofs among
  /// them are left out (K^+ is zero there).
  /// ordering: of the other dofs (AMD: constrained AMD over all; METIS: nested dissection of
  /// the non-interface dofs).
  void factorize_with_interface_last(const std::vector<int>& interface_dofs,
                                     SubdomainCache* cache = nullptr,
                                     Ordering ordering = Ordering::amd);
  /// Seconds of the last factorization: symbolic (forming K_rr, ordering, analysis) and numeric.
  double symbolic_seconds() const { return symbolic_seconds_; }
  double numeric_seconds() const { return chol_.numeric_seconds(); }
  /// One entry of the subdomain's part of B~: row `mult` (subdomain-local numbering), column `dof`.
  struct BEntry {
    int mult;
    int dof;
    double value;
  };
  /// The dense local dual operator F_i = B_i K_i^+ B_i^T (nmult x nmult). Needs
  /// factorize_with_interface_last() with every dof that b touches. With L_s L_s^T the Schur
  /// complement S of K_rr onto the interface, (K_rr^{-1}) restricted to it is S^{-1}, formed
  /// from L_s by LAPACK's dpotri (2/3 n_b^3 flops); then F_i = B_i S^{-1} B_i^T by sparse-dense
  /// products ((n_b + n_mult) flops per entry of B_i). The route through T = L_s^{-1} B_i^T and
  /// F_i = T^T T costs about n_b^2 n_mult + n_b n_mult^2 flops, 3 times more when n_mult is
  /// about n_b (docs/performance.md). Returned packed (lower triangle) in `precision`. The dense
  /// work arrays (n_b x n_mult and n_mult x n_mult) are kept per thread from one call to the next
  /// (fresh pages for every subdomain made the setup's kernel time, page faults and the TLB
  /// flushes of their unmapping, larger than its arithmetic); release_dual_block_work() frees them.
  PackedSymmetric dual_block(const std::vector<BEntry>& b, int nmult, Precision precision) const;
  /// Frees the calling thread's work arrays of dual_block().
  static void release_dual_block_work();
  /// y = K^+ x (x and y of length size(); they may alias). Allocates nothing.
  void apply_pinv(const double* x, double* y) { apply_pinv_with(x, y, false); }
  /// SubdomainSystem::repeats.
  bool repeats() const { return sys_.repeats; }
  /// Whether apply_pinv() refines single-precision solves (SingleCopy::instead_of_double).
  bool single_only() const { return chol_.refines(); }
  /// Bytes kept for the refinement (SparseCholesky::refinement_bytes).
  long refinement_bytes() const { return chol_.refinement_bytes(); }
  /// The refined solves (SparseCholesky::refinement_stats).
  SparseCholesky::RefinementStats refinement_stats() const { return chol_.refinement_stats(); }
  long single_bytes() const { return chol_.single_bytes(); }
  const void* single_data() const { return chol_.single_data(); }
  /// apply_pinv() with the single-precision copy of the factor (SparseCholesky::solve_single):
  /// K^+ of the matrix L_s L_s^T, within about cond(K) times single precision of K^+.
  /// Allocates nothing.
  void apply_pinv_single(const double* x, double* y) { apply_pinv_with(x, y, true); }
  /// X = K^+ X for every column of X (size() rows), in place: one multi-column solve, each
  /// column the same as apply_pinv() gives up to round-off. Setup work (allocates).
  void apply_pinv_many(Eigen::MatrixXd& X);
  /// K_i^+ X as apply_pinv_many gives it, held once for all subdomains that share this factor
  /// (numeric cache) and ask with an equal X and equal fixed dofs (SparseCholesky::shared_result):
  /// the cluster's K_i^+ C_i^T for the equal subdomains of a box. Thread-safe across subdomains.
  std::shared_ptr<const Eigen::MatrixXd> pinv_many_shared(const Eigen::MatrixXd& X);
  /// K_i^+ X with the columns of each block of `blocks` (indices of columns of X, together
  /// covering them once) solved together, one pinv_many_shared() per block, so that a block is
  /// solved once for all subdomains that share this factor and hold an equal block (the
  /// cluster's C_i^T of a box: the same face averages in up to 27 kinds of subdomain); the whole
  /// result is held once as pinv_many_shared()'s is. A column's value depends only on its block,
  /// not on the subdomain or the rank that holds it.
  std::shared_ptr<const Eigen::MatrixXd> pinv_many_shared(
      const Eigen::MatrixXd& X, const std::vector<std::vector<int>>& blocks);
  /// Nonzeros of the last factorization (also after release_factor()).
  long factor_nonzeros() const { return factor_nonzeros_; }
  /// Bytes factorize(ordering) would hold, from CHOLMOD's symbolic analysis alone.
  long symbolic_factor_bytes(Ordering ordering) {
    return SparseCholesky::symbolic_factor_bytes(reduced_matrix(), ordering);
  }
  /// CHOLMOD's symbolic analysis of factorize(ordering) (no numeric work): values, supernodes,
  /// flops.
  SparseCholesky::SymbolicStats symbolic_stats(Ordering ordering) {
    return SparseCholesky::symbolic_stats(reduced_matrix(), ordering);
  }
  /// Bytes of the current factorization (0 after release_factor()).
  long factor_bytes() const { return chol_.factor_bytes(); }
  bool factor_shared() const { return chol_.factor_shared(); }
  /// Frees the factorization (apply_pinv needs factorize() again).
  void release_factor();

 private:
  void apply_pinv_with(const double* x, double* y, bool single);
  void factorize_impl(Ordering ordering, const std::vector<int>* interface_dofs,
                      SubdomainCache* cache, SingleCopy single = SingleCopy::none);
  Eigen::SparseMatrix<double> reduced_matrix();
  SubdomainSystem sys_;
  std::shared_ptr<const Eigen::SparseMatrix<double>> shared_K_;  // K_i when interned (sys_.K empty)
  std::vector<int> reduced_;  // dof -> index in K_rr, -1 for fixed dofs
  long factor_nonzeros_ = 0;
  double symbolic_seconds_ = 0;
  SparseCholesky chol_;
  Eigen::VectorXd work_;  // reduced vectors
};

}  // namespace htfeti
