#include "htfeti/parallel/comm.hpp"

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

}  // namespace htfeti
