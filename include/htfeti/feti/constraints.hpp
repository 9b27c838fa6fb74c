// The dual constraints B~ (gluing, Dirichlet, contact) with orthonormal rows and a right-hand
// side c, and the primal constraints C that join the subdomains of a cluster (paper, (3), (13),
// (14)), built from the dof sharing alone.
//
// Interface objects. The extended sharing set of a node is the set of subdomains holding a copy,
// plus a mark "on the domain boundary" (as PETSc's PCBDDCGraph does), so that the ends of an
// interface edge on the boundary are told apart from the edge. A node is
//  - averaged (in cluster c): shared by exactly two subdomains, both of cluster c, and not on the
//    boundary (the interior of an edge in 2D, of a face in 3D), when the glue has averages;
//  - a vertex: its extended set has at least 3 members and (in 3D) no other node has that set.
// Objects: the averaged nodes of one pair of subdomains form one object.
//
// Rows of B~ (every row orthonormal to every other, B~ B~^T = I):
//  1. per node with k >= 2 copies that is not averaged: copies are grouped when they are joined
//     primally (a vertex with corner gluing: the copies of one cluster form a group); gluing rows
//     are an orthonormal (generalized Helmert) basis of the differences of the groups, constant on
//     each group, one set per component;
//  2. a Dirichlet row per fixed dof: (1/sqrt(k)) on each copy, c = sqrt(k) * value;
//  3. a contact row n.(sum_j c_j avg u_j) <= W gap (input.hpp: ContactRow; node-to-node rows
//     have c_a = 1, c_b = -1, W = 1; mortar rows D_ij and -M_ik) scaled to unit norm: entries
//     s c_j n / k_j on the k_j copies of node j, s = 1/sqrt(sum_j c_j^2 / k_j), right-hand side
//     s W gap; W s lambda is the row's contact force (for a node-to-node row the nodal force,
//     for a mortar row the integral of the pressure s lambda times the slave basis function);
//  4. per averaged object with p nodes: W = the orthonormalized kernel of the physics on the
//     object's nodes (constants, rigid body motions); the rows (w, -w)/sqrt(2) for w in an
//     orthonormal basis of the complement of W in R^(p dofs) with O(p log p) nonzeros
//     (hierarchical_complement). The primal constraints of the object
//     are (W, -W)/sqrt(2), so Ker B~ = Ker B Z (the averages of the jump are enforced primally).
// Corner primal constraints: the Helmert differences of the copies of a vertex in one cluster.
//
// Global order of the rows (independent of the number of ranks): by key, per-node rows first
// (key = global node, then gluing/Dirichlet/contact, then the row number), then the object rows
// (key = cluster, the object's subdomain pair, its lowest node, the row number).
#pragma once

#include <Eigen/Dense>
#include <array>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "htfeti/feti/input.hpp"

