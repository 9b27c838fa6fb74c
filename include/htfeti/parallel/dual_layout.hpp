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

}  // namespace htfeti
