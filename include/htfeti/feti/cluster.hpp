// The generalized inverse of a cluster of subdomains joined by primal constraints (paper,
// Section 5: K~ = Z^T diag(K_i) Z, with Z an orthonormal basis of the vectors that satisfy the
// primal constraints C u = 0: corners and/or averages of the kernel over shared edges/faces).
//
// Cluster kernel. A vector of the cluster is in Ker K~ iff u_i = R_i beta_i on every subdomain and
// C R beta = 0; so Ker K~ = R N with N an orthonormal basis of Null(C R). C has orthonormal rows
// and R orthonormal columns, so C R is O(1) whatever the physics' scale (E ~ 2e7 or 1) and its
// rank is decided by an absolute threshold (scale-invariant). A cluster that is really joined has
// dim Ker = the dimension of one subdomain's kernel (1 for Laplace, 3/6 for elasticity); a
// disconnected cluster or a mechanism is handled by the same formula with a larger kernel.
//
// K~^+ is never formed. Applied to x (one vector per subdomain) it returns y = Z K~^+ Z^T x, the
// solution of
//     min 1/2 u'Ku - x'u  subject to  C u = 0  and  beta_J = 0,
// where beta_J are dim Ker kernel coefficients chosen (greedily in subdomain order) so that N
// restricted to them is invertible; that fixes the cluster kernel, so K~ K~^+ K~ = K~. With
// K_i^+ (fixed dofs, sparse Cholesky) and the free coefficients beta_F:
//     u = K^+ (x - C^T mu) + R_F beta_F,
//     [ C K^+ C^T   -C R_F ] [mu    ]   [ C K^+ x  ]
//     [ -R_F^T C^T     0   ] [beta_F] = [ -R_F^T x ],
// a dense system of size (#constraints + sum_i dim R_i - dim Ker), equilibrated (the C K^+ C^T
// block, O(1/E), is scaled to O(1)) and factored by partial-pivoting LU (LAPACK's dgetrf on one
// thread: 0.05 s where Eigen's took 0.13-0.16 s for the 1,242 unknowns of the 40^3 cube in one
// cluster of 4^3); its reciprocal condition number after scaling (dgecon) decides singularity. For
// one subdomain there are no constraints and y = K_0^+ x: plain TFETI.
//
// Cost of one application: one K_i^+ solve per subdomain, plus a dense solve of size above and
// products with the precomputed K_i^+ C_i^T. Setup: K_i^+ C_i^T by one multi-column K_i^+ solve
// per object (face, edge, vertex) of each subdomain, each held once for the subdomains that share
// the factor and the object (a box); one dense LU, 2/3 n^3 flops.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/feti/constraints.hpp"
#include "htfeti/feti/subdomain.hpp"
#include "htfeti/linalg/packed_symmetric.hpp"

namespace htfeti {

/// How F = B~ K~^+ B~^T is applied on a cluster: by sparse triangular solves every time
/// (implicit), or by dense local blocks F_i = B_i K_i^+ B_i^T built once from the Schur complement
/// of each subdomain onto its interface (explicit), plus the low-rank cluster correction
/// B_i K_i^+ C_i^T and B_i R_i (see apply_dual). checked: the explicit operator, compared with
/// the implicit one at every application (a diagnostic: what the explicit blocks, in double or
/// single precision, change in F; CheckedClusterOperator).
enum class DualOperator { implicit, explicit_, checked, automatic };
inline constexpr std::array<EnumName<DualOperator>, 4> kDualOperatorNames{
    {{DualOperator::implicit, "implicit"},
     {DualOperator::explicit_, "explicit"},
     {DualOperator::checked, "checked"},
     {DualOperator::automatic, "auto"}}};
DualOperator parse_dual_operator(const std::string& name);
std::string to_string(DualOperator kind);

class Cluster;

/// The dual operator on one cluster, F_c: out_i = (B~ K~^+ B~^T lam)_i for each subdomain i of
/// the cluster, on its local rows (lam[i] and out[i] have sizes()[i] entries; apply() checks
/// them). Implementations: implicit (sparse solves with the cluster's K~^+ every time) and
/// explicit (dense local blocks in double or single precision, with the cluster's saddle-point
/// correction). A new way to apply F (on a GPU, or by a Schur-complement solver) derives from
/// this class and is created by Cluster's constructor (docs/architecture.md).
class ClusterDualOperator {
 public:
  virtual ~ClusterDualOperator() = default;
  virtual std::string name() const = 0;
  /// Bytes held beyond the factors (the explicit blocks).
  virtual long bytes() const = 0;
  const std::vector<int>& sizes() const { return sizes_; }
  /// Checks the sizes, then applies the operator. Allocates nothing.
  void apply(const std::vector<Eigen::VectorXd>& lam, std::vector<Eigen::VectorXd>& out);

