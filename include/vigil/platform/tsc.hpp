#pragma once
/// @file
/// The optional TSC clock: the CPU's time-stamp counter (x86-64 `rdtsc`), converted to
/// nanoseconds of the monotonic clock with a calibration made off the real-time path.
///
/// Why: a read of CLOCK_MONOTONIC through the vDSO costs ~20-25 ns (an ordered `rdtsc`, the
/// vDSO's seqlock and clock-mode checks, a call through libc); a bare `rdtsc` costs a few ns.
/// Supervision reads the clock twice per cycle, so the clock is most of its cost.
///
/// How: `select_clock(ClockSource::Tsc)` (once per process, before tasks run; deployments say
/// `process: clock: tsc`) checks that the TSC is invariant (CPUID 0x80000007 EDX bit 8, and the
/// kernel's `constant_tsc` and `nonstop_tsc` flags), calibrates it against CLOCK_MONOTONIC for
/// ~50 ms, and starts a non-real-time thread that re-calibrates it once per second. The
/// calibration is a linear map `ns = base_ns + (ticks - base_ticks) * mult >> 32`, published
/// through a sequence lock: the real-time side reads the raw counter and converts it with one
/// 64x64->128-bit multiply, wait-free (it retries only if a re-calibration was being published
/// at that very moment, once a second). Re-calibration keeps the converted time continuous and
/// monotonic: it never jumps; it bends the slope so that the converted time meets the monotonic
/// clock again one interval later (docs/design/tsc_clock.md gives the measured error).
///
/// Where the TSC is not invariant, or the CPU is not x86-64 (ARM64, any Cobalt build on it),
/// `select_clock(ClockSource::Tsc)` falls back to the monotonic clock and says why
/// (`ClockSelection::reason`, also printed on standard error by the deploy module).

#include <atomic>
#include <cstdint>
#include <string>

#include "vigil/platform/clock.hpp"

