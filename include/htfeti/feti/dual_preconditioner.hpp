// The FETI preconditioner of the dual problem (docs/method.md, "Preconditioners"):
//     M^{-1} = B_D S B_D^T (Dirichlet)  or  B_D K B_D^T (lumped),
// with B_D the rows of B~ scaled by multiplicity or stiffness scaling; the local parts S_i or
// K_i are LocalPreconditioner objects (preconditioner.hpp). The caller projects: P M^{-1} P.
//
// Set up in DualProblem's stages: start() in the assembly (whether the exact node scaling is
// used; then the copy count of every node), plan() once the multipliers are numbered (the
// interface of each subdomain and the storage), set_up_subdomain() from each K_i before it is
// freed, finish() with the work vectors and the stiffness scaling.
// Cost of one apply(): one exchange each way (two more of each with the exact node scaling) and
// one LocalPreconditioner::apply per subdomain; allocates nothing.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <memory>
#include <vector>

#include "htfeti/feti/multipliers.hpp"
#include "htfeti/feti/preconditioner.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"

namespace htfeti {

struct FetiOptions;

class DualPreconditioner {
 public:
  using Vec = Eigen::VectorXd;

  /// Stage 1: kind and scaling as requested (resolved: not automatic); with stiffness scaling on
  /// nodes without primal groups the exact node scaling, which needs every node's copy count
  /// (node_copies(s), filled by the assembly for each of the nsub local subdomains).
  void start(const FetiOptions& options, const FetiLayout& layout, int nsub);
  bool collects_node_copies() const { return !node_copies_.empty(); }
  std::vector<int>& node_copies(int s) { return node_copies_[s]; }

  /// Stage 2: the interface of each subdomain (the dofs its rows of B~ touch, sorted; returned)
  /// and the storage. Automatic storage: in 2D dense S_i when they fit
  /// options.dirichlet_dense_budget_bytes on every rank, else the fallback; in 3D implicit
  /// (docs/method.md, "Preconditioners": measured faster and smaller there). Collective.
  std::vector<std::vector<int>> plan(const FetiOptions& options, const Multipliers& m,
                                     const Comm& comm);
  /// Whether the Dirichlet preconditioner applies S_i with factors of K_ii rather than storing
  /// it dense: asked for (dirichlet_storage 2), or the automatic storage in 3D, or in 2D when the
  /// dense S_i do not fit the budget (dense_fits). plan() decides with it, and so does the memory
  /// check (memory_estimate.cpp).
  static bool implicit_storage(const FetiOptions& options, int dim, bool dense_fits);
  /// Whether set_up_subdomain needs the diagonal of K at the row entries (stiffness scaling).
  bool wants_diagonal() const { return built() && scaling_ == Scaling::stiffness; }

  /// Stage 3: the local part of subdomain s from its K (thread-safe across subdomains).
  void set_up_subdomain(int s, const Eigen::SparseMatrix<double>& K, std::vector<int> interface,
                        Ordering ordering, const Eigen::MatrixXd* kernel, SubdomainCache* cache);

  /// Stage 4: work vectors, and the scaled B_D from rho (per subdomain, per row entry: K's
  /// diagonal; empty for multiplicity scaling). dofs_per_node per local subdomain. Collective.
  void finish(Multipliers& m, const std::vector<std::vector<double>>& rho,
              const std::vector<int>& dofs_per_node);

  /// y = M^{-1} x (owned parts). Requires built(). Collective.
  void apply(Multipliers& m, const Vec& x, Vec& y);

  /// Stiffness scaling: per owned row, the b^2-weighted harmonic mean of diag K over the row's
  /// entries (the weights of the projector P_Q); empty otherwise.
  const std::vector<double>& row_stiffness() const { return row_stiffness_; }
  /// Whether row_stiffness() was formed (on every rank alike; a rank may own no rows).
  bool has_row_stiffness() const { return has_row_stiffness_; }
  bool built() const { return kind_ != PreconditionerKind::none; }
  PreconditionerKind kind() const { return kind_; }
  Scaling scaling() const { return scaling_; }
  /// Whether the Dirichlet S_i are stored dense on this rank.
  bool dense() const { return dense_; }
  /// The Dirichlet preconditioner's layers (FetiOptions::dirichlet_layers; 0: the whole interior).
  int layers() const { return layers_; }
  /// Whether the implicit Dirichlet preconditioner solves with single-precision copies of the
  /// factors of K_ii on this rank (FetiOptions::factor_precision other than double).
  bool single() const {
    for (const auto& l : local_)
      if (l && l->single()) return true;
    return false;
  }
  long bytes() const;  ///< on this rank

 private:
  void build_scaling(Multipliers& m, const std::vector<std::vector<double>>& rho,
                     const std::vector<int>& dofs_per_node);
  // Stiffness scaling on nodes with per-node gluing rows: q = B_g^T B_g w on the interfaces
  // (B_g: those rows; one exchange each way), and the weighted sums over a node's copies.
  void gluing_BtB(Multipliers& m, const std::vector<Vec>& w, std::vector<Vec>& q);
  void copy_sums(Multipliers& m, std::vector<Vec>& v, std::vector<Vec>& sums);

  PreconditionerKind kind_ = PreconditionerKind::none;
  Scaling scaling_ = Scaling::multiplicity;
  bool dense_ = true;
  int layers_ = 0;
  bool single_ = false;  // the implicit form's solves with K_ii in single precision (start)
  int dim_ = 2;
  std::vector<std::unique_ptr<LocalPreconditioner>> local_;  // per local subdomain
  // Per local subdomain, per row entry: the interface position of its dof, and (stiffness
  // scaling) the scaled value of B_D.
  std::vector<std::vector<int>> interface_position_;
  std::vector<std::vector<double>> scaled_value_;
  std::vector<double> row_stiffness_;
  bool has_row_stiffness_ = false;
  std::vector<Vec> in_, out_;  // work: per subdomain, on its interface
  // The exact node scaling (build_scaling): per local subdomain the copies of each node (until
  // finish), and per interface position with per-node gluing rows its copy count and weight.
  bool exact_node_scaling_ = false;
  std::vector<std::vector<int>> node_copies_;
  std::vector<std::vector<int>> node_row_positions_;
  std::vector<std::vector<double>> node_row_copies_, node_row_delta_;
  std::vector<Vec> scaling_w_, scaling_q_, scaling_sums_;  // interface work vectors
};

}  // namespace htfeti