 protected:
  explicit ClusterDualOperator(std::vector<int> sizes) : sizes_(std::move(sizes)) {}
  virtual void do_apply(const std::vector<Eigen::VectorXd>& lam,
                        std::vector<Eigen::VectorXd>& out) = 0;

 private:
  std::vector<int> sizes_;
};

/// x = B_i^T lam_i, x <- K~^+ x (Cluster::solve), out_i = B_i x_i. Cost: one K_i^+ per
/// subdomain, plus the cluster's saddle-point solve.
class ImplicitClusterOperator final : public ClusterDualOperator {
 public:
  ImplicitClusterOperator(Cluster& cluster, std::vector<std::vector<Subdomain::BEntry>> b,
                          std::vector<int> nmult);
  std::string name() const override { return "implicit"; }
  long bytes() const override { return 0; }

 protected:
  void do_apply(const std::vector<Eigen::VectorXd>& lam,
                std::vector<Eigen::VectorXd>& out) override;

 private:
  Cluster& cluster_;
  std::vector<std::vector<Subdomain::BEntry>> b_;  // rows of B~ per subdomain (local numbering)
  std::vector<Eigen::VectorXd> xw_;                // physical work vectors
};

/// out_i = F_i lam_i - U_i mu + V_i beta_i with U_i = B_i K_i^+ C_i^T, V_i = B_i R_i and
/// [mu; beta_F] = S^{-1} [sum_i U_i^T lam_i; -V_i,F^T lam_i] (the cluster's saddle-point
/// system). Cost: one dense n_i x n_i symmetric matrix-vector product per subdomain
/// (memory-bound: 8 n_i^2 bytes in double, 4 in single precision). The blocks are formed by
/// Cluster's constructor while the factors are at hand.
class ExplicitClusterOperator final : public ClusterDualOperator {
 public:
  ExplicitClusterOperator(Cluster& cluster, std::vector<int> nmult, Precision precision)
      : ClusterDualOperator(std::move(nmult)), cluster_(cluster), precision_(precision) {}
  std::string name() const override { return "explicit (" + to_string(precision_) + ")"; }
  long bytes() const override;

 protected:
  void do_apply(const std::vector<Eigen::VectorXd>& lam,
                std::vector<Eigen::VectorXd>& out) override;

 private:
  friend class Cluster;  // forms the blocks
  Cluster& cluster_;
  Precision precision_;
  std::vector<PackedSymmetric> F_;  // F_i (lower triangle, packed)
  std::vector<Eigen::MatrixXd> U_;  // B_i K_i^+ C_i^T
  std::vector<Eigen::MatrixXd> V_;  // B_i R_i
};

/// The explicit operator checked against the implicit one: out = F_explicit lam (what the solve
/// uses), and at every application also F_implicit lam, recording the largest relative
/// difference ||F_explicit lam - F_implicit lam|| / ||F_implicit lam|| over the cluster's
/// subdomains. A user sees what the explicit blocks (single precision, or an ill-conditioned
/// factor) change in F; a new operator is verified the same way. Cost: both operators' (the
/// factors are kept). Allocates nothing per application.
class CheckedClusterOperator final : public ClusterDualOperator {
 public:
  CheckedClusterOperator(std::unique_ptr<ClusterDualOperator> applied,
                         std::unique_ptr<ClusterDualOperator> reference);
  std::string name() const override {
    return applied_->name() + " checked against " + reference_->name();
  }
  long bytes() const override { return applied_->bytes() + reference_->bytes(); }
  long applications() const { return applications_; }
  double max_relative_difference() const { return max_relative_difference_; }

 protected:
  void do_apply(const std::vector<Eigen::VectorXd>& lam,
                std::vector<Eigen::VectorXd>& out) override;

