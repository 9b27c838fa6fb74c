// Sparse Cholesky factorization of a symmetric positive definite matrix by CHOLMOD
// (supernodal, fill-reducing ordering), with solves that allocate nothing after the first call.
#pragma once

#include <Eigen/Sparse>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "htfeti/enum_names.hpp"

namespace htfeti {

/// Fill-reducing ordering of the subdomain factors: AMD, METIS's nested dissection
/// (METIS_NodeND), or CHOLMOD's nested dissection (nesdis: METIS's vertex separators down to
/// parts of 200 rows, constrained AMD within them). automatic (resolve_ordering): METIS in 3D
/// (27% fewer factor nonzeros than AMD on the cube-obstacle subdomains; nesdis saves another
/// 2-3% of the factor and of F's time but its analysis costs as much more on the METIS cubes,
/// docs/performance.md) and for the explicit operator's interface-last factors, AMD for the
/// implicit operator in 2D (the paper's tables were measured with it).
enum class Ordering { amd, metis, nesdis, automatic };
inline constexpr std::array<EnumName<Ordering>, 4> kOrderingNames{{{Ordering::amd, "amd"},
                                                                   {Ordering::metis, "metis"},
                                                                   {Ordering::nesdis, "nesdis"},
                                                                   {Ordering::automatic, "auto"}}};
/// The ordering `automatic` stands for (see Ordering); others are returned as given.
inline Ordering resolve_ordering(Ordering asked, int dim, bool explicit_operator) {
  if (asked != Ordering::automatic) return asked;
  return dim == 3 || explicit_operator ? Ordering::metis : Ordering::amd;
}
/// The values the implicit operator's sweeps read (FetiOptions::factor_precision): the factors
/// in double, or their single-precision copies (sums in double; the solve then verified and, if
/// need be, finished with the factors: docs/method.md, "Single-precision factor sweeps").
/// automatic: single where the operator is implicit and a cluster has no primal constraints
/// (TFETI).
enum class FactorPrecision { automatic, double_, single };
inline constexpr std::array<EnumName<FactorPrecision>, 3> kFactorPrecisionNames{
    {{FactorPrecision::automatic, "auto"},
     {FactorPrecision::double_, "double"},
     {FactorPrecision::single, "single"}}};
Ordering parse_ordering(const std::string& name);
std::string to_string(Ordering ordering);

/// The one cache of the FETI setup for equal subdomains (a generated box with one material has
/// mostly equal K_i; a METIS-split mesh has none) and for equal sparsity patterns. Its key is the
/// content of a subdomain matrix, compared in full after a hash, never its position or id:
///   (pattern of the upper triangle, values bit for bit, the set of rows ordered last).
/// Four levels use a part of that key or extend it:
///  1. the assembled matrix (pattern and values of the whole K_i): intern_matrix() hands back a
///     held equal matrix (remembered by weak_ptr: freed with its last holder). On a box, all K_i
///     alive at the end of the assembly were most of the setup's peak.
///  2. the symbolic analysis (pattern, ordering and the set ordered last): it depends on the
///     pattern alone, so a factorization reusing one gives bit for bit the factor of its own.
///     At most `capacity` patterns (the first ones analysed); capacity 0 turns levels 2-4 off.
///  3. the numeric factor (pattern, values and the set ordered last): equal matrices share one
///     factor (read only, freed with the last holder) instead of factoring. Kept only for a
///     pattern seen before (a symbolic reuse), at most numeric_bytes in all (factors and values).
///  4. results computed with a shared factor, keyed further by their input's content:
///     SparseCholesky::solve_many's solves and shared_result's matrices (K_i^+ C_i^T of equal
///     subdomains of a cluster, Subdomain::pinv_many_shared), held in the factor's slot.
/// Every level gives the bits the computation it replaces would give. Thread-safe.
class SubdomainCache {
 public:
  /// numeric_bytes > 0 also keeps numeric factors (see above), up to that many bytes in all.
  explicit SubdomainCache(int capacity = 64, double numeric_bytes = 0);
  ~SubdomainCache();
  SubdomainCache(const SubdomainCache&) = delete;
  SubdomainCache& operator=(const SubdomainCache&) = delete;
  long analyses() const;        ///< symbolic analyses done (cache misses)
  long reuses() const;          ///< factorizations that reused a cached analysis
  int patterns() const;         ///< patterns held
  long numeric_reuses() const;  ///< factorizations that share a cached numeric factor
  /// Multi-column solves (SparseCholesky::solve_many) answered from an earlier equal one.
  long solve_reuses() const;
  int matrices() const;              ///< numeric factors held
  double kept_factor_bytes() const;  ///< their bytes (factor_bytes() of each, once)
  /// Level 1: empties K and returns a held matrix equal to it (pattern and values compared in
  /// full after a hash), or K's storage itself, now held by a shared_ptr.
  using Matrix = Eigen::SparseMatrix<double>;
  std::shared_ptr<const Matrix> intern_matrix(Matrix& K);
  long matrix_reuses() const;  ///< matrices found equal to a held one
  /// Whether levels 2-4 are on (capacity > 0); callers pass the cache to factorizations then.
  bool factors() const { return capacity_ > 0; }

