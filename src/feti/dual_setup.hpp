// Internal to the FETI layer: what DualProblem's setup stages hand to each other (the
// constructor in dual_problem.cpp runs the stages in order). Dropped when the
// constructor returns.
#pragma once

#include <vector>

#include "htfeti/feti/dual_problem.hpp"

namespace htfeti {

// What the setup's stages hand to each other (DualProblem's constructor).
struct DualProblem::Setup {
  explicit Setup(const FetiOptions& o) : options(o) {}
  const FetiOptions& options;
  int P = 1, me = 0;              // ranks, this rank
  int ncl = 0, s0 = 0, nsub = 0;  // local clusters, first local subdomain, local subdomains
  std::vector<std::vector<LocalRow>> local_rows;  // per subdomain, until numbered (2.)
  std::vector<std::vector<std::vector<ConstraintEntry>>> primal;  // per cluster, until 3.
  std::vector<std::vector<Subdomain::BEntry>> local_b;            // per subdomain: B_i, until 3.
  std::vector<double> packed_bytes;         // per subdomain: the packed F_i's bytes
  double local_dofs = 0;                    // the rank's primal unknowns
  std::vector<std::vector<int>> interface;  // per subdomain: the preconditioner's interface
  std::vector<std::vector<double>> rho;     // per row entry: K's diagonal (stiffness scaling)
  double coarse_start = 0;                  // when stage 4 began (seconds_now)
};

}  // namespace htfeti