 private:
  std::unique_ptr<ClusterDualOperator> applied_, reference_;
  std::vector<Eigen::VectorXd> ref_;  // F_reference lam
  long applications_ = 0;
  double max_relative_difference_ = 0;
};

class Cluster {
 public:
  /// subs: the cluster's subdomains in id order (assembled); C: its primal constraints
  /// (cluster_primal_constraints); b[i]: the rows of B~ on subdomain i, numbered 0..nmult[i]-1
  /// locally. Factors the subdomains. kind: implicit, explicit_ (builds the dense local blocks)
  /// or checked (builds them and keeps the rows of B~ for the implicit operator too).
  /// by_object: K_i^+ C_i^T by one solve per object (face, edge, vertex), each shared by the
  /// subdomains that share the factor and hold the same object; for models whose subdomains and
  /// objects repeat (a generated box: SubdomainInput's kernel frame). Otherwise one solve per
  /// subdomain for all its columns, which costs less when nothing repeats (parts from METIS:
  /// 0.2-0.3 s more setup in total with solves by object on the 40^3 cube in 64 parts). The
  /// choice must not depend on what a rank holds: the two round differently.
  Cluster(int id, std::vector<Subdomain*> subs, std::vector<std::vector<ConstraintEntry>> C,
          Ordering ordering, std::vector<std::vector<Subdomain::BEntry>> b, std::vector<int> nmult,
          DualOperator kind, SubdomainCache* cache = nullptr,
          Precision precision = Precision::double_, bool by_object = false,
          bool single_sweeps = false);
  /// Without dual rows: for tests of the generalized inverse alone.
  Cluster(int id, std::vector<Subdomain*> subs, std::vector<std::vector<ConstraintEntry>> C,
          Ordering ordering)
      : Cluster(id, subs, std::move(C), ordering,
                std::vector<std::vector<Subdomain::BEntry>>(subs.size()),
                std::vector<int>(subs.size(), 0), DualOperator::implicit) {}

  int id() const { return id_; }
  const std::vector<Subdomain*>& subdomains() const { return subs_; }
  int num_primal_constraints() const { return nc_; }
  /// Dimension of the cluster kernel R~ (rows of G~ contributed by this cluster).
  int kernel_dimension() const { return static_cast<int>(N_.cols()); }
  /// out[j] += (R~_j restricted to subdomain i) . x (j < kernel_dimension()).
  void kernel_dot(int i, const Eigen::VectorXd& x, double* out) const;
  /// u += R~ restricted to subdomain i, times gamma.
  void kernel_add(int i, const double* gamma, Eigen::VectorXd& u) const;
  /// Value of R~_j at dof `dof` of subdomain i.
  double kernel_entry(int i, int dof, int j) const;
  /// Doubles held by the cluster's dense data (K^+ C^T blocks and the LU). With `seen`, a
  /// K^+ C^T block shared with equal subdomains (SparseCholesky::shared_result) is counted only
  /// if it is not in the set yet, and added to it.
  long dense_doubles(std::unordered_set<const void*>* seen = nullptr) const;

