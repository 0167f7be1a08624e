#pragma once
/// @file
/// `ExceptionCheck`: exceptions caught at a hook boundary, and the Exception/FatalError states.
///
/// - any exception (`exception.sticky: true`, the default): Error
///   "exception in <hook>: <type>: <what> (<n> in total)";
/// - with `sticky: false`: Error while the component is in Exception or FatalError or threw
///   within the window, then Warn "recovered after <n> exceptions; last: <type>: <what>";
/// - Exception or FatalError without any exception report (e.g. `fatal()`): Error "in <state>".
///
/// Thresholds: `exception.enabled`, `exception.sticky`. The count and the last exception are in
/// the report itself (`Report::exception`).

#include <string_view>

#include "vigil/monitor/check.hpp"

namespace vigil::monitor::checks {

class ExceptionCheck {
 public:
  [[nodiscard]] std::string_view name() const noexcept { return "exception"; }
  void run(const CheckInput& in, Report& out) const;
};

}  // namespace vigil::monitor::checks
