// A symmetric matrix stored as its lower triangle: n(n+1)/2 values instead of the n^2 of a full
// array, in double or single precision. The values are grouped in panels of four columns, each
// its 4 x 4 diagonal block and then the rows below it in tiles of 8 rows (column-major within a
// tile), so that the product reads them as one stream (packed_symmetric.cpp); the last n mod 4
// columns are packed column by column, as in LAPACK's 'L' packed layout, where each panel also
// starts.
// Products accumulate in double whatever the storage. Used for the explicit local dual operators
// F_i, whose product streams the stored values once per application of F (memory-bound: the
// values are read once, 4 flops each).
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"

namespace htfeti {

/// Storage precision of the explicit F_i: double, or single (half the memory and the bytes
/// streamed per product; the values are rounded to 24 bits, the sums stay in double).
enum class Precision { double_, single };
inline constexpr std::array<EnumName<Precision>, 2> kPrecisionNames{
    {{Precision::double_, "double"}, {Precision::single, "single"}}};
Precision parse_precision(const std::string& name);  // throws std::invalid_argument
std::string to_string(Precision precision);

class PackedSymmetric {
 public:
  PackedSymmetric() = default;
  /// Packs the lower triangle of A (the upper one is not read).
  PackedSymmetric(const Eigen::Ref<const Eigen::MatrixXd>& A, Precision precision);
  int size() const { return n_; }
  Precision precision() const { return single_ ? Precision::single : Precision::double_; }
  /// Bytes of the stored values.
  long bytes() const { return static_cast<long>(d_.size()) * 8 + static_cast<long>(s_.size()) * 4; }
  /// y = A x (length size(); x and y must not alias). Allocates nothing.
  void multiply(const double* x, double* y) const;
  /// The same product by the code that every instruction set compiles (multiply() may take a
  /// hand-vectorized kernel instead, with the same operations in the same order): for tests.
  void multiply_portable(const double* x, double* y) const;
  /// Entry (i, j) (either triangle), for tests.
  double operator()(int i, int j) const;

 private:
  int n_ = 0;
  bool single_ = false;
  std::vector<double> d_;
  std::vector<float> s_;
};

}  // namespace htfeti
