// OpenBLAS's work buffers under an address-space limit: see blas_buffers.hpp.
#include "htfeti/parallel/blas_buffers.hpp"

#include <dlfcn.h>
#include <omp.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cstdio>

#include "htfeti/parallel/memory.hpp"

namespace htfeti {

std::string reserve_blas_buffers() {
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return "";
  using Alloc = void* (*)(int);
  using Free = void (*)(void*);
  // Looked up at run time: present when the BLAS loaded is OpenBLAS, absent otherwise.
  const auto alloc = reinterpret_cast<Alloc>(dlsym(RTLD_DEFAULT, "blas_memory_alloc"));
  const auto release = reinterpret_cast<Free>(dlsym(RTLD_DEFAULT, "blas_memory_free"));
  if (!alloc || !release) return "";

  const int threads = omp_get_max_threads();
  const double need_mib = threads * kBlasBufferMiB + kBlasBufferMarginMiB;
  const size_t bytes = static_cast<size_t>(need_mib * 1048576.0);
  void* probe = mmap(nullptr, bytes, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (probe == MAP_FAILED) {
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "the address-space limit (ulimit -v: %.0f MiB, of which %.0f MiB are mapped "
                  "at the start) leaves no room for the BLAS work buffers (%d thread%s x %.0f "
                  "MiB, and %.0f MiB for the threads' heaps): raise the limit by at least "
                  "%.0f MiB, or run fewer threads per rank (OMP_NUM_THREADS)",
                  static_cast<double>(limit.rlim_cur) / 1048576.0,
                  proc_status_mb("/proc/self/status", "VmSize"), threads, threads > 1 ? "s" : "",
                  kBlasBufferMiB, kBlasBufferMarginMiB, need_mib);
    return msg;
  }
  munmap(probe, bytes);
  // Every thread takes a buffer, and returns it only when all hold one.
#pragma omp parallel num_threads(threads)
  {
    void* buffer = alloc(1);  // (1: as OpenBLAS's LAPACK interface asks)
#pragma omp barrier
    release(buffer);
  }
  return "";
}

BlasOnOneThread::BlasOnOneThread() {
  if (omp_in_parallel()) return;
  saved_ = omp_get_max_threads();
  if (saved_ > 1) omp_set_num_threads(1);
}

BlasOnOneThread::~BlasOnOneThread() {
  if (saved_ > 1) omp_set_num_threads(saved_);
}

}  // namespace htfeti