  /// x[i] -> K~^+ x[i] in place (physical vectors of the cluster's subdomains). Allocates nothing.
  void solve(std::vector<Eigen::VectorXd>& x);
  /// solve() for the implicit operator, whose right-hand sides are B~^T lam: with single sweeps
  /// on (the constructor's single_sweeps, for a cluster without primal constraints, and not
  /// switched off by set_single_sweeps), each K_i^+ from the single-precision copy of its factor
  /// (Subdomain::apply_pinv_single); otherwise solve(). Allocates nothing.
  void solve_interface(std::vector<Eigen::VectorXd>& x);
  /// Whether the implicit operator reads single-precision copies of the factors (set up).
  bool single_sweeps() const { return single_; }
  /// Switches the implicit operator between the copies (on) and the factors (off).
  void set_single_sweeps(bool on) { use_single_ = on && single_; }
  /// Bytes of the single-precision copies (a copy shared by equal subdomains counted once per
  /// `seen` set).
  long single_bytes(std::unordered_set<const void*>* seen = nullptr) const;
  /// out[i] = (B~ K~^+ B~^T lam) restricted to subdomain i's local rows; lam[i], out[i] have
  /// nmult[i] entries. Implicit: x = B^T lam, solve(x), B x. Explicit, with the same dense
  /// saddle-point system as solve():
  ///   out_i = F_i lam_i - U_i mu + V_i beta_i,  U_i = B_i K_i^+ C_i^T,  V_i = B_i R_i,
  ///   [mu; beta_F] = S^{-1} [sum_i U_i^T lam_i; -V_i,F^T lam_i].
  /// Cost: implicit, one K_i^+ per subdomain; explicit, one dense n_i x n_i symmetric
  /// matrix-vector product per subdomain (memory-bound: 8 n_i^2 bytes). Allocates nothing.
  void apply_dual(const std::vector<Eigen::VectorXd>& lam, std::vector<Eigen::VectorXd>& out);
  /// Frees the subdomain factorizations and matrices (the explicit blocks stay); solve() then
  /// needs refactor() first.
  void release_factors();
  /// Factors the subdomains again so that solve() works. as_setup: as the constructor did
  /// (explicit: the same interface-last factors, so that solve() gives bit for bit what the kept
  /// factors gave); otherwise a plain factorization with `ordering`, which is all solve() needs
  /// (2D: 40% less numeric work than the interface-last factor; the same solution to round-off).
  void refactor(Ordering ordering, SubdomainCache* cache = nullptr, bool as_setup = true);
  /// Seconds this cluster spent on its primal-constraint setup (K_i^+ C_i^T, the saddle-point
  /// matrix and its LU, U_i), beyond the subdomain factorizations and explicit blocks.
  double setup_seconds() const { return setup_seconds_; }
  /// Bytes held by the explicit blocks F_i (packed), U_i, V_i.
  long explicit_bytes() const;
  /// F on this cluster (its name, sizes; a CheckedClusterOperator's record).
  const ClusterDualOperator& dual_operator() const { return *dual_; }

 private:
  struct LocalRow {
    int constraint;
    int dof;
    double value;
  };
  void solve_saddle();                               // sol_ = S^{-1} rhs_ with the equilibration
  void solve_each(std::vector<Eigen::VectorXd>& x);  // x_i <- K_i^+ x_i, exceptions carried out
  int id_;
  int nc_ = 0;  // primal constraints
  std::vector<Subdomain*> subs_;
  std::vector<int> beta_offset_;                 // first kernel coefficient of subdomain i
  std::vector<int> beta_index_;                  // coefficient -> saddle unknown, -1 if fixed
  Eigen::MatrixXd N_;                            // cluster kernel in coefficient space
  std::vector<std::vector<LocalRow>> c_of_sub_;  // C_i entries, per subdomain
  std::vector<std::vector<int>> cols_of_sub_;    // constraints touching subdomain i
  // K_i^+ C_i^T (columns: cols_of_sub_[i]), read only: shared by equal subdomains of a box
  std::vector<std::shared_ptr<const Eigen::MatrixXd>> W_;
  // P L U of the scaled saddle-point matrix as LAPACK's dgetrf leaves it (L unit lower and U in
  // one matrix; row i was interchanged with row pivots_[i], 0-based, in that order)
  Eigen::MatrixXd lu_;
  std::vector<int> pivots_;
  Eigen::VectorXd rhs_, sol_, dscale_;
  friend class ExplicitClusterOperator;  // uses the saddle-point system
  bool explicit_ = false;
  bool single_ = false, use_single_ = false;  // single sweeps set up / in use
  // With single sweeps each subdomain keeps the single-precision copy alone, its double solves
  // refined with K_rr (Subdomain::SingleCopy): half the factors' memory and of the pages that
  // the setup makes new. Subdomains of a generated grid (SubdomainSystem::repeats) share their
  // factors, and keep the double values beside the copy.
  Subdomain::SingleCopy single_copy(const Subdomain& sd) const {
    return !single_       ? Subdomain::SingleCopy::none
           : sd.repeats() ? Subdomain::SingleCopy::beside_double
                          : Subdomain::SingleCopy::instead_of_double;
  }
  std::unique_ptr<ClusterDualOperator> dual_;  // F on this cluster
  std::vector<std::vector<int>> interface_;    // explicit: the dofs ordered last (refactor())
  double setup_seconds_ = 0;
};

}  // namespace htfeti
