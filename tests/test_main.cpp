// GoogleTest main for htfeti: initializes MPI so the same test binaries run serially and under
// mpiexec -n P. Only rank 0 prints; a failure on any rank fails the run on every rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include "htfeti/parallel/threads.hpp"

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  htfeti::init_threads();
  ::testing::InitGoogleTest(&argc, argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  int local = RUN_ALL_TESTS(), global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return global;
}
