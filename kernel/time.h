// kernel/time.h — simulated time: an integer count of nanoseconds (no floating-point clock).
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace ncosim::kernel {

using SimTime = std::int64_t;  // nanoseconds since t = 0

inline constexpr SimTime kNanosecond = 1;
inline constexpr SimTime kSecond = 1'000'000'000;

// Seconds (as written in a scenario) to ns, rounded to the nearest ns. Throws on a
// value that does not fit or is not finite.
inline SimTime seconds_to_time(double seconds) {
  if (!std::isfinite(seconds) || std::fabs(seconds) > 9.2e9) {
    throw std::invalid_argument("time out of range");
  }
  return static_cast<SimTime>(std::llround(seconds * 1e9));
}

inline double time_to_seconds(SimTime t) { return static_cast<double>(t) * 1e-9; }

}  // namespace ncosim::kernel
