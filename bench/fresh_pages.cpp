// What a fresh page costs on this machine (docs/performance.md, "Fresh pages in one call"):
// anonymous memory mapped anew and written page by page (one page fault per 4 KiB page), against
// the same memory made resident first by madvise(MADV_POPULATE_WRITE) (parallel/fresh_pages.hpp)
// and then written; then a pass that reads it all, to show that the populated memory reads as
// fast. Each way is timed on new mappings, `repeat` times, and the medians are printed.
// Usage: htfeti_fresh_pages [MiB per mapping, default 1024] [repeat, default 3]
#include <sys/mman.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
}  // namespace

int main(int argc, char** argv) {
  const std::size_t mib = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 1024;
  const int repeat = argc > 2 ? std::atoi(argv[2]) : 3;
  const std::size_t bytes = mib << 20, pages = bytes / 4096;
  double sink = 0;
  for (int populate = 0; populate < 2; ++populate) {
    std::vector<double> first, write, read;
    for (int r = 0; r < repeat; ++r) {
      const double t0 = now();
      void* m = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (m == MAP_FAILED) return std::perror("mmap"), 1;
      auto* p = static_cast<double*>(m);
      if (populate && madvise(m, bytes, MADV_POPULATE_WRITE) != 0)
        return std::perror("madvise(MADV_POPULATE_WRITE)"), 1;
      const double t1 = now();
      std::memset(m, 1, bytes);
      const double t2 = now();
      double s = 0;
      for (std::size_t i = 0; i < bytes / sizeof(double); ++i) s += p[i];
      const double t3 = now();
      sink += s;
      first.push_back(t1 - t0), write.push_back(t2 - t1), read.push_back(t3 - t2);
      munmap(m, bytes);
    }
    const double total = median(first) + median(write);
    std::printf(
        "%-30s %zu MiB: map%s %.3f s, first write %.3f s, %.2f us per 4 KiB page; then a read "
        "pass %.2f GB/s\n",
        populate ? "populated, then written" : "written page by page", mib,
        populate ? " + populate" : "", median(first), median(write), 1e6 * total / pages,
        bytes / median(read) / 1e9);
  }
  return sink == 42 ? 2 : 0;
}
