#pragma once
/// @file
/// The mapping of health supervision's status (vigil/health/report.hpp, AUTOSAR PHM's local
/// supervision status) onto the monitor's levels, for whoever shows supervisions next to the
/// other units (a contributor, an output): OK and DEACTIVATED are Ok (a supervision stopped on
/// purpose is not a fault), FAILED is Warn (failures within the tolerance), EXPIRED is Error.

#include "vigil/health/report.hpp"
#include "vigil/monitor/status.hpp"

namespace vigil::monitor {

/// The level of a supervision in status `s`. RT-safe (a table).
[[nodiscard]] constexpr StatusLevel status_level(health::SupervisionStatus s) noexcept {
  switch (s) {
    case health::SupervisionStatus::Ok:
    case health::SupervisionStatus::Deactivated:
      return StatusLevel::Ok;
    case health::SupervisionStatus::Failed:
      return StatusLevel::Warn;
    case health::SupervisionStatus::Expired:
      return StatusLevel::Error;
  }
  return StatusLevel::Error;
}

static_assert(status_level(health::SupervisionStatus::Failed) == StatusLevel::Warn);
static_assert(status_level(health::SupervisionStatus::Expired) == StatusLevel::Error);

}  // namespace vigil::monitor
