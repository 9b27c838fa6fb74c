// A STREAM-like triad a = b + s c over arrays far larger than the caches: the machine's
// sustainable memory bandwidth, the bound for applying F (which streams factors or dense blocks).
// Usage: htfeti_stream [MB per array, default 512] [repetitions, default 10]. Prints JSON.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

int main(int argc, char** argv) {
  const long mb = argc > 1 ? std::atol(argv[1]) : 512;
  const int reps = argc > 2 ? std::atoi(argv[2]) : 10;
  const long n = mb * 1024 * 1024 / 8;
  std::vector<double> a(n), b(n), c(n);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) a[i] = 0, b[i] = 1, c[i] = 2;
  std::vector<double> seconds;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) a[i] = b[i] + 3.0 * c[i];
    seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(seconds.begin(), seconds.end());
  const double best = seconds.front(), median = seconds[seconds.size() / 2];
  const double bytes = 3.0 * 8.0 * n;  // two reads and one write per element
  std::printf(
      "{\"threads\": %d, \"array_mb\": %ld, \"triad_gb_s_best\": %.3f, \"triad_gb_s_median\": "
      "%.3f, \"check\": %.1f}\n",
      omp_get_max_threads(), mb, bytes / best / 1e9, bytes / median / 1e9, a[n / 2]);
  return 0;
}
