// populate(), and CHOLMOD's allocations through it and a pool of large blocks
// (parallel/fresh_pages.hpp).
#include "htfeti/parallel/fresh_pages.hpp"

#include <SuiteSparse_config.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <unordered_map>

// Under AddressSanitizer CHOLMOD's blocks stay with malloc, where the sanitizer checks them.
#if defined(__SANITIZE_ADDRESS__)
#define HTFETI_BLOCK_POOL 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HTFETI_BLOCK_POOL 0
#endif
#endif
#ifndef HTFETI_BLOCK_POOL
#define HTFETI_BLOCK_POOL 1
#endif

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // Linux 5.14 (older headers lack it; older kernels refuse it)
#endif

namespace htfeti {

namespace {
std::atomic<bool> populate_works{true};
thread_local bool kept_blocks = false;  // KeptAllocations

std::size_t whole_pages(std::size_t bytes) {
  static const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  return (bytes + page - 1) / page * page;
}

// CHOLMOD's blocks of kPopulateBytes and more, mapped by the pool and kept when freed (up to
// kIdleBytes) for the next such block: the blocks a factorization frees (its work arrays, and
// the double values of a factor kept in single precision only) serve the next one with pages
// already resident. A block larger than any idle one grows the largest idle block (mremap:
// only the added pages are new).
class BlockPool {
 public:
  // Enough for the blocks of a few factorizations in flight (on the 40^3 METIS cube 64 MiB
  // reused as much as 256 MiB did); little against an address-space limit.
  static constexpr std::size_t kIdleBytes = std::size_t(64) << 20;

  void* allocate(std::size_t bytes, bool* reused) {  // nullptr when the pages cannot be had
    const std::size_t want = whole_pages(bytes);
    std::unique_lock<std::mutex> lock(mutex_);
    void* p = nullptr;
    std::size_t capacity = want;
    *reused = false;
    if (!idle_.empty()) {
      auto it = idle_.lower_bound(want);
      if (it == idle_.end()) {  // grow the largest
        it = std::prev(idle_.end());
        void* q = mremap(it->second, it->first, want, MREMAP_MAYMOVE);
        if (q == MAP_FAILED) q = nullptr;
        idle_bytes_ -= it->first;
        if (!q) munmap(it->second, it->first);
        idle_.erase(it);
        p = q;
        if (p) populate(p, want);  // the added pages (the others are resident: skipped)
      } else {
        p = it->second, capacity = it->first;
        idle_bytes_ -= capacity;
        idle_.erase(it);
        // A block to be kept for the run (KeptAllocations) takes no more than it asked for:
        // a tail of kPopulateBytes or more stays idle as a block of its own (the pool's
        // blocks are page ranges, which mremap and munmap take apart).
        if (kept_blocks && capacity - want >= kPopulateBytes) {
          idle_.emplace(capacity - want, static_cast<char*>(p) + want);
          idle_bytes_ += capacity - want;
          capacity = want;
        }
      }
      *reused = p != nullptr;
    }
    if (!p) {
      lock.unlock();
      p = map(want);
      if (!p) {  // under a memory limit the idle blocks may be what is missing
        release_idle();
        p = map(want);
      }
      if (!p) return nullptr;
      populate(p, want);
      lock.lock();
    }
    live_[p] = capacity;
    return p;
  }
  // false: not a pool block.
  bool release(void* p) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = live_.find(p);
    if (it == live_.end()) return false;
    const std::size_t capacity = it->second;
    live_.erase(it);
    if (idle_bytes_ + capacity <= kIdleBytes) {
      idle_.emplace(capacity, p);
      idle_bytes_ += capacity;
    } else {
      munmap(p, capacity);
    }
    return true;
  }
  // The capacity of a pool block, 0 for any other block.
  std::size_t capacity(void* p) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = live_.find(p);
    return it == live_.end() ? 0 : it->second;
  }
  // A pool block resized (the contents kept), nullptr when the pages cannot be had.
  void* resize(void* p, std::size_t bytes) {
    const std::size_t want = whole_pages(bytes);
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = live_.find(p);
    if (it->second >= want) return p;
    void* q = mremap(p, it->second, want, MREMAP_MAYMOVE);
    if (q == MAP_FAILED) return nullptr;
    live_.erase(it);
    live_[q] = want;
    return q;
  }
  void release_idle() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [capacity, p] : idle_) munmap(p, capacity);
    idle_.clear();
    idle_bytes_ = 0;
  }

 private:
  static void* map(std::size_t bytes) {
    void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    return p == MAP_FAILED ? nullptr : p;
  }
  std::mutex mutex_;
  std::unordered_map<void*, std::size_t> live_;  // block -> capacity
  std::multimap<std::size_t, void*> idle_;       // capacity -> block
  std::size_t idle_bytes_ = 0;
};

BlockPool& block_pool() {
  static BlockPool* pool = new BlockPool;  // never destroyed: CHOLMOD may free after main
  return *pool;
}

// An allocation that fails gets a second try after the pool's idle blocks are returned (under an
// address-space limit they may be what is missing).
template <class Allocate>
void* with_retry(Allocate allocate) {
  void* p = allocate();
  if (!p && HTFETI_BLOCK_POOL) {
    block_pool().release_idle();
    p = allocate();
  }
  return p;
}

void* cholmod_malloc_pooled(std::size_t bytes) {
  if (HTFETI_BLOCK_POOL && bytes >= kPopulateBytes) {
    bool reused = false;
    return block_pool().allocate(bytes, &reused);
  }
  void* p = with_retry([&] { return std::malloc(bytes); });
  if (p) populate(p, bytes);
  return p;
}
void* cholmod_calloc_pooled(std::size_t n, std::size_t size) {
  if (size != 0 && n > SIZE_MAX / size) return nullptr;
  if (HTFETI_BLOCK_POOL && n * size >= kPopulateBytes) {
    bool reused = false;
    void* p = block_pool().allocate(n * size, &reused);
    if (p && reused) std::memset(p, 0, n * size);  // (new pages are zero)
    return p;
  }
  void* p = with_retry([&] { return std::calloc(n, size); });
  if (p) populate(p, n * size);
  return p;
}
void* cholmod_realloc_pooled(void* old, std::size_t bytes) {
  if (HTFETI_BLOCK_POOL && old && block_pool().capacity(old) > 0)
    return block_pool().resize(old, bytes);
  if (HTFETI_BLOCK_POOL && bytes >= kPopulateBytes) {
    void* p = cholmod_malloc_pooled(bytes);
    if (p && old) {
      std::memcpy(p, old, std::min(bytes, malloc_usable_size(old)));
      std::free(old);
    }
    return p;
  }
  void* p = with_retry([&] { return std::realloc(old, bytes); });  // (old stays valid on failure)
  if (p) populate(p, bytes);  // the moved part is resident already: the call skips it
  return p;
}
void cholmod_free_pooled(void* p) {
  if (!p) return;
  if (HTFETI_BLOCK_POOL && block_pool().release(p)) return;
  std::free(p);
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
    SuiteSparse_config.malloc_func = cholmod_malloc_pooled;
    SuiteSparse_config.calloc_func = cholmod_calloc_pooled;
    SuiteSparse_config.realloc_func = cholmod_realloc_pooled;
    SuiteSparse_config.free_func = cholmod_free_pooled;
  });
}

void release_idle_blocks() { block_pool().release_idle(); }

KeptAllocations::KeptAllocations() : previous_(kept_blocks) { kept_blocks = true; }
KeptAllocations::~KeptAllocations() { kept_blocks = previous_; }

}  // namespace htfeti
