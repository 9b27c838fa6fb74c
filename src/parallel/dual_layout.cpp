#include "htfeti/parallel/dual_layout.hpp"

#include <omp.h>

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

OrderedSum::OrderedSum(const Comm& comm, const DualLayout& layout, const std::vector<int>& k,
                       const std::vector<long long>& contributor, const std::vector<int>& owner)
    : comm_(comm.raw()), n_owned_(layout.n_owned()), k_(k) {
  const int P = comm.size(), me = comm.rank();
  const int n = static_cast<int>(k.size());
  std::vector<std::vector<int>> ghost(P);
  for (int p = 0; p < n; ++p) {
    if (k[p] < n_owned_)
      local_order_.push_back(p);
    else
      ghost[owner[k[p]]].push_back(p);
  }
  // By owned entry, then by contributor: first_[e] .. first_[e + 1] are entry e's pairs.
  std::stable_sort(local_order_.begin(), local_order_.end(), [&](int a, int b) {
    return k[a] != k[b] ? k[a] < k[b] : contributor[a] < contributor[b];
  });
  first_.assign(n_owned_ + 1, 0);
  for (int p : local_order_) ++first_[k[p] + 1];
  for (int e = 0; e < n_owned_; ++e) first_[e + 1] += first_[e];
  std::vector<int> scount(P, 0), rcount(P, 0);
  for (int r = 0; r < P; ++r) {
    if (r == me && !ghost[r].empty()) throw std::logic_error("OrderedSum: ghost owned by itself");
    std::sort(ghost[r].begin(), ghost[r].end(), [&](int a, int b) {
      const long long ga = layout.global(k[a]), gb = layout.global(k[b]);
      return ga != gb ? ga < gb : contributor[a] < contributor[b];
    });
    scount[r] = static_cast<int>(ghost[r].size());
  }
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm_);
  std::vector<int> sd(P + 1, 0), rd(P + 1, 0);
  for (int r = 0; r < P; ++r) sd[r + 1] = sd[r] + scount[r], rd[r + 1] = rd[r] + rcount[r];
  std::vector<long long> sg(sd[P]), rg(rd[P]);
  for (int r = 0; r < P; ++r)
    for (int i = 0; i < scount[r]; ++i) sg[sd[r] + i] = layout.global(k[ghost[r][i]]);
  MPI_Alltoallv(sg.data(), scount.data(), sd.data(), MPI_LONG_LONG, rg.data(), rcount.data(),
                rd.data(), MPI_LONG_LONG, comm_);
  for (int r = 0; r < P; ++r) {
    if (scount[r] == 0 && rcount[r] == 0) continue;
    Neighbour nb{r, ghost[r], {}};
    for (int i = rd[r]; i < rd[r + 1]; ++i) {
      const int e = layout.ext_index(rg[i]);
      if (e < 0 || e >= n_owned_)
        throw std::logic_error("OrderedSum: a value for an unowned entry");
      nb.recv.push_back(e);
    }
    neighbours_.push_back(std::move(nb));
  }
  for (const auto& nb : neighbours_) {
    sbuf_.emplace_back(nb.send.size());
    rbuf_.emplace_back(nb.recv.size());
  }
  req_.resize(2 * neighbours_.size());
}

void OrderedSum::combine(const double* values, double* ext) {
  const int nn = static_cast<int>(neighbours_.size());
  for (int i = 0; i < nn; ++i) {
    const auto& nb = neighbours_[i];
    MPI_Irecv(rbuf_[i].data(), static_cast<int>(nb.recv.size()), MPI_DOUBLE, nb.rank, 13, comm_,
              &req_[i]);
    for (size_t j = 0; j < nb.send.size(); ++j) sbuf_[i][j] = values[nb.send[j]];
    MPI_Isend(sbuf_[i].data(), static_cast<int>(nb.send.size()), MPI_DOUBLE, nb.rank, 13, comm_,
              &req_[nn + i]);
  }
  // Each owned entry sums its own contributions in contributor order: the entries are
  // independent, so threads share them, and every sum is formed as in one sweep.
#pragma omp parallel for schedule(static) if (n_owned_ > 50000 && !omp_in_parallel())
  for (int e = 0; e < n_owned_; ++e) {
    double s = 0.0;
    for (int q = first_[e]; q < first_[e + 1]; ++q) s += values[local_order_[q]];
    ext[e] = s;
  }
  MPI_Waitall(2 * nn, req_.data(), MPI_STATUSES_IGNORE);
  for (int i = 0; i < nn; ++i)  // neighbours in rank order: their contributors come later
    for (size_t j = 0; j < neighbours_[i].recv.size(); ++j)
      ext[neighbours_[i].recv[j]] += rbuf_[i][j];
}

}  // namespace htfeti
