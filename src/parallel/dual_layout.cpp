#include "htfeti/parallel/dual_layout.hpp"

#include <algorithm>
#include <map>
#include <stdexcept>

namespace htfeti {

DualLayout::DualLayout(const Comm& comm, const std::vector<long long>& touched,
                       const std::vector<int>& owner)
    : comm_(comm.raw()) {
  const int me = comm.rank(), P = comm.size();
  std::map<int, std::vector<long long>> ghosts_by_owner;
  for (size_t i = 0; i < touched.size(); ++i)
    if (owner[i] == me)
      globals_.push_back(touched[i]);
    else
      ghosts_by_owner[owner[i]].push_back(touched[i]);
  n_owned_ = static_cast<int>(globals_.size());
  for (size_t i = 0; i < touched.size(); ++i)
    if (owner[i] != me) globals_.push_back(touched[i]);
  std::sort(globals_.begin() + n_owned_, globals_.end());

  // Tell each owner which of its entries this rank needs.
  std::vector<int> nreq(P, 0), nask(P, 0);
  for (const auto& [r, list] : ghosts_by_owner) nreq[r] = static_cast<int>(list.size());
  MPI_Alltoall(nreq.data(), 1, MPI_INT, nask.data(), 1, MPI_INT, comm_);
  std::vector<int> sdisp(P + 1, 0), rdisp(P + 1, 0);
  for (int r = 0; r < P; ++r) sdisp[r + 1] = sdisp[r] + nreq[r], rdisp[r + 1] = rdisp[r] + nask[r];
  std::vector<long long> sreq(sdisp[P]), rreq(rdisp[P]);
  for (const auto& [r, list] : ghosts_by_owner)
    std::copy(list.begin(), list.end(), &sreq[sdisp[r]]);
  MPI_Alltoallv(sreq.data(), nreq.data(), sdisp.data(), MPI_LONG_LONG, rreq.data(), nask.data(),
                rdisp.data(), MPI_LONG_LONG, comm_);

  for (int r = 0; r < P; ++r) {
    if (nreq[r] == 0 && nask[r] == 0) continue;
    Neighbour nb{r, {}, {}};
    for (int i = rdisp[r]; i < rdisp[r + 1]; ++i) {
      const int k = ext_index(rreq[i]);
      if (k < 0 || k >= n_owned_)
        throw std::logic_error("DualLayout: request for an unowned entry");
      nb.send.push_back(k);
    }
    for (int i = sdisp[r]; i < sdisp[r + 1]; ++i) nb.recv.push_back(ext_index(sreq[i]));
    neighbours_.push_back(std::move(nb));
  }
  for (const auto& nb : neighbours_) {
    sbuf_.emplace_back(std::max(nb.send.size(), nb.recv.size()));
    rbuf_.emplace_back(std::max(nb.send.size(), nb.recv.size()));
  }
  req_.resize(2 * neighbours_.size());
}

int DualLayout::ext_index(long long g) const {
  auto lo = std::lower_bound(globals_.begin(), globals_.begin() + n_owned_, g);
  if (lo != globals_.begin() + n_owned_ && *lo == g) return static_cast<int>(lo - globals_.begin());
  auto gl = std::lower_bound(globals_.begin() + n_owned_, globals_.end(), g);
  if (gl != globals_.end() && *gl == g) return static_cast<int>(gl - globals_.begin());
  return -1;
}

void DualLayout::forward(double* ext) {
  const int nn = static_cast<int>(neighbours_.size());
  for (int i = 0; i < nn; ++i) {
    const auto& nb = neighbours_[i];
    MPI_Irecv(rbuf_[i].data(), static_cast<int>(nb.recv.size()), MPI_DOUBLE, nb.rank, 11, comm_,
              &req_[i]);
    for (size_t j = 0; j < nb.send.size(); ++j) sbuf_[i][j] = ext[nb.send[j]];
    MPI_Isend(sbuf_[i].data(), static_cast<int>(nb.send.size()), MPI_DOUBLE, nb.rank, 11, comm_,
              &req_[nn + i]);
  }
  MPI_Waitall(2 * nn, req_.data(), MPI_STATUSES_IGNORE);
  for (int i = 0; i < nn; ++i)
    for (size_t j = 0; j < neighbours_[i].recv.size(); ++j)
      ext[neighbours_[i].recv[j]] = rbuf_[i][j];
}

void DualLayout::reverse_add(double* ext) {
  const int nn = static_cast<int>(neighbours_.size());
  for (int i = 0; i < nn; ++i) {
    const auto& nb = neighbours_[i];
    MPI_Irecv(rbuf_[i].data(), static_cast<int>(nb.send.size()), MPI_DOUBLE, nb.rank, 12, comm_,
              &req_[i]);
    for (size_t j = 0; j < nb.recv.size(); ++j) sbuf_[i][j] = ext[nb.recv[j]];
    MPI_Isend(sbuf_[i].data(), static_cast<int>(nb.recv.size()), MPI_DOUBLE, nb.rank, 12, comm_,
              &req_[nn + i]);
  }
  MPI_Waitall(2 * nn, req_.data(), MPI_STATUSES_IGNORE);
  // Fixed order of neighbours: the sums do not depend on message arrival.
  for (int i = 0; i < nn; ++i)
    for (size_t j = 0; j < neighbours_[i].send.size(); ++j)
      ext[neighbours_[i].send[j]] += rbuf_[i][j];
}

}  // namespace htfeti
