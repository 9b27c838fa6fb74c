// The coarse space of (H-)TFETI (paper, (11)-(12) and (15)-(16)): G~ = R~^T B~^T, one row per
// kernel vector of a cluster (the coarse dimension is the sum of the cluster kernel dimensions),
// the coarse matrix G~ G~^T and its factor, the projector P = I - G~^T (G~ G~^T)^{-1} G~ onto
// Ker G~, and the coarse image E = F G~^T with C = G~ F G~^T for one coarse step per Hessian
// product (coarse_image.cpp).
//
// Every rank holds the rows of G~ of its clusters (sparse: the entries at the multipliers the
// cluster's rows touch). The coarse matrix is assembled from partial sums formed per owner
// cluster and added in cluster order, so that nothing depends on the number of ranks, and
// factored by every rank, or (FetiOptions::coarse_ranks = K) by the first rank of each of K
// groups of consecutive ranks, which solves and broadcasts the solution to its group: the same
// factor and the same solution bit for bit, held once per group instead of once per rank.
// G~ and G~^T: every cluster writes its own coarse entries and its own pairs, so threads take
// clusters and each value is formed in the same order as by one thread.
// Cost: apply_G one pass over the rank's G~ and an allreduce of the coarse vector; apply_Gt one
// pass and one reverse exchange (ordered sums over clusters); project both and one sparse
// coarse solve (with coarse_ranks: on the group's first rank, then a broadcast of the coarse
// vector in the group). None allocates.
#pragma once

#include <mpi.h>

#include <Eigen/Dense>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "htfeti/feti/cluster.hpp"
#include "htfeti/feti/multipliers.hpp"
#include "htfeti/feti/sparse_cholesky.hpp"

namespace htfeti {

class CoarseSpace {
 public:
  using Vec = Eigen::VectorXd;
  /// The space of the rank's multipliers (held by reference: the owner of both keeps them in
  /// place, see DualProblem).
  CoarseSpace(const FetiLayout& layout, const Comm& comm, Multipliers& multipliers)
      : layout_(layout), comm_(comm), m_(multipliers) {}
  CoarseSpace(const CoarseSpace&) = delete;
  CoarseSpace& operator=(const CoarseSpace&) = delete;
  ~CoarseSpace();

  /// The kernel dimension of every cluster (allgathered), the rank's rows of G~ and the pairs of
  /// G~^T. clusters: the rank's clusters [first_cluster, first_cluster + clusters.size()), local
  /// cluster c holding the local subdomains [sub_first[c], sub_first[c + 1]); threads go over
  /// clusters when threads_over_clusters; coarse_ranks: FetiOptions::coarse_ranks. Collective.
  void set_up(const std::vector<std::unique_ptr<Cluster>>& clusters, int first_cluster,
              std::vector<int> sub_first, bool threads_over_clusters, int coarse_ranks = 0);
  /// Assembles and factors G~ G~^T. With bounded rows (contact, friction) and a coarse
  /// dimension of at most kFaceCheapDimension it also keeps, from the same pass over G~'s items,
  /// the parts of G~ W G~^T that do not depend on which bounded rows W masks (the fixed part of
  /// solve_weighted and set_face; above that dimension they are formed at their first use).
  /// Collective.
  void factor();

  int dimension() const { return first_.empty() ? 0 : first_.back(); }
  /// Cluster c's first coarse index (all clusters; c = num_clusters gives dimension()).
  int first(int cluster) const { return first_[cluster]; }
  std::vector<int> cluster_kernel_dimensions() const {
    std::vector<int> d(first_.size() - 1);
    for (size_t c = 0; c < d.size(); ++c) d[c] = first_[c + 1] - first_[c];
    return d;
  }

  /// coarse = G~ lambda (all clusters, on every rank).
  void apply_G(const Vec& lambda, Vec& coarse);
  /// lambda = G~^T coarse.
  void apply_Gt(const Vec& coarse, Vec& lambda);
  /// coarse <- (G~ G~^T)^{-1} coarse. Collective when the factor is held by a subset of ranks.
  void solve(Vec& coarse) { solve_with(factor_, coarse); }
  /// y = P x (x and y may alias).
  void project(const Vec& x, Vec& y);
  /// coarse <- (G~ W G~^T)^{-1} coarse with W = diag(weight) on the owned multipliers (the
  /// reconstruction's active rows); returns the null dimension of G~ W G~^T. Where W is 1 on
  /// every row that is neither a contact nor a friction row, G~ W G~^T is the fixed part (kept,
  /// or formed at this first use) plus the bounded rows' products (a pass over the bounded rows'
  /// items only); otherwise it is assembled from all of G~'s items. Collective.
  int solve_weighted(const std::vector<double>& weight, Vec& coarse);