namespace vigil::platform {

/// Which clock supervision reads in this process.
enum class ClockSource : std::uint8_t {
  Monotonic,  ///< CLOCK_MONOTONIC (vDSO on Linux, libcobalt on Cobalt): the default
  Tsc,        ///< the invariant TSC, calibrated against CLOCK_MONOTONIC (x86-64 only)
};
/// "monotonic", "tsc".
[[nodiscard]] const char* to_string(ClockSource s) noexcept;

/// Whether this machine's TSC can serve as the clock, and if not, why.
struct TscSupport {
  bool usable = false;
  /// Why not (empty when usable): "not x86-64", "CPUID: TSC not invariant", "no constant_tsc
  /// flag in /proc/cpuinfo", ... or the reason set by the test hook.
  std::string reason;
};

/// Checks CPUID 0x80000007 EDX bit 8 (invariant TSC) and the kernel's `constant_tsc` and
/// `nonstop_tsc` flags (/proc/cpuinfo, when readable). Not RT-safe (reads a file). Any thread.
[[nodiscard]] TscSupport tsc_support();

/// Test hook: makes tsc_support() report the TSC as not usable with `reason` (empty: back to
/// the real check). Not RT-safe. For tests of the fallback path only.
void force_tsc_unusable_for_testing(std::string reason);

/// What select_clock() did.
struct ClockSelection {
  ClockSource requested = ClockSource::Monotonic;
  ClockSource active = ClockSource::Monotonic;  ///< what supervision now reads
  /// Why the request was not met (empty when it was), e.g. "TSC not usable: CPUID: TSC not
  /// invariant; using the monotonic clock".
  std::string reason;
  double tsc_ghz = 0;  ///< the calibrated TSC frequency (0 when not active)
};

/// Selects the clock supervision reads in this process (`Clock::system()`, every activity and
/// every Task). Call it before tasks run, from one thread (process set-up); not RT-safe (the TSC
/// is calibrated for ~50 ms and a re-calibration thread is started; Monotonic stops it).
/// Never fails: a TSC that cannot be used falls back to Monotonic, with the reason.
ClockSelection select_clock(ClockSource source);
/// The clock selected now. Any thread.
[[nodiscard]] ClockSource active_clock() noexcept;

/// The linear map from TSC ticks to monotonic nanoseconds.
struct TscCalibration {
  std::uint64_t base_ticks = 0;
  Nanos base_ns = 0;
  std::uint64_t mult = 0;  ///< nanoseconds per tick, times 2^32
};

/// Reads the TSC (no ordering fence: the surrounding code's loads and stores may pass it by a few
/// instructions, which is below the clock's resolution here). RT-safe; 0 on other CPUs.
[[nodiscard]] inline std::uint64_t read_tsc() noexcept {
#if defined(__x86_64__)
  return __builtin_ia32_rdtsc();
#else
  return 0;
#endif
}

/// `c` applied to `ticks`. RT-safe, pure.
[[nodiscard]] inline Nanos tsc_to_ns(const TscCalibration& c, std::uint64_t ticks) noexcept {
  const auto d = static_cast<std::int64_t>(ticks - c.base_ticks);  // before the base: negative
#if defined(__SIZEOF_INT128__)
  __extension__ using Wide = __int128;  // one 64x64->128 multiply, no overflow for any span
  const auto p = (static_cast<Wide>(d) * static_cast<Wide>(c.mult)) >> 32;
  return c.base_ns + static_cast<Nanos>(p);
#else
  return c.base_ns +
         static_cast<Nanos>(static_cast<double>(d) * static_cast<double>(c.mult) / 4294967296.0);
#endif
}

/// Calibrates from scratch: reads CLOCK_MONOTONIC and the TSC in pairs for `duration_ns`
/// (keeping the pairs read closest together) and fits the map. Not RT-safe (sleeps). Used by
/// select_clock() and by tests.
[[nodiscard]] TscCalibration calibrate_tsc(Nanos duration_ns);

/// Re-calibrates the active TSC clock now (the background thread does it once per second).
/// Not RT-safe. No effect when the TSC clock is not active.
void recalibrate_tsc();

/// The calibration in use (a consistent copy). Any thread.
[[nodiscard]] TscCalibration tsc_calibration() noexcept;

namespace detail {
/// The published calibration, a sequence lock: odd `seq` while the writer updates it.
struct TscState {
  std::atomic<std::uint32_t> seq{0};
  std::atomic<std::uint64_t> base_ticks{0};
  std::atomic<std::int64_t> base_ns{0};
  std::atomic<std::uint64_t> mult{0};
};
extern TscState g_tsc;
/// The active clock source (a ClockSource), read by Clock::system_now once per read.
extern std::atomic<std::uint8_t> g_clock_source;

/// The published calibration, read through the sequence lock (retries while one is published).
[[nodiscard]] [[gnu::always_inline]] inline TscCalibration read_calibration() noexcept {
#if defined(__SANITIZE_THREAD__)
  // ThreadSanitizer does not model fences (GCC refuses them): each field's load is an acquire
  // instead, which keeps the sequence's re-read after it just as the fence does.
  constexpr auto field_order = std::memory_order_acquire;
#else
  constexpr auto field_order = std::memory_order_relaxed;
#endif
  for (;;) {
    const std::uint32_t s0 = g_tsc.seq.load(std::memory_order_acquire);
    TscCalibration c;
    c.base_ticks = g_tsc.base_ticks.load(field_order);
    c.base_ns = g_tsc.base_ns.load(field_order);
    c.mult = g_tsc.mult.load(field_order);
#if !defined(__SANITIZE_THREAD__)
    std::atomic_thread_fence(std::memory_order_acquire);
#endif
    if ((s0 & 1U) == 0 && g_tsc.seq.load(std::memory_order_relaxed) == s0) [[likely]]
      return c;
  }
}

}  // namespace detail

/// The TSC, converted with the published calibration. RT-safe: wait-free (retries only across a
/// re-calibration being published, once a second), no system call.
[[nodiscard]] [[gnu::always_inline]] inline Nanos tsc_now_ns() noexcept {
  const std::uint64_t ticks = read_tsc();
  return tsc_to_ns(detail::read_calibration(), ticks);
}

/// The clock supervision reads: tsc_now_ns() when the TSC clock is selected, now_ns() otherwise.
/// RT-safe.
[[nodiscard]] inline Nanos supervision_now_ns() noexcept {
  if (detail::g_clock_source.load(std::memory_order_relaxed) ==
      static_cast<std::uint8_t>(ClockSource::Tsc)) {
    return tsc_now_ns();
  }
  return now_ns();
}

}  // namespace vigil::platform
