#pragma once
/// @file
/// The one way out of a supervision pipeline: `Output`, and `Snapshot`, what every output is
/// handed once per monitor cycle.
///
/// An output is started with the pipeline, told about every monitor cycle with one consistent
/// snapshot (the cycle's reports, the buckets of the same cycle, the events raised since the
/// previous cycle), and stopped with the final snapshot. The text summary, the JSON file, the
/// HTTP server, the node-exporter textfile, the event log and the flight-recorder traces are all
/// outputs; a program adds its own by implementing `Output` and registering it with
/// `SupervisionService::add_output()` (docs/guide/writing-an-output.md):
///
/// ```cpp
/// class WorstLevel final : public vigil::exporter::Output {
///  public:
///   void publish(const vigil::exporter::Snapshot& s) override {
///     std::printf("cycle %llu: %s\n", (unsigned long long)s.cycle, to_string(s.reports.worst()));
///   }
/// };
/// service.add_output(std::make_unique<WorstLevel>());
/// ```
///
/// Threads: start() and stop() run on the pipeline's control thread; publish() on the monitor's
/// thread (or the caller of `SupervisionService::step()`), one cycle at a time, never on a
/// real-time thread. An output that needs more time than a monitor cycle gives keeps a thread of
/// its own. Nothing here is RT-safe.

#include <cstdint>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/metrics_snapshot.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/events.hpp"

namespace vigil::exporter {

/// One monitor cycle, as every output receives it. Plain values, built once per cycle by the
/// pipeline and shared by all its outputs.
struct Snapshot {
  /// The monitor cycle (`reports.cycle`); 0 before the first.
  std::uint64_t cycle = 0;
  /// The monitor's reports and those of every contributor (CAN nodes, processes), in that order.
  ReportSet reports;
  /// The components' timing distributions as Prometheus buckets, read from the aggregator in the
  /// same monitor cycle as the reports (by registry id).
  std::vector<ComponentHistograms> histograms;
  /// The contributors' distributions (a CAN node's or group's gaps), by report name.
  std::vector<CanHistograms> can_histograms;
  /// The contributors' CAN bus loads as numbers (`can bus 0`), by report name.
  std::vector<CanBusLoads> can_buses;
  /// The events published since the previous snapshot, oldest first (at most the hub's
  /// `recent`; the count of those it no longer held is in `events_missed`). An output that must
  /// act on an event within milliseconds subscribes to the event hub instead (`start()`'s
  /// context), as the event log and the traces do.
  std::vector<Event> events;
  std::uint64_t events_missed = 0;
};

/// What an output may use while it runs: the pipeline's aggregator (its event hub, flight
/// records and latches). Valid from start() to the end of stop().
struct OutputContext {
  supervisor::ComponentAggregator& aggregator;
};

/// The one output interface. Every member has a default that does nothing.
class Output {
 public:
  virtual ~Output() = default;
  /// Called once when the pipeline starts, before its first cycle (bind a socket, open a file,
  /// subscribe to events). An error makes the pipeline's start fail with it; nothing is
  /// published to an output that did not start.
  virtual expected<void, Error> start(OutputContext& /*context*/) { return {}; }
  /// Called after every monitor cycle with its snapshot. Keep it short: the next cycle waits.
  virtual void publish(const Snapshot& /*snapshot*/) {}
  /// Called once when the pipeline stops, with the final snapshot (after the last drain and the
  /// last monitor cycle). The output must not use the context after it returns.
  virtual void stop(const Snapshot& /*final_snapshot*/) {}
};

}  // namespace vigil::exporter
