// Linux wait/wake on a 32-bit word: private futexes, absolute CLOCK_MONOTONIC deadlines.
#include "vigil/platform/wait.hpp"

#include "platform/posix/futex.hpp"
#include "platform/posix/timespec.hpp"

namespace vigil::platform {

void wait_on(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
             Nanos deadline_ns) noexcept {
  if (deadline_ns > 0) {
    const timespec ts = detail::to_timespec(deadline_ns);
    detail::futex_wait_until(word, expected, &ts);
  } else {
    detail::futex_wait_until(word, expected, nullptr);
  }
}

void wake_one(const std::atomic<std::uint32_t>& word) noexcept { detail::futex_wake_one(word); }

}  // namespace vigil::platform
