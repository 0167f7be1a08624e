#include "vigil/monitor/checks/latched.hpp"

#include <fmt/format.h>

namespace vigil::monitor::checks {

namespace {
bool exception_kind(EventKind k) noexcept {
  return k == EventKind::Exception || k == EventKind::FaultState;
}
}  // namespace

void LatchedCheck::run(const CheckInput& in, Report& out) const {
  const supervisor::LatchedFault& l = in.component.latch;
  if (!l.active) return;
  if (exception_kind(l.first_kind) &&
      (!in.thresholds.exception.enabled || !in.thresholds.exception.sticky)) {
    return;
  }
  const auto ago = [&](Nanos t) {
    return format_nanos(static_cast<double>(in.now_ns >= t ? in.now_ns - t : 0));
  };
  out.merge(StatusLevel::Error,
            fmt::format("latched: {}: {} ({} error event{}; first {} ago, last {} ago; clear to "
                        "reset)",
                        to_string(l.first_kind), l.first_detail, l.count, l.count == 1 ? "" : "s",
                        ago(l.first_ns), ago(l.last_ns)));
}

}  // namespace vigil::monitor::checks
