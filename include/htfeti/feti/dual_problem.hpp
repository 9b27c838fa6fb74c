// The (H-)TFETI dual problem (paper, (8)-(12) and (14)-(16)):
//     min 1/2 lambda' F lambda - lambda' d   s.t.  lambda_I >= 0,  G lambda = e,
// with F = B~ K~^+ B~^T applied matrix-free, d = B~ K~^+ f - c (c: the right-hand sides of the
// rows: Dirichlet values, gaps), G~ = R~^T B~^T (one row per cluster kernel vector: the coarse
// dimension is the sum of the cluster kernel dimensions), e~ = R~^T f and the orthogonal
// projector P = I - G~^T (G~ G~^T)^{-1} G~ onto Ker G. The orthonormalized G = T G~ with
// T = L^{-1}, G~ G~^T = L L^T, is never formed: P, Q = I - P and ||G x|| = ||Q x|| need only the
// coarse matrix G~ G~^T, which is sparse, assembled once and factored by CHOLMOD on every rank.
//
// Setup (parallel rules of DESIGN.md): each rank generates and assembles only its own
// subdomains, builds the rows of B~ that touch them from the dof sharing, and numbers the rows
// by their keys (parallel/key_numbering.hpp) so that the numbering does not depend on the
// number of ranks; the owner of a row is the rank of the lowest subdomain it touches.
//
// DualProblem is a small aggregate of parts, each with one job and its own state:
//   Multipliers         the numbering of the rows of B~, their data, the exchange of dual
//                       vectors and the fixed-order sums (multipliers.hpp);
//   Cluster             per cluster K~^+ and the dual operator F_c, implicit or explicit
//                       (ClusterDualOperator, cluster.hpp);
//   CoarseSpace         G~, G~ G~^T and its factor, the projector, the coarse image
//                       (coarse_space.hpp);
//   DualPreconditioner  M^{-1} with its scaling (dual_preconditioner.hpp).
// DualProblem itself runs the setup stages, owns the subdomains and clusters, applies F and
// reconstructs the primal solution (reconstruction.cpp: u, energy, KKT checks, contact output).
//
// Vectors passed in and out are the rank's owned part of a dual vector (DualLayout).
// Cost of one F: one forward and one reverse neighbour exchange, per cluster one K~^+ (see
// cluster.hpp) and 2 nnz(B~) flops. Clusters run in parallel over OpenMP threads; each writes
// its B~ x into its own buffer and the buffers are summed in a fixed order afterwards, so the
// result does not depend on the number of threads. Cost of one P: one exchange each way, an
// allreduce of the coarse vector and one sparse coarse solve.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "htfeti/errors.hpp"
#include "htfeti/feti/cluster.hpp"
#include "htfeti/feti/coarse_space.hpp"
#include "htfeti/feti/constraints.hpp"
#include "htfeti/feti/dual_preconditioner.hpp"
#include "htfeti/feti/multipliers.hpp"
#include "htfeti/feti/preconditioner.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"
#include "htfeti/parallel/dual_layout.hpp"
#include "htfeti/qp/qp.hpp"

