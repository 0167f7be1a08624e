// Linux futex wait/wake on a 32-bit word (private futexes, CLOCK_MONOTONIC absolute deadlines).
#include "vigil/platform/wait.hpp"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <ctime>

namespace vigil::platform {

namespace {
// The kernel reads the futex word through its address; std::atomic<uint32_t> has the same
// size and representation as uint32_t (static_asserted below).
static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);

auto* word_address(const std::atomic<std::uint32_t>& word) noexcept {
  return reinterpret_cast<std::uint32_t*>(const_cast<std::atomic<std::uint32_t>*>(&word));
}
}  // namespace

void wait_on(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
             Nanos deadline_ns) noexcept {
  timespec ts{};
  timespec* timeout = nullptr;
  if (deadline_ns > 0) {
    ts.tv_sec = static_cast<time_t>(deadline_ns / kNanosPerSecond);
    ts.tv_nsec = static_cast<long>(deadline_ns % kNanosPerSecond);
    timeout = &ts;
  }
  // FUTEX_WAIT_BITSET takes an absolute CLOCK_MONOTONIC deadline (unlike FUTEX_WAIT).
  ::syscall(SYS_futex, word_address(word), FUTEX_WAIT_BITSET_PRIVATE, expected, timeout, nullptr,
            FUTEX_BITSET_MATCH_ANY);
}

void wake_one(const std::atomic<std::uint32_t>& word) noexcept {
  ::syscall(SYS_futex, word_address(word), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
}

}  // namespace vigil::platform
