#include "vigil/monitor/checks/initialization.hpp"

namespace vigil::monitor::checks {

void InitializationCheck::run(const CheckInput& in, Report& out) const {
  if (!in.thresholds.initialization.enabled || !in.component.alive) return;
  if (!in.component.has_info) out.merge(StatusLevel::Warn, "not configured");
}

}  // namespace vigil::monitor::checks
