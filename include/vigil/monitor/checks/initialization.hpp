#pragma once
/// @file
/// `InitializationCheck`: a component that never sent its identity (TaskInfo, sent by configure)
/// is Warn "not configured". Thresholds: `initialization.enabled`.

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

/// Warn "not configured" while no TaskInfo arrived (alive components only).
class InitializationCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "initialization"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
