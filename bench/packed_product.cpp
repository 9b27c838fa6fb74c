// The explicit F's kernel alone: y_i = F_i x_i for many packed symmetric blocks of one size, in an
// OpenMP loop over the blocks (as DualProblem::apply_F runs it), against the bytes it streams.
// The blocks together are far larger than the caches (default 1,200 MB, the size of the full
// Table 3's F_i), so the product is bound by memory bandwidth; compare with htfeti_stream.
// Usage: htfeti_packed_product [n, default 396] [MB of blocks, default 1200] [double|single]
//        [repetitions, default 10]. Prints JSON (median and best GB/s of stored values read).
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "htfeti/linalg/packed_symmetric.hpp"

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 396;
  const long mb = argc > 2 ? std::atol(argv[2]) : 1200;
  const std::string prec = argc > 3 ? argv[3] : "double";
  const int reps = argc > 4 ? std::atoi(argv[4]) : 10;
  const htfeti::Precision p = htfeti::parse_precision(prec);
  const long block_bytes = static_cast<long>(n) * (n + 1) / 2 * (p == htfeti::Precision::single ? 4 : 8);
  const int nb = static_cast<int>(std::max(1L, mb * 1024 * 1024 / block_bytes));
  Eigen::MatrixXd A(n, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) A(i, j) = 1.0 / (1.0 + std::abs(i - j)) + (i == j ? n : 0);
  std::vector<htfeti::PackedSymmetric> blocks(nb);
#pragma omp parallel for schedule(static)
  for (int b = 0; b < nb; ++b) blocks[b] = htfeti::PackedSymmetric(A, p);  // first touch
  std::vector<Eigen::VectorXd> x(nb, Eigen::VectorXd::Ones(n)), y(nb, Eigen::VectorXd::Zero(n));
  std::vector<double> seconds;
  for (int r = 0; r < reps + 1; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel for schedule(dynamic)
    for (int b = 0; b < nb; ++b) blocks[b].multiply(x[b].data(), y[b].data());
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (r > 0) seconds.push_back(s);  // the first pass warms up
  }
  // y = A 1: every row sums to n + sum of 1/(1+|i-j|); check one row against the dense product.
  const double check = (A * Eigen::VectorXd::Ones(n))[n / 2] - y[nb / 2][n / 2];
  std::sort(seconds.begin(), seconds.end());
  const double bytes = static_cast<double>(block_bytes) * nb;
  std::printf(
      "{\"threads\": %d, \"n\": %d, \"precision\": \"%s\", \"blocks\": %d, \"mb\": %.1f, "
      "\"gb_s_median\": %.3f, \"gb_s_best\": %.3f, \"ms_median\": %.3f, \"check\": %.2e}\n",
      omp_get_max_threads(), n, prec.c_str(), nb, bytes / 1048576, bytes / seconds[seconds.size() / 2] / 1e9,
      bytes / seconds.front() / 1e9, seconds[seconds.size() / 2] * 1e3, check);
  return std::abs(check) < 1e-6 * n ? 0 : 1;
}
