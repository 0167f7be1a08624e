#include "vigil/monitor/checks/overhead.hpp"

#include <fmt/format.h>

#include "monitor/checks/common.hpp"

namespace vigil::monitor::checks {

void OverheadCheck::run(const CheckInput& in, Report& out) const {
  const OverheadThresholds& t = in.thresholds.overhead;
  const supervisor::ComponentSnapshot& c = in.component;
  if (!t.enabled || c.overhead_ns.count == 0 || c.total_ns.mean <= 0) return;
  const double share = c.overhead_share();
  if (share <= t.warn_share) return;
  // Only an overhead that matters warns: above the absolute floor and, for a periodic
  // component, above a share of its period (a short on_update() makes the share large while
  // supervision costs nothing next to the period).
  const double mean = c.overhead_ns.mean;
  if (mean <= static_cast<double>(t.min_overhead_ns)) return;
  const Nanos period = c.has_info ? c.info.period_ns : 0;
  if (period > 0 && mean <= t.min_period_share * static_cast<double>(period)) return;
  out.merge(StatusLevel::Warn, fmt::format("supervision overhead {} of cycle time (limit {})",
                                           detail::percent(share), detail::percent(t.warn_share)));
}

}  // namespace vigil::monitor::checks
