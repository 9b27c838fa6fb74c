// What a fresh page costs on this machine (docs/performance.md, "Fresh pages in one call" and
// "What a fresh page costs here, and huge pages again"): anonymous memory mapped anew and written
// page by page (one page fault per 4 KiB page), against the same memory made resident first by
// madvise(MADV_POPULATE_WRITE) (parallel/fresh_pages.hpp) and then written, and against a mapping
// started on a 2 MiB boundary, marked MADV_HUGEPAGE (transparent huge pages) and then populated;
// then a pass that reads it all. Each way is timed on new mappings, `repeat` times, and the
// medians are printed. By default each mapping is unmapped before the next, so the kernel can
// give the next one the pages it just got back; with `keep` every mapping stays until the end,
// so each one needs memory the process has not used before.
// Usage: htfeti_fresh_pages [MiB per mapping, default 1024] [repeat, default 3] [keep]
#include <sys/mman.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
constexpr std::size_t kHuge = std::size_t(2) << 20;
enum Way { page_by_page, populated, huge_populated };
const char* kNames[] = {"written page by page", "populated, then written", "huge pages, populated"};
}  // namespace

int main(int argc, char** argv) {
  const std::size_t mib = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 1024;
  const int repeat = argc > 2 ? std::atoi(argv[2]) : 3;
  const bool keep = argc > 3 && std::strcmp(argv[3], "keep") == 0;
  const std::size_t bytes = mib << 20, pages = bytes / 4096;
  double sink = 0;
  std::vector<std::pair<void*, std::size_t>> kept;
  for (int way = page_by_page; way <= huge_populated; ++way) {
    std::vector<double> first, write, read;
    for (int r = 0; r < repeat; ++r) {
      const double t0 = now();
      const std::size_t mapped = way == huge_populated ? bytes + kHuge : bytes;
      void* base =
          mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (base == MAP_FAILED) return std::perror("mmap"), 1;
      void* m = base;
      if (way == huge_populated) {  // the first 2 MiB boundary in the mapping
        const auto a = reinterpret_cast<std::uintptr_t>(base);
        m = reinterpret_cast<void*>((a + kHuge - 1) & ~std::uintptr_t(kHuge - 1));
        if (madvise(m, bytes, MADV_HUGEPAGE) != 0) return std::perror("madvise(MADV_HUGEPAGE)"), 1;
      }
      if (way != page_by_page && madvise(m, bytes, MADV_POPULATE_WRITE) != 0)
        return std::perror("madvise(MADV_POPULATE_WRITE)"), 1;
      const double t1 = now();
      std::memset(m, 1, bytes);
      const double t2 = now();
      auto* p = static_cast<double*>(m);
      double s = 0;
      for (std::size_t i = 0; i < bytes / sizeof(double); ++i) s += p[i];
      const double t3 = now();
      sink += s;
      first.push_back(t1 - t0), write.push_back(t2 - t1), read.push_back(t3 - t2);
      if (keep)
        kept.push_back({base, mapped});
      else
        munmap(base, mapped);
    }
    const double total = median(first) + median(write);
    std::printf(
        "%-24s %zu MiB%s: map%s %.3f s, first write %.3f s, %.2f us per 4 KiB page (%.2f s per "
        "GiB); then a read pass %.2f GB/s\n",
        kNames[way], mib, keep ? " (kept)" : "", way == page_by_page ? "" : " + populate",
        median(first), median(write), 1e6 * total / pages, total * 1024.0 / mib,
        bytes / median(read) / 1e9);
  }
  for (const auto& [p, n] : kept) munmap(p, n);
  return sink == 42 ? 2 : 0;
}
