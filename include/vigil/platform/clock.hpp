#pragma once
/// @file
/// The one clock vigil uses for everything: monotonic time in nanoseconds, 64-bit signed.
///
/// Linux: CLOCK_MONOTONIC through the vDSO (no system call). Cobalt: the same clock, served by
/// libcobalt without a mode switch. A signed 64-bit count of nanoseconds lasts 292 years, so
/// differences and sums of timestamps never overflow in practice.

#include <cstdint>

namespace vigil {

/// Nanoseconds on the monotonic clock, or a duration in nanoseconds.
using Nanos = std::int64_t;

inline constexpr Nanos kNanosPerMicro = 1'000;
inline constexpr Nanos kNanosPerMilli = 1'000'000;
inline constexpr Nanos kNanosPerSecond = 1'000'000'000;

namespace platform {

/// Current monotonic time in nanoseconds.
/// RT-safe: yes (wait-free, no allocation; on Linux and Cobalt no system call).
[[nodiscard]] Nanos now_ns() noexcept;

/// Sleeps until the monotonic clock reaches `deadline_ns` (absolute, TIMER_ABSTIME); returns at
/// once if it has passed. Interrupted sleeps (EINTR) are resumed, so it never returns early.
/// Returns 0, or the error number of clock_nanosleep (EINVAL for a negative deadline).
/// RT-safe: yes, it is the blocking point of a periodic loop (one system call).
int sleep_until(Nanos deadline_ns) noexcept;

}  // namespace platform

/// A clock that can be replaced, for tests that control time and for log replay.
///
/// It is a plain function pointer with a context, not a virtual interface: one indirect call,
/// no allocation. The default (`system()`) reads the process's supervision clock:
/// `platform::now_ns()`, or the calibrated TSC when the process selected it
/// (`platform::select_clock`, vigil/platform/tsc.hpp); supervision recognises it and reads it
/// without the indirect call.
struct Clock {
  using Fn = Nanos (*)(const void* ctx) noexcept;
  Fn fn = &system_now;
  const void* ctx = nullptr;

  /// RT-safe: yes when `fn` is (the default is).
  [[nodiscard]] Nanos now() const noexcept { return fn(ctx); }

  /// The process's supervision clock (see above). RT-safe. Defined in the platform module.
  static Nanos system_now(const void* ctx) noexcept;
  /// The process's supervision clock: monotonic, or the TSC when selected.
  static constexpr Clock system() noexcept { return Clock{}; }
};

}  // namespace vigil
