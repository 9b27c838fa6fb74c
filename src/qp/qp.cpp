// The QP object and its transforms (qp.hpp).
#include "htfeti/qp/qp.hpp"

#include <cmath>
#include <limits>
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

SeparableSet::SeparableSet(Vec lower, Vec upper, std::vector<Pair> discs, Vec centers, Vec radii)
    : lower_(std::move(lower)),
      upper_(std::move(upper)),
      discs_(std::move(discs)),
      centers_(std::move(centers)),
      radii_(std::move(radii)) {
  const Eigen::Index n = lower_.size();
  const auto nd = static_cast<Eigen::Index>(discs_.size());
  if (upper_.size() != n || centers_.size() != 2 * nd || radii_.size() != nd)
    throw std::invalid_argument("SeparableSet: the sizes of the bounds, centers and radii differ");
  for (Eigen::Index i = 0; i < n; ++i)
    if (!(lower_[i] <= upper_[i]))
      throw std::invalid_argument("SeparableSet: bound " + std::to_string(i) + " is empty or NaN");
  std::vector<char> taken(n, 0);
  const double inf = std::numeric_limits<double>::infinity();
  for (Eigen::Index d = 0; d < nd; ++d) {
    if (!(radii_[d] >= 0) || !centers_.segment(2 * d, 2).allFinite())
      throw std::invalid_argument("SeparableSet: disc " + std::to_string(d) +
                                  " has a negative or NaN radius or a non-finite center");
    for (Eigen::Index i : discs_[d]) {
      if (i < 0 || i >= n || taken[i] || lower_[i] != -inf || upper_[i] != inf)
        throw std::invalid_argument("SeparableSet: disc " + std::to_string(d) +
                                    " has an entry out of range, bounded or in another disc");
      taken[i] = 1;
    }
  }
}

void SeparableSet::project(Vec& x) const {
  x = x.cwiseMax(lower_).cwiseMin(upper_);
  for (size_t d = 0; d < discs_.size(); ++d) {
    const auto [i, j] = discs_[d];
    const double dx = x[i] - centers_[2 * d], dy = x[j] - centers_[2 * d + 1];
    const double len = std::hypot(dx, dy), r = radii_[static_cast<Eigen::Index>(d)];
    if (len > r) {
      const double s = len > 0 ? r / len : 0.0;
      x[i] = centers_[2 * d] + s * dx, x[j] = centers_[2 * d + 1] + s * dy;
    }
  }
}

std::shared_ptr<const ConstraintSet> SeparableSet::shifted(const Vec& s) const {
  Vec c = centers_;
  for (size_t d = 0; d < discs_.size(); ++d)
    c[2 * d] -= s[discs_[d][0]], c[2 * d + 1] -= s[discs_[d][1]];
  return std::make_shared<SeparableSet>(lower_ - s, upper_ - s, discs_, c, radii_);
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
