// The undecomposed problem solved directly, as an independent check of the FETI solvers:
// global stiffness on the global nodes (Dirichlet nodes eliminated), sparse LDL^T (Eigen, not
// CHOLMOD), and for the contact problems a primal-dual active set method on the assembled KKT
// system [K B_A'; B_A 0] with the contact rows u1(1,y) - u2(1,y) <= 0 (sparse LU).
#pragma once

#include <Eigen/Dense>
#include <vector>

#include "htfeti/mesh/problem.hpp"

namespace htfeti {

struct ReferenceSolution {
  Eigen::VectorXd u;  ///< global nodes: index q (n+1)^2 + gy (n+1) + gx
  double energy = 0;  ///< 1/2 u'Ku - f'u
  std::vector<double> contact_y, u_left, u_right, multiplier;  ///< contact problems only
  int active_set_iterations = 0;
};

ReferenceSolution solve_undecomposed(ProblemKind problem, ElementKind element, int n);

}  // namespace htfeti
