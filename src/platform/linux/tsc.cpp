// The optional TSC clock (vigil/platform/tsc.hpp): the invariance check, the calibration against
// the monotonic clock, and the re-calibration thread. Compiled on both platforms: the reference
// is platform::now_ns(), CLOCK_MONOTONIC on Linux and on Cobalt alike.
#include "vigil/platform/tsc.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>

#include "vigil/platform/thread.hpp"

#if defined(__x86_64__)
#include <cpuid.h>
#endif

namespace vigil::platform {

namespace detail {
TscState g_tsc;
std::atomic<std::uint8_t> g_clock_source{static_cast<std::uint8_t>(ClockSource::Monotonic)};
}  // namespace detail

namespace {

constexpr Nanos kCalibrationNs = 50 * kNanosPerMilli;
constexpr Nanos kRecalibrationPeriodNs = kNanosPerSecond;
// Beyond this error the converted time is set back onto the monotonic clock in one step (a
// suspended machine, a migrated VM) instead of being bent back over one interval.
constexpr Nanos kResetErrorNs = kNanosPerMilli;

std::string& forced_reason() {
  static std::string r;
  return r;
}

// One (TSC, monotonic) pair, read with the TSC on both sides of the clock read; the tick is the
// middle of the two TSC reads, and `gap` their distance (the pair's uncertainty).
struct Pair {
  std::uint64_t ticks = 0;
  Nanos ns = 0;
  std::uint64_t gap = ~std::uint64_t{0};
};

Pair read_pair(int tries = 64) {
  Pair best;
  for (int i = 0; i < tries; ++i) {
    const std::uint64_t a = read_tsc();
    const Nanos ns = now_ns();
    const std::uint64_t b = read_tsc();
    if (b >= a && b - a < best.gap) best = Pair{a + (b - a) / 2, ns, b - a};
  }
  return best;
}

std::uint64_t mult_of(double ns_per_tick) {
  return static_cast<std::uint64_t>(std::llround(ns_per_tick * 4294967296.0));
}

void publish(const TscCalibration& c) noexcept {
  auto& s = detail::g_tsc;
  const std::uint32_t seq = s.seq.load(std::memory_order_relaxed);
  s.seq.store(seq + 1, std::memory_order_relaxed);
#if defined(__SANITIZE_THREAD__)
  // ThreadSanitizer does not model fences (GCC refuses them): each field's store is a release
  // instead, which orders it after the odd sequence just as the fence does.
  constexpr auto field_order = std::memory_order_release;
#else
  std::atomic_thread_fence(std::memory_order_release);
  constexpr auto field_order = std::memory_order_relaxed;
#endif
  s.base_ticks.store(c.base_ticks, field_order);
  s.base_ns.store(c.base_ns, field_order);
  s.mult.store(c.mult, field_order);
  s.seq.store(seq + 2, std::memory_order_release);
}

// The re-calibration state (select_clock's thread only, and recalibrate_tsc's callers: both
// serialised by the mutex).
struct Calibrator {
  std::mutex mutex;
  Pair anchor;  // the first pair: the long baseline of the frequency estimate
  Thread thread;
  std::atomic<bool> quit{false};

  ~Calibrator() { stop(); }
  void stop() {
    quit.store(true, std::memory_order_relaxed);
    thread.join();
    quit.store(false, std::memory_order_relaxed);
  }
};
Calibrator& calibrator() {
  static Calibrator c;
  return c;
}

#if defined(__x86_64__)
// The kernel's view: it clears constant_tsc / nonstop_tsc when it does not trust the counter.
std::string cpuinfo_flags() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("flags", 0) == 0) return line + " ";
  }
  return {};
}
#endif

}  // namespace

const char* to_string(ClockSource s) noexcept {
  switch (s) {
    case ClockSource::Monotonic:
      return "monotonic";
    case ClockSource::Tsc:
      return "tsc";
  }
  return "?";
}

void force_tsc_unusable_for_testing(std::string reason) { forced_reason() = std::move(reason); }

TscSupport tsc_support() {
  if (!forced_reason().empty()) return {false, forced_reason()};
#if defined(__x86_64__)
  if (__get_cpuid_max(0x80000000U, nullptr) < 0x80000007U) {
    return {false, "CPUID: no leaf 0x80000007 (cannot tell whether the TSC is invariant)"};
  }
  unsigned a = 0;
  unsigned b = 0;
  unsigned c = 0;
  unsigned d = 0;
  __get_cpuid(0x80000007U, &a, &b, &c, &d);
  if ((d & (1U << 8)) == 0) return {false, "CPUID: TSC not invariant (0x80000007 EDX bit 8 clear)"};
  const std::string flags = cpuinfo_flags();
  if (!flags.empty()) {
    if (flags.find(" constant_tsc ") == std::string::npos) {
      return {false, "the kernel does not list constant_tsc in /proc/cpuinfo"};
    }
    if (flags.find(" nonstop_tsc ") == std::string::npos) {
      return {false, "the kernel does not list nonstop_tsc in /proc/cpuinfo"};
    }
  }
  return {true, {}};
#else
  return {false, "not x86-64: no TSC clock on this CPU"};
#endif
}

