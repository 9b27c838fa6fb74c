// Distribution of the dual vector (one entry per row of B~) over MPI ranks.
//
// Every multiplier is owned by exactly one rank (the rank of the lowest-numbered subdomain it
// touches). A rank's "extended" vector holds its owned entries first, in increasing global order,
// then the ghosts: entries owned elsewhere that its subdomains touch, also in global order.
// forward() copies owners' values into the ghosts; reverse_add() adds the ghosts' values into the
// owners' entries. Both exchange messages only with neighbouring ranks and allocate nothing.
#pragma once

#include <vector>

#include "htfeti/parallel/comm.hpp"

namespace htfeti {

class DualLayout {
 public:
  DualLayout() = default;
  /// touched: the global indices this rank's subdomains touch (sorted, unique), owner: their
  /// owning ranks. Collective.
  DualLayout(const Comm& comm, const std::vector<long long>& touched,
             const std::vector<int>& owner);

  int n_owned() const { return n_owned_; }
  int n_ext() const { return static_cast<int>(globals_.size()); }
  /// Global index of extended entry i.
  long long global(int i) const { return globals_[i]; }
  /// Extended index of a touched global index (binary search); -1 if not touched.
  int ext_index(long long global) const;

  void forward(double* ext);
  void reverse_add(double* ext);

 private:
  struct Neighbour {
    int rank;
    std::vector<int> send;  // forward: owned entries to send; reverse: where received values go
    std::vector<int> recv;  // forward: ghost entries to fill; reverse: ghost entries to send
  };
  MPI_Comm comm_ = MPI_COMM_NULL;
  int n_owned_ = 0;
  std::vector<long long> globals_;
  std::vector<Neighbour> neighbours_;
  std::vector<std::vector<double>> sbuf_, rbuf_;
  std::vector<MPI_Request> req_;
};

/// Sums of contributions to dual entries in a fixed order, so that results do not depend on the
/// number of ranks: every contribution is a (extended index, contributor) pair with one value,
/// contributors are globally ordered ids (subdomains or clusters), and each owned entry becomes
/// the sequential sum of its contributions in increasing contributor order, exactly as on one
/// rank. This works because ranks own contiguous contributor ranges and the owner of an entry
/// holds its lowest contributor: the owner adds its own contributions first, then those of the
/// neighbours in rank order, one value per contributor (never a neighbour's partial sum).
/// Cost: the same messages as DualLayout::reverse_add, one double per remote pair.
class OrderedSum {
 public:
  OrderedSum() = default;
  /// k[p], contributor[p]: the pairs, in the order the values will be given. owner[k]: the rank
  /// owning extended entry k. Collective.
  OrderedSum(const Comm& comm, const DualLayout& layout, const std::vector<int>& k,
             const std::vector<long long>& contributor, const std::vector<int>& owner);
  int pairs() const { return static_cast<int>(k_.size()); }
  /// ext[0 .. n_owned) = the ordered sums of values (ghost entries untouched). Allocates nothing.
  void combine(const double* values, double* ext);

 private:
  struct Neighbour {
    int rank;
    std::vector<int> send;  // pair indices sent to this owner, in (global index, contributor) order
    std::vector<int> recv;  // owned extended indices the received values go to, same order
  };
  MPI_Comm comm_ = MPI_COMM_NULL;
  int n_owned_ = 0;
  std::vector<int> k_;
  std::vector<int> local_order_;  // pairs with an owned entry, by (entry, contributor)
  std::vector<int> first_;        // n_owned + 1: entry e's pairs in local_order_
  std::vector<Neighbour> neighbours_;
  std::vector<std::vector<double>> sbuf_, rbuf_;
  std::vector<MPI_Request> req_;
};

}  // namespace htfeti