namespace htfeti {

struct FetiOptions {
  Ordering ordering = Ordering::automatic;  ///< fill-reducing ordering of the subdomain factors
  /// implicit, explicit, or automatic: automatic_prefers_explicit() when its blocks fit
  /// explicit_budget(), and explicit when only it fits in memory (check_memory). checked:
  /// the explicit operator compared with the implicit one at every product (a diagnostic; the
  /// factors are kept, keep_factors ignored).
  DualOperator dual_operator = DualOperator::automatic;
  /// automatic: the cost model's verdict (operator_cost.hpp; set by solve() before the memory
  /// check). Unset (a DualProblem made without solve()): explicit_for_speed().
  std::optional<bool> explicit_by_cost;
  /// With the explicit operator the subdomain factors are needed only for d (setup) and the
  /// primal reconstruction. A cluster frees them right after its setup, and factors again for
  /// the reconstruction (a plain factor, without the interface last: u agrees to round-off), when
  ///  - factor_budget_bytes < 0 (automatic, the default): the machine's available memory, less
  ///    what the clusters not yet set up will still allocate (their F_i, known from the
  ///    multipliers, and their dense K_i^+ C_i^T, estimated from the clusters done), has fallen
  ///    below kFactorReserve of what was available when the factorizations began (measured after
  ///    each cluster: clusters keep their factors while memory is plentiful);
  ///  - factor_budget_bytes >= 0: the rank's factors, estimated at 100 nonzeros per node, exceed
  ///    it (0: always free them).
  /// keep_factors = true always keeps them.
  bool keep_factors = false;
  double factor_budget_bytes = -1;  ///< see keep_factors
  /// The memory the solve may use on each machine, in MiB (0: no limit but the machine's). The
  /// automatic factor release and the memory check (memory_estimate.hpp) then count with the
  /// smaller of it and the available memory; with R ranks on a machine, each rank's share is
  /// memory_limit_mb / R less what the rank already holds.
  double memory_limit_mb = 0;
  /// automatic picks the explicit operator only when its dense blocks (8 n_i^2 bytes per
  /// subdomain, n_i its multipliers) fit this budget on every rank. Negative (the default):
  /// automatic, resolved by the memory check (check_memory: the blocks fit when the whole run
  /// with the explicit operator is estimated at most kExplicitMemoryShare of the memory of every
  /// machine), else kExplicitBudgetUnchecked (explicit_budget()).
  double explicit_budget_bytes = -1;
  /// Storage of the explicit F_i (lower triangle, packed): double, or single precision with
  /// double sums (half the memory and bandwidth; docs/performance.md).
  Precision explicit_precision = Precision::double_;
  /// What the implicit operator's sweeps read: automatic and single take single-precision copies
  /// of the factors of clusters without primal constraints (TFETI), double the factors.
  FactorPrecision factor_precision = FactorPrecision::automatic;
  /// The preconditioner built for apply_preconditioner() (none: not built; preconditioner.hpp).
  PreconditionerKind preconditioner = PreconditionerKind::none;
  Scaling scaling = Scaling::multiplicity;
  /// With the automatic storage the Dirichlet preconditioner stores S_i dense in 2D when
  /// 8 n_b^2 bytes summed over the rank's subdomains fit this budget on every rank (n_b:
  /// interface dofs), else applies it with a factor of K_ii; in 3D always the latter.
  double dirichlet_dense_budget_bytes = 2.0 * (1LL << 30);
  /// Force the Dirichlet storage: 0 automatic (implicit in 3D; in 2D the budget above), 1 dense,
  /// 2 implicit.
  int dirichlet_storage = 0;
  /// The Dirichlet preconditioner's interior: 0 all of it (S_i), k >= 1 the k layers of dofs
  /// next to the interface, the rest clamped (S_i^(k), preconditioner.hpp).
  int dirichlet_layers = 0;
  /// Subdomain factorizations share the symbolic analysis of an earlier subdomain with the same
  /// sparsity pattern (SubdomainCache); this many patterns are kept per rank (0: every subdomain
  /// is analysed on its own). The factors are the same either way.
  int symbolic_cache_patterns = 64;
  /// With the symbolic cache on, numeric factors of repeated patterns are kept too, up to this
  /// many bytes per rank, and a subdomain whose K_rr equals a kept one entry for entry copies
  /// its factor instead of factoring (SubdomainCache; the same factor bit for bit). 0: off.
  double numeric_cache_bytes = 512.0 * (1 << 20);
  /// With automatic storage in 2D, what to use when the dense S_i do not fit: the implicit
  /// Dirichlet preconditioner (dirichlet), or another kind (the automatic choice falls back to
  /// none: the implicit one needs a second factor per subdomain, which the memory check does not
  /// count). In 3D the automatic storage is implicit and there is no fallback.
  PreconditionerKind dirichlet_fallback = PreconditionerKind::dirichlet;
  /// How many ranks hold the factor of the coarse matrix G~ G~^T (CoarseSpace): 0 (or the rank
  /// count or more) every rank, as before; K > 0 splits the ranks into groups of ceil(P / K)
  /// consecutive ranks, whose first rank factors and solves, then broadcasts the solution to its
  /// group. The same solution bit for bit; the other ranks hold no coarse factor.
  int coarse_ranks = 0;
};

constexpr int kExplicitMinNodes = 25;
/// The automatic explicit budget: the share of a machine's memory the estimated run with the
/// explicit operator may take (the estimate leaves out the dual vectors and the clusters' dense
/// K_i^+ C_i^T; the factor release frees factors when memory runs short), and the budget per
/// rank when no memory check resolves it.
constexpr double kExplicitMemoryShare = 0.75;
constexpr double kExplicitBudgetUnchecked = 4.0 * (1LL << 30);
/// The budget in effect for the explicit blocks (bytes per rank).
inline double explicit_budget(const FetiOptions& o) {
  return o.explicit_budget_bytes < 0 ? kExplicitBudgetUnchecked : o.explicit_budget_bytes;
}
/// The automatic operator's rule for speed: explicit in 2D when every subdomain has at least
/// kExplicitMinNodes nodes (the packed F_i are 45 times faster per F than the factor sweeps and
/// pay for their setup after about 20 applications), implicit in 3D, where the F_i over large
/// interfaces are no faster per F than the sweeps and cost 8 times a factorization to form
/// (`bench/operator_choice.py`: 2.1-4.2x faster runs with the implicit operator on the cube,
/// box and METIS split). The explicit operator is still taken in 3D when the implicit one does not
/// fit in memory (check_memory: its factors can be freed after setup).
inline bool explicit_for_speed(int dim, double min_nodes) {
  return dim == 2 && min_nodes >= kExplicitMinNodes;
}
/// The automatic operator, as far as speed goes: the cost model's verdict where solve() ran it,
/// else the rule above. (The explicit blocks must still fit explicit_budget().)
inline bool automatic_prefers_explicit(const FetiOptions& o, int dim, double min_nodes) {
  return o.explicit_by_cost.value_or(explicit_for_speed(dim, min_nodes));
}
/// Automatic factor release: clusters keep their factors while the available memory stays above
/// this fraction of what was available at the start of the setup (FetiOptions::keep_factors).
constexpr double kFactorReserve = 0.3;

/// Seconds spent in each setup phase (wall clock on this rank).
struct SetupTimings {
  double assembly = 0, factorization = 0, constraints = 0, coarse = 0;
  double cluster_setup =
      0;  ///< part of factorization: primal-constraint systems (summed over clusters)
  double preconditioner = 0;  ///< part of factorization: the local preconditioners (summed)
  /// Part of factorization, summed over subdomains (thread-seconds): forming K_rr, ordering and
  /// symbolic analysis (or its copy from the cache), and the numeric factorization.
  double factor_symbolic = 0, factor_numeric = 0;
  /// The rank's SubdomainCache after the setup's factorizations (subdomains and preconditioner):
  /// analyses done, analyses reused, patterns held (all 0 when the cache is off).
  long symbolic_analyses = 0, symbolic_reuses = 0, symbolic_patterns = 0;
  /// Factorizations that copied the numeric factor of an equal matrix; numeric factors held.
  long numeric_reuses = 0, numeric_matrices = 0;
  long solve_reuses = 0;  ///< cluster solves K_i^+ C_i^T taken from an equal subdomain's
  /// Peak resident memory of the rank (MiB) at the end of each setup phase.
  double factor_mb = 0;  ///< the rank's subdomain factors as built (before any release)
  /// The same with a factor shared by equal subdomains (numeric cache) counted once.
  double distinct_factor_mb = 0;
  /// The single-precision copies of the factors (a shared copy counted once).
  double single_factor_mb = 0;
  /// The K_rr kept to refine double solves where a factor is kept in single precision alone.
  double refinement_mb = 0;
  /// Subdomains whose assembled K_i equals an earlier one's and shares its storage.
  long shared_matrices = 0;
  double peak_mb_assembly = 0, peak_mb_constraints = 0, peak_mb_factorization = 0,
         peak_mb_coarse = 0;
};

class DualProblem {
 public:
  using Vec = Eigen::VectorXd;
  /// Builds the rank's part of the dual problem. make_input(s) returns the input of subdomain s
  /// (called once for each subdomain of the rank's clusters, possibly from several threads).
  /// Collective; a failure on any rank (bad input, a non-positive pivot) is agreed on by all
  /// ranks and thrown on every rank (std::runtime_error, or std::invalid_argument for input).
  DualProblem(const FetiLayout& layout, const std::function<SubdomainInput(int)>& make_input,
              const Comm& comm, const FetiOptions& options = {});
  // The parts refer to each other (coarse_ to multipliers_): a DualProblem stays where it is.
  DualProblem(const DualProblem&) = delete;
  DualProblem& operator=(const DualProblem&) = delete;

