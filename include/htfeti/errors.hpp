// The errors htfeti throws beyond the standard ones (the program maps each to an exit code,
// docs/user-guide.md "Exit codes").
#pragma once

#include <cstdlib>
#include <cstring>
#include <new>
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

/// A test hook: with HTFETI_INJECT_FAILURE="<stage>:<rank>" in the environment, the named rank
/// throws std::bad_alloc at that stage of the setup (scatter: rank 0 sending a whole mesh's
/// subdomains; assembly, factorization, coarse) or in the reconstruction, as if an allocation had failed there on that rank alone; the tests check that
/// every rank then ends with "out of memory" (exit 2) and none waits for the others
/// (Cli.AllocationFailureOnOneRankEndsEveryRank). Not for users; read once per call.
inline void inject_failure(const char* stage, int rank) {
  const char* v = std::getenv("HTFETI_INJECT_FAILURE");
  if (!v) return;
  const char* colon = std::strchr(v, ':');
  if (!colon || static_cast<size_t>(colon - v) != std::strlen(stage) ||
      std::strncmp(v, stage, std::strlen(stage)) != 0)
    return;
  if (std::atoi(colon + 1) == rank) throw std::bad_alloc();
}

/// The first failure inside an OpenMP loop, kept for after the loop (no exception may leave the
/// region): rethrow() throws std::bad_alloc for out of memory (so the program still reports "out
/// of memory", exit 2, and not the text "std::bad_alloc" as a numerical failure),
/// std::invalid_argument for an input error, std::runtime_error with the message otherwise.
class RegionError {
 public:
  /// Call from a catch block inside the region (thread-safe); prefix goes before the message.
  void record(const std::exception& e, const std::string& prefix = "") {
    const bool oom = dynamic_cast<const std::bad_alloc*>(&e) != nullptr;
    const bool input = dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
#pragma omp critical(htfeti_region_error)
    {
      message_ = prefix + e.what(), oom_ = oom_ || oom, input_ = input;
      failed_ = true;
    }
  }
  bool failed() const { return failed_; }
  void rethrow() const {
    if (!failed_) return;
    if (oom_) throw std::bad_alloc();
    if (input_) throw std::invalid_argument(message_);
    throw std::runtime_error(message_);
  }

 private:
  std::string message_;
  bool oom_ = false, input_ = false, failed_ = false;
};

}  // namespace htfeti
