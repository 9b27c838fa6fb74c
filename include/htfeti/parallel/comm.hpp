// A thin wrapper over an MPI communicator: rank, size and the reductions the solvers need.
// The QP solvers see only this (through qp::Reducer), never MPI itself.
#pragma once

#include <mpi.h>

#include <string>
#include <vector>

namespace htfeti {

class Comm {
 public:
  explicit Comm(MPI_Comm comm = MPI_COMM_WORLD);
  int rank() const { return rank_; }
  int size() const { return size_; }
  MPI_Comm raw() const { return comm_; }
  double sum(double v) const;
  long long sum(long long v) const;
  double max(double v) const;
  double min(double v) const;
  void sum_in_place(double* data, int n) const;
  void barrier() const;
  /// Failure agreement (DESIGN.md, "Parallel rules"): every rank passes its error message (empty
  /// if it succeeded); if any rank failed, every rank throws the message of the lowest failing
  /// rank: std::invalid_argument if that failure was bad input (input_error), else
  /// std::runtime_error. Collective; never hangs because every rank takes part.
  void agree(const std::string& error, bool input_error = false) const;

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
};

}  // namespace htfeti