  const FetiLayout& layout() const { return layout_; }
  const Comm& comm() const { return comm_; }
  int n_owned() const { return multipliers_.n_owned(); }
  long long dual_dimension() const { return multipliers_.dimension; }
  long long equalities() const {
    return multipliers_.dimension - multipliers_.inequalities - multipliers_.friction_rows;
  }
  /// Tangential rows of Tresca friction (neither equalities nor contact rows).
  long long friction_rows() const { return multipliers_.friction_rows; }
  long long inequalities() const { return multipliers_.inequalities; }
  int coarse_dimension() const { return coarse_.dimension(); }
  /// The kernel dimension of every cluster (all ranks): the rows of G~ it contributes.
  std::vector<int> cluster_kernel_dimensions() const { return coarse_.cluster_kernel_dimensions(); }
  /// Clusters [first, last) of this rank.
  std::pair<int, int> cluster_range() const { return {first_cluster_, end_cluster_}; }
  const SetupTimings& setup_timings() const { return setup_; }
  /// Global index of owned entry i.
  long long global_index(int i) const { return multipliers_.layout.global(i); }

  void apply_F(const Vec& lambda, Vec& y);
  /// y = M^{-1} x = B_D S B_D^T x (Dirichlet) or B_D K B_D^T x (lumped), summed over the
  /// subdomains in a fixed order (preconditioner.hpp; the caller projects: P M^{-1} P).
  /// Requires FetiOptions::preconditioner != none. Cost: one exchange each way and one
  /// LocalPreconditioner::apply per subdomain.
  void apply_preconditioner(const Vec& x, Vec& y) { preconditioner_.apply(multipliers_, x, y); }
  PreconditionerKind preconditioner() const { return preconditioner_.kind(); }
  Scaling scaling() const { return preconditioner_.scaling(); }
  /// Whether the Dirichlet S_i are stored dense on every rank (false: implicit somewhere).
  bool preconditioner_dense() const { return preconditioner_.dense(); }
  int preconditioner_layers() const { return preconditioner_.layers(); }
  /// Whether the implicit Dirichlet preconditioner solves in single precision on this rank.
  bool preconditioner_single() const { return preconditioner_.single(); }
  long preconditioner_bytes() const { return preconditioner_.bytes(); }  ///< on this rank
  /// Global sums that do not depend on the number of ranks: per owner cluster (the cluster of the
  /// lowest subdomain a multiplier touches) a partial sum over its entries in global order, the
  /// partial sums combined in cluster order. Collective.
  double dot(const Vec& a, const Vec& b) const { return multipliers_.dot(a, b); }
  /// Several dot products and sums in one reduction (Multipliers::dots).
  void dots(int count, const Vec* const* a, const Vec* const* b, double* out) const {
    multipliers_.dots(count, a, b, out);
  }
  double sum(const Vec& v) const { return multipliers_.sum(v); }
  /// coarse = G~ lambda (all clusters, on every rank).
  void apply_G(const Vec& lambda, Vec& coarse) { coarse_.apply_G(lambda, coarse); }
  /// lambda = G~^T coarse.
  void apply_Gt(const Vec& coarse, Vec& lambda) { coarse_.apply_Gt(coarse, lambda); }
  /// coarse <- (G~ G~^T)^{-1} coarse.
  void coarse_solve(Vec& coarse) { coarse_.solve(coarse); }
  /// coarse <- (G~ W G~^T)^{-1} coarse, W = diag(weight) on the owned rows (as the
  /// reconstruction masks open contact rows); returns its null dimension (CoarseSpace).
  int coarse_solve_weighted(const std::vector<double>& weight, Vec& coarse) {
    return coarse_.solve_weighted(weight, coarse);
  }
  /// Directions of the coarse space that no constraint row restrains (0 for a well-posed
  /// problem; see CoarseSpace::Factor): the solution is unique up to these rigid motions, whose
  /// coefficients are chosen zero.
  int unrestrained_rigid_motions() const { return coarse_.null_dimension(); }
  /// As above for the reconstruction, where the contact rows with a zero multiplier drop out.
  int unrestrained_at_solution() const { return reconstruction_null_; }
  /// y = P x (x and y may alias).
  void project(const Vec& x, Vec& y) { coarse_.project(x, y); }
  /// The coefficient field's largest ratio max / min over one subdomain's cells, and over all
  /// cells (SubdomainSystem::coefficient_min, coefficient_max; 1 without a field).
  double coefficient_spread() const { return coefficient_spread_; }
  double coefficient_range() const { return coefficient_range_; }
  /// The projector weighted by the stiffness scaling's row stiffness (PCG's preconditioner
  /// P_Q M^{-1} P_Q^T); false when there is no stiffness scaling. Collective.
  bool set_weighted_projector() {
    if (!preconditioner_.has_row_stiffness()) return false;
    coarse_.set_weighted(preconditioner_.row_stiffness());
    return true;
  }
  void project_weighted(const Vec& x, Vec& y, bool transpose) {
    coarse_.project_weighted(x, y, transpose);
  }
  /// The face of the bounds for SMALBE-M's face solve (CoarseSpace::set_face, face_correction):
  /// free is 1 on the owned multipliers not held at a bound. Collective.
  bool set_face(const Vec& free) { return coarse_.set_face(free); }
  void face_correction(const Vec& v, Vec& y) { coarse_.face_correction(v, y); }
  bool face_cheap() const { return coarse_.face_cheap(); }

