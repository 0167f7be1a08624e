#pragma once
/// @file
/// Waiting on and waking a 32-bit word (Linux: a futex; Cobalt: per-thread Cobalt semaphores,
/// see docs/design/platform.md).
/// Used by TriggeredActivity so that a trigger makes a system call only when it must wake.

#include <atomic>
#include <cstdint>

#include "vigil/platform/clock.hpp"

namespace vigil::platform {

/// Blocks while `word == expected`, at most until `deadline_ns` (absolute monotonic; 0 = no
/// deadline). May return spuriously; callers re-check their condition. Blocking: call it only
/// where the thread is meant to sleep.
void wait_on(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
             Nanos deadline_ns = 0) noexcept;

/// Wakes one thread blocked in `wait_on(word, ...)`. One system call. RT-safe apart from that
/// system call (no allocation, no lock).
void wake_one(const std::atomic<std::uint32_t>& word) noexcept;

}  // namespace vigil::platform
