// Personalized all-to-all exchange of 64-bit integers: every rank sends a list to every rank and
// receives one from every rank (MPI_Alltoall of the counts, then MPI_Alltoallv). The building
// block of the rendezvous steps that need no rank to see everything (the distributed mesh input,
// model/partitioned_source.cpp). Communication: the lists themselves, plus P counts per rank.
#pragma once

#include <vector>

#include "htfeti/parallel/comm.hpp"

namespace htfeti {

/// send[r]: what this rank sends to rank r (send.size() == comm.size()). Returns recv[r]: what
/// rank r sent to this rank. Collective. Throws std::runtime_error above 2^31 - 1 entries per
/// pair of ranks or in all.
std::vector<std::vector<long long>> exchange_lists(const Comm& comm,
                                                   const std::vector<std::vector<long long>>& send);

/// Every rank's list, in rank order (MPI_Allgatherv). Collective.
std::vector<std::vector<long long>> all_gather(const Comm& comm,
                                               const std::vector<long long>& mine);

}  // namespace htfeti
