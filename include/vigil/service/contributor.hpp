#pragma once
/// @file
/// The one way in of a supervision pipeline: `Contributor`, code that adds units of its own
/// (reports with their buckets) to every monitor cycle: CAN nodes and groups, the processes of
/// `vigil supervise`, a program's own subsystems.
///
/// A contributor runs once per monitor cycle, on the monitor's thread (or the caller of
/// `SupervisionService::step()`), after the monitor made the cycle's reports and before any
/// output sees the snapshot; readers of the service's reports get that snapshot, never a second
/// evaluation. Register it with `SupervisionService::add_contributor()` before the service
/// starts (docs/guide/writing-an-output.md, "Adding units"). Not RT-safe.

#include "vigil/export/output.hpp"

namespace vigil::service {

class Contributor {
 public:
  virtual ~Contributor() = default;
  /// Adds reports to `snapshot.reports` (after the monitor's) and, for those with timing
  /// distributions, their buckets to `snapshot.can_histograms`, matched by report name. May
  /// read the reports already there (the monitor's, the earlier contributors'). Exceptions are
  /// caught and said on stderr; the other contributors and the outputs still run.
  virtual void contribute(exporter::Snapshot& snapshot) = 0;
};

}  // namespace vigil::service
