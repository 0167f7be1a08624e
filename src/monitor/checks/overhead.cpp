#include "vigil/monitor/checks/overhead.hpp"

#include <fmt/format.h>

#include "monitor/checks/common.hpp"

namespace vigil::checks {

void OverheadCheck::run(const CheckInput& in, Report& out) const {
  const OverheadThresholds& t = in.thresholds.overhead;
  const ComponentSnapshot& c = in.component;
  if (!t.enabled || c.overhead_ns.count == 0 || c.total_ns.mean <= 0) return;
  const double share = c.overhead_share();
  if (share <= t.warn_share) return;
  out.merge(StatusLevel::Warn, fmt::format("supervision overhead {} of cycle time (limit {})",
                                           detail::percent(share), detail::percent(t.warn_share)));
}

}  // namespace vigil::checks
