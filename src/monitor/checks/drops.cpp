#include "vigil/monitor/checks/drops.hpp"

#include <fmt/format.h>

namespace vigil::monitor::checks {

void DropsCheck::run(const CheckInput& in, Report& out) const {
  const DropsThresholds& t = in.thresholds.drops;
  const supervisor::ComponentSnapshot& c = in.component;
  if (!t.enabled) return;
  if (in.window.dropped <= t.warn_drops) return;
  out.merge(StatusLevel::Warn,
            fmt::format("port dropped {} message{} ({} in total)", in.window.dropped,
                        in.window.dropped == 1 ? "" : "s", c.counters.dropped));
}

}  // namespace vigil::monitor::checks
