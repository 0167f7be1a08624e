#pragma once
/// @file
/// `MetricsSnapshot`: what the HTTP exporter serves. One immutable value per monitor cycle: the
/// monitor's reports, the components' timing distributions reduced to Prometheus buckets, and a
/// short history of p99s and overruns for the dashboard's charts.
///
/// Design (copy-on-publish): the thread that publishes (the monitor's, through a subscription)
/// builds a new snapshot and swaps a `shared_ptr<const MetricsSnapshot>`; HTTP threads only read
/// snapshots they hold a reference to. Nothing here touches the real-time side.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "vigil/can/can_statistics.hpp"
#include "vigil/export/buckets.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::exporter {

/// An OpenMetrics exemplar that names one cycle of a component: `# {cycle="4711",trace="17"}
/// 0.00125 1764423135.123` (docs/reference/metrics.md, "Exemplars").
struct CycleExemplar {
  std::uint64_t cycle = 0;  ///< the component's cycle number (0: no exemplar)
  /// The value it stands for: the cycle's time in the histogram, in seconds; 1 on the overrun
  /// counter (one overrun).
  double value = 0;
  std::int64_t unix_ns = 0;  ///< when the cycle started (the overrun: ended), Unix time; 0: unknown
  /// The sequence number of the event whose flight record holds the cycle (served at
  /// `/api/v1/events/<trace>/trace`, written as `<component>-<trace>.trace.json`); 0: none.
  std::uint64_t trace = 0;
};

/// A component's timing histograms, in the order of `ComponentHistograms::worst`.
enum class TimingHistogram : std::uint8_t { Execution, Total, Latency, MeasuredPeriod };
inline constexpr std::size_t kTimingHistograms = 4;

/// The exemplar of one bucket of one of a component's histograms.
struct BucketExemplar {
  TimingHistogram histogram = TimingHistogram::Execution;
  /// The bucket: an index into kBucketBoundsNs, or kBucketBounds for `+Inf`. The exemplar's
  /// value is within it (above the bound before, at most its own).
  std::uint8_t bucket = 0;
  CycleExemplar exemplar;
};

/// The timing distributions of one component as Prometheus buckets.
struct ComponentHistograms {
  std::uint32_t id = 0;  ///< the registry id (`Report::id`)
  /// The monitor cycle whose reports these buckets go with (`ReportSet::cycle`; 0: not set).
  std::uint64_t cycle = 0;
  std::string name;
  BucketCounts execution;        ///< on_update() alone (`Report::execution_ns`)
  BucketCounts total;            ///< execution + supervision overhead (`Report::total_ns`)
  BucketCounts latency;          ///< wake-up latency (`Report::latency_ns`)
  BucketCounts measured_period;  ///< measured start-to-start period (`Report::measured_period_ns`)
  /// The worst cycles of each histogram by window, by `TimingHistogram` (collect_histograms):
  /// what the exemplars are chosen from.
  std::array<supervisor::WorstCycles, kTimingHistograms> worst{};
  /// The buckets' exemplars, sorted by histogram then bucket, at most one per bucket (an
  /// `ExemplarBook` fills them in; empty: none, as in the 0.0.4 text format).
  std::vector<BucketExemplar> exemplars;
  /// The exemplar of the overrun counter: the latest overrun (cycle 0: none).
  CycleExemplar overrun;
};

/// The buckets of every component of `aggregator`, by id. Takes each record's lock for the
/// time of one reduction (microseconds). Not RT-safe (allocates); any non-RT thread.
[[nodiscard]] std::vector<ComponentHistograms> collect_histograms(
    const supervisor::ComponentAggregator& aggregator);

/// The gap distributions of one CAN node or group report as Prometheus buckets (served as
/// `vigil_can_gap_seconds` and `vigil_can_group_gap_seconds`).
struct CanHistograms {
  /// The report's name: "can0/drive_5" (a node), "can group left_arm" (a group).
  std::string name;
  bool group = false;  ///< a group's (else a node's)
  /// Time between consecutive frames received from the node (a group: from each member);
  /// none when no gap was measured in that direction.
  std::optional<BucketCounts> rx_gap;
  /// Time between consecutive frames sent to the node (a group: to each member).
  std::optional<BucketCounts> tx_gap;
};

/// The bus load of one CAN bus report (`can bus 0`) as numbers, for the bus families
/// (`vigil_can_bus_load_ratio`, `vigil_can_bus_bit_times_total`, `vigil_can_bus_frames_total`):
/// the report's own fields give the loads as text.
struct CanBusLoads {
  std::string name;                             ///< the bus report's name: "can bus 0"
  can::Stuffing judged = can::Stuffing::Exact;  ///< the count the bus is judged by
  /// [stuffing mode][0 rx, 1 tx, 2 both], as `can::BusProtocolStats::load`.
  std::array<std::array<can::BusLoad, 3>, can::kStuffingModes> load{};
};

/// Reduces one of the CAN aggregator's gap distributions to the fixed boundaries: its
/// histogram (live, the same rule as the components') or its samples (exact mode: exact).
/// Allocation-free; call inside `CanAggregator::visit_gap_distributions`.
[[nodiscard]] BucketCounts reduce_to_buckets(const can::GapDistribution& distribution) noexcept;

/// One component at one point of the dashboard's history.
struct HistoryPoint {
  std::string name;
  Nanos execution_p99_ns = 0;         ///< p99 of on_update() time (since the start)
  Nanos latency_p99_ns = 0;           ///< p99 of wake-up latency (since the start)
  std::uint64_t overruns = 0;         ///< cumulative overruns
  std::uint64_t window_overruns = 0;  ///< overruns in the monitor's recent window
  StatusLevel status = StatusLevel::Ok;
};

/// Every component at one monitor cycle.
struct HistoryFrame {
  std::uint64_t cycle = 0;
  Nanos time_ns = 0;  ///< monitor clock
  std::vector<HistoryPoint> points;
};

/// Builds the history frame of `reports` (components only).
[[nodiscard]] HistoryFrame make_history_frame(const ReportSet& reports);

/// Everything the HTTP endpoints serve, from one monitor cycle. Immutable once published.
struct MetricsSnapshot {
  ReportSet reports;
  /// Buckets by component id; empty when the publisher had no aggregator (then the histogram
  /// families carry only their count and sum).
  std::vector<ComponentHistograms> histograms;
  /// The recent history, oldest first (shared between consecutive snapshots).
  std::vector<std::shared_ptr<const HistoryFrame>> history;
  /// The CAN nodes' and groups' gap buckets, sorted by name; empty without CAN (or when the
  /// publisher did not collect them: the gap families then carry only their count and sum).
  std::vector<CanHistograms> can_histograms;
  /// The CAN buses' loads, sorted by name; empty without CAN (the bus families are then absent).
  std::vector<CanBusLoads> can_buses;
  std::int64_t wall_time_ns = 0;  ///< Unix time at publication (for ROS header stamps)
  Nanos published_ns = 0;         ///< monotonic time at publication

  /// The buckets of `report` (a component), or null. O(log n).
  [[nodiscard]] const ComponentHistograms* histograms_of(const Report& report) const noexcept;
  /// The gap buckets of `report` (a CAN node or group), or null. O(log n).
  [[nodiscard]] const CanHistograms* can_histograms_of(const Report& report) const noexcept;
  /// The loads of `report` (a CAN bus), or null. O(log n).
  [[nodiscard]] const CanBusLoads* can_bus_of(const Report& report) const noexcept;
};

}  // namespace vigil::exporter
