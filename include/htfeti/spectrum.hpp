// Extreme non-zero eigenvalues of the Schur complement of one floating cluster of m x m square
// subdomains joined by edge averages, and the lower estimate (19) of the paper (Table 1).
//
// The cluster is the unit square (H_c = 1) with n elements per side (h = 1/n), H_s = 1/m. S^i is
// the Schur complement of the subdomain stiffness K^i on its 4 H_s/h boundary nodes (all
// subdomains are congruent, so S^i is computed once). Z is the basis (13) of the paper: per
// subdomain its corner nodes and the interior nodes of edges on the cluster boundary unchanged;
// per shared edge, with p = H_s/h - 1 interior nodes on each side, the p - 1 Helmert vectors
// orthogonal to the constant on each side and the joint average (e_i + e_j)/sqrt(2p). S~ = Z' S Z
// is formed densely and its eigenvalues computed by LAPACK dsyevd (OpenBLAS).
// The estimate: lambda_min(S~) >= 2 n_e / n_s lambda_min(S) sin^2(pi / (2m)), with n_e = H_s/h - 1
// interior nodes of an edge, n_s = 4 H_s/h boundary nodes of a subdomain and lambda_min(S) the
// smallest non-zero eigenvalue of one subdomain's Schur complement.
#pragma once

#include "htfeti/mesh/problem.hpp"

namespace htfeti {

struct ClusterSpectrum {
  int m = 0, n = 0, H_over_h = 0, dimension = 0;
  double lambda_max = 0, lambda_min = 0, lambda_min_estimate = 0;
  double subdomain_lambda_max = 0, subdomain_lambda_min = 0;  ///< of one S^i
};

/// Throws std::invalid_argument unless m >= 1, n divisible by m and n/m >= 2.
ClusterSpectrum cluster_spectrum(int m, int n, ElementKind element);

}  // namespace htfeti
