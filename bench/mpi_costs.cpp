// The MPI costs of one Hessian product, measured on this machine (bench/scale_model.py builds its
// model of 1,000 and 10,000 ranks on them): MPI_Allreduce of n doubles (the coarse vector, the
// per-cluster partial sums of a dot product) and a ping-pong of n doubles between ranks 0 and 1
// (one neighbour exchange of interface multipliers). Medians of `reps` repetitions after a warm-up.
// Usage: mpiexec -n P htfeti_mpi_costs [reps, default 200]. Prints JSON on rank 0.
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const int reps = argc > 1 ? std::atoi(argv[1]) : 200;
  const int sizes[] = {1, 8, 64, 512, 4096, 32768, 262144, 1048576};
  if (rank == 0) std::printf("{\"ranks\": %d, \"allreduce\": [", size);
  for (size_t k = 0; k < sizeof(sizes) / sizeof(sizes[0]); ++k) {
    const int n = sizes[k];
    std::vector<double> a(n, 1.0), b(n);
    std::vector<double> t;
    const int r = n >= 262144 ? std::max(reps / 10, 5) : reps;
    for (int i = 0; i < r + 5; ++i) {
      MPI_Barrier(MPI_COMM_WORLD);
      const double t0 = MPI_Wtime();
      MPI_Allreduce(a.data(), b.data(), n, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
      double dt = MPI_Wtime() - t0, worst = 0;
      MPI_Allreduce(&dt, &worst, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
      if (i >= 5) t.push_back(worst);
    }
    if (rank == 0)
      std::printf("%s{\"doubles\": %d, \"seconds\": %.3e}", k ? ", " : "", n, median(t));
  }
  if (rank == 0) std::printf("], \"ping_pong\": [");
  for (size_t k = 0; k < sizeof(sizes) / sizeof(sizes[0]) && size > 1; ++k) {
    const int n = sizes[k];
    std::vector<double> a(n, 1.0);
    std::vector<double> t;
    const int r = n >= 262144 ? std::max(reps / 10, 5) : reps;
    for (int i = 0; i < r + 5; ++i) {
      MPI_Barrier(MPI_COMM_WORLD);
      const double t0 = MPI_Wtime();
      if (rank == 0) {
        MPI_Send(a.data(), n, MPI_DOUBLE, 1, 0, MPI_COMM_WORLD);
        MPI_Recv(a.data(), n, MPI_DOUBLE, 1, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      } else if (rank == 1) {
        MPI_Recv(a.data(), n, MPI_DOUBLE, 0, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(a.data(), n, MPI_DOUBLE, 0, 0, MPI_COMM_WORLD);
      }
      if (i >= 5) t.push_back((MPI_Wtime() - t0) / 2);  // one way
    }
    if (rank == 0)
      std::printf("%s{\"doubles\": %d, \"seconds\": %.3e}", k ? ", " : "", n, median(t));
  }
  if (rank == 0) std::printf("]}\n");
  MPI_Finalize();
  return 0;
}