TscCalibration calibrate_tsc(Nanos duration_ns) {
  const Pair p0 = read_pair();
  sleep_until(now_ns() + duration_ns);
  const Pair p1 = read_pair();
  TscCalibration c;
  c.base_ticks = p1.ticks;
  c.base_ns = p1.ns;
  const auto dt = static_cast<double>(p1.ticks - p0.ticks);
  c.mult = dt > 0 ? mult_of(static_cast<double>(p1.ns - p0.ns) / dt) : 0;
  return c;
}

TscCalibration tsc_calibration() noexcept { return detail::read_calibration(); }

void recalibrate_tsc() {
  if (active_clock() != ClockSource::Tsc) return;
  Calibrator& k = calibrator();
  const std::lock_guard lock(k.mutex);
  const TscCalibration old = tsc_calibration();
  const Pair p = read_pair();
  if (p.ticks <= k.anchor.ticks) return;
  // The frequency over the whole baseline (the pairs' read uncertainty shrinks with it).
  const double ns_per_tick =
      static_cast<double>(p.ns - k.anchor.ns) / static_cast<double>(p.ticks - k.anchor.ticks);
  const Nanos converted = tsc_to_ns(old, p.ticks);
  const Nanos error = converted - p.ns;
  TscCalibration next;
  next.base_ticks = p.ticks;
  if (error > kResetErrorNs || error < -kResetErrorNs) {
    next.base_ns = p.ns;  // too far off to bend back: one step
    next.mult = mult_of(ns_per_tick);
  } else {
    // Continuous: start where the old map is now, and meet the monotonic clock one period later.
    next.base_ns = converted;
    const double period = static_cast<double>(kRecalibrationPeriodNs);
    next.mult = mult_of(ns_per_tick * (period - static_cast<double>(error)) / period);
  }
  publish(next);
}

ClockSelection select_clock(ClockSource source) {
  Calibrator& k = calibrator();
  k.stop();
  ClockSelection sel;
  sel.requested = source;
  if (source == ClockSource::Tsc) {
    const TscSupport support = tsc_support();
    if (support.usable) {
      {
        const std::lock_guard lock(k.mutex);
        k.anchor = read_pair();
        const TscCalibration c = calibrate_tsc(kCalibrationNs);
        const double ns_per_tick = static_cast<double>(c.base_ns - k.anchor.ns) /
                                   static_cast<double>(c.base_ticks - k.anchor.ticks);
        publish(TscCalibration{c.base_ticks, c.base_ns, mult_of(ns_per_tick)});
        sel.tsc_ghz = 1.0 / ns_per_tick;
      }
      detail::g_clock_source.store(static_cast<std::uint8_t>(ClockSource::Tsc),
                                   std::memory_order_release);
      sel.active = ClockSource::Tsc;
      ThreadConfig config;
      config.name = "vigil-tsc";
      config.stack_bytes = std::size_t{64} * 1024;
      config.prefault_stack_bytes = 0;
      auto t = Thread::spawn(config, [&k] {
        Nanos next = now_ns();
        Nanos due = next + kRecalibrationPeriodNs;
        while (!k.quit.load(std::memory_order_relaxed)) {
          next += kRecalibrationPeriodNs / 10;  // checks for quit ten times per period
          sleep_until(next);
          if (now_ns() >= due) {
            recalibrate_tsc();
            due += kRecalibrationPeriodNs;
          }
        }
      });
      if (t) {
        k.thread = std::move(*t);
      } else {
        sel.reason = "TSC clock active, but its re-calibration thread could not start (" +
                     t.error().message + "): the error grows with time";
      }
      return sel;
    }
    sel.reason = "TSC not usable: " + support.reason + "; using the monotonic clock";
  }
  detail::g_clock_source.store(static_cast<std::uint8_t>(ClockSource::Monotonic),
                               std::memory_order_release);
  return sel;
}

}  // namespace vigil::platform

namespace vigil {
Nanos Clock::system_now(const void* /*ctx*/) noexcept { return platform::supervision_now_ns(); }
}  // namespace vigil

namespace vigil::platform {

ClockSource active_clock() noexcept {
  return static_cast<ClockSource>(detail::g_clock_source.load(std::memory_order_acquire));
}

}  // namespace vigil::platform
