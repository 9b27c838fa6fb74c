// Shared helpers of the tests: global node numbering and comparison with the undecomposed solution.
#pragma once

#include <Eigen/Dense>
#include <vector>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/reference.hpp"

namespace htfeti::test {

/// Index of subdomain-local node k of subdomain s in the global numbering of reference.hpp.
inline int global_node(const Decomposition& dec, int s, int k) {
  const auto p = dec.position(s);
  const int H = dec.H(), np = dec.n() + 1;
  return p.q * np * np + (p.sy * H + k / (H + 1)) * np + p.sx * H + k % (H + 1);
}

/// max |u - u_ref| over all copies of all nodes, relative to max |u_ref| (collective).
inline double relative_error(const DualProblem& dual, const std::vector<Eigen::VectorXd>& u,
                             const Eigen::VectorXd& ref) {
  double err = 0;
  for (size_t i = 0; i < u.size(); ++i) {
    const int s = dual.subdomains()[i]->id();
    for (int k = 0; k < u[i].size(); ++k)
      err = std::max(err, std::abs(u[i][k] - ref[global_node(dual.decomposition(), s, k)]));
  }
  return dual.comm().max(err) / ref.cwiseAbs().maxCoeff();
}

/// A vector of owned dual entries that depends only on global indices (rank-count independent).
inline Eigen::VectorXd pseudo_random(const DualProblem& dual, double seed) {
  Eigen::VectorXd v(dual.n_owned());
  for (int i = 0; i < v.size(); ++i) {
    const double g = static_cast<double>(dual.global_index(i));
    v[i] = std::sin(12.9898 * g + seed) * 43758.5453;
    v[i] -= std::floor(v[i]);
    v[i] -= 0.5;
  }
  return v;
}

}  // namespace htfeti::test
