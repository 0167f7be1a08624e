#pragma once
/// @file
/// `LatchedCheck`: a fault latched by an Error event (vigil/supervisor/events.hpp) keeps the
/// component at Error until it is cleared (`ComponentAggregator::clear`, the deployment's
/// `supervision.events.auto_clear`, or `POST /clear` on the HTTP endpoint when enabled):
/// Error "latched: <kind>: <detail> (<n> error events; first <t> ago, last <t> ago; clear to
/// reset)".
///
/// A latch raised by an exception follows `exception.sticky`: with `sticky: false` the exception
/// check alone decides (Warn once recovered). Thresholds: `exception.enabled` (the latch of an
/// exception); the other kinds are always reported.

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class LatchedCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "latched"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
