#pragma once
/// @file
/// `CanMonitor`: judges every CAN node from the CAN aggregator's statistics and the thresholds
/// of a `CanConfig`, and `CanReport`, what it produces: one status per node, an overall status,
/// and the statistics judged. The export module prints it as text or JSON
/// (vigil/export/can_report.hpp).
///
/// The checks, per node (bus, node), in this order:
///  1. never seen ("not initialized"): an expected node (named in `nodes:` or listed in a
///     group's `nodes:`) from which no frame was ever received;
///  2. not responding: a node that was received from, but not for longer than
///     `not_responding.after` (now - last Rx frame, from the sniffer's exact table);
///  3. read time, write time, Rx gap, Tx gap: the chosen statistic (`stat`, max by default) of
///     the distribution above `warn` / `error` (strictly above: equal passes);
///  4. custom checks added with `add_check`.
/// Liveness and counts come from the sniffers' tables, so they are exact even when the ports
/// dropped records; timing checks use the records that arrived.
///
/// Overall status: the worst node status, plus WARN for frames the sniffers could not track
/// (table full) and for error frames; dropped records are reported as an OK message (timing is
/// sampled, counts are not).
///
/// Threads: `evaluate` from any non-RT thread; `set_config` and `add_check`
/// are thread-safe against `evaluate`. Not RT-safe (allocates).

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// What the monitor says about one node (both directions).
struct NodeReport {
  std::optional<std::uint8_t> bus;  ///< empty: an expected any-bus node never seen on any bus
  std::uint32_t node = 0;
  std::string name;                 ///< the configured name, or the node as the mapping numbers it
  bool named = false;               ///< `name` comes from the configuration
  bool expected = false;            ///< "never seen" applies
  std::vector<std::string> groups;  ///< groups it belongs to, in configuration order
  std::optional<NodeStats> rx;      ///< frames received from the node, if any
  std::optional<NodeStats> tx;      ///< frames sent to the node, if any
  Nanos silence_ns = -1;            ///< now - latest Rx frame; -1 when never received from
  NodeThresholds thresholds;        ///< as resolved for this node
  Status status;
};

/// One monitor evaluation.
struct CanReport {
  Nanos time_ns = 0;  ///< the "now" the checks used
  NodeMapKind node_map = NodeMapKind::Identity;
  Status status;                  ///< overall (see the file comment)
  CanSnapshot snapshot;           ///< the statistics judged (ids, nodes, categories, totals)
  std::vector<NodeReport> nodes;  ///< by bus, then node; never-seen any-bus nodes last

  /// The report of (bus, node), or null. O(n).
  [[nodiscard]] const NodeReport* find(std::uint8_t bus, std::uint32_t node) const noexcept;
  /// The report of the node named `name`, or null. O(n).
  [[nodiscard]] const NodeReport* find(std::string_view name) const noexcept;
};

/// A custom per-node check: merge findings into `out` (the node's status).
using CanNodeCheck =
    std::function<void(const NodeReport& node, const CanReport& report, Status& out)>;

/**
 * Runs the CAN checks.
 *
 * @code
 * vigil::can::CanMonitor monitor(*vigil::can::load_can_config_file("can.yaml"));
 * vigil::can::CanReport r = monitor.evaluate(aggregator, vigil::platform::now_ns());
 * std::fputs(vigil::exporter::format_can_report(r).c_str(), stdout);  // vigil/export
 * @endcode
 */
class CanMonitor {
 public:
  /// A monitor with `config`'s thresholds, nodes and groups.
  explicit CanMonitor(CanConfig config = {});

  /// Replaces the configuration (e.g. from a `config::Reloadable<CanConfig>` subscription);
  /// takes effect at the next `evaluate`. Thread-safe.
  void set_config(CanConfig config);
  /// Same, sharing an existing value. Null is ignored. Thread-safe.
  void set_config(std::shared_ptr<const CanConfig> config);
  /// The configuration in use. Thread-safe.
  [[nodiscard]] std::shared_ptr<const CanConfig> config() const;

  /// Adds a check run on every node after the built-in ones. Thread-safe.
  void add_check(std::string name, CanNodeCheck check);

  /// Takes a snapshot of `aggregator` (with the configuration's groups) and judges it at `now`
  /// (the clock of the sniffers' timestamps). Thread-safe.
  [[nodiscard]] CanReport evaluate(const CanAggregator& aggregator, Nanos now) const;
  /// Judges `snapshot` at `now`. Its categories should come from `config()->group_specs()`.
  [[nodiscard]] CanReport evaluate(CanSnapshot snapshot, Nanos now) const;

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const CanConfig> config_;
  std::vector<std::pair<std::string, CanNodeCheck>> checks_;
};

}  // namespace vigil::can
