#include "vigil/monitor/checks/starvation.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace vigil::monitor::checks {

Nanos starvation_limit(const Thresholds& t, Nanos period_ns) noexcept {
  const StarvationThresholds& s = t.starvation;
  if (period_ns <= 0) return s.aperiodic_silence_ns;
  const double k = s.periods * static_cast<double>(period_ns);
  const Nanos by_periods = k >= 9.2e18 ? Nanos{9'200'000'000'000'000'000} : std::llround(k);
  return std::max(by_periods, s.min_silence_ns);
}

void StarvationCheck::run(const CheckInput& in, Report& out) const {
  if (!in.thresholds.starvation.enabled || in.silence_ns < 0) return;
  const supervisor::ComponentSnapshot& c = in.component;
  if (!c.alive || c.state != TaskState::Running) return;
  const Nanos limit = starvation_limit(in.thresholds, c.has_info ? c.info.period_ns : 0);
  if (limit <= 0) return;
  out.add("starvation_limit", format_nanos(static_cast<double>(limit)));
  if (in.silence_ns <= limit) return;
  out.merge(StatusLevel::Stale, fmt::format("starved: no cycle for {} (limit {})",
                                            format_nanos(static_cast<double>(in.silence_ns)),
                                            format_nanos(static_cast<double>(limit))));
}

}  // namespace vigil::monitor::checks
