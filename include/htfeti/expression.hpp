// A scalar expression of the coordinates x, y, z (muparser syntax, with pi), e.g. the gap
// "sin(pi*x/50)" of a contact condition or a Laplace source. Compiled once; evaluation is not
// thread-safe on one object (make a copy per thread).
#pragma once

#include <array>
#include <memory>
#include <string>

namespace htfeti {

class Expression {
 public:
  /// Throws std::invalid_argument with muparser's message if the text does not parse or uses
  /// names other than x, y, z, pi and muparser's functions.
  explicit Expression(const std::string& text = "0");
  Expression(const Expression& other);
  Expression& operator=(const Expression& other);
  ~Expression();
  const std::string& text() const { return text_; }
  /// The value at a point; throws std::invalid_argument if it is not finite.
  double operator()(const std::array<double, 3>& p) const;

 private:
  struct Impl;
  std::string text_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace htfeti