  /// The face of the bounds (qp/face_cg.hpp): assembles and factors G~ D G~^T, D = diag(free)
  /// on the owned multipliers (1 free, 0 held at a bound). Returns false, and keeps no factor,
  /// when that matrix is singular (a rigid motion restrained only by rows held at a bound: the
  /// problem on the face is not well posed). Collective.
  bool set_face(const Vec& free);
  /// y = G~^T (G~ D G~^T)^{-1} G~ v for the face last set (x and y may alias). Collective.
  void face_correction(const Vec& v, Vec& y);
  /// Whether faces may be tried early (SMALBE-M, face_cg.hpp): once a face has been set, or
  /// where the coarse dimension is at most kFaceCheapDimension. This was the rule when a first
  /// face paid for the pass over all of G~'s items (1.9 s = 6 products at 3,072 with 512 METIS
  /// parts, 19.7 s = 16 products at 24,576 in Table 4 row 1), which factor() now makes up to
  /// kFaceCheapDimension; the rule is kept as measured (trying faces earlier changes
  /// SMALBE-M's path).
  bool face_cheap() const { return face_used_ || dimension() <= kFaceCheapDimension; }
  static constexpr int kFaceCheapDimension = 4096;

  /// Directions of the coarse space that no constraint row restrains (see Factor).
  int null_dimension() const { return factor_.null_dimension(); }
  const Eigen::MatrixXd& null_space() const { return factor_.null; }
  /// Of one copy of the factor (the same on every rank, also where none is held).
  long factor_nonzeros() const { return factor_.nonzeros; }
  /// How many ranks hold the coarse factor (every rank, or one per group: coarse_ranks).
  int factor_ranks() const { return factor_ranks_; }
  /// "k rigid motion(s) of cluster(s) ..." for the null directions Z (columns).
  std::string describe_null(const Eigen::MatrixXd& Z) const;
  /// Why the contact problem with coarse right-hand side e has no solution, or "" (Farkas'
  /// lemma on the rigid motions no equality restrains; DualProblem::unbounded_motion).
  std::string unbounded_motion(const Vec& e);

  /// The coarse image (coarse_image.cpp): E = F G~^T by owned rows and C = G~ F G~^T on every
  /// rank, formed with apply_F. Throws std::invalid_argument on every rank when E does not fit
  /// in the usable memory (memory_limit_mb: MiB per machine, 0: the machine's). Collective.
  void build_image(const std::function<void(const Vec&, Vec&)>& apply_F, double memory_limit_mb);
  bool has_image() const { return image_.built; }
  struct ImageStats {
    int colours = 0;           ///< of the distance-3 colouring
    int F_applications = 0;    ///< spent forming E
    long long E_nonzeros = 0;  ///< summed over ranks
    long long C_nonzeros = 0;
    double seconds = 0;  ///< wall clock on this rank
  };
  const ImageStats& image_stats() const { return image_.stats; }
  /// y = E z (the owned rows of F G~^T z).
  void apply_image(const Vec& z, Vec& y) const;
  /// H_rho v = P F P v + rho Q v from fv = F v with one global reduction (DualProblem).
  void hessian_from_Fv(const Vec& v, const Vec& fv, double rho, Vec& y, Vec& qv);

  /// The projector weighted by Q = diag(q) (q > 0 per owned multiplier): forms and factors
  /// G~ Q G~^T (collective). Then project_weighted applies P_Q = I - Q G~^T (G~ Q G~^T)^{-1} G~
  /// (onto Ker G~) or, with transpose, P_Q^T = I - G~^T (G~ Q G~^T)^{-1} G~ Q (zero on Im G~^T).
  void set_weighted(const std::vector<double>& q);
  void project_weighted(const Vec& x, Vec& y, bool transpose);