  /// The coarse image of F, for one coarse step per Hessian product (docs/method.md, "One
  /// coarse step per Hessian product"): E = F G~^T, stored by owned rows, and the coarse matrix
  /// C = G~ F G~^T (on every rank). Columns of E are formed together for clusters of one colour
  /// of a distance-3 colouring of the cluster graph (clusters are adjacent when a row of B~
  /// touches both), whose columns of F G~^T then have disjoint supports: one G~^T and one F
  /// application per (colour, kernel vector). Collective. Throws std::invalid_argument on every
  /// rank when E would not fit in the memory usable on some rank (usable_memory_mb with
  /// memory_limit_mb, MiB per machine, 0: the machine's).
  void build_coarse_image(double memory_limit_mb = 0) {
    coarse_.build_image([this](const Vec& x, Vec& y) { apply_F(x, y); }, memory_limit_mb);
  }
  bool has_coarse_image() const { return coarse_.has_image(); }
  using CoarseImageStats = CoarseSpace::ImageStats;
  const CoarseImageStats& coarse_image_stats() const { return coarse_.image_stats(); }
  /// y = E z (the owned rows of F G~^T z); requires build_coarse_image().
  void apply_coarse_image(const Vec& z, Vec& y) const { coarse_.apply_image(z, y); }
  /// The second half of H_rho v = P F P v + rho Q v with one global reduction, given fv = F v
  /// (requires build_coarse_image()): [a, b] = [G~ v, G~ fv] summed in one allreduce,
  /// z1 = (G~ G~^T)^{-1} a, z2 = (G~ G~^T)^{-1} (b - C z1) (no communication between the two),
  /// qv = G~^T z1 = Q v and y = fv - E z1 - G~^T z2 + rho qv. Cost: one pass of G~ over two
  /// vectors and one of G~^T for two coarse vectors (each entry summed as by apply_G and
  /// apply_Gt), one of E, two sparse coarse solves and one product with C.
  void hessian_from_Fv(const Vec& v, const Vec& fv, double rho, Vec& y, Vec& qv) {
    coarse_.hessian_from_Fv(v, fv, rho, y, qv);
  }

