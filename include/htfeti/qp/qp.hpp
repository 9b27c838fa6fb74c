// The QP object that the solvers take (PERMON's QP and its transforms, DESIGN.md "qp/"):
//     min 1/2 x'Ax - b'x   subject to  x in Omega  and  G x = 0,
// with A a symmetric operator, Omega a constraint set, and the equalities given by P, the
// orthogonal projector onto Ker G (G with orthonormal rows; Q = I - P = G'G). Nothing here knows
// FETI: the dual problem builds a QP (solver.cpp) and the transforms below bring it to the form a
// solver needs:
//   - homogenize(qp, x0): x = x0 + y, so b -> b - A x0 and Omega -> Omega - x0 (the paper's
//     (12): lambda = lambda~ + x with G lambda~ = e~);
//   - enforce_by_projector(qp): A -> P A P and b -> P b (the paper's (15): the dual Hessian on
//     Ker G), keeping P for the equality G y = 0 that SMALBE-M enforces by penalty;
//   - PenalizedOperator: H_rho = A + rho Q as one counted operator (SMALBE-M's inner Hessian).
// Operators are shared: a QP made by a transform keeps the operators it was made from alive,
// and borrow() wraps an operator the caller keeps alive (no ownership).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "htfeti/qp/operator.hpp"

namespace htfeti::qp {

/// The feasible set Omega of the variables. Bounds (LowerBounds, BoxBounds: MPRGP) today;
/// separable convex sets (discs for friction in 3D, MPGP) derive from it without changing the QP
/// or SMALBE-M.
class ConstraintSet {
 public:
  virtual ~ConstraintSet() = default;
  virtual Eigen::Index size() const = 0;
  /// x <- the Euclidean projection of x onto Omega.
  virtual void project(Vec& x) const = 0;
  /// Omega - s = {y : y + s in Omega} (homogenization moves the set with the iterate).
  virtual std::shared_ptr<const ConstraintSet> shifted(const Vec& s) const = 0;
};

/// x_i >= l_i (l_i = -infinity: x_i is free).
class LowerBounds final : public ConstraintSet {
 public:
  explicit LowerBounds(Vec lower) : lower_(std::move(lower)) {}
  const Vec& lower() const { return lower_; }
  Eigen::Index size() const override { return lower_.size(); }
  void project(Vec& x) const override { x = x.cwiseMax(lower_); }
  std::shared_ptr<const ConstraintSet> shifted(const Vec& s) const override {
    return std::make_shared<LowerBounds>(lower_ - s);
  }

 private:
  Vec lower_;
};

/// l_i <= x_i <= u_i (l_i = -infinity or u_i = +infinity: no bound on that side). The interval
/// constraints of Tresca friction in 2D; MPRGP solves with them as with LowerBounds.
class BoxBounds final : public ConstraintSet {
 public:
  /// Throws std::invalid_argument when the sizes differ, a bound is NaN or some l_i > u_i.
  BoxBounds(Vec lower, Vec upper);
  const Vec& lower() const { return lower_; }
  const Vec& upper() const { return upper_; }
  Eigen::Index size() const override { return lower_.size(); }
  void project(Vec& x) const override { x = x.cwiseMax(lower_).cwiseMin(upper_); }
  std::shared_ptr<const ConstraintSet> shifted(const Vec& s) const override {
    return std::make_shared<BoxBounds>(lower_ - s, upper_ - s);
  }

 private:
  Vec lower_, upper_;
};

/// l_i <= x_i <= u_i on single entries and, on disjoint pairs of entries (i, j) whose bounds are
/// infinite, discs |(x_i, x_j) - c| <= r: the separable convex set of Tresca friction in 3D (the
/// two tangential multipliers of a contact node lie in a disc of radius g A, the normal one is
/// bounded below). MPGP (mpgp.hpp) solves with it; on entries without a disc it acts as
/// BoxBounds. Over MPI each rank holds the discs of its own entries.
class SeparableSet final : public ConstraintSet {
 public:
  using Pair = std::array<Eigen::Index, 2>;
  /// centers: 2 per disc; a radius may be +infinity (no constraint on the pair). Throws
  /// std::invalid_argument when the sizes differ, a bound is NaN or empty, a disc's entries are
  /// out of range, shared with another disc or bounded, or a radius is negative or NaN.
  SeparableSet(Vec lower, Vec upper, std::vector<Pair> discs, Vec centers, Vec radii);
  const Vec& lower() const { return lower_; }
  const Vec& upper() const { return upper_; }
  const std::vector<Pair>& discs() const { return discs_; }
  const Vec& centers() const { return centers_; }
  const Vec& radii() const { return radii_; }
  Eigen::Index size() const override { return lower_.size(); }
  void project(Vec& x) const override;
  std::shared_ptr<const ConstraintSet> shifted(const Vec& s) const override;

