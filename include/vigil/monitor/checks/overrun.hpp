#pragma once
/// @file
/// `OverrunCheck`: periodic components whose cycles take (nearly) their whole period.
///
/// Two findings, both on periodic components only:
/// - near overrun: the EWMA of total time (user + supervision) above `overrun.near_fraction` ×
///   period → Warn "near overrun: ...". The EWMA, not the arithmetic mean: a load that creeps up
///   is flagged while the mean still carries the cheap cycles of the past, and a spike of a few
///   cycles moves it only a little (weight 0.05 per cycle by default, see AggregatorOptions);
/// - overruns in the window: overruns / cycles above `overrun.error_rate` → Error, else above
///   `overrun.warn_rate` → Warn, "overruns: <n> in <cycles> cycles (<rate>)" with the missed
///   cycles.
///
/// Comparisons are strict: a value equal to its threshold passes. Key/values: `load_ewma`
/// (EWMA of total time / period), `overrun_rate` (in the window).

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class OverrunCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "overrun"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
