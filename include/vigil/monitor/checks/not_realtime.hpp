#pragma once
/// @file
/// `NotRealtimeCheck`: the component asked for FIFO and its thread runs OTHER (the system
/// refused the real-time policy and the activity fell back) → Warn "not real-time: asked for
/// FIFO, runs OTHER". Thresholds: `not_realtime.enabled`.

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class NotRealtimeCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "not_realtime"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
