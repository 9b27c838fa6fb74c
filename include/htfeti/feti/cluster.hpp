// The generalized inverse of a cluster of m x m subdomains joined by primal constraints
// (paper, Section 5: K~ = Z^T diag(K_i) Z, with Z an orthonormal basis of the vectors that satisfy
// the primal constraints C u = 0: corner continuity and/or equal edge averages).
//
// K~^+ is never formed. Applied to a physical right-hand side x (one vector per subdomain) it
// returns y = Z K~^+ Z^T x, the solution of
//     min 1/2 u'Ku - x'u   subject to  C u = 0  and  u(fixed node of subdomain 0) = 0,
// computed from the subdomain generalized inverses K_i^+ (fixed nodes, sparse Cholesky) and a
// small dense saddle-point system over the primal constraints mu and the kernel coefficients beta
// of subdomains 1..s-1 (subdomain 0 is fixed, which removes the cluster kernel):
//     u = K^+ (x - C^T mu) + R' beta,
//     [ C K^+ C^T   -C R' ] [mu  ]   [ C K^+ x ]
//     [ -R'^T C^T     0   ] [beta] = [ -R'^T x ].
// Fixing one cluster variable gives K~^+ = [K~_rr^{-1} 0; 0 0], so K~ K~^+ K~ = K~. For m = 1
// there are no constraints and y = K_0^+ x: plain TFETI.
//
// Cost of one application: one K_i^+ solve per subdomain, plus a dense solve of size
// (#constraints + s - 1) and products with the precomputed K_i^+ C_i^T (at most 12 columns each).
// Setup: #constraints touching a subdomain extra solves per subdomain, and one dense LU.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "htfeti/feti/subdomain.hpp"

namespace htfeti {

/// How F = B~ K~^+ B~^T is applied on a cluster: by sparse triangular solves every time
/// (implicit), or by dense local blocks F_i = B_i K_i^+ B_i^T built once from the Schur complement
/// of each subdomain onto its interface (explicit), plus the low-rank cluster correction
/// B_i K_i^+ C_i^T and B_i R_i (see apply_dual).
enum class DualOperator { implicit, explicit_, automatic };
DualOperator parse_dual_operator(const std::string& name);
std::string to_string(DualOperator kind);

class Cluster {
 public:
  /// subs: the cluster's m*m subdomains in cluster-local order (already assembled); b[i]: the
  /// rows of B~ on subdomain i, numbered 0..nmult[i]-1 locally. Factors the subdomains.
  /// explicit_F: build the dense local blocks (implicit or explicit_, not automatic).
  Cluster(const Decomposition& dec, int id, std::vector<Subdomain*> subs, Ordering ordering,
          std::vector<std::vector<Subdomain::BEntry>> b, std::vector<int> nmult, bool explicit_F);
  /// Without dual rows: for tests of the generalized inverse alone.
  Cluster(const Decomposition& dec, int id, std::vector<Subdomain*> subs, Ordering ordering)
      : Cluster(dec, id, subs, ordering, std::vector<std::vector<Subdomain::BEntry>>(subs.size()),
                std::vector<int>(subs.size(), 0), false) {}

  int id() const { return id_; }
  const std::vector<Subdomain*>& subdomains() const { return subs_; }
  int num_primal_constraints() const { return nc_; }
  /// Value of the cluster kernel R~ (the normalized constant) at every physical dof.
  double kernel_value() const { return kernel_value_; }
  /// Doubles held by the cluster's dense data (K^+ C^T blocks and the LU).
  long dense_doubles() const;

  /// x[i] -> K~^+ x[i] in place (physical vectors of the cluster's subdomains). Allocates nothing.
  void solve(std::vector<Eigen::VectorXd>& x);
  /// out[i] = (B~ K~^+ B~^T lam) restricted to subdomain i's local rows; lam[i], out[i] have
  /// nmult[i] entries. Implicit: x = B^T lam, solve(x), B x. Explicit, with the same dense
  /// saddle-point system as solve():
  ///   out_i = F_i lam_i - U_i mu + V_i beta_i,  U_i = B_i K_i^+ C_i^T,  V_i = B_i R_i,
  ///   [mu; beta] = S^{-1} [sum_i U_i^T lam_i; -V_i^T lam_i].
  /// Cost: implicit, one K_i^+ per subdomain; explicit, one dense n_i x n_i symmetric
  /// matrix-vector product per subdomain (memory-bound: 8 n_i^2 bytes). Allocates nothing.
  void apply_dual(const std::vector<Eigen::VectorXd>& lam, std::vector<Eigen::VectorXd>& out);
  /// Frees the subdomain factorizations and matrices (the explicit blocks stay); solve() then
  /// needs refactor() first.
  void release_factors();
  /// Factors the subdomains again (plain fill-reducing ordering) so that solve() works.
  void refactor(Ordering ordering);
  /// Seconds this cluster spent on its primal-constraint setup (K_i^+ C_i^T, the saddle-point
  /// matrix and its LU, U_i), beyond the subdomain factorizations and explicit blocks.
  double setup_seconds() const { return setup_seconds_; }
  /// Doubles held by the explicit blocks F_i, U_i, V_i.
  long explicit_doubles() const;

 private:
  struct LocalRow {
    int constraint;
    int dof;
    double value;
  };
  int id_;
  int nc_ = 0;  // primal constraints
  std::vector<Subdomain*> subs_;
  std::vector<std::vector<LocalRow>> c_of_sub_;  // C_i entries, per subdomain
  std::vector<std::vector<int>> cols_of_sub_;    // constraints touching subdomain i
  std::vector<Eigen::MatrixXd> W_;               // K_i^+ C_i^T (columns: cols_of_sub_[i])
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  Eigen::VectorXd rhs_, sol_;
  std::vector<std::vector<Subdomain::BEntry>> b_;  // rows of B~ per subdomain (local numbering)
  std::vector<Eigen::VectorXd> xw_;                // implicit apply_dual: physical work vectors
  bool explicit_ = false;
  std::vector<Eigen::MatrixXd> F_, U_;  // explicit: F_i, B_i K_i^+ C_i^T
  std::vector<Eigen::VectorXd> V_;      // explicit: B_i R_i
  double kernel_value_ = 0;
  double setup_seconds_ = 0;
};

}  // namespace htfeti
