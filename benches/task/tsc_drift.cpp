// How far the TSC clock (vigil/platform/tsc.hpp) strays from CLOCK_MONOTONIC, with and without
// re-calibration. Not a Google Benchmark (it runs for minutes): `vigil_tsc_drift [seconds]`
// (default 60) prints, at 1 s, 10 s, 30 s and 60 s (and every 10 s after), the error of
//   - "fixed":        the first 50 ms calibration, never re-calibrated;
//   - "recalibrated": the clock supervision reads (re-calibrated once per second);
// each measured as |converted TSC - CLOCK_MONOTONIC| at the middle of a monotonic read pair
// taken within 1 us (the best of 200 tries, so a preempted read is not counted).
// Results: docs/design/tsc-clock.md.
#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "vigil/platform/tsc.hpp"

namespace pf = vigil::platform;
using vigil::kNanosPerMicro;
using vigil::kNanosPerSecond;
using vigil::Nanos;

namespace {

struct Error {
  Nanos fixed = 0;
  Nanos recalibrated = 0;
  Nanos read_window = 0;  // the monotonic pair's width: the measurement's own uncertainty
};

Error measure(const pf::TscCalibration& fixed) {
  Error best{0, 0, kNanosPerSecond};
  for (int i = 0; i < 200; ++i) {
    const Nanos a = pf::now_ns();
    const std::uint64_t ticks = pf::read_tsc();
    const Nanos live = pf::tsc_now_ns();
    const Nanos b = pf::now_ns();
    if (b - a >= best.read_window || b - a > kNanosPerMicro) continue;
    const Nanos mid = a + (b - a) / 2;
    best = Error{pf::tsc_to_ns(fixed, ticks) - mid, live - mid, b - a};
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  const long seconds = argc > 1 ? std::atol(argv[1]) : 60;
  const pf::TscSupport support = pf::tsc_support();
  if (!support.usable) {
    std::printf("not available: TSC clock: %s\n", support.reason.c_str());
    return 0;
  }
  const pf::ClockSelection sel = pf::select_clock(pf::ClockSource::Tsc);
  if (sel.active != pf::ClockSource::Tsc) {
    std::printf("not available: %s\n", sel.reason.c_str());
    return 0;
  }
  const pf::TscCalibration fixed = pf::tsc_calibration();
  std::printf("TSC %.6f GHz; error = converted TSC - CLOCK_MONOTONIC (ns)\n", sel.tsc_ghz);
  std::printf("%8s %12s %14s %12s\n", "t (s)", "fixed", "recalibrated", "read window");
  const Nanos t0 = pf::now_ns();
  Nanos worst_recal = 0;
  for (long s = 1; s <= seconds; ++s) {
    pf::sleep_until(t0 + s * kNanosPerSecond + kNanosPerSecond / 2);  // between re-calibrations
    const Error e = measure(fixed);
    worst_recal = std::max(worst_recal, e.recalibrated < 0 ? -e.recalibrated : e.recalibrated);
    if (s == 1 || s == 10 || s == 30 || s % 10 == 0 || s == seconds) {
      std::printf("%8ld %12lld %14lld %12lld\n", s, static_cast<long long>(e.fixed),
                  static_cast<long long>(e.recalibrated), static_cast<long long>(e.read_window));
    }
  }
  std::printf("worst |recalibrated| over %ld s: %lld ns\n", seconds,
              static_cast<long long>(worst_recal));
  (void)pf::select_clock(pf::ClockSource::Monotonic);
  return 0;
}
