#include "vigil/monitor/checks/not_realtime.hpp"

#include <fmt/format.h>

namespace vigil::monitor::checks {

void NotRealtimeCheck::run(const CheckInput& in, Report& out) const {
  const supervisor::ComponentSnapshot& c = in.component;
  if (!in.thresholds.not_realtime.enabled || !c.has_info) return;
  if (c.info.requested_policy != SchedPolicy::Fifo || c.info.policy == SchedPolicy::Fifo) return;
  out.merge(StatusLevel::Warn, fmt::format("not real-time: asked for FIFO, runs {}",
                                           platform::to_string(c.info.policy)));
}

}  // namespace vigil::monitor::checks
