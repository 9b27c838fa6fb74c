// Thread policy: one level of parallelism, htfeti's own loops over the clusters of a rank
// (OpenMP). CHOLMOD and OpenBLAS (the OpenMP flavour) open parallel regions of their own; nested
// inside ours they must run serially, and with a single thread they must not start teams at all
// (CHOLMOD asks for a fixed number of threads, which costs more than it gains on small supernodes
// and oversubscribes the cores). Call once at program start, after MPI_Init.
#pragma once

#include <omp.h>

namespace htfeti {

inline void init_threads() { omp_set_max_active_levels(omp_get_max_threads() > 1 ? 1 : 0); }

}  // namespace htfeti