  /// d = B~ K~^+ f - c.
  const Vec& d() const { return d_; }
  /// e~ = R~^T f (all clusters).
  const Vec& e() const { return e_; }
  /// A solution of G~ lambda = e~ (the paper's (12)): the least-squares one,
  /// G~^T (G~ G~^T)^{-1} e~, or, when that one leaves the feasible set and the equality rows alone
  /// restrain every rigid motion, W G~^T (G~ W G~^T)^{-1} e~ with W = 0 on the bounded rows
  /// (then zero is feasible for the homogenized QP: see choose_feasible_lambda_tilde).
  const Vec& lambda_tilde() const { return lambda_tilde_; }
  /// How lambda~ was chosen: "least squares" or "equality rows".
  const std::string& lambda_tilde_choice() const { return lambda_tilde_choice_; }
  /// The feasible set of the owned multipliers (the dual problem's Omega): lambda_I >= 0 on the
  /// contact rows (qp::LowerBounds) and, with friction, |lambda_t| <= bound: an interval per
  /// tangential row in 2D (qp::BoxBounds), a disc per node's two tangential rows in 3D
  /// (qp::SeparableSet, solved by MPGP).
  std::shared_ptr<const qp::ConstraintSet> constraint_set() const;
  /// Whether some contact condition has friction (tangential rows), and Coulomb friction.
  bool has_friction() const { return multipliers_.friction_rows > 0; }
  bool has_coulomb() const { return coulomb_; }
  /// Coulomb: the bound of every Coulomb friction row is mu max(lambda_n, 0), lambda_n of its
  /// node's normal row (a fixed-point step on the slip bound); returns ||new - old|| and ||new||
  /// over the Coulomb rows (global) and, with `apply`, makes them the bounds in effect (without,
  /// the bounds the multipliers were solved with stay: the reconstruction tells stick from slip
  /// by them). Collective.
  std::pair<double, double> update_coulomb_bounds(const Vec& lambda, bool apply);
  /// Whether owned friction row k slips at lambda: |lambda_k| (2D) or the length of its node's
  /// pair (3D) is at its bound within rel_tol.
  bool friction_slips(int k, const Vec& lambda, double rel_tol) const;
  /// Per friction condition summed over ranks: the total tangential force sum scale * lambda
  /// along t (2D), and the contact nodes with friction in stick (their tangential multipliers
  /// below the bound by more than rel_tol) and in slip.
  struct FrictionSummary {
    double tangential_force = 0;
    long long stick = 0, slip = 0;
  };
  FrictionSummary friction_summary(const Vec& lambda, double rel_tol = 1e-6) const;
  bool has_inequalities() const { return multipliers_.inequalities > 0; }
  /// Why a contact problem has no solution, or "" when it has one (or the check cannot be made:
  /// a coarse dimension over kMaxDenseCoarse): a rigid motion restrained by no equality that
  /// opens every contact it touches while the load does work along it (Farkas' lemma on the
  /// coarse space; coarse_space.cpp). Costs one coarse factorization (dense when singular);
  /// called when SMALBE-M did not converge. Collective.
  std::string unbounded_motion() {
    // (With friction the tangential rows are bounded both ways: no diagnosis is attempted.)
    return multipliers_.inequalities && !has_friction() ? coarse_.unbounded_motion(e_) : "";
  }

