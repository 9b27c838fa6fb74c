// The errors htfeti throws beyond the standard ones (the program maps each to an exit code,
// docs/user-guide.md "Exit codes").
#pragma once

#include <stdexcept>
#include <string>

namespace htfeti {

/// A value that is not finite (an overflow) in the data of the dual problem or in the solution:
/// the result would be meaningless. Thrown on every rank alike (exit code 5).
class NonFiniteError : public std::runtime_error {
 public:
  explicit NonFiniteError(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace htfeti
