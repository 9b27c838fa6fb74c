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

// Column j of the lower triangle serves row j (a dot product with x below the diagonal) and the
// rows below it (an axpy with x_j): each value is read once.
template <class T>
void packed_symv(const T* a, int n, const double* x, double* y) {
  for (int i = 0; i < n; ++i) y[i] = 0.0;
  for (int j = 0; j < n; ++j) {
    const double xj = x[j];
    double s = static_cast<double>(*a++) * xj;  // the diagonal
    const int len = n - j - 1;
    double* yb = y + j + 1;
    const double* xb = x + j + 1;
#pragma omp simd reduction(+ : s)
    for (int k = 0; k < len; ++k) {
      const double v = static_cast<double>(a[k]);
      yb[k] += v * xj;
      s += v * xb[k];
    }
    y[j] += s;
    a += len;
  }
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
