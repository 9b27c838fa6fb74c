// The dual constraints B~ (gluing, Dirichlet, contact) with orthonormal rows, and the primal
// constraints C that join the subdomains of a cluster (paper, (3), (13), (14)).
//
// Rows of B~ are generated per interface object, in one global order that every rank computes
// alike (so multiplier numbers do not depend on the number of ranks):
//  1. every node on the subdomain skeleton of square q (q, then row gy, then column gx):
//     - gluing rows: an orthonormal basis of the differences between the node's copies. Copies
//       that are joined primally (same cluster, corner gluing) count as one group; the rows are
//       constant on a group, so they are orthogonal to the primal constraints (B~ B~^T = I holds in
//       the cluster variables too). Nodes inside an edge joined by its average are skipped here;
//     - a Dirichlet row (1/sqrt(k)) (1,...,1) on the node's k copies (the average of the copies);
//     - on x = 1 of a contact problem, one contact row c (avg of left copies - avg of right
//       copies), c = 1/sqrt(1/k_L + 1/k_R), so that B_I u <= 0 means u2 - u1 >= 0;
//  2. every edge inside a cluster that is joined by its average: with p interior nodes, the
//     p - 1 rows (c_l, -c_l)/sqrt(2), c_l an orthonormal basis of the vectors orthogonal to
//     (1,...,1) in R^p. The average of the jump is the primal constraint, so Ker B~ = Ker B Z.
// Every row is orthogonal to every other one and of unit norm: B~ B~^T = I.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "htfeti/decomposition/decomposition.hpp"

namespace htfeti {

enum class MultiplierKind : std::uint8_t { gluing, dirichlet, contact };

struct ConstraintEntry {
  int subdomain;  ///< global subdomain id
  int dof;        ///< subdomain-local node
  double value;
};

struct Multiplier {
  long long index = 0;
  MultiplierKind kind = MultiplierKind::gluing;
  double y = 0;      ///< contact rows: node height on x = 1
  double scale = 1;  ///< contact rows: c, so that c * lambda is the nodal contact force
  std::vector<ConstraintEntry> entries;
};

/// Calls fn for every row of B~ in the global order; returns the number of rows.
long long for_each_multiplier(const Decomposition& dec,
                              const std::function<void(const Multiplier&)>& fn);

/// The primal constraints C of one cluster (rows with entries on its subdomains); empty for m = 1.
std::vector<std::vector<ConstraintEntry>> cluster_primal_constraints(const Decomposition& dec,
                                                                     int cluster);

/// Rows of an orthonormal basis of the complement of s (s_i > 0) in R^t: t - 1 rows of length t.
std::vector<std::vector<double>> orthonormal_complement(const std::vector<double>& s);

}  // namespace htfeti
