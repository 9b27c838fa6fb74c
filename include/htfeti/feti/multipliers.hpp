// The rank's Lagrange multipliers, the rows of B~ (paper, (8)-(9)): their global numbering by
// key, the rows on each local subdomain, the data of each owned row (kind, right-hand side,
// contact data), and the movement of dual vectors between the owned layout, the subdomains and
// the ranks, with every sum formed in a fixed order.
//
// Numbering (number()): each rank keys the rows touching its subdomains (constraints.hpp),
// numbers the keys globally (parallel/key_numbering.hpp), so that the numbering does not depend
// on the number of ranks, and takes the owner of a row to be the rank of the lowest subdomain it
// touches. The extended layout (DualLayout) is the owned entries followed by the ghosts this
// rank's subdomains touch.
//
// Exchange (the hot path; allocates nothing): gather() spreads an owned vector to ext_in
// (one forward exchange); a stage writes one value per (subdomain, multiplier) pair into
// `pairs` and combine_subdomains() sums them on the owners into ext_out, in the order of
// (global index, subdomain) (one reverse exchange). dot() and sum() sum per owner cluster and
// then in cluster order, so that iterates do not depend on the number of ranks or threads.
// Cost: gather one message per neighbour rank, combine_subdomains one per neighbour plus a
// pass over the pairs, dot and sum one allreduce of one double per cluster.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <vector>

#include "htfeti/feti/constraints.hpp"
#include "htfeti/feti/subdomain.hpp"
#include "htfeti/parallel/comm.hpp"
#include "htfeti/parallel/dual_layout.hpp"

namespace htfeti {

/// A row of B~ as one subdomain sees it: a per-node gluing row, a row of an averaged object
/// (H-TFETI-DP), or a Dirichlet or contact row (other; the scaling treats the classes apart).
enum class RowClass : std::uint8_t { node, object, other };

/// One entry of a row of B~ on a subdomain (24 bytes: a face average's rows have O(p log p)
/// entries, H-TFETI-DP's constraint phase holds them all).
struct BRowEntry {
  int k;             ///< extended dual index of the row
  int j;             ///< index among the subdomain's multipliers (of_subdomain[s][j] == k)
  int dof;           ///< the subdomain's dof
  std::int8_t side;  ///< contact rows: +1 on node a, -1 on node b; 0 otherwise
  RowClass cls;
  std::uint8_t key;  ///< contact rows: 1 on the node the row is keyed by (its pressure's node)
  double value;
};
static_assert(sizeof(BRowEntry) == 24);

/// Terms of Multipliers::dots whose work array is allocated with the numbering (more grow it once).
inline constexpr int kDotsReserved = 5;

struct Multipliers {
  using Vec = Eigen::VectorXd;

  /// Numbers the rows in local_rows (per local subdomain, consumed), the first local subdomain
  /// being first_subdomain globally, and sets every member below. Returns per local subdomain
  /// the entries of B_i in its own multiplier numbering (for the clusters). Collective.
  std::vector<std::vector<Subdomain::BEntry>> number(const FetiLayout& layout, const Comm& comm,
                                                     std::vector<std::vector<LocalRow>>& local_rows,
                                                     int first_subdomain);

  int n_owned() const { return layout.n_owned(); }
  int n_ext() const { return layout.n_ext(); }
  int subdomains() const { return static_cast<int>(rows.size()); }

  /// ext_in = [owned, ghosts]: the owned values spread to the ranks that touch them.
  void gather(const Vec& owned) {
    ext_in.head(layout.n_owned()) = owned;
    layout.forward(ext_in.data());
  }
  /// ext_out[0, n_owned) = the sums over subdomains of `pairs`, in a fixed order.
  void combine_subdomains() { subdomain_sum.combine(pairs.data(), ext_out.data()); }
  /// As combine_subdomains with one value per row entry (per local subdomain, in the order of
  /// rows[s]) summed into its pair first.
  void combine_row_entries(const std::vector<std::vector<double>>& per_entry);
  /// Global sums in a fixed order (per owner cluster, then in cluster order). Collective.
  double dot(const Vec& a, const Vec& b) const;
  double sum(const Vec& v) const;
  /// out[k] = a[k]' b[k], or the sum of a[k]'s entries where b[k] is null, each formed as dot()
  /// and sum() form it (they are its one-term cases), with one allreduce for all count terms.
  /// Collective.
  void dots(int count, const Vec* const* a, const Vec* const* b, double* out) const;

  const Comm* comm = nullptr;
  DualLayout layout;
  long long dimension = 0;      ///< rows of B~ (all ranks)
  long long inequalities = 0;   ///< contact rows (all ranks)
  long long friction_rows = 0;  ///< tangential rows of Tresca friction (all ranks)
  /// Per local subdomain: the entries of its rows, in the global order of the rows.
  std::vector<std::vector<BRowEntry>> rows;
  /// Per local subdomain: its multipliers (extended indices), by global index. Their positions
  /// are the subdomain's own multiplier numbering (the rows and columns of F_i).
  std::vector<std::vector<int>> of_subdomain;
  std::vector<int> owner_rank;     ///< per extended entry
  std::vector<int> owner_cluster;  ///< per owned entry: the cluster of its owner subdomain
  // Per owned entry: the row's kind, the right-hand side c of B~ u (<)= c, and for contact rows
  // the force scale and weight (weight * scale * lambda is the row's force: constraints.hpp),
  // the gap, the contact area (summed over the copies), the condition and the point (node a or
  // the slave node).
  std::vector<MultiplierKind> kind;
  Vec rhs;
  /// Per owned entry: the bound on |lambda| of a friction row (+infinity elsewhere; in 3D the
  /// bound on the length of the node's two rows together, the same on both).
  Vec friction_bound;
  /// Per owned friction row: Coulomb's coefficient (< 0: Tresca), the owned index of the normal
  /// contact row of its node and condition, and in 3D the node's other friction row (-1 in 2D
  /// and on other rows).
  std::vector<double> friction_mu;
  std::vector<int> friction_normal, friction_partner;
  std::vector<double> contact_scale, contact_weight, contact_gap, contact_area;
  std::vector<int> contact_condition;
  std::vector<std::array<double, 3>> contact_point;
  /// Per local subdomain: its first (subdomain, multiplier) pair (subdomains() + 1 entries).
  std::vector<int> pair_first;
  OrderedSum subdomain_sum;  ///< the fixed-order sums of the pairs on the owners

  /// Sets friction_mu, friction_normal and friction_partner (number()'s last step): per owned
  /// friction row, found by key among the owned rows (a node's rows have one owner).
  void pair_friction_rows(const FetiLayout& layout, const std::vector<RowKey>& keys,
                          const std::vector<long long>& index,
                          const std::vector<const LocalRow*>& key_row);

  // Work vectors (allocated by number()): one value per pair; extended dual vectors.
  Vec pairs, ext_in, ext_out;
  int num_clusters = 0;                       // all clusters (every rank's): dots()
  mutable std::vector<double> partial_terms;  // per term and cluster: dots() (kDotsReserved)
};

}  // namespace htfeti
