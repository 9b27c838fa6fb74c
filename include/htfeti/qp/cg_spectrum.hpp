// Extreme eigenvalues of the operator a conjugate gradient run iterates with, estimated from the
// run's own coefficients, at no product with the operator (the Lanczos connection of CG: Saad,
// "Iterative Methods for Sparse Linear Systems", 2nd ed., Section 6.7.3; PETSc's
// KSPComputeExtremeSingularValues does the same). With the step lengths alpha_j and the ratios
// beta_j = w_(j+1)'z_(j+1) / w_j'z_j of k steps, the tridiagonal matrix
//     T_jj = 1/alpha_j + beta_(j-1)/alpha_(j-1),   T_(j,j+1) = sqrt(beta_j)/alpha_j
// is the Lanczos matrix of the preconditioned operator (Z A on Ker G for FETI's projected CG,
// P_F D Z A on a face for SMALBE-M's face solve) on the k-dimensional Krylov space. Its
// eigenvalues (Ritz values) lie inside that operator's spectrum on the space CG works in, and
// the extreme ones approach the extreme eigenvalues first. So `max` never exceeds the largest
// eigenvalue, `min` never falls below the smallest, and max / min is a lower estimate of the
// condition number that governs CG (for FETI with the Dirichlet or lumped preconditioner the
// smallest eigenvalue is near 1, and the largest is what a mesh, a partition or a
// preconditioner changes). Round-off in CG makes Ritz values repeat; the extremes stay valid.
//
// Cost: recording is two stores per CG step into room reserved before the run; the estimate,
// once per run, bisects on Sturm counts of the k x k tridiagonal matrix (100 halvings, O(k)
// each). Nothing is allocated after start(). At most kCgSpectrumSteps steps are recorded: the
// first k steps of a longer run give the Ritz values of the first k-dimensional Krylov space.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace htfeti::qp {

/// Steps of a CG run whose coefficients CgLanczos keeps (later steps are not recorded).
inline constexpr int kCgSpectrumSteps = 2000;

/// The extreme Ritz values of one or more CG runs (merged: the smallest min, the largest max).
struct SpectrumEstimate {
  double min = std::numeric_limits<double>::infinity();
  double max = 0;
  int steps = 0;  ///< CG steps the estimate rests on (summed over merged runs)
  bool empty() const { return steps == 0; }
  double ratio() const { return empty() ? 0.0 : max / min; }
  void merge(const SpectrumEstimate& other) {
    if (other.empty()) return;
    min = std::min(min, other.min);
    max = std::max(max, other.max);
    steps += other.steps;
  }
};

/// CG steps after which the energy norm of the error has fallen by at least `factor` (< 1) on an
/// operator whose spectrum lies in [s.min, s.max]: the smallest j with
/// 2 ((sqrt(k) - 1) / (sqrt(k) + 1))^j <= factor, k = s.ratio() (Saad, "Iterative Methods for
/// Sparse Linear Systems", 2nd ed., Theorem 6.29). The bound ignores CG's superlinear phase, so
/// it is an upper estimate when the spectrum is right; `s` from a run's Ritz values
/// underestimates k (a lower estimate of the condition number), so it is a guide, not a bound.
/// 0 when s is empty.
inline int cg_steps_for(const SpectrumEstimate& s, double factor) {
  if (s.empty() || !(factor > 0) || factor >= 1) return 0;
  const double sk = std::sqrt(std::max(s.ratio(), 1.0));
  const double rate = (sk - 1) / (sk + 1);
  if (!(rate > 0)) return 1;
  return static_cast<int>(std::ceil(std::log(factor / 2) / std::log(rate)));
}

/// The coefficients of one CG run and the estimate from them.
class CgLanczos {
 public:
  /// A new run of at most max_steps steps (room for min(max_steps, kCgSpectrumSteps)).
  void start(int max_steps);
  /// The step length of the step just taken (a = w'z / p'Ap).
  void step(double alpha) {
    if (static_cast<int>(alpha_.size()) < room_) alpha_.push_back(alpha);
  }
  /// The ratio that built the next direction (beta = w_new'z_new / w'z).
  void direction(double beta) {
    if (static_cast<int>(beta_.size()) < room_) beta_.push_back(beta);
  }
  /// The extreme Ritz values of the recorded steps (empty when no step was taken, or when a
  /// coefficient is not positive and finite).
  SpectrumEstimate estimate() const;

 private:
  std::vector<double> alpha_, beta_;
  int room_ = 0;
};

}  // namespace htfeti::qp
