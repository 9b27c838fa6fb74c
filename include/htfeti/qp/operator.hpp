// What the QP solvers know of the world: a symmetric operator with apply(x, y), local vectors,
// and a Reducer that sums, maxes and mins scalars over all ranks. Nothing here knows FETI or MPI.
//
// Operator::apply is non-virtual: it counts applications and times them, then calls the
// implementation (the pattern of Ginkgo's LinOp), so counting happens in one place.
#pragma once

#include <Eigen/Dense>
#include <chrono>
#include <functional>
#include <string>

namespace htfeti::qp {

using Vec = Eigen::VectorXd;

class Operator {
 public:
  virtual ~Operator() = default;
  void apply(const Vec& x, Vec& y) {
    const auto t0 = std::chrono::steady_clock::now();
    do_apply(x, y);
    seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++count_;
  }
  long count() const { return count_; }
  double seconds() const { return seconds_; }
  void reset_counters() { count_ = 0, seconds_ = 0; }

 protected:
  virtual void do_apply(const Vec& x, Vec& y) = 0;

 private:
  long count_ = 0;
  double seconds_ = 0;
};

/// An operator given by a callable (the callable owns nothing of the caller's lifetime).
class FunctionOperator final : public Operator {
 public:
  explicit FunctionOperator(std::function<void(const Vec&, Vec&)> f) : f_(std::move(f)) {}

 protected:
  void do_apply(const Vec& x, Vec& y) override { f_(x, y); }

 private:
  std::function<void(const Vec&, Vec&)> f_;
};

/// Global reductions. dot() and sum_entries() reduce distributed vectors; an implementation may
/// form them in a fixed order so that results do not depend on the number of ranks (the FETI
/// reducer does); sum(), max() and min() reduce rank-local scalars.
class Reducer {
 public:
  virtual ~Reducer() = default;
  virtual double sum(double v) const = 0;
  virtual double max(double v) const = 0;
  virtual double min(double v) const = 0;
  virtual double dot(const Vec& a, const Vec& b) const { return sum(a.dot(b)); }
  /// The sum of all entries of a distributed vector.
  virtual double sum_entries(const Vec& v) const { return sum(v.sum()); }
  double norm(const Vec& a) const { return std::sqrt(dot(a, a)); }
  /// Several reductions at once: out[k] = a[k]' b[k], or the sum of a[k]'s entries where b[k]
  /// is null, each the same number dot() or sum_entries() gives. A reducer over ranks overrides
  /// it with one global reduction for all count terms (DualReducer); this default makes one per
  /// term.
  virtual void dots(int count, const Vec* const* a, const Vec* const* b, double* out) const {
    for (int k = 0; k < count; ++k) out[k] = b[k] ? dot(*a[k], *b[k]) : sum_entries(*a[k]);
  }
};

/// One process: the reductions are the identity.
class SerialReducer final : public Reducer {
 public:
  double sum(double v) const override { return v; }
  double max(double v) const override { return v; }
  double min(double v) const override { return v; }
};

/// Why a solver stopped. Non-convergence is a result, not an exception.
/// diverged: PCG's residual grew a thousandfold above the smallest it had reached (round-off has
/// taken over; the iterate with the smallest residual is returned); stagnated: PCG's residual did
/// not come below the smallest it had reached for kStagnation iterations (the same, when
/// round-off holds the residual on a plateau instead of letting it grow).
enum class StopReason { converged, max_iterations, breakdown, diverged, stagnated };
inline std::string to_string(StopReason r) {
  switch (r) {
    case StopReason::converged:
      return "converged";
    case StopReason::max_iterations:
      return "max_iterations";
    case StopReason::breakdown:
      return "breakdown";
    case StopReason::diverged:
      return "diverged";
    case StopReason::stagnated:
      return "stagnated";
  }
  return "?";
}

/// Called once per (outer) iteration with the iteration number and the stopping measures
/// relative to their scales: PCG ||P r|| / ||P b|| and 0; SMALBE-M ||g^P|| / ||b|| and
/// ||A|| ||G x|| / ||b|| (smalbe.hpp), and also where a face solve ends the solve, with
/// kFaceProgress for the iteration number, and with 0 where a continuation's start point passes
/// the test.
using Progress = std::function<void(int, double, double)>;
inline constexpr int kFaceProgress = -1;

/// The accuracy refinement inside a solve: at a point x that passes the stopping test with
/// relative precision rtol, a solver that can go on without starting over (PCG, SMALBE-M's face
/// solve: the CG recurrences continue) asks its caller whether to; the answer is the rtol to go
/// on to, or rtol itself (or more) to stop there. Collective: the same answer on every rank.
using Tighten = std::function<double(const Vec& x, double rtol)>;
/// CG steps a solver gives going on to a smaller rtol (Tighten): cg_steps_for (cg_spectrum.hpp)
/// of the run's spectrum estimate and the reduction asked, plus this many. When the new
/// tolerance is not met within them (or a face solve ends at a bound or a release, or round-off
/// holds it), the solver returns the point where it went on, which met the last rtol.
inline constexpr int kGoOnExtraSteps = 20;

}  // namespace htfeti::qp
