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

/// An output that could not be written (disk full, a file size limit, standard output closed):
/// nothing is left behind (exit code 6).
class IoError : public std::runtime_error {
 public:
  explicit IoError(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace htfeti
