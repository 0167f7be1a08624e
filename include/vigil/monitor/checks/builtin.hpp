#pragma once
/// @file
/// Every built-in check, and `add_builtin_checks`, which the Monitor calls unless told not to.

#include "vigil/monitor/check.hpp"
#include "vigil/monitor/checks/drops.hpp"
#include "vigil/monitor/checks/exception.hpp"
#include "vigil/monitor/checks/initialization.hpp"
#include "vigil/monitor/checks/latched.hpp"
#include "vigil/monitor/checks/not_realtime.hpp"
#include "vigil/monitor/checks/overhead.hpp"
#include "vigil/monitor/checks/overrun.hpp"
#include "vigil/monitor/checks/realtime.hpp"
#include "vigil/monitor/checks/starvation.hpp"

namespace vigil::monitor::checks {

/// Appends the built-in checks in their reporting order: initialization, exception,
/// starvation, overrun, realtime, not_realtime, overhead, drops, latched. Not RT-safe.
void add_builtin_checks(CheckList& list);

}  // namespace vigil::monitor::checks
