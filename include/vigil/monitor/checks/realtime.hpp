#pragma once
/// @file
/// `RealTimeCheck`: real-time losses in the window (heap allocations, blocking calls, page
/// faults, mode switches, as the component's detectors count them) above `realtime.warn_losses`
/// → Warn "real-time losses: 3 allocation, 1 blocking (<n> in total)". With
/// `realtime.fifo_only` (the default) only components running on a real-time policy (FIFO) are
/// checked. The cumulative counts by cause are in the report (`Report::counters.losses`).

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class RealTimeCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "realtime"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
