#pragma once
/// @file
/// `ThreadUnits`: the contributor that makes each thread shared by several components a unit of
/// the diagnosis graph (monitor/diagnosis.hpp), so that a thread stuck in one component's
/// `on_update()`, which silences every component on it, is one root cause and not one per
/// component. One report per thread with two or more alive components: kind "thread", named
/// "thread <activity> (tid <tid>)"; ERROR "stuck or starved" when none of its components has
/// cycled within its limit (the watchdog's deadline, else 10 periods, at least 100 ms), naming
/// the component whose cycle was the last to end (the one after it in the thread's order is the
/// likely culprit). Each component on the thread depends on it. `SupervisionService` adds one
/// itself. Not RT-safe.

#include <string>
#include <string_view>

#include "vigil/monitor/report.hpp"
#include "vigil/service/contributor.hpp"

namespace vigil::service {

/// The unit kind of a shared thread's report (`Report::unit_kind`).
inline constexpr std::string_view kThreadUnit = "thread";

/// Adds a unit per shared thread to each monitor cycle and the edges from its components.
class ThreadUnits final : public Contributor {
 public:
  void contribute(exporter::Snapshot& snapshot) override;
};

/// The threads' units of `reports` (and the edges, added to the component reports). Exposed for
/// tests. Not RT-safe.
void add_thread_units(monitor::ReportSet& reports);

}  // namespace vigil::service