  /// Primal solution u = K~^+ (f - B~^T lambda) + R~ alpha, with alpha chosen so that the
  /// equality rows and the contact rows with lambda_i > 0 hold in the least-squares sense
  /// (paper, (10)). One vector per local subdomain, in the order of subdomains().
  std::vector<Vec> reconstruct(const Vec& lambda);

  const std::vector<std::unique_ptr<Subdomain>>& subdomains() const { return subs_; }

  /// Checks of a primal solution (global, on every rank).
  struct Kkt {
    double equality_residual = 0;  ///< ||B_E u - c_E||
    /// ||u|| + ||c_E|| (u over all copies): B~ has orthonormal rows, so ||B_E u - c_E|| is at
    /// most this; a solution whose residual comes near it does not hold the subdomains together
    double equality_scale = 0;
    double max_violation = 0;    ///< max over contact rows of (n.(u_a - u_b) - gap)_+
    double min_multiplier = 0;   ///< smallest contact force (0 without contact)
    double complementarity = 0;  ///< max |force * gap| over contact rows
  };
  Kkt kkt(const std::vector<Vec>& u, const Vec& lambda);
  /// q(u) = 1/2 u'Ku - f'u summed over subdomains.
  double energy(const std::vector<Vec>& u) const;

  /// Per contact row, sorted by the point (x, y, z), gathered on rank 0 (empty elsewhere):
  /// coordinates of node a (the slave node of a mortar row), the normal displacements n.u_a and
  /// n.u_b (0 for an obstacle; for a mortar row the averages over the slave and master sides,
  /// weighted by D and M), the remaining gap (length), the row's force (W scale lambda) and its
  /// pressure (the force over the row's contact area; NaN where the group has no facets).
  /// With friction also the tangential traction on the body (2D: along t = (-n_y, n_x), 3D:
  /// its length), the slip (the tangential relative displacement, likewise) and the state (0
  /// open, 1 stick, 2 slip); NaN on rows without friction.
  struct ContactData {
    std::vector<double> x, y, z, u_a, u_b, gap, force, pressure, tangential, slip, state;
  };
  ContactData contact_data(const std::vector<Vec>& u, const Vec& lambda);
  /// The per-row values behind contact_data and contact_fields, on the owned rows (NaN on rows
  /// that are not contact rows or lack the value): the side sums n.(avg u_a) and n.(avg u_b)
  /// times the row's scale, the pressure, the tangential traction, the slip and the state.
  /// Collective.
  struct ContactRowValues {
    Vec u_a, u_b, pressure, tangential, slip, state;
  };
  ContactRowValues contact_row_values(const std::vector<Vec>& u, const Vec& lambda);

