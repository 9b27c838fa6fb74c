// The QP object and its transforms (qp.hpp).
#include "htfeti/qp/qp.hpp"

#include <stdexcept>
#include <string>

namespace htfeti::qp {

BoxBounds::BoxBounds(Vec lower, Vec upper) : lower_(std::move(lower)), upper_(std::move(upper)) {
  if (lower_.size() != upper_.size())
    throw std::invalid_argument("BoxBounds: " + std::to_string(lower_.size()) + " lower and " +
                                std::to_string(upper_.size()) + " upper bounds");
  for (Eigen::Index i = 0; i < lower_.size(); ++i)
    if (!(lower_[i] <= upper_[i]))  // NaN fails too
      throw std::invalid_argument("BoxBounds: bound " + std::to_string(i) +
                                  " is empty or NaN (lower " + std::to_string(lower_[i]) +
                                  ", upper " + std::to_string(upper_[i]) + ")");
}

void QuadraticProgram::check() const {
  if (!hessian) throw std::invalid_argument("QP: no Hessian operator");
  const Eigen::Index n = size();
  if (constraints && constraints->size() != n)
    throw std::invalid_argument("QP: the constraint set has " +
                                std::to_string(constraints->size()) + " variables, not " +
                                std::to_string(n));
  if (shift.size() != 0 && shift.size() != n)
    throw std::invalid_argument("QP: the shift has " + std::to_string(shift.size()) +
                                " entries, not " + std::to_string(n));
}

QuadraticProgram homogenize(const QuadraticProgram& qp, const Vec& x0) {
  qp.check();
  if (x0.size() != qp.size()) throw std::invalid_argument("homogenize: x0 has the wrong size");
  QuadraticProgram out = qp;
  Vec ax(qp.size());
  qp.hessian->apply(x0, ax);
  out.linear = qp.linear - ax;
  if (qp.constraints) out.constraints = qp.constraints->shifted(x0);
  out.shift = qp.shift.size() ? Vec(qp.shift + x0) : x0;
  return out;
}

QuadraticProgram enforce_by_projector(const QuadraticProgram& qp) {
  qp.check();
  if (!qp.equality_projector)
    throw std::invalid_argument("enforce_by_projector: the QP has no equality projector");
  QuadraticProgram out = qp;
  out.hessian = std::make_shared<ProjectedOperator>(qp.hessian, qp.equality_projector, qp.size());
  out.linear.resize(qp.size());
  qp.equality_projector->apply(qp.linear, out.linear);
  return out;
}

}  // namespace htfeti::qp
