// The one wall clock of the timings: seconds since an arbitrary fixed point (steady, never set
// back), so that differences of two readings time a phase.
#pragma once

#include <chrono>

namespace htfeti {

inline double seconds_now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace htfeti