  /// Per contact condition (0 .. conditions - 1, the problem file's order; the rows carry their
  /// condition): rows, rows in contact (lambda > 0), the contact area of those rows, the total
  /// normal force (positive in compression) and the largest penetration (the most negative
  /// remaining gap, as a positive length; 0 when none). The same on every rank, independent of
  /// the rank count. Collective.
  /// `resultant`: the force of the condition's rows on the body of its key nodes (the slave
  /// body; the body on an obstacle), -B_I^T lambda summed over those nodes, in the global frame
  /// (Laplace: its one component first).
  /// With friction also: `tangential` the friction rows' force on the same body (global
  /// frame), `tangential_force` its sum along each row's tangent (2D: a number along
  /// t = (-n_y, n_x)), and the nodes with friction rows that are open (lambda_n = 0), in stick
  /// and in slip (their tangential multipliers at the bound within 1e-6).
  struct ContactSummary {
    long long rows = 0, active = 0;
    double area = 0, normal_force = 0, max_penetration = 0;
    std::array<double, 3> resultant{0, 0, 0};
    bool friction = false;
    std::array<double, 3> tangential{0, 0, 0};
    double tangential_force = 0;
    long long open = 0, stick = 0, slip = 0;
  };
  std::vector<ContactSummary> contact_summary(const std::vector<Vec>& u, const Vec& lambda,
                                              int conditions);
  /// Per local subdomain one value per node, at the node each contact row is keyed by (a, an
  /// obstacle's node, a mortar row's slave node; NaN elsewhere): the pressure (of all the node's
  /// rows), and with friction the tangential traction, the slip and the state of contact_data.
  /// Collective.
  struct ContactFields {
    std::vector<Vec> pressure, tangential, slip, state;
  };
  ContactFields contact_fields(const std::vector<Vec>& u, const Vec& lambda);

  /// The force of the contact rows on each local subdomain's copy, -B_I^T lambda (one vector per
  /// local subdomain; summed over a node's copies it is the nodal contact force). Collective.
  std::vector<Vec> contact_forces(const Vec& lambda);

  /// The remaining gap gap - n.(u_a - u_b) of each contact row at the copies of the node it is
  /// keyed by (a, or the slave node), per local subdomain one value per node (the smallest of
  /// the node's rows; NaN on nodes without one). Collective.
  std::vector<Vec> contact_gap_field(const std::vector<Vec>& u);

  long factor_nonzeros() const;  ///< summed over this rank's subdomains
  /// Whether the explicit blocks apply F (explicit or checked).
  bool explicit_operator() const { return explicit_; }
  /// The dual operator in effect: "implicit", "explicit" or "checked".
  std::string dual_operator_name() const {
    return checked_ ? "checked" : explicit_ ? "explicit" : "implicit";
  }
  /// With the checked operator: the products with F and the largest relative difference
  /// ||F_explicit lam - F_implicit lam|| / ||F_implicit lam|| of a cluster over them (all ranks).
  /// Collective.
  struct OperatorCheck {
    long applications = 0;
    double max_relative_difference = 0;
  };
  OperatorCheck dual_operator_check() const;
  /// The ordering of the subdomain factors in effect (automatic resolved). The explicit operator
  /// orders the interface last, the rest by constrained AMD (amd) or by nested dissection.
  std::string ordering_in_effect() const {
    return explicit_ ? (ordering_ == Ordering::amd ? std::string("camd") : to_string(ordering_)) +
                           " (interface last)"
                     : to_string(ordering_);
  }
  /// Whether the subdomain factors of some cluster were freed after setup and are rebuilt for the
  /// reconstruction (on any rank), and how many clusters of this rank freed them.
  bool factors_released() const { return factors_released_; }
  /// Whether the implicit operator reads single-precision copies of the factors on some rank
  /// (FetiOptions::factor_precision), and the switch between them and the factors (collective
  /// in effect: every rank switches with the same argument).
  bool single_sweeps() const { return single_sweeps_; }
  void set_single_sweeps(bool on);
  int clusters_released() const;
  long explicit_bytes() const;         ///< bytes of the explicit blocks on this rank
  long cluster_dense_doubles() const;  ///< doubles in the clusters' K^+ C^T blocks and LUs
  long coarse_factor_nonzeros() const { return coarse_.factor_nonzeros(); }
  /// How many ranks hold a copy of the coarse factor (FetiOptions::coarse_ranks).
  int coarse_factor_ranks() const { return coarse_.factor_ranks(); }

