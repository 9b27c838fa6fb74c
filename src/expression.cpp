#include "htfeti/expression.hpp"

#include <muParser.h>

#include <cmath>
#include <stdexcept>

namespace htfeti {

struct Expression::Impl {
  mu::Parser parser;
  double x = 0, y = 0, z = 0;
  explicit Impl(const std::string& text) {
    parser.DefineVar("x", &x);
    parser.DefineVar("y", &y);
    parser.DefineVar("z", &z);
    parser.DefineConst("pi", M_PI);
    parser.SetExpr(text);
    parser.Eval();  // compiles; throws on syntax errors and unknown names
  }
};

Expression::Expression(const std::string& text) : text_(text) {
  try {
    impl_ = std::make_unique<Impl>(text);
  } catch (const mu::Parser::exception_type& e) {
    throw std::invalid_argument("the expression '" + text + "' does not parse: " + e.GetMsg());
  }
}

Expression::Expression(const Expression& o) : Expression(o.text_) {}
Expression& Expression::operator=(const Expression& o) {
  if (this != &o) {
    text_ = o.text_;
    impl_ = std::make_unique<Impl>(o.text_);
  }
  return *this;
}
Expression::~Expression() = default;

double Expression::operator()(const std::array<double, 3>& p) const {
  impl_->x = p[0], impl_->y = p[1], impl_->z = p[2];
  double v = 0;
  try {
    v = impl_->parser.Eval();
  } catch (const mu::Parser::exception_type& e) {
    throw std::invalid_argument("the expression '" + text_ + "' fails: " + e.GetMsg());
  }
  if (!std::isfinite(v))
    throw std::invalid_argument("the expression '" + text_ + "' is not finite at (" +
                                std::to_string(p[0]) + ", " + std::to_string(p[1]) + ", " +
                                std::to_string(p[2]) + ")");
  return v;
}

}  // namespace htfeti
