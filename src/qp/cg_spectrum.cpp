#include "htfeti/qp/cg_spectrum.hpp"

#include <algorithm>
#include <cmath>

namespace htfeti::qp {

void CgLanczos::start(int max_steps) {
  room_ = std::clamp(max_steps, 0, kCgSpectrumSteps);
  alpha_.clear();
  beta_.clear();
  alpha_.reserve(room_);
  beta_.reserve(room_);
}

// The extreme eigenvalues of T by bisection on Sturm counts (the number of negative pivots of
// T - s I in its LDL' factorization is the number of eigenvalues below s): 100 halvings of the
// Gershgorin interval, each O(k), and nothing allocated.
SpectrumEstimate CgLanczos::estimate() const {
  SpectrumEstimate out;
  const int k = static_cast<int>(alpha_.size());
  if (k == 0 || static_cast<int>(beta_.size()) < k - 1) return out;
  for (int j = 0; j < k; ++j)
    if (!(alpha_[j] > 0) || !std::isfinite(alpha_[j]) ||
        (j < k - 1 && (!(beta_[j] >= 0) || !std::isfinite(beta_[j]))))
      return out;
  const auto diag = [&](int j) {
    return 1 / alpha_[j] + (j > 0 ? beta_[j - 1] / alpha_[j - 1] : 0.0);
  };
  const auto off2 = [&](int j) { return beta_[j] / (alpha_[j] * alpha_[j]); };  // T_(j,j+1)^2
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int j = 0; j < k; ++j) {
    const double r =
        (j > 0 ? std::sqrt(off2(j - 1)) : 0.0) + (j < k - 1 ? std::sqrt(off2(j)) : 0.0);
    lo = std::min(lo, diag(j) - r);
    hi = std::max(hi, diag(j) + r);
  }
  const double tiny = std::numeric_limits<double>::min() * 1e10;
  const auto below = [&](double s) {  // eigenvalues of T below s
    int count = 0;
    double d = 1;
    for (int j = 0; j < k; ++j) {
      d = diag(j) - s - (j > 0 ? off2(j - 1) / d : 0.0);
      if (std::abs(d) < tiny) d = -tiny;
      count += d < 0;
    }
    return count;
  };
  const auto bisect = [&](int index) {  // the eigenvalue with `index` eigenvalues below it
    double a = lo, b = hi;
    for (int it = 0; it < 100 && b - a > 0; ++it) {
      const double m = 0.5 * (a + b);
      if (m <= a || m >= b) break;
      (below(m) > index ? b : a) = m;
    }
    return 0.5 * (a + b);
  };
  out.min = bisect(0);
  out.max = bisect(k - 1);
  out.steps = k;
  return out;
}

}  // namespace htfeti::qp