 private:
  // The coarse matrix G~ W G~^T (W = diag(weight)) and its factor. Sparse Cholesky; if that
  // finds the matrix singular (a floating body that no constraint restrains: a pure Neumann
  // problem, or in the reconstruction a body whose contact rows all have zero multipliers),
  // the matrix is formed densely (up to kMaxDense), its null space Z found by a symmetric
  // eigendecomposition, and G W G^T + Z Z^T factored instead: on the range of G W G^T that is
  // the pseudo-inverse, and the coefficients along Z come out zero.
  struct Factor {
    SparseCholesky sparse;
    Eigen::LLT<Eigen::MatrixXd> dense;
    Eigen::MatrixXd null;  // Z (orthonormal columns); empty when the sparse factor is used
    bool use_dense = false;
    long nonzeros = 0;  // of the factor (the same on every rank, also where none is held)
    void solve(Vec& x) {
      if (use_dense)
        x = dense.solve(x);  // allocates: only for degenerate problems
      else
        sparse.solve(x.data(), x.data());
    }
    int null_dimension() const { return static_cast<int>(null.cols()); }
  };
  static constexpr int kMaxDense = 4000;
  static constexpr double kSingularRcond = 1e-15;  // SparseCholesky::rcond() below it: singular
  // Returns false, leaving factor empty, for a singular matrix when fail_if_singular (the face);
  // else a singular matrix takes the dense path above (true).
  bool assemble(const std::vector<double>& weight, Factor& factor, bool fail_if_singular = false);
  // x <- factor^{-1} x: on every rank (replicated, or the dense factor of a singular problem),
  // or on the group's first rank and broadcast in the group.
  void solve_with(Factor& factor, Vec& x);
  void gt_into_ext(const Vec& coarse);  // m_.ext_out = G~^T coarse (owners summed)
  // m_.ext_out = G~^T factor^{-1} G~ v: the coarse correction of P, P_Q and the face.
  void coarse_correction(const Vec& v, Factor& factor);
  // The passes over one local cluster's rows (entry_*: see below); allocate nothing.
  static constexpr int kFusedRows = 16;  // kernel dimensions up to this: one pass for all rows
  void apply_rows(int c, const double* x, double* out) const;
  void pairs_from_rows(int c, const double* z, double* pairs) const;
  int local_clusters() const { return static_cast<int>(rows_.size()); }
  int members(int c) const { return sub_first_[c + 1] - sub_first_[c]; }
  int sub_of(int c, int i) const { return sub_first_[c] + i; }

  // G~'s columns at the owned multipliers: (global multiplier, coarse row, value) for every
  // nonzero of G~, sent to the multiplier's owner and sorted by (multiplier, row). Collective.
  struct GItem {
    long long k;
    int row;
    double g;
  };
  std::vector<GItem> g_columns_at_owners() const;
  // (key, a, b, value) partial sums of a coarse matrix, summed over ranks in (a, b, key) order.
  struct CoarseTriplet {
    long long k;
    int a, b;
    double v;
  };
  static MPI_Datatype triplet_type();  // committed; the caller frees it
  std::vector<CoarseTriplet> allgather_sorted(const std::vector<CoarseTriplet>& mine,
                                              MPI_Comm comm) const;
  // The summed triplets on the ranks that factor (all, or the groups' first ranks; the others
  // get none): allgather_sorted, or a gather to each group's first rank and an allgather among
  // those.
  std::vector<CoarseTriplet> gather_to_factor_ranks(const std::vector<CoarseTriplet>& mine) const;
  // Partial sums of a coarse matrix sum_k (products at multiplier k): products_of(i, j, out)
  // appends the products of gcol[i, j) (one multiplier's items), which are summed per (a, b)
  // over each owner cluster's multipliers in multiplier order (key: the owner cluster).
  using ProductsOf = std::function<void(size_t, size_t, std::vector<CoarseTriplet>&)>;
  // G~ W G~^T's partial sums from G~'s items at the owners (W = diag(weight) on the owned
  // multipliers), gathered to the ranks that factor. Collective.
  std::vector<CoarseTriplet> weighted_triplets(const std::vector<GItem>& items,
                                               const std::vector<double>& weight) const;
  // Factors the coarse matrix of the summed triplets (upper triangle; duplicates summed in
  // order) into factor: see assemble. Collective.
  bool factor_triplets(std::vector<CoarseTriplet> all, Factor& factor, bool fail_if_singular);
  // With also_sum_of and also_out: the same pass also sums, into *also_out, the products of the
  // multipliers gcol[i] for which also_sum_of(i) holds, each entry in the same order as a pass
  // over those products alone would (so bit for bit its result), and only the entries they touch.
  std::vector<CoarseTriplet> owner_cluster_sums(
      const std::vector<GItem>& gcol, const ProductsOf& products_of,
      const std::function<bool(size_t)>& also_sum_of = {},
      std::vector<CoarseTriplet>* also_out = nullptr) const;
  // products_of for G~ W G~^T (W = diag(weight) on the owned multipliers; none where w = 0).
  ProductsOf weighted_products(const std::vector<GItem>& items,
                               const std::vector<double>& weight) const;
  // build_image's steps 1 and 4 (coarse_image.cpp).
  std::vector<std::vector<int>> clusters_touching_owned_rows() const;
  void assemble_image_coarse_matrix();