 private:
  Vec lower_, upper_;
  std::vector<Pair> discs_;
  Vec centers_, radii_;
};

/// A shared pointer to an operator that the caller keeps alive (not owned).
inline std::shared_ptr<Operator> borrow(Operator& op) {
  return std::shared_ptr<Operator>(&op, [](Operator*) {});
}

struct QuadraticProgram {
  std::shared_ptr<Operator> hessian;                 ///< A
  Vec linear;                                        ///< b
  std::shared_ptr<const ConstraintSet> constraints;  ///< Omega; null: none
  std::shared_ptr<Operator> equality_projector;      ///< P onto Ker G; null: no equalities
  /// The solution of the original QP is shift + the solution of this one (homogenize); empty:
  /// no shift.
  Vec shift;
  Eigen::Index size() const { return linear.size(); }
  /// Throws std::invalid_argument when the parts do not fit: no Hessian, or a constraint set
  /// or shift of another size.
  void check() const;
};

/// x = x0 + y: b -> b - A x0, Omega -> Omega - x0, shift -> shift + x0. One application of A.
QuadraticProgram homogenize(const QuadraticProgram& qp, const Vec& x0);

/// A -> P A P and b -> P b with the QP's equality projector P (which the result keeps). Two
/// applications of P per application of the new Hessian; one of P here.
QuadraticProgram enforce_by_projector(const QuadraticProgram& qp);

/// y = P A P x (the Hessian that enforce_by_projector makes). No operator is asked to work in
/// place. Cost: two P, one A.
class ProjectedOperator final : public Operator {
 public:
  ProjectedOperator(std::shared_ptr<Operator> A, std::shared_ptr<Operator> P, Eigen::Index n)
      : A_(std::move(A)), P_(std::move(P)), px_(n), apx_(n) {}

 protected:
  void do_apply(const Vec& x, Vec& y) override {
    P_->apply(x, px_);
    A_->apply(px_, apx_);
    P_->apply(apx_, y);
  }

 private:
  std::shared_ptr<Operator> A_, P_;
  Vec px_, apx_;
};

/// y = x - P x: Q = I - P, the projector onto Im G' (||G x|| = ||Q x||). Cost: one P.
class ComplementOperator final : public Operator {
 public:
  explicit ComplementOperator(std::shared_ptr<Operator> P) : P_(std::move(P)) {}

 protected:
  void do_apply(const Vec& x, Vec& y) override {
    P_->apply(x, y);
    y = x - y;
  }

 private:
  std::shared_ptr<Operator> P_;
};

/// y = A x + rho Q x and, as a side result, Q x (image()) in one counted application: SMALBE-M's
/// inner Hessian H_rho. A caller that can share work between the two (with A = P F P and
/// Q = I - P one projection of x serves both) gives a fused callable; otherwise A and Q are
/// applied apart. Cost: one A and one Q, or one fused call.
using PenalizedHessian = std::function<void(const Vec& x, double rho, Vec& y, Vec& qx)>;
class PenalizedOperator final : public Operator {
 public:
  PenalizedOperator(Operator& A, Operator& Q, double rho, Eigen::Index n,
                    PenalizedHessian fused = {})
      : A_(A), Q_(Q), rho_(rho), qx_(n), fused_(std::move(fused)) {}
  double rho() const { return rho_; }
  /// A new penalty (SMALBE-M's late update); the next application uses it.
  void set_rho(double rho) { rho_ = rho; }
  /// Q x of the vector this operator was applied to last.
  const Vec& image() const { return qx_; }

 protected:
  void do_apply(const Vec& x, Vec& y) override {
    if (fused_) return fused_(x, rho_, y, qx_);
    A_.apply(x, y);
    Q_.apply(x, qx_);
    y += rho_ * qx_;
  }

 private:
  Operator &A_, &Q_;
  double rho_;
  Vec qx_;
  PenalizedHessian fused_;
};

}  // namespace htfeti::qp
