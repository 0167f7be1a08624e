#include "vigil/monitor/checks/exception.hpp"

#include <fmt/format.h>

namespace vigil::monitor::checks {

void ExceptionCheck::run(const CheckInput& in, Report& out) const {
  const ExceptionThresholds& t = in.thresholds.exception;
  if (!t.enabled) return;
  const supervisor::ComponentSnapshot& c = in.component;
  const bool failed_state = c.state == TaskState::Exception || c.state == TaskState::FatalError;
  const std::uint64_t n = c.counters.exceptions;
  if (n == 0) {
    if (failed_state) out.merge(StatusLevel::Error, fmt::format("in {}", to_string(c.state)));
    return;
  }
  std::string last = "unknown";
  if (c.has_exception) {
    last = c.last_exception_type;
    if (!c.last_exception.message.empty()) {
      last += ": ";
      last += c.last_exception.message.view();
    }
  }
  const char* hook = c.has_exception ? to_string(c.last_exception.hook) : "?";
  if (t.sticky || failed_state || in.window.exceptions > 0) {
    out.merge(StatusLevel::Error, fmt::format("exception in {}: {} ({} in total)", hook, last, n));
  } else {
    out.merge(StatusLevel::Warn,
              fmt::format("recovered after {} exception{}; last: {}", n, n == 1 ? "" : "s", last));
  }
}

}  // namespace vigil::monitor::checks
