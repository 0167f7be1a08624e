#include "vigil/monitor/checks/realtime.hpp"

#include <fmt/format.h>

namespace vigil::monitor::checks {

namespace {
std::string by_cause(const std::array<std::uint64_t, task::kLossCauses>& losses) {
  std::string out;
  for (int i = 0; i < task::kLossCauses; ++i) {
    const std::uint64_t n = losses[static_cast<std::size_t>(i)];
    if (n == 0) continue;
    if (!out.empty()) out += ", ";
    out += fmt::format("{} {}", n, platform::to_string(static_cast<platform::LossCause>(i)));
  }
  return out.empty() ? "none" : out;
}
}  // namespace

void RealTimeCheck::run(const CheckInput& in, Report& out) const {
  const RealTimeThresholds& t = in.thresholds.realtime;
  const supervisor::ComponentSnapshot& c = in.component;
  if (!t.enabled) return;
  if (t.fifo_only && !(c.has_info && c.info.policy == SchedPolicy::Fifo)) return;
  const std::uint64_t n = in.window.total_losses();
  if (n <= t.warn_losses) return;
  out.merge(StatusLevel::Warn, fmt::format("real-time losses: {} ({} in total)",
                                           by_cause(in.window.losses), c.counters.total_losses()));
  if (c.has_loss) {
    out.add("latest_loss", fmt::format("cycle {}: {} {}", c.last_loss.cycle, c.last_loss.count,
                                       platform::to_string(c.last_loss.cause)));
  }
}

}  // namespace vigil::monitor::checks