 private:
  friend class SparseCholesky;
  struct Entry;
  mutable std::mutex mutex_;
  int capacity_;
  double numeric_bytes_, numeric_held_ = 0;
  long analyses_ = 0, reuses_ = 0, numeric_reuses_ = 0;
  std::vector<std::unique_ptr<Entry>> entries_;
  std::vector<std::unique_ptr<Entry>> numeric_;  // entries with the values too
  mutable std::mutex matrix_mutex_;              // level 1
  std::unordered_multimap<std::uint64_t, std::weak_ptr<const Matrix>> held_matrices_;
  long matrix_reuses_ = 0;
};

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
  /// With a cache, the symbolic analysis of an earlier matrix of the same pattern is reused.
  void factorize(const Eigen::SparseMatrix<double>& A, SubdomainCache* cache = nullptr);
  /// Factors A with the rows in `last` ordered after all others (constrained AMD, no
  /// postordering), so that the trailing block of the factor is the Cholesky factor of the Schur
  /// complement of A onto `last`. The ordering option of the constructor is not used.
  void factorize(const Eigen::SparseMatrix<double>& A, const std::vector<int>& last,
                 SubdomainCache* cache = nullptr);
  /// Seconds of the last factorize(): the symbolic part (ordering and analysis, or the copy of a
  /// cached analysis; includes forming the upper triangle) and the numeric factorization.
  double symbolic_seconds() const;
  double numeric_seconds() const;
  /// After factorize(A, last): lower-triangular L_s (|last| x |last|) with L_s L_s^T the Schur
  /// complement, and order[i] = the row of A that row i of L_s stands for.
  void schur_factor(Eigen::MatrixXd& L, std::vector<int>& order) const;
  /// After factorize(A, last): S^{-1} (both halves) with S = L_s L_s^T, and `order` as for
  /// schur_factor(); LAPACK's dpotri, 2/3 |last|^3 flops. A factor shared with the cache's
  /// numeric entry shares the entry's S^{-1}: computed once for all equal matrices.
  struct SchurInverse {
    Eigen::MatrixXd S;
    std::vector<int> order;
  };
  std::shared_ptr<const SchurInverse> schur_inverse() const;
  /// x = A^{-1} b; x and b may alias (after keep_single_only(), by refinement of the
  /// single-precision solve). Work arrays are kept between calls, so a solve allocates
  /// nothing once the first one has run. Not safe to call concurrently on one object. A factor
  /// shared through the numeric cache (interface-last factors of the explicit operator, which
  /// solve only in the setup and the reconstruction, never in the iterations) goes through
  /// solve_many and its memo instead (equal subdomains with equal loads: K_i^+ f_i of d).
  void solve(const double* b, double* x);
  /// X = A^{-1} X for the ncols columns of X (column-major, rows() x ncols), in place. One pass
  /// over the factor in each direction for all columns (BLAS-3 in the supernodes) instead of one
  /// per column; setup work, with work arrays of its own that it frees (it allocates). A factor
  /// shared with the numeric cache (equal matrices, a set ordered last) remembers up to 16 such
  /// solves with all its holders: an equal X (its nonzeros compared in full) takes the stored
  /// result, which is what the solve gives for it, without solving.
  void solve_many(double* X, int ncols);
  /// What compute() returns for `key` and `tag`, held once for all holders of a factor shared
  /// through the numeric cache: the first holder that asks for an equal key (nonzeros and tag
  /// compared in full) computes it, later ones (waiting if it is under way) get the same
  /// matrix; up to 64 keys per factor. Without a shared factor, compute()'s result.
  /// Thread-safe. (Subdomain::pinv_many_shared: K_i^+ C_i^T of equal subdomains held once.)
  std::shared_ptr<const Eigen::MatrixXd> shared_result(
      const Eigen::MatrixXd& key, const std::vector<int>& tag,
      const std::function<Eigen::MatrixXd()>& compute);
  int rows() const;
  /// Keeps a copy of the factor's values rounded to single precision (4 bytes a value) for
  /// solve_single(); a factor shared through the numeric cache shares one copy among its holders.
  /// Needs the supernodal factor; setup work (allocates). A new factorization drops the copy.
  void make_single();
  bool has_single() const;
  /// Keeps the single-precision copy alone: the factor's values are freed (their pages go to
  /// the block pool of parallel/fresh_pages.hpp, for the next factorization) and A, the upper
  /// triangle that was factored (moved in), is kept instead, about a quarter of the values'
  /// bytes in 3D. solve() and solve_many() then refine the single-precision solve with A to the
  /// accuracy of a double solve (solve_refined); a matrix for which that does not converge is
  /// factored again in double and solved with that from then on. A factor shared through the
  /// numeric cache keeps its values (its other holders solve with them) but refines all the
  /// same, so that its solves are those of an unshared one. Needs make_single(); false (nothing
  /// changed) without the copy, or for a factor with rows ordered last (the explicit operator's,
  /// whose solves go through the memo). factor_bytes() still counts the values as built.
  bool keep_single_only(Eigen::SparseMatrix<double>&& A);
  /// Keeps the single-precision copy alone, with no refinement: the factor's values are freed
  /// (to the block pool, as in keep_single_only) and only solve_single() may be called after it,
  /// for a use that needs a solve to single precision only (a preconditioner's). A factor shared
  /// through the numeric cache keeps its values for its other holders. Needs make_single()
  /// (std::logic_error otherwise).
  void drop_double();
  /// Whether the double-precision values are held (false after keep_single_only() or
  /// drop_double(), unless shared or factored again).
  bool has_double() const;
  /// Bytes held now: the factor's structure, its values if held (a shared factor's counted by
  /// every holder) and the single-precision copy.
  long held_bytes() const;
  /// Bytes kept for the refinement (A and two work vectors; 0 without keep_single_only()).
  long refinement_bytes() const;
  /// Whether solve() refines (keep_single_only(), until a matrix is factored again in double).
  bool refines() const;
  /// The refined solves since keep_single_only(), their refinement steps in all (each one
  /// product with A and one single-precision solve), and whether the matrix had to be factored
  /// in double again.
  struct RefinementStats {
    long solves = 0, steps = 0;
    bool refactored = false;
  };
  RefinementStats refinement_stats() const;
  /// Bytes of the single-precision copy (0 without one).
  long single_bytes() const;
  const void* single_data() const;  ///< identifies a shared copy (nullptr without one)
  /// x = (L_s L_s^T)^{-1} b with L_s the copy of make_single() (the permutation as in solve()):
  /// the values read in single precision, every sum and quotient in double, so the result is
  /// the exact solve with L_s up to double round-off, for half the bytes of the factor. One pass
  /// over the copy in each direction. Allocates nothing; b == x allowed.
  void solve_single(const double* b, double* x);
  /// CHOLMOD's estimate of the reciprocal condition number, (min_j L_jj / max_j L_jj)^2: at least
  /// 1 / cond(A), so a value below round-off means a matrix that is singular to working precision
  /// (a semidefinite A can factor with a round-off pivot instead of failing). 0 without a factor.
  double rcond() const;
  /// Nonzeros of the factor L (memory is about 8 bytes per nonzero plus the pattern).
  long factor_nonzeros() const;
  /// Bytes held by the factor: values, row indices and the supernode/permutation arrays.
  long factor_bytes() const;
  /// Whether the factor is shared with a numeric cache entry (and so with equal matrices).
  bool factor_shared() const;
  /// The bytes factor_bytes() would report after factorize(A), from the symbolic analysis
  /// alone (ordering and supernodes; no numeric work).
  static long symbolic_factor_bytes(const Eigen::SparseMatrix<double>& A, Ordering ordering);
  /// What CHOLMOD's symbolic analysis of A says of its factor, before any numeric work: the
  /// values stored (supernodal: the dense supernode blocks), the supernodes, the flops of the
  /// numeric factorization (cholmod_common::fl) and the bytes of symbolic_factor_bytes(). The
  /// dual operator's cost model reads them.
  struct SymbolicStats {
    double values = 0, supernodes = 0, flops = 0, bytes = 0;
  };
  static SymbolicStats symbolic_stats(const Eigen::SparseMatrix<double>& A, Ordering ordering);

 private:
  void factorize_impl(const Eigen::SparseMatrix<double>& A, const std::vector<int>* last,
                      SubdomainCache* cache);
  void solve_refined(const double* b, double* x);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace htfeti
