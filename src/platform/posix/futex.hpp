#pragma once
// Private to the platform module (never installed): Linux futex wait/wake on a 32-bit word. The
// Linux implementation of wait_on/wake_one is these calls; the Cobalt one uses them for threads
// that Cobalt does not manage. Raw system calls, so no libc wrapper is ever involved.

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <ctime>

namespace vigil::platform::detail {

// The kernel reads the futex word through its address; std::atomic<uint32_t> has the same size
// and representation as uint32_t.
static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);

inline std::uint32_t* futex_address(const std::atomic<std::uint32_t>& word) noexcept {
  return reinterpret_cast<std::uint32_t*>(const_cast<std::atomic<std::uint32_t>*>(&word));
}

/// Sleeps while `word == expected` (checked by the kernel atomically with going to sleep), at
/// most until the absolute CLOCK_MONOTONIC time `deadline` (nullptr: no deadline). May return
/// spuriously (EINTR, EAGAIN); the caller re-checks.
inline void futex_wait_until(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                             const timespec* deadline) noexcept {
  // FUTEX_WAIT_BITSET takes an absolute CLOCK_MONOTONIC deadline (unlike FUTEX_WAIT).
  ::syscall(SYS_futex, futex_address(word), FUTEX_WAIT_BITSET_PRIVATE, expected, deadline, nullptr,
            FUTEX_BITSET_MATCH_ANY);
}

/// Like futex_wait_until with a relative timeout (nullptr: none).
inline void futex_wait_for(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                           const timespec* timeout) noexcept {
  ::syscall(SYS_futex, futex_address(word), FUTEX_WAIT_PRIVATE, expected, timeout, nullptr, 0);
}

/// Wakes at most one thread sleeping in futex_wait_* on `word`.
inline void futex_wake_one(const std::atomic<std::uint32_t>& word) noexcept {
  ::syscall(SYS_futex, futex_address(word), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
}

}  // namespace vigil::platform::detail
