#include "htfeti/linalg/packed_symmetric.hpp"

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

template <class T>
void pack(const Eigen::MatrixXd& A, std::vector<T>& out) {
  const long n = A.rows();
  out.resize(static_cast<size_t>(n * (n + 1) / 2));
  size_t p = 0;
  for (long j = 0; j < n; ++j)
    for (long i = j; i < n; ++i) out[p++] = static_cast<T>(A(i, j));
}

// Four columns j..j+3 of the lower triangle at a time: their 4 x 4 diagonal block, then the rows
// below it, where each row k gets y_k += sum_c a_k,j+c x_j+c and each column's dot product with x
// gets a_k,j+c x_k. Every stored value is read once, y is loaded and stored once per four columns,
// and the four dot products are independent accumulations. One column at a time, the single
// accumulator's add latency and the per-column overhead, not memory, bounded the product
// (bench/packed_product.cpp measures it).
template <class T>
inline __attribute__((always_inline)) void packed_symv_blocked(const T* a, int n, const double* x,
                                                               double* y) {
  for (int i = 0; i < n; ++i) y[i] = 0.0;
  int j = 0;
  for (; j + 3 < n; j += 4) {
    const T* c0 = a;                // A(j.., j): n - j values
    const T* c1 = c0 + (n - j);     // A(j+1.., j+1)
    const T* c2 = c1 + (n - j - 1);  // A(j+2.., j+2)
    const T* c3 = c2 + (n - j - 2);  // A(j+3.., j+3)
    const double x0 = x[j], x1 = x[j + 1], x2 = x[j + 2], x3 = x[j + 3];
    // The diagonal block: A(j+r, j+c) for r >= c is c_c[r - c].
    auto d = [&](int r, int c) {
      const T* col = c == 0 ? c0 : c == 1 ? c1 : c == 2 ? c2 : c3;
      return static_cast<double>(col[r - c]);
    };
    double s0 = d(0, 0) * x0 + d(1, 0) * x1 + d(2, 0) * x2 + d(3, 0) * x3;
    double s1 = d(1, 0) * x0 + d(1, 1) * x1 + d(2, 1) * x2 + d(3, 1) * x3;
    double s2 = d(2, 0) * x0 + d(2, 1) * x1 + d(2, 2) * x2 + d(3, 2) * x3;
    double s3 = d(3, 0) * x0 + d(3, 1) * x1 + d(3, 2) * x2 + d(3, 3) * x3;
    const int len = n - j - 4;
    const T *v0p = c0 + 4, *v1p = c1 + 3, *v2p = c2 + 2, *v3p = c3 + 1;
    const double* xb = x + j + 4;
    double* yb = y + j + 4;
#pragma omp simd simdlen(8) reduction(+ : s0, s1, s2, s3)
    for (int k = 0; k < len; ++k) {
      const double v0 = static_cast<double>(v0p[k]), v1 = static_cast<double>(v1p[k]),
                   v2 = static_cast<double>(v2p[k]), v3 = static_cast<double>(v3p[k]);
      yb[k] += v0 * x0 + v1 * x1 + v2 * x2 + v3 * x3;
      const double xk = xb[k];
      s0 += v0 * xk;
      s1 += v1 * xk;
      s2 += v2 * xk;
      s3 += v3 * xk;
    }
    y[j] += s0;
    y[j + 1] += s1;
    y[j + 2] += s2;
    y[j + 3] += s3;
    a = c3 + (n - j - 3);
  }
  for (; j < n; ++j) {  // the last n mod 4 columns, one at a time
    const double xj = x[j];
    double s = static_cast<double>(a[0]) * xj;
    for (int k = 1; k < n - j; ++k) {
      const double v = static_cast<double>(a[k]);
      y[j + k] += v * xj;
      s += v * x[j + k];
    }
    y[j] += s;
    a += n - j;
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
  packed_symv_blocked(a, n, x, y);
}
HTFETI_ISA_CLONES void packed_symv(const float* a, int n, const double* x, double* y) {
  packed_symv_blocked(a, n, x, y);
}

}  // namespace

PackedSymmetric::PackedSymmetric(const Eigen::MatrixXd& A, Precision precision)
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
  const long p = static_cast<long>(j) * n_ - static_cast<long>(j) * (j - 1) / 2 + (i - j);
  return single_ ? static_cast<double>(s_[p]) : d_[p];
}

}  // namespace htfeti
