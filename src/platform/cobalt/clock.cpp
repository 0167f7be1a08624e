// Cobalt clock: libcobalt's CLOCK_MONOTONIC (vDSO, no system call) and Cobalt's clock_nanosleep.
//
// Every call names the Cobalt implementation explicitly with __RT() (= __cobalt_<name>): vigil's
// executables are linked without libcobalt's --wrap list, and this file would resolve to Cobalt
// with it too.
// With a Dovetail kernel (3.2+) Cobalt's CLOCK_MONOTONIC is Linux's; with an I-pipe kernel it is
// Cobalt's own timebase, so vigil never mixes it with glibc's clock (XENOMAI.md §3.1) once
// libcobalt runs. Before (a program that has not called vigil::platform::initialize() yet),
// now_ns() reads glibc's: on an I-pipe kernel, start Cobalt before taking timestamps.
#include "vigil/platform/clock.hpp"

#include "platform/cobalt/build_check.hpp"
#include "platform/cobalt/core.hpp"

#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>

#include "platform/posix/timespec.hpp"

// Xenomai headers last: they define macros that C++ headers must not see.
#include <cobalt/wrappers.h>
#include <time.h>  // through -I<prefix>/include/cobalt: declares __cobalt_clock_*

namespace vigil::platform {

namespace {

using detail::to_timespec;

// A thread that is not a Cobalt thread (std::thread, a library's thread) gets EPERM from Cobalt's
// clock_nanosleep. It sleeps with Linux instead, in relative steps so that the Cobalt timebase of
// the deadline never meets Linux's absolute clock (they differ with I-pipe kernels).
int sleep_until_linux(Nanos deadline_ns) noexcept {
  for (;;) {
    const Nanos left = deadline_ns - now_ns();
    if (left <= 0) return 0;
    const timespec rel = to_timespec(left);
    // The raw system call: Linux's, even in a program that a user linked with libcobalt's --wrap
    // list (where glibc's name would reach Cobalt again).
    if (::syscall(SYS_clock_nanosleep, CLOCK_MONOTONIC, 0, &rel, nullptr) != 0 && errno != EINTR) {
      return errno;
    }
  }
}

}  // namespace

Nanos now_ns() noexcept {
  timespec ts{};
  // Before libcobalt starts (initialize()) its clock_gettime must not be called (core.hpp): read
  // Linux's CLOCK_MONOTONIC, which is Cobalt's on Dovetail kernels. One acquire load otherwise.
  if (!detail::cobalt_ready()) [[unlikely]] {
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
  }
  __RT(clock_gettime)(CLOCK_MONOTONIC, &ts);
  return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

int sleep_until(Nanos deadline_ns) noexcept {
  if (deadline_ns < 0) return EINVAL;
  // No Cobalt thread before libcobalt starts: the caller sleeps with Linux.
  if (!detail::cobalt_ready()) return sleep_until_linux(deadline_ns);
  const timespec ts = to_timespec(deadline_ns);
  int rc = 0;
  // Cobalt's clock_nanosleep returns the error number itself, like POSIX's; an absolute deadline
  // survives EINTR (a SIGDEBUG handler may run here), so the loop never sleeps too long. The call
  // brings a relaxed thread back to primary mode.
  do {
    rc = __RT(clock_nanosleep)(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  } while (rc == EINTR);
  if (rc == EPERM) return sleep_until_linux(deadline_ns);
  return rc;
}

}  // namespace vigil::platform
