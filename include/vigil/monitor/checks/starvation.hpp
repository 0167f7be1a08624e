#pragma once
/// @file
/// `StarvationCheck`: a Running component whose cycles stopped arriving: its thread is blocked,
/// starved by higher priorities, or stuck in a long update. Stale "starved: no cycle for <t>
/// (limit <l>)".
///
/// The limit is max(`starvation.periods` × period, `starvation.min_silence`) for periodic
/// components and `starvation.aperiodic_silence` for the others (0: never). The silence is
/// measured on the monitor clock from the supervisor's stamp of the latest sample, or from the
/// moment the monitor saw the component enter Running if that is later, so the clocks of the
/// aggregator and of the monitor must be the same (both are the monotonic clock by default).
/// Strict comparison: a silence equal to the limit passes. Key/values: `starvation_limit`.

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

/// The starvation limit in ns of a component with period `period_ns` (0: non-periodic) under
/// thresholds `t`; 0 when the check never applies.
[[nodiscard]] Nanos starvation_limit(const Thresholds& t, Nanos period_ns) noexcept;

class StarvationCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "starvation"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