 private:
  // The setup in stages (the constructor calls them in this order; Setup carries what one stage
  // hands to the next and is dropped at the end). dual_problem.cpp.
  struct Setup;
  // 1. Per cluster: the subdomains assembled, their rows of B~ and the primal constraints.
  void assemble_subdomains(const std::function<SubdomainInput(int)>& make_input, Setup& st);
  // 2. The multipliers numbered globally by key, and on each subdomain (Multipliers::number).
  void number_multipliers(Setup& st);
  // The dual operator (implicit or explicit) and the ordering of the factors.
  void choose_operator(Setup& st);
  // The preconditioner's interfaces and its storage (dense or implicit Dirichlet blocks).
  void plan_preconditioner(Setup& st);
  // 3. Clusters: factorizations, explicit blocks, primal-constraint systems, the local
  //    preconditioners, the clusters' parts of d, and the factor release.
  void set_up_clusters(Setup& st);
  // 4. The coarse space: cluster kernel dimensions, the rows of G~ and its pairs for G~^T.
  void set_up_coarse_space(Setup& st);
  // The coarse factor, d, e~, lambda~, the bounds and the scaling.
  void finish_setup(Setup& st);
  // lambda~ with zero on the contact and friction rows, when the least-squares lambda~ violates
  // their bounds and G~ restricted to the other rows has full rank. Homogenized by it, the QP's
  // start x = 0 is feasible and in Ker G~: MPRGP then starts on the equality constraint instead
  // of from the projection of 0 onto the shifted bounds, which SMALBE-M's outer loop has to
  // bring back to Ker G~ (examples/membranes-coercive.toml: 43 products instead of 69). Costs
  // one more coarse factorization, only when the least-squares lambda~ is infeasible.
  void choose_feasible_lambda_tilde();
  void cluster_rhs_from_ext(int c, bool add_f,
                            double sign);  // x_i = (f_i) + sign B_i^T multipliers_.ext_in
  void b_of_x(int c);                      // contrib_ = B_i x_i, per row entry
  template <class Body>
  void for_each_cluster(Body body);  // OpenMP over local clusters
  // B~ applied to per-subdomain vectors; sums are on owners afterwards (reverse_add done).
  void apply_B(const std::vector<Vec>& u, Vec& out);
  int members(int c) const { return sub_first_[c + 1] - sub_first_[c]; }
  int sub_of(int c, int i) const { return sub_first_[c] + i; }

  FetiLayout layout_;
  const Comm& comm_;
  SetupTimings setup_;
  int first_cluster_ = 0, end_cluster_ = 0;  // local clusters
  std::vector<int> sub_first_;               // per local cluster: first local subdomain index
  std::vector<std::unique_ptr<Subdomain>> subs_;
  std::vector<std::unique_ptr<Cluster>> clusters_;
  // Equal subdomains' matrices, analyses, factors and their results (sparse_cholesky.hpp).
  std::unique_ptr<SubdomainCache> cache_;
  // The cache for factorizations: null when its factor levels are off.
  SubdomainCache* factor_cache() const {
    return cache_ && cache_->factors() ? cache_.get() : nullptr;
  }
  // The multipliers: numbering, rows of B~ per subdomain, row data and the exchange.
  Multipliers multipliers_;
  // The coarse space: G~, its factor, the projector and the coarse image.
  CoarseSpace coarse_{layout_, comm_, multipliers_};
  int reconstruction_null_ = 0;
  Vec d_, e_, lambda_tilde_;
  std::string lambda_tilde_choice_ = "least squares";
  bool coulomb_ = false;  // some friction row is Coulomb's
  // work arrays (allocated once)
  std::vector<std::vector<Vec>> x_;           // per cluster, per subdomain
  std::vector<std::vector<double>> contrib_;  // per subdomain, per row entry
  std::vector<std::vector<Vec>> lam_, out_;   // per cluster, per subdomain: local dual vectors
  // The preconditioner with its scaling.
  DualPreconditioner preconditioner_;
  bool explicit_ = false;
  bool checked_ = false;  // the explicit operator checked against the implicit one
  bool factors_released_ = false;
  bool single_sweeps_ = false;
  std::vector<char> released_;     // per local cluster: factors freed after setup
  bool by_object_ = false;         // the clusters' K_i^+ C_i^T by object (Cluster)
  double coefficient_spread_ = 1;  // the largest coefficient max / min of one subdomain
  double coefficient_range_ = 1;   // the coefficient's max / min over all subdomains
  bool outer_parallel_ = false;    // threads over clusters (true) or inside each cluster
  Ordering ordering_ = Ordering::amd;
};

// OpenMP over the rank's clusters; an exception inside is carried out of the region (the
// other clusters still run; RegionError rethrows the first one after it).
template <class Body>
void DualProblem::for_each_cluster(Body body) {
  const int nc = static_cast<int>(clusters_.size());
  RegionError failure;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) {
    try {
      body(c);
    } catch (const std::exception& e) {
      failure.record(e);
    }
  }
  failure.rethrow();
}

}  // namespace htfeti
