#include "htfeti/qp/power_norm.hpp"

#include <cmath>

namespace htfeti::qp {

double estimate_norm(Operator& A, const Vec& start, const Reducer& red, int max_iterations,
                     double rtol) {
  Vec x = start, y(start.size());
  double nx = red.norm(x), estimate = 0;
  if (nx == 0) return 0;
  x /= nx;
  for (int it = 0; it < max_iterations; ++it) {
    A.apply(x, y);
    const double rq = red.dot(x, y);  // Rayleigh quotient x'Ax, x of unit norm
    const double ny = red.norm(y);
    const bool done = it > 0 && std::abs(rq - estimate) <= rtol * rq;
    estimate = rq;
    if (ny == 0 || done) break;
    x = y / ny;
  }
  return estimate;
}

}  // namespace htfeti::qp
