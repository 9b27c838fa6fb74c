#include "htfeti/parallel/exchange.hpp"

#include <limits>
#include <stdexcept>

namespace htfeti {

namespace {

int checked_int(size_t n) {
  if (n > static_cast<size_t>(std::numeric_limits<int>::max()))
    throw std::runtime_error("exchange: more than 2^31 - 1 entries in one message");
  return static_cast<int>(n);
}

}  // namespace

std::vector<std::vector<long long>> exchange_lists(
    const Comm& comm, const std::vector<std::vector<long long>>& send) {
  const int P = comm.size();
  if (static_cast<int>(send.size()) != P)
    throw std::logic_error("exchange: one list per rank expected");
  std::vector<int> sc(P), rc(P), sd(P + 1, 0), rd(P + 1, 0);
  for (int r = 0; r < P; ++r) sc[r] = checked_int(send[r].size());
  MPI_Alltoall(sc.data(), 1, MPI_INT, rc.data(), 1, MPI_INT, comm.raw());
  size_t stotal = 0, rtotal = 0;
  for (int r = 0; r < P; ++r) stotal += sc[r], rtotal += rc[r];
  checked_int(stotal), checked_int(rtotal);
  for (int r = 0; r < P; ++r) sd[r + 1] = sd[r] + sc[r], rd[r + 1] = rd[r] + rc[r];
  std::vector<long long> sbuf(stotal), rbuf(rtotal);
  for (int r = 0; r < P; ++r) std::copy(send[r].begin(), send[r].end(), sbuf.begin() + sd[r]);
  MPI_Alltoallv(sbuf.data(), sc.data(), sd.data(), MPI_LONG_LONG, rbuf.data(), rc.data(), rd.data(),
                MPI_LONG_LONG, comm.raw());
  std::vector<std::vector<long long>> recv(P);
  for (int r = 0; r < P; ++r) recv[r].assign(rbuf.begin() + rd[r], rbuf.begin() + rd[r + 1]);
  return recv;
}

std::vector<std::vector<long long>> all_gather(const Comm& comm,
                                               const std::vector<long long>& mine) {
  const int P = comm.size();
  int n = checked_int(mine.size());
  std::vector<int> counts(P), displs(P + 1, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.raw());
  size_t total = 0;
  for (int r = 0; r < P; ++r) total += counts[r], displs[r + 1] = displs[r] + counts[r];
  checked_int(total);
  std::vector<long long> all(total);
  MPI_Allgatherv(mine.data(), n, MPI_LONG_LONG, all.data(), counts.data(), displs.data(),
                 MPI_LONG_LONG, comm.raw());
  std::vector<std::vector<long long>> out(P);
  for (int r = 0; r < P; ++r) out[r].assign(all.begin() + displs[r], all.begin() + displs[r + 1]);
  return out;
}

}  // namespace htfeti
