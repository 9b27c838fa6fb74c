// populate() and CHOLMOD's allocations through it (parallel/fresh_pages.hpp).
#include "htfeti/parallel/fresh_pages.hpp"

#include <SuiteSparse_config.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <mutex>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // Linux 5.14 (older headers lack it; older kernels refuse it)
#endif

namespace htfeti {

namespace {
std::atomic<bool> populate_works{true};

void* cholmod_malloc_populated(std::size_t bytes) {
  void* p = std::malloc(bytes);
  if (p) populate(p, bytes);
  return p;
}
void* cholmod_calloc_populated(std::size_t n, std::size_t size) {
  void* p = std::calloc(n, size);
  if (p) populate(p, n * size);  // (calloc has checked n * size)
  return p;
}
void* cholmod_realloc_populated(void* old, std::size_t bytes) {
  void* p = std::realloc(old, bytes);
  if (p) populate(p, bytes);  // the moved part is resident already: the call skips it
  return p;
}
}  // namespace

void populate(void* p, std::size_t bytes) {
  if (bytes < kPopulateBytes || !populate_works.load(std::memory_order_relaxed)) return;
  static const std::uintptr_t page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t begin = (a + page - 1) & ~(page - 1), end = (a + bytes) & ~(page - 1);
  if (end <= begin) return;
  // EINVAL: a kernel without MADV_POPULATE_WRITE. Any other failure (ENOMEM under a memory
  // limit, EFAULT, EINTR) leaves the pages to be faulted in as they are touched, as before.
  if (madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_WRITE) != 0 &&
      errno == EINVAL)
    populate_works.store(false, std::memory_order_relaxed);
}

void populate_cholmod_allocations() {
  static std::once_flag once;
  std::call_once(once, [] {
    SuiteSparse_config.malloc_func = cholmod_malloc_populated;
    SuiteSparse_config.calloc_func = cholmod_calloc_populated;
    SuiteSparse_config.realloc_func = cholmod_realloc_populated;
  });
}

}  // namespace htfeti
