// OpenBLAS's work buffers under an address-space limit (ulimit -v, RLIMIT_AS).
//
// OpenBLAS maps one work buffer (128 MiB in Debian's x86-64 build) for each thread the first
// time that thread calls a LAPACK routine such as dpotrf (CHOLMOD's supernodes, the dense
// blocks), and when the mapping fails it retries forever (blas_memory_alloc in OpenBLAS 0.3):
// a rank whose address space is full hangs there, and every other rank waits for it. Measured
// with `ulimit -v 700000; mpiexec -n 2 htfeti solve --problem membranes`: both ranks spun in
// blas_memory_alloc until killed, for any problem size.
//
// reserve_blas_buffers() runs once before the solve. Without an address-space limit it does
// nothing (mappings do not fail there; memory runs out as resident pages, which the memory
// check and std::bad_alloc handle). With a limit it checks that one buffer per thread, with a
// margin for the threads' malloc arenas, still fits below the limit, and if so has every thread
// take and return its buffer at once (holding them together, so that OpenBLAS keeps one per
// thread): later LAPACK calls reuse them and never map again, and memory that runs out later
// fails as an ordinary allocation (exit 2 on every rank). Nothing happens when the BLAS in use
// is not OpenBLAS.
#pragma once

#include <string>

namespace htfeti {

/// The size OpenBLAS maps per work buffer on x86-64 (its BUFFER_SIZE, 32 << 22 bytes).
constexpr double kBlasBufferMiB = 128;
/// Room left for what the threads map besides the BLAS buffers (glibc arenas reserve 64 MiB
/// each, in a 128 MiB window).
constexpr double kBlasBufferMarginMiB = 128;

/// See the file comment. Returns "" on success, or a message naming the limit when the buffers
/// do not fit (the caller agrees on it with the other ranks and ends the run with exit 2).
/// Not thread-safe: call from the main thread outside parallel regions. Local (no MPI).
std::string reserve_blas_buffers();

/// BLAS on one thread for the scope of one call into CHOLMOD or LAPACK, for results that do not
/// depend on the number of threads. Called outside a parallel region, OpenBLAS's OpenMP flavour
/// uses every thread, and its threaded blocks (dpotrf, dgemm, dsyrk in CHOLMOD's supernodes)
/// round differently per thread count: a rank holding fewer clusters than threads, which
/// factors them one at a time, got other bits than a rank factoring the same subdomains in
/// parallel, one per thread (measured: the 4 floating subdomains of a tet4 cube read from Gmsh's
/// parts, B K^+ f different in the last bits between 1 and 3 ranks of 2 threads, and the
/// energy with it). Inside a parallel region it does nothing (OpenBLAS runs on one thread there
/// anyway). OpenBLAS's own setting (openblas_set_num_threads) cannot do this: in the OpenMP
/// flavour it sets OpenMP's thread count, and OpenBLAS follows OpenMP's at every call.
class BlasOnOneThread {
 public:
  BlasOnOneThread();
  ~BlasOnOneThread();
  BlasOnOneThread(const BlasOnOneThread&) = delete;
  BlasOnOneThread& operator=(const BlasOnOneThread&) = delete;

 private:
  int saved_ = 0;  // the thread count to restore, 0 inside a parallel region
};

}  // namespace htfeti
