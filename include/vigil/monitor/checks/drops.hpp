#pragma once
/// @file
/// `DropsCheck`: messages the component's port dropped in the window (the supervisor did not
/// drain it in time; counters stay exact, timing detail is lost) above `drops.warn_drops` →
/// Warn "port dropped <n> messages (<total> in total)". The totals and the port's high-water mark
/// are in the report (`Report::counters.dropped`, `Report::port_high_water`).

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class DropsCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "drops"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
