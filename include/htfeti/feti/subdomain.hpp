// One subdomain of TFETI (paper, Section 4): stiffness K_i, load f_i, orthonormal kernel R_i and
// the generalized inverse K_i^+ obtained by fixing one node: K_rr (K without the fixed node's row
// and column) is factored by sparse Cholesky and K^+ = [K_rr^{-1} 0; 0 0], so K K^+ K = K.
// For the Laplacian the kernel is the constant vector, R_i = e / sqrt(n_i).
//
// Cost of one K^+ application: one forward and one backward triangular solve with the factor
// of K_rr (about 4 nnz(L) flops) plus two gathers of n_i values.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <vector>

#include "htfeti/decomposition/decomposition.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"

namespace htfeti {

class Subdomain {
 public:
  /// Assembles K_i and f_i of subdomain `id`; the factorization is separate (factorize()).
  Subdomain(const Decomposition& dec, int id);

  int id() const { return id_; }
  const SubdomainPosition& position() const { return pos_; }
  int size() const { return static_cast<int>(f_.size()); }
  /// The assembled K_i; empty after release_matrix().
  const Eigen::SparseMatrix<double>& K() const { return K_; }
  /// Frees K_i once it is factored (the factor and the element matrices remain): about
  /// 12 bytes x 9 nonzeros per node.
  void release_matrix() { K_ = Eigen::SparseMatrix<double>(); }  // factorize() reassembles it
  /// q_i(u) = 1/2 u'K_i u - f_i'u, element by element (works after release_matrix()).
  double energy(const Eigen::VectorXd& u) const;
  const Eigen::VectorXd& f() const { return f_; }
  /// The orthonormal kernel basis (one column for the Laplacian).
  const Eigen::VectorXd& kernel() const { return R_; }
  int fixed_node() const { return fixed_; }

  void factorize(Ordering ordering);
  /// Factors with the given dofs (the interface) ordered last, so that the Schur complement of
  /// K_rr onto them is available for dual_block() (explicit dual operator).
  void factorize_with_interface_last(const std::vector<int>& interface_dofs);
  /// One entry of the subdomain's part of B~: row `mult` (subdomain-local numbering), column `dof`.
  struct BEntry {
    int mult;
    int dof;
    double value;
  };
  /// The dense local dual operator F_i = B_i K_i^+ B_i^T (nmult x nmult). Needs
  /// factorize_with_interface_last() with every dof that b touches. With L_s L_s^T the Schur
  /// complement of K_rr onto the interface, (K_rr^{-1}) restricted to it is (L_s L_s^T)^{-1}, so
  /// F_i = T^T T with T = L_s^{-1} B_i^T: one triangular solve with nmult right-hand sides and
  /// one product, about 2 n_b^2 nmult flops, instead of nmult sparse solves.
  Eigen::MatrixXd dual_block(const std::vector<BEntry>& b, int nmult) const;
  /// y = K^+ x (x and y of length size(); they may alias). Allocates nothing.
  void apply_pinv(const double* x, double* y);
  /// Nonzeros of the last factorization (also after release_factor()).
  long factor_nonzeros() const { return factor_nonzeros_; }
  /// Frees the factorization (apply_pinv needs factorize() again).
  void release_factor();

  /// Coordinates of local node k.
  double x_of(int k) const;
  double y_of(int k) const;

 private:
  void assemble();
  void factorize_impl(Ordering ordering, const std::vector<int>* interface_dofs);
  int id_;
  SubdomainPosition pos_;
  int H_;
  double h_;
  std::array<std::array<double, 4>, 4> ke_;
  Eigen::SparseMatrix<double> K_;
  Eigen::VectorXd f_, R_;
  int fixed_ = 0;
  long factor_nonzeros_ = 0;
  SparseCholesky chol_;
  Eigen::VectorXd work_;  // reduced vectors of length size() - 1
};

}  // namespace htfeti
