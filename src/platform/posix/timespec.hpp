#pragma once
// Private to the platform module (never installed): nanoseconds <-> timespec, for the POSIX calls
// of both implementations (src/platform/linux/, src/platform/cobalt/).

#include <ctime>

#include "vigil/platform/clock.hpp"

namespace vigil::platform::detail {

/// `ns` (absolute time or duration, >= 0) as a timespec. RT-safe.
inline timespec to_timespec(Nanos ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNanosPerSecond);
  ts.tv_nsec = static_cast<long>(ns % kNanosPerSecond);
  return ts;
}

}  // namespace vigil::platform::detail
