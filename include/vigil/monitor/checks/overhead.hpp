#pragma once
/// @file
/// `OverheadCheck`: supervision's share of the component's cycle time (mean overhead / mean
/// total time, from the sampled overhead measurements) above `overhead.warn_share` → Warn
/// "supervision overhead <share> of cycle time (limit <l>)". Nothing without a measurement.
/// The share itself is in the report (`Report::overhead_share`).

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class OverheadCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "overhead"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
