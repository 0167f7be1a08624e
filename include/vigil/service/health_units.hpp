#pragma once
/// @file
/// `HealthUnits`: the contributor that shows each health supervision (vigil/health; AUTOSAR
/// PHM's alive, deadline and logical supervision) as a unit of the monitor's cycle, beside the
/// components and the CAN nodes: one report per supervision, kind "supervision", named
/// "supervision <name>", with its status mapped onto OK / WARN / ERROR (`monitor::status_level`)
/// and its figures as fields. Every output then shows it (the text summary's table of
/// supervisions, JSON units, `/api/v1/diagnostics`, the dashboard, `vigil_component_status`).
/// `SupervisionService` adds one itself; it contributes nothing while no supervision is
/// configured.

#include <string>
#include <string_view>

#include "vigil/health/report.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/service/contributor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::service {

/// The unit kind of a health supervision's report (`Report::unit_kind`).
inline constexpr std::string_view kSupervisionUnit = health::kSupervisionUnit;

/// The report of one supervision: a unit of kind "supervision" named "supervision <name>";
/// state: "ok", "failed", "expired" or "deactivated"; status: OK (ok, deactivated), WARN
/// (failed), ERROR (expired), with the latest failure's text as its message; fields: `type`
/// (alive, deadline, logical), `entities`, `checkpoints`, `lost`, `evaluations`, `failures`,
/// `failed` (failures not taken back yet), `tolerance`, `expirations`; alive: `last_cycle` and
/// `this_cycle` (indications); deadline: `last`, `min`, `max` (start-to-end durations, once
/// measured); logical: `at` (the sequence's latest checkpoint); after a failure: `last_failure`
/// (its kind) and `detected_after` (its detection latency). Not RT-safe (allocates).
[[nodiscard]] monitor::Report supervision_unit(const health::SupervisionReport& s);

/// Adds `supervision_unit()` of every supervision of an aggregator to each monitor cycle.
class HealthUnits final : public Contributor {
 public:
  explicit HealthUnits(const supervisor::ComponentAggregator& aggregator)
      : aggregator_(aggregator) {}
  void contribute(exporter::Snapshot& snapshot) override;

 private:
  const supervisor::ComponentAggregator& aggregator_;
};

}  // namespace vigil::service
