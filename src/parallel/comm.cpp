#include "htfeti/parallel/comm.hpp"

#include <stdexcept>

namespace htfeti {

Comm::Comm(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
}

double Comm::sum(double v) const {
  double r;
  MPI_Allreduce(&v, &r, 1, MPI_DOUBLE, MPI_SUM, comm_);
  return r;
}
long long Comm::sum(long long v) const {
  long long r;
  MPI_Allreduce(&v, &r, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  return r;
}
double Comm::max(double v) const {
  double r;
  MPI_Allreduce(&v, &r, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return r;
}
double Comm::min(double v) const {
  double r;
  MPI_Allreduce(&v, &r, 1, MPI_DOUBLE, MPI_MIN, comm_);
  return r;
}
void Comm::sum_in_place(double* data, int n) const {
  if (size_ > 1) MPI_Allreduce(MPI_IN_PLACE, data, n, MPI_DOUBLE, MPI_SUM, comm_);
}
void Comm::barrier() const { MPI_Barrier(comm_); }

void Comm::agree(const std::string& error, bool input_error) const {
  int mine = error.empty() ? size_ : rank_, first = size_;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm_);
  if (first == size_) return;
  long long len = rank_ == first ? static_cast<long long>(error.size()) : 0;
  int kind = rank_ == first && input_error ? 1 : 0;
  MPI_Bcast(&len, 1, MPI_LONG_LONG, first, comm_);
  MPI_Bcast(&kind, 1, MPI_INT, first, comm_);
  std::string msg = rank_ == first ? error : std::string(static_cast<size_t>(len), ' ');
  MPI_Bcast(msg.data(), static_cast<int>(len), MPI_CHAR, first, comm_);
  if (kind) throw std::invalid_argument(msg);
  throw std::runtime_error(msg);
}

}  // namespace htfeti
