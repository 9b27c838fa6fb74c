// The subdomain part of the FETI preconditioners (Farhat, Mandel, Roux 1994; Klawonn, Widlund
// 2001; Dostal et al. 2016, Section 10.4):
//     lumped     M^{-1} = B_D K B_D^T,        Dirichlet  M^{-1} = B_D S B_D^T,
// with K = diag(K_i) and S = diag(S_i), S_i = K_bb - K_bi K_ii^{-1} K_ib the Schur complement of
// K_i onto its interface b (the dofs that rows of B~ touch: gluing, Dirichlet and contact rows).
// Only the interface block enters: the lumped one applies K_bb, the Dirichlet one S_i. The
// scaled B_D and the assembly over subdomains are in DualProblem (apply_preconditioner).
//
// S_i is stored dense when it fits (DualProblem decides by a budget), computed from one Cholesky
// factorization of K_i + sigma I_b with the interface ordered last: the trailing block L_s of the
// factor satisfies L_s L_s^T = S_i + sigma I (K_i itself is singular for a floating subdomain,
// the shifted matrix is not), so S_i = L_s L_s^T - sigma I with sigma = max diag K_bb.
// Otherwise S_i is applied implicitly with a sparse factor of K_ii.
//
// S_i vanishes on the subdomain's rigid motions restricted to the interface (R_b). In TFETI
// with B_D = B~ those directions are cut off by the projector (R^T B^T x = G x = 0 on Ker G),
// but with H-TFETI-DP (cluster kernels only) or a scaled B_D they are not, and B_D S B_D^T is
// then only semidefinite on Ker G (observed on the 3D cube with clusters). Given the kernel,
// the Dirichlet operator is S_i + tau Q Q^T, Q an orthonormal basis of R_b and tau the mean
// diagonal of K_bb: positive definite, and unchanged on the complement of R_b.
//
// The layered Dirichlet preconditioner (layers k >= 1) replaces K_i by its rows and columns of
// the interface and of the dofs within k steps of it in the graph of K_i, the others clamped:
//     S_i^(k) = K_bb - K_bs K_ss^{-1} K_sb,   s: the interior dofs of the k layers.
// For symmetric positive semidefinite K_i, S_i <= S_i^(k+1) <= S_i^(k) <= S_i^(0) = K_bb (the
// Schur complement is the energy minimum over the interior; clamping more interior dofs can
// only raise it), and S_i^(k) = S_i once the layers reach every dof. So k = 0 is the lumped
// preconditioner's K_bb and large k the Dirichlet one. One layer of a METIS part of about 1,000
// hex8 cells keeps about half of its interior dofs, in a shell one cell thick.
//
// Cost of one application: lumped 2 nnz(K_bb) flops; Dirichlet dense 2 n_b^2; implicit
// 2 nnz(K_ib) + 2 nnz(K_bb) + one solve with the factor of K_ii (about 4 nnz(L_ii)), K_ii and
// K_ib of the k layers for the layered one. The implicit solve reads a single-precision copy of
// that factor (4 bytes a value, sums in double; SparseCholesky::solve_single) unless the caller
// asks for double: a preconditioner needs no more, and the copy halves the bytes it streams.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"

namespace htfeti {

/// automatic: chosen by solve() from the problem class (resolve_preconditioner in solver.hpp);
/// DualProblem needs it resolved.
enum class PreconditionerKind { none, lumped, dirichlet, automatic };
inline constexpr std::array<EnumName<PreconditionerKind>, 4> kPreconditionerNames{
    {{PreconditionerKind::none, "none"},
     {PreconditionerKind::lumped, "lumped"},
     {PreconditionerKind::dirichlet, "dirichlet"},
     {PreconditionerKind::automatic, "auto"}}};
PreconditionerKind parse_preconditioner(const std::string& name);  // throws std::invalid_argument
std::string to_string(PreconditionerKind kind);

/// How B_D weights the rows of B~ (DualProblem::apply_preconditioner):
///  - multiplicity: B_D = B~. B~ has orthonormal rows, so B~^T B~ is already the
///    multiplicity-weighted jump operator (a node with k copies: I - 11^T / k);
///  - stiffness: the gluing rows weighted by the diagonal of K (rho), so that the stiffer
///    side of an interface is trusted more (the rho-scaling of Klawonn and Widlund).
///  - automatic: stiffness when the problem has a coefficient field, else multiplicity (solve()).
enum class Scaling { multiplicity, stiffness, automatic };
inline constexpr std::array<EnumName<Scaling>, 3> kScalingNames{
    {{Scaling::multiplicity, "multiplicity"},
     {Scaling::stiffness, "stiffness"},
     {Scaling::automatic, "auto"}}};
Scaling parse_scaling(const std::string& name);  // throws std::invalid_argument
std::string to_string(Scaling scaling);

class LocalPreconditioner {
 public:
  /// K: the subdomain's full stiffness (both triangles); interface: sorted distinct dofs.
  /// dense: store S_i dense (Dirichlet only). Throws std::runtime_error if K_ii (or the shifted
  /// matrix) is not positive definite (the interface does not restrain the subdomain).
  /// kernel: the subdomain's kernel basis (rows: dofs), or nullptr (S_i as it is).
  /// layers (Dirichlet only): 0 the Schur complement on the whole interior; k >= 1 S_i^(k) of
  /// the k layers of interior dofs next to the interface (no kernel term where any dof is
  /// clamped: S_i^(k) is then positive definite).
  /// single (implicit storage only): the solves with K_ii read a single-precision copy of its
  /// factor (SparseCholesky::solve_single, sums in double) and the double values are freed.
  LocalPreconditioner(const Eigen::SparseMatrix<double>& K, std::vector<int> interface,
                      PreconditionerKind kind, bool dense, Ordering ordering,
                      const Eigen::MatrixXd* kernel = nullptr, SubdomainCache* cache = nullptr,
                      int layers = 0, bool single = false);
  int size() const { return static_cast<int>(interface_.size()); }
  const std::vector<int>& interface() const { return interface_; }
  bool dense() const { return dense_; }
  /// Whether the implicit form solves with the single-precision copy of K_ii's factor.
  bool single() const { return single_; }
  /// y = K_bb x (lumped) or y = S_i x (Dirichlet), vectors of size(); allocates nothing.
  void apply(const double* x, double* y);
  /// Bytes held (dense S, sparse blocks, factor).
  long bytes() const;

 private:
  // work_ <- K_ii^{-1} work_ (in double, or with the single-precision copy).
  void solve_interior() {
    if (single_)
      Kii_.solve_single(work_.data(), work_.data());
    else
      Kii_.solve(work_.data(), work_.data());
  }
  std::vector<int> interface_;
  PreconditionerKind kind_;
  bool dense_ = false;
  bool single_ = false;
  Eigen::MatrixXd S_;                      // dense Schur complement
  Eigen::SparseMatrix<double> Kbb_, Kib_;  // interface block; interior x interface block
  SparseCholesky Kii_;                     // implicit Dirichlet
  Eigen::VectorXd work_;                   // interior vector
  Eigen::MatrixXd Q_;                      // orthonormal basis of R_b (implicit: applied apart)
  Eigen::VectorXd qwork_;
  double tau_ = 0;
};

}  // namespace htfeti
