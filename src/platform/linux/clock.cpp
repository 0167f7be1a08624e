// Linux clock: CLOCK_MONOTONIC through the vDSO, absolute sleeps with clock_nanosleep.
#include "vigil/platform/clock.hpp"

#include <cerrno>
#include <ctime>

#include "platform/posix/timespec.hpp"

namespace vigil::platform {

Nanos now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

int sleep_until(Nanos deadline_ns) noexcept {
  if (deadline_ns < 0) return EINVAL;
  const timespec ts = detail::to_timespec(deadline_ns);
  int rc = 0;
  // clock_nanosleep returns the error number itself (not -1/errno); with TIMER_ABSTIME a resumed
  // sleep keeps the same deadline, so looping on EINTR never sleeps too long.
  do {
    rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  } while (rc == EINTR);
  return rc;
}

}  // namespace vigil::platform
