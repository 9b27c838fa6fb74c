#include "htfeti/linalg/packed_symmetric.hpp"

#include <algorithm>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <stdexcept>
#include <utility>

namespace htfeti {

Precision parse_precision(const std::string& name) {
  return parse_name(kPrecisionNames, name, "precision");
}

std::string to_string(Precision value) { return name_of(kPrecisionNames, value); }

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
    for (int i = j; i < n; ++i)
      out[static_cast<size_t>(position(i, j, n))] = static_cast<T>(A(i, j));
}

// y = A x, a panel at a time: the diagonal block, then every tile, which adds its four columns
// times x_j..x_j+3 to y over its rows and its rows times x to the four columns' dot products.
// Each stored value is read once and in storage order (one stream), y is loaded and stored once
// per four columns, and the dot products are kept per tile row (kTile independent sums per
// column, added up after the panel), so neither an add latency nor the work per column bounds the
// product, only the memory (bench/packed_product.cpp measures it; docs/performance.md).
// Tiles::run(t, k, n, x, y, x0..x3, a0..a3) takes the panel's whole tiles from row k on, adds to
// y and to the dot products a0..a3 (kTile sums each), and returns the first row it did not take
// (t advanced past the tiles it took).
#define HTFETI_INLINE inline __attribute__((always_inline))

struct GenericTiles {
  template <class T>
  HTFETI_INLINE static int run(const T*& t, int k, int n, const double* x, double* y, double x0,
                               double x1, double x2, double x3, double* a0, double* a1, double* a2,
                               double* a3) {
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
    return k;
  }
};

#include "packed_symv_panels.inc"  // packed_symv_panels<Tiles>(a, n, x, y)

// One instance per instruction set: the loader picks AVX-512 or AVX2 with FMA where the CPU has
// them and the baseline x86-64 code elsewhere. Results differ between them only by the rounding
// of fused multiply-adds; on one machine every rank and thread runs the same.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define HTFETI_ISA_CLONES \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#define HTFETI_AVX2_SINGLE 1
#else
#define HTFETI_ISA_CLONES
#define HTFETI_AVX2_SINGLE 0
#endif

HTFETI_ISA_CLONES void packed_symv(const double* a, int n, const double* x, double* y) {
  packed_symv_panels<GenericTiles>(a, n, x, y);
}
HTFETI_ISA_CLONES void packed_symv_generic(const float* a, int n, const double* x, double* y) {
  packed_symv_panels<GenericTiles>(a, n, x, y);
}

#if HTFETI_AVX2_SINGLE
#pragma GCC push_options
#pragma GCC target("avx2,fma")
namespace avx2 {
#include "packed_symv_panels.inc"

// Single precision on AVX2 (16 vector registers) with the tiles in intrinsics. GCC's AVX2 code
// of GenericTiles for float keeps the eight accumulators, the four broadcasts and the converted
// values in more than 16 registers; the accumulators it spills put a store-to-load forward on
// each tile's critical path (about 19 cycles per tile of 32 values, in cache). Here they stay in
// registers: per half tile one conversion per column, and the same operations in the same order
// as the Release build (-O3) compiles GenericTiles for AVX2 (bit-identical results there:
// y += ((v0 x0 + v1 x1) + v2 x2) + v3 x3 as fma(v3, x3, fma(v2, x2, fma(v0, x0, v1 x1))), one
// fused multiply-add per accumulator; tests/test_fem.cpp compares the two).
struct Avx2SingleTiles {
  // Half a tile: four rows of the four columns.
  HTFETI_INLINE static void half(const float* tt, double* yk, const double* xk, __m256d b0,
                                 __m256d b1, __m256d b2, __m256d b3, __m256d& c0, __m256d& c1,
                                 __m256d& c2, __m256d& c3) {
    const __m256d xv = _mm256_loadu_pd(xk);
    const __m256d v0 = _mm256_cvtps_pd(_mm_loadu_ps(tt));
    const __m256d v1 = _mm256_cvtps_pd(_mm_loadu_ps(tt + kTile));
    const __m256d v2 = _mm256_cvtps_pd(_mm_loadu_ps(tt + 2 * kTile));
    const __m256d v3 = _mm256_cvtps_pd(_mm_loadu_ps(tt + 3 * kTile));
    __m256d s = _mm256_mul_pd(v1, b1);
    s = _mm256_fmadd_pd(v0, b0, s);
    s = _mm256_fmadd_pd(v2, b2, s);
    s = _mm256_fmadd_pd(v3, b3, s);
    _mm256_storeu_pd(yk, _mm256_add_pd(_mm256_loadu_pd(yk), s));
    c0 = _mm256_fmadd_pd(v0, xv, c0);
    c1 = _mm256_fmadd_pd(v1, xv, c1);
    c2 = _mm256_fmadd_pd(v2, xv, c2);
    c3 = _mm256_fmadd_pd(v3, xv, c3);
  }
  HTFETI_INLINE static int run(const float*& t, int k, int n, const double* x, double* y, double x0,
                               double x1, double x2, double x3, double* a0, double* a1, double* a2,
                               double* a3) {
    const __m256d b0 = _mm256_set1_pd(x0), b1 = _mm256_set1_pd(x1), b2 = _mm256_set1_pd(x2),
                  b3 = _mm256_set1_pd(x3);
    __m256d c0l = _mm256_setzero_pd(), c0h = c0l, c1l = c0l, c1h = c0l, c2l = c0l, c2h = c0l,
            c3l = c0l, c3h = c0l;
    for (; k + kTile <= n; k += kTile, t += 4 * kTile) {
      half(t, y + k, x + k, b0, b1, b2, b3, c0l, c1l, c2l, c3l);
      half(t + 4, y + k + 4, x + k + 4, b0, b1, b2, b3, c0h, c1h, c2h, c3h);
    }
    static_assert(kTile == 8);
    _mm256_storeu_pd(a0, c0l), _mm256_storeu_pd(a0 + 4, c0h);
    _mm256_storeu_pd(a1, c1l), _mm256_storeu_pd(a1 + 4, c1h);
    _mm256_storeu_pd(a2, c2l), _mm256_storeu_pd(a2 + 4, c2h);
    _mm256_storeu_pd(a3, c3l), _mm256_storeu_pd(a3 + 4, c3h);
    return k;
  }
};

void packed_symv(const float* a, int n, const double* x, double* y) {
  packed_symv_panels<Avx2SingleTiles>(a, n, x, y);
}
}  // namespace avx2
#pragma GCC pop_options

// AVX2 without AVX-512 (where GenericTiles' code has 32 registers and is taken instead).
const bool kAvx2Single = [] {
  __builtin_cpu_init();
  return __builtin_cpu_supports("x86-64-v3") && !__builtin_cpu_supports("x86-64-v4");
}();
#endif

void packed_symv(const float* a, int n, const double* x, double* y) {
#if HTFETI_AVX2_SINGLE
  if (kAvx2Single) return avx2::packed_symv(a, n, x, y);
#endif
  packed_symv_generic(a, n, x, y);
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

void PackedSymmetric::multiply_portable(const double* x, double* y) const {
  if (single_)
    packed_symv_generic(s_.data(), n_, x, y);
  else
    packed_symv(d_.data(), n_, x, y);
}

double PackedSymmetric::operator()(int i, int j) const {
  if (i < j) std::swap(i, j);
  const long p = position(i, j, n_);
  return single_ ? static_cast<double>(s_[p]) : d_[p];
}

}  // namespace htfeti
