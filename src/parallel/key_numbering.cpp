#include "htfeti/parallel/key_numbering.hpp"

#include <algorithm>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace htfeti {

std::vector<long long> number_keys(const Comm& comm, const std::vector<NumberingKey>& keys,
                                   long long positions,
                                   const std::function<long long(const NumberingKey&)>& position,
                                   long long& total) {
  const int P = comm.size();
  const size_t n = keys.size();
  std::vector<int> bucket(n), scount(P, 0), rcount(P, 0);
  const long long T = std::max(positions, 1LL);
  for (size_t i = 0; i < n; ++i) {
    long long t = std::clamp(position(keys[i]), 0LL, T - 1);
    bucket[i] = static_cast<int>(static_cast<__int128>(t) * P / T);
    ++scount[bucket[i]];
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return bucket[a] < bucket[b]; });
  const int K = 6;
  std::vector<int> sc(P), rc(P), sd(P + 1, 0), rd(P + 1, 0);
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm.raw());
  for (int r = 0; r < P; ++r) {
    if (scount[r] > std::numeric_limits<int>::max() / K ||
        rcount[r] > std::numeric_limits<int>::max() / K)
      throw std::runtime_error("key numbering: too many keys between two ranks");
    sc[r] = scount[r] * K, rc[r] = rcount[r] * K;
    sd[r + 1] = sd[r] + sc[r], rd[r + 1] = rd[r] + rc[r];
  }
  std::vector<long long> sbuf(static_cast<size_t>(sd[P])), rbuf(static_cast<size_t>(rd[P]));
  for (size_t j = 0; j < n; ++j)
    std::copy(keys[order[j]].begin(), keys[order[j]].end(), &sbuf[K * j]);
  MPI_Alltoallv(sbuf.data(), sc.data(), sd.data(), MPI_LONG_LONG, rbuf.data(), rc.data(), rd.data(),
                MPI_LONG_LONG, comm.raw());
  // Bucket: sort the received keys, count the distinct ones.
  const size_t m = rbuf.size() / K;
  std::vector<NumberingKey> recv(m);
  for (size_t j = 0; j < m; ++j) std::copy(&rbuf[K * j], &rbuf[K * j] + K, recv[j].begin());
  // On one rank (and wherever the buckets arrive in order) the keys come sorted: then the
  // sort is skipped and each key's index is the count of distinct keys before it.
  const bool in_order = std::is_sorted(recv.begin(), recv.end());
  std::vector<NumberingKey> uniq = recv;
  if (!in_order) std::sort(uniq.begin(), uniq.end());
  uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
  long long local = static_cast<long long>(uniq.size()), offset = 0;
  MPI_Exscan(&local, &offset, 1, MPI_LONG_LONG, MPI_SUM, comm.raw());
  if (comm.rank() == 0) offset = 0;
  MPI_Allreduce(&local, &total, 1, MPI_LONG_LONG, MPI_SUM, comm.raw());
  std::vector<long long> ridx(m), sidx(n);
  if (in_order) {
    long long distinct = -1;
    for (size_t j = 0; j < m; ++j) {
      if (j == 0 || recv[j] != recv[j - 1]) ++distinct;
      ridx[j] = offset + distinct;
    }
  } else {
    for (size_t j = 0; j < m; ++j)
      ridx[j] = offset + (std::lower_bound(uniq.begin(), uniq.end(), recv[j]) - uniq.begin());
  }
  // Answers go back along the same counts (in units of one index).
  std::vector<int> sd1(P + 1, 0), rd1(P + 1, 0);
  for (int r = 0; r < P; ++r) sd1[r + 1] = sd1[r] + scount[r], rd1[r + 1] = rd1[r] + rcount[r];
  MPI_Alltoallv(ridx.data(), rcount.data(), rd1.data(), MPI_LONG_LONG, sidx.data(), scount.data(),
                sd1.data(), MPI_LONG_LONG, comm.raw());
  std::vector<long long> out(n);
  for (size_t j = 0; j < n; ++j) out[order[j]] = sidx[j];
  return out;
}

}  // namespace htfeti