  const FetiLayout& layout_;
  const Comm& comm_;
  Multipliers& m_;
  int first_cluster_ = 0;
  std::vector<int> sub_first_;  // per local cluster: its first local subdomain (+ 1 entry)
  bool outer_parallel_ = false;
  std::vector<int> first_;  // per global cluster: its first coarse index (num_clusters + 1)
  // Per local cluster, per kernel vector: the row of G~ as (extended index, value), in the
  // global order of the multipliers; and the same with the pair index of G~^T's ordered sums.
  std::vector<std::vector<std::vector<std::pair<int, double>>>> rows_;
  // The same rows for the passes of apply_G and G~^T (apply_rows, pairs_from_rows): per local
  // cluster its multipliers in the global order, each with its extended index, its pair and the
  // values of all kernel_dimension rows there (zeros included: a multiplier on an x dof has no
  // entry in the y and z translations). Each row's sum is formed in the order of rows_, so the
  // results are bit for bit those of the sparse rows, from 8 + 8 r bytes per multiplier instead
  // of 32 per nonzero (r = 6: 56 against about 96 bytes).
  std::vector<int> entry_first_;  // local cluster c's entries: [entry_first_[c], ...[c + 1])
  std::vector<int> entry_k_, entry_p_;
  std::vector<double> entry_g_;    // entry e's r values at entry_g_[value_first_[c] + ...]
  std::vector<long> value_first_;  // per local cluster (+ 1)
  std::vector<int> pair_first_;    // local cluster c's pairs: [pair_first_[c], pair_first_[c + 1])
  OrderedSum cluster_sum_;         // the pairs summed on the multipliers' owners, in a fixed order
  Vec pairs_;                      // work: one value per (cluster, multiplier) pair
  Vec work_;                       // work: one coarse vector
  Factor factor_;
  Factor face_;                // G~ D G~^T of the last set_face
  Factor weighted_;            // G~ Q G~^T (set_weighted)
  Vec q_, qx_;                 // Q's diagonal (owned multipliers), and Q x
  bool weighted_set_ = false;  // set_weighted was called (a rank may own no multipliers)
  bool face_set_ = false;
  // The parts of G~ W G~^T that do not depend on the bounded rows' weights (set by factor(), or
  // at the first set_face): the summed entries of the never-held rows' products (on the ranks
  // that factor) and the bounded rows' items.
  bool face_cached_ = false;
  bool face_used_ = false;  // set_face was called
  void cache_face_parts(const std::vector<GItem>& items);
  // face_fixed_ from the never-held rows' partial sums (gathered to the ranks that factor), and
  // face_items_ from items.
  void set_face_parts(const std::vector<GItem>& items, const std::vector<CoarseTriplet>& fixed);
  std::vector<CoarseTriplet> face_fixed_;
  std::vector<GItem> face_items_;
  // The ranks that hold the coarse factor (FetiOptions::coarse_ranks): every rank (subset_
  // false), or the first rank of each group of consecutive ranks (leader_): group_comm_ is the
  // group (its first rank is rank 0 in it), leader_comm_ the groups' first ranks
  // (MPI_COMM_NULL on the others).
  bool subset_ = false, leader_ = true;
  int factor_ranks_ = 1;
  MPI_Comm group_comm_ = MPI_COMM_NULL, leader_comm_ = MPI_COMM_NULL;
  // build_image(): E by owned rows (CSR, columns sorted), C = G~ F G~^T (CSR, all ranks).
  struct Image {
    bool built = false;
    std::vector<int> e_ptr, e_col, c_ptr, c_col;
    std::vector<double> e_val, c_val;
    Vec ab, z1, z2;  // work: [G~ v; G~ F v], the two coarse solutions
    // work: the second vector of the fused G~ and G~^T passes
    Vec ext_in_second, pairs_second, ext_out_second;
    ImageStats stats;
  } image_;
  double image_row(int e, const Vec& z) const {  // (E z)_e, E's columns in increasing order
    double s = 0;
    for (int q = image_.e_ptr[e]; q < image_.e_ptr[e + 1]; ++q)
      s += image_.e_val[q] * z[image_.e_col[q]];
    return s;
  }
};

}  // namespace htfeti
