// Decomposition of the built-in 2D problems' unit squares into N_s x N_s square subdomains
// (H_s = 1/N_s), grouped into clusters of m x m subdomains (paper, Sections 3 and 5). It is the
// box generator (mesh/box.hpp) with the built-ins' options; grid() gives that generator.
//
// Numbering is cluster-major so that a contiguous range of subdomain ids is a contiguous range of
// clusters: subdomain id = cluster id * m^2 + (ly * m + lx), cluster id = (q * nc + cy) * nc + cx
// with nc = N_s / m clusters per side of square q. Clusters are the unit spread over MPI ranks,
// in contiguous blocks.
#pragma once

#include <string>
#include <vector>

#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/box.hpp"
#include "htfeti/mesh/problem.hpp"

namespace htfeti {

struct DecompositionOptions {
  ProblemKind problem = ProblemKind::membranes;
  ElementKind element = ElementKind::q1;
  int elements = 64;     ///< n: elements per side of each unit square
  int subdomains = 4;    ///< N_s: subdomains per side of each unit square
  int cluster_size = 1;  ///< m: subdomains per side of a cluster (1 = TFETI)
  Glue glue = Glue::averages;
};

struct SubdomainPosition {
  int q, sx, sy;  ///< square and subdomain column/row in it
};

class Decomposition {
 public:
  /// Validates the options; throws std::invalid_argument with a message naming the problem.
  explicit Decomposition(const DecompositionOptions& options);

  const DecompositionOptions& options() const { return opt_; }
  Problem problem() const { return Problem{opt_.problem}; }
  int n() const { return opt_.elements; }
  int ns() const { return opt_.subdomains; }
  int m() const { return opt_.cluster_size; }
  int H() const { return opt_.elements / opt_.subdomains; }  ///< elements per subdomain side
  int clusters_per_side() const { return opt_.subdomains / opt_.cluster_size; }
  int squares() const { return problem().squares(); }
  int num_subdomains() const { return squares() * ns() * ns(); }
  int num_clusters() const { return squares() * clusters_per_side() * clusters_per_side(); }
  long long nodes_per_subdomain() const { return (H() + 1LL) * (H() + 1LL); }
  /// Primal unknowns of the decomposed problem (every subdomain has its own copy of its nodes).
  long long primal_dimension() const { return 1LL * num_subdomains() * nodes_per_subdomain(); }
  bool glue_averages() const { return m() > 1 && opt_.glue != Glue::corners; }

  SubdomainPosition position(int subdomain) const;
  int subdomain_id(int q, int sx, int sy) const;
  int cluster_of(int subdomain) const { return subdomain / (m() * m()); }

  /// Clusters [first, last) owned by rank r of P.
  std::pair<int, int> cluster_range(int r, int P) const;
  int rank_of_cluster(int c, int P) const;
  int rank_of_subdomain(int s, int P) const { return rank_of_cluster(cluster_of(s), P); }

  /// The generated mesh of the squares (one or two boxes, Q1 -> quad4, P1 -> tri3).
  BoxGrid grid() const;

 private:
  DecompositionOptions opt_;
};

}  // namespace htfeti