namespace htfeti {

/// friction: a tangential row of a contact row with friction (one in 2D, two in 3D), |lambda| <=
/// bound (in 3D the node's two rows together: a disc; one row, an interval, where Dirichlet
/// conditions leave the node one tangential direction).
enum class MultiplierKind : std::uint8_t { gluing, dirichlet, contact, friction };

using RowKey = std::array<long long, 6>;
/// A friction row's key is {0, node, 3, condition, m, 0}: m = 0, 1 the two rows of a 3D disc
/// (or the one row in 2D), m = kSingleTangent the single row of a 3D interval.
inline constexpr long long kSingleTangent = 2;

/// The part of one row of B~ on one local subdomain.
struct LocalRow {
  RowKey key{};
  MultiplierKind kind = MultiplierKind::gluing;
  int owner_subdomain = 0;  ///< lowest subdomain the row touches: its rank owns the multiplier
  double rhs = 0;           ///< c: B~ u = c (equalities) or B~ u <= c (contact)
  double scale = 1;         ///< contact: scale * lambda is the row's force per unit W
  double weight = 1;        ///< contact: W (ContactRow); the row's force is W scale lambda
  double gap = 0;           ///< contact: the gap in length units
  double area = 0;          ///< contact: this subdomain's part of the row's contact area
  int condition = 0;        ///< contact, friction: the contact condition (problem-file order)
  double bound = 0;         ///< friction: this subdomain's part of the bound on |lambda| (summed)
  double mu = -1;           ///< friction: Coulomb's coefficient (< 0: Tresca, the bound above)
  int side = 0;             ///< contact: +1 for the part on node a, -1 on node b
  bool key_node = false;    ///< contact: the part is on the node the row is keyed by
  std::array<double, 3> point{0, 0, 0};         ///< contact: node a
  std::array<double, 3> direction{0, 0, 0};     ///< contact: n
  std::vector<std::pair<int, double>> entries;  ///< (local dof, value)
};

class ObjectRowCache;

/// Rows of B~ touching one subdomain (unsorted). With a cache, the rows of an averaged object
/// (hierarchical_complement) are computed once for all objects of the cache's holders with the
/// same kernel W and the same tree (both sides of a face; every equal face of a box).
void subdomain_rows(const FetiLayout& layout, const SubdomainInput& input,
                    std::vector<LocalRow>& out, ObjectRowCache* cache = nullptr);

struct ConstraintEntry {
  int member;  ///< index of the subdomain within its cluster
  int dof;
  double value;
};

/// The primal constraints C of one cluster, rows in a deterministic order; `members` are the
/// cluster's subdomain inputs in id order. Empty for a cluster of one subdomain.
std::vector<std::vector<ConstraintEntry>> cluster_primal_constraints(
    const FetiLayout& layout, int cluster, const std::vector<const SubdomainInput*>& members);

/// Rows of an orthonormal basis of the complement of s (s_i != 0) in R^t: t - 1 rows of length t.
std::vector<std::vector<double>> orthonormal_complement(const std::vector<double>& s);

/// Sparse rows: (index, value) pairs per row.
using SparseRows = std::vector<std::vector<std::pair<int, double>>>;

/// An orthonormal basis of the complement of span(W) in R^(p dpn) (W: orthonormal columns, rows
/// node-major, p nodes at xyz, 3 coordinates each), with O(p log p) nonzeros instead of the
/// O(p^2) of a dense basis: a multiwavelet construction on a binary tree of the nodes (coordinate
/// bisection down to leaves of at most 4 nodes). Each group keeps an orthonormal basis of W
/// restricted to it (its coarse basis); the rest of the span of its children's coarse bases
/// (of the leaf's own dofs for a leaf) becomes rows supported on the group. The rows are
/// orthonormal, orthogonal to W, and p dpn - rank(W) in number: the same row space as any
/// orthonormal complement, so the dual problem changes only by an orthogonal transformation of
/// the object's multipliers. Deterministic (both subdomains of an object compute the same rows).
SparseRows hierarchical_complement(const Eigen::MatrixXd& W, const double* xyz, int p, int dpn);

/// hierarchical_complement's rows held once per distinct input: its result depends on the
/// coordinates only through the tree's leaf order, so the key is W (bit for bit), that order and
/// dpn, compared in full. The first caller with a key computes the rows, callers with an equal
/// key (waiting while it is under way) get the same rows: what hierarchical_complement gives
/// them, whichever thread or subdomain asks first. Thread-safe; holds every key it is given
/// (one per distinct object: a setup's worth).
class ObjectRowCache {
 public:
  std::shared_ptr<const SparseRows> rows(const Eigen::MatrixXd& W, const double* xyz, int p,
                                         int dpn);
  long reuses() const { return reuses_; }

 private:
  struct Entry {
    std::uint64_t hash = 0;
    int dpn = 0;
    Eigen::Index w_rows = 0;
    std::vector<double> w;
    std::vector<int> order;
    std::shared_ptr<const SparseRows> rows;  // null while its first caller computes it
    bool failed = false;                     // that computation threw: callers compute their own
  };
  std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<std::shared_ptr<Entry>> entries_;
  long reuses_ = 0;
};

}  // namespace htfeti
