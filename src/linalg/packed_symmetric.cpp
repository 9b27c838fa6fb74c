#include "htfeti/linalg/packed_symmetric.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

namespace htfeti {

Precision parse_precision(const std::string& name) {
  if (name == "double") return Precision::double_;
  if (name == "single") return Precision::single;
  throw std::invalid_argument("unknown precision '" + name + "' (expected double or single)");
}

std::string to_string(Precision precision) {
  return precision == Precision::double_ ? "double" : "single";
}

namespace {

// Storage (see the header): panels of four columns j..j+3 (j a multiple of 4), each its 4 x 4
// diagonal block (the lower triangle column by column, 10 values) and then the rows below it in
// tiles of kTile rows, every tile column-major (kTile rows of column j, then of j+1, ...; the last
// tile of a panel has the remaining rows); the last n mod 4 columns packed column by column. A
// panel holds the same values as its four packed columns, so the total is n (n + 1) / 2 and a
// panel starts where its first column would in LAPACK's packed layout.
constexpr int kTile = 8;
constexpr int kDiagStart[4] = {0, 4, 7, 9};

long column_start(long j, long n) { return j * n - j * (j - 1) / 2; }

long position(int i, int j, int n) {  // i >= j
  const int panels_end = n / 4 * 4;
  if (j >= panels_end) return column_start(j, n) + (i - j);
  const int J = j / 4 * 4, c = j - J, r = i - J;
  const long base = column_start(J, n);
  if (r < 4) return base + kDiagStart[c] + (r - c);
  const int k = r - 4, below = n - J - 4, t = k / kTile;
  const int rows = std::min(kTile, below - t * kTile);
  return base + 10 + static_cast<long>(t) * 4 * kTile + c * rows + (k - t * kTile);
}

template <class T>
void pack(const Eigen::Ref<const Eigen::MatrixXd>& A, std::vector<T>& out) {
  const int n = static_cast<int>(A.rows());
  out.resize(static_cast<size_t>(n) * (n + 1) / 2);
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i) out[static_cast<size_t>(position(i, j, n))] = static_cast<T>(A(i, j));
}

// y = A x, a panel at a time: the diagonal block, then every tile, which adds its four columns
// times x_j..x_j+3 to y over its rows and its rows times x to the four columns' dot products.
// Each stored value is read once and in storage order (one stream), y is loaded and stored once
// per four columns, and the dot products are kept per tile row (kTile independent sums per
// column, added up after the panel), so neither an add latency nor the work per column bounds the
// product, only the memory (bench/packed_product.cpp measures it; docs/performance.md).
template <class T>
inline __attribute__((always_inline)) void packed_symv_panels(const T* a, int n, const double* x,
                                                              double* y) {
  for (int i = 0; i < n; ++i) y[i] = 0.0;
  const int panels_end = n / 4 * 4;
  for (int J = 0; J < panels_end; J += 4) {
    const T* p = a + column_start(J, n);
    const double x0 = x[J], x1 = x[J + 1], x2 = x[J + 2], x3 = x[J + 3];
    auto d = [&](int r, int c) { return static_cast<double>(p[kDiagStart[c] + r - c]); };
    double s0 = d(0, 0) * x0 + d(1, 0) * x1 + d(2, 0) * x2 + d(3, 0) * x3;
    double s1 = d(1, 0) * x0 + d(1, 1) * x1 + d(2, 1) * x2 + d(3, 1) * x3;
    double s2 = d(2, 0) * x0 + d(2, 1) * x1 + d(2, 2) * x2 + d(3, 2) * x3;
    double s3 = d(3, 0) * x0 + d(3, 1) * x1 + d(3, 2) * x2 + d(3, 3) * x3;
    double a0[kTile] = {}, a1[kTile] = {}, a2[kTile] = {}, a3[kTile] = {};
    const T* t = p + 10;
    int k = J + 4;
    for (; k + kTile <= n; k += kTile, t += 4 * kTile) {
      double* yk = y + k;
      const double* xk = x + k;
#pragma omp simd
      for (int i = 0; i < kTile; ++i) {
        const double v0 = static_cast<double>(t[i]), v1 = static_cast<double>(t[kTile + i]),
                     v2 = static_cast<double>(t[2 * kTile + i]),
                     v3 = static_cast<double>(t[3 * kTile + i]);
        yk[i] += v0 * x0 + v1 * x1 + v2 * x2 + v3 * x3;
        a0[i] += v0 * xk[i];
        a1[i] += v1 * xk[i];
        a2[i] += v2 * xk[i];
        a3[i] += v3 * xk[i];
      }
    }
    const int rows = n - k;  // the last, partial tile
    for (int i = 0; i < rows; ++i) {
      const double v0 = static_cast<double>(t[i]), v1 = static_cast<double>(t[rows + i]),
                   v2 = static_cast<double>(t[2 * rows + i]),
                   v3 = static_cast<double>(t[3 * rows + i]);
      y[k + i] += v0 * x0 + v1 * x1 + v2 * x2 + v3 * x3;
      a0[i] += v0 * x[k + i];
      a1[i] += v1 * x[k + i];
      a2[i] += v2 * x[k + i];
      a3[i] += v3 * x[k + i];
    }
    for (int i = 0; i < kTile; ++i) s0 += a0[i], s1 += a1[i], s2 += a2[i], s3 += a3[i];
    y[J] += s0;
    y[J + 1] += s1;
    y[J + 2] += s2;
    y[J + 3] += s3;
  }
  for (int j = panels_end; j < n; ++j) {  // the last n mod 4 columns, packed one by one
    const T* c = a + column_start(j, n);
    const double xj = x[j];
    double s = static_cast<double>(c[0]) * xj;
    for (int k = 1; k < n - j; ++k) {
      const double v = static_cast<double>(c[k]);
      y[j + k] += v * xj;
      s += v * x[j + k];
    }
    y[j] += s;
  }
}

// One instance per instruction set: the loader picks AVX2 with FMA where the CPU has it (four
// doubles per instruction) and the baseline x86-64 code elsewhere. Results differ between the two
// only by the rounding of fused multiply-adds; on one machine every rank and thread runs the same.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define HTFETI_ISA_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define HTFETI_ISA_CLONES
#endif

HTFETI_ISA_CLONES void packed_symv(const double* a, int n, const double* x, double* y) {
  packed_symv_panels(a, n, x, y);
}
HTFETI_ISA_CLONES void packed_symv(const float* a, int n, const double* x, double* y) {
  packed_symv_panels(a, n, x, y);
}

}  // namespace

PackedSymmetric::PackedSymmetric(const Eigen::Ref<const Eigen::MatrixXd>& A, Precision precision)
    : n_(static_cast<int>(A.rows())), single_(precision == Precision::single) {
  if (A.rows() != A.cols()) throw std::invalid_argument("PackedSymmetric: matrix is not square");
  if (single_)
    pack(A, s_);
  else
    pack(A, d_);
}

void PackedSymmetric::multiply(const double* x, double* y) const {
  if (single_)
    packed_symv(s_.data(), n_, x, y);
  else
    packed_symv(d_.data(), n_, x, y);
}

double PackedSymmetric::operator()(int i, int j) const {
  if (i < j) std::swap(i, j);
  const long p = position(i, j, n_);
  return single_ ? static_cast<double>(s_[p]) : d_[p];
}

}  // namespace htfeti
