// The QP solvers' reductions over a DualProblem's vectors, in a fixed order (per owner cluster,
// then in cluster order: DualProblem::dot), so that iterates do not depend on the number of
// ranks or threads.
#pragma once

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/qp/operator.hpp"

namespace htfeti {

class DualReducer final : public qp::Reducer {
 public:
  DualReducer(const Comm& c, const DualProblem& d) : c_(c), d_(d) {}
  double sum(double v) const override { return c_.sum(v); }
  double max(double v) const override { return c_.max(v); }
  double min(double v) const override { return c_.min(v); }
  double dot(const qp::Vec& a, const qp::Vec& b) const override { return d_.dot(a, b); }
  double sum_entries(const qp::Vec& v) const override { return d_.sum(v); }
  void dots(int count, const qp::Vec* const* a, const qp::Vec* const* b,
            double* out) const override {
    d_.dots(count, a, b, out);
  }

 private:
  const Comm& c_;
  const DualProblem& d_;
};

}  // namespace htfeti
