#pragma once
/// @file
/// CAN supervision configuration: the node mapping, the filter, the thresholds of the CAN
/// monitor (defaults, per group, per node), named nodes and groups; and their YAML loaders.
///
/// ```yaml
/// node_map: canopen                  # identity (default) | canopen | j1939 | dronecan
/// filter:                            # default: every frame
///   all:
///     - bus: 0
///     - any: [{ids: [0x181, 0x182]}, {id_range: [0x200, 0x27F]}]
/// defaults:                          # thresholds for every node
///   not_responding: {after: 100ms}   # default: learned from each node's traffic
///   rx_gap: {warn: 15ms, error: 50ms, stat: max}
/// nodes:
///   left_shoulder: {node: 11, bus: 0}
/// groups:
///   left_arm: {nodes: [11, 12, 13, 14], thresholds: {read_time: {warn: 200us}}}
/// ```
///
/// Every key is documented in docs/reference/can-config.md. Errors name file:line:col and the
/// field, as every vigil schema does (vigil/config/node.hpp). Reload at run time with
/// `config::Reloadable<CanConfig>::open(path, load_can_config)`, then hand the new value to
/// `CanMonitor::set_config` and its filter to `Sniffer::set_filter`.
///
/// Nothing here is RT-safe: configuration is read by non-RT threads only.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/can_statistics.hpp"
#include "vigil/can/filter.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/can/protocol.hpp"
#include "vigil/config/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::config {
class Node;
}

namespace vigil::can {

/// Which statistic of a distribution a limit compares.
enum class LimitStat : std::uint8_t {
  Last,  ///< the latest sample
  Mean,  ///< the mean since the start
  Ewma,  ///< the exponentially weighted moving average (recovers after a spike)
  Max,   ///< the largest sample since the start (the default)
  P50,   ///< median
  P90,   ///< 90th percentile
  P99,   ///< 99th percentile
  P999,  ///< 99.9th percentile
};

/// "last", "mean", "ewma", "max", "p50", "p90", "p99", "p999".
[[nodiscard]] std::string_view to_string(LimitStat s) noexcept;

/// `s`'s value of `summary`, in ns (the mean and EWMA rounded to the nearest ns).
[[nodiscard]] Nanos stat_value(const StatsSummary& summary, LimitStat s) noexcept;

/// A resolved limit on a duration: WARN above `warn`, ERROR above `error` (strictly: a value
/// equal to its limit passes); disabled when both are empty.
struct Limit {
  std::optional<Nanos> warn;
  std::optional<Nanos> error;
  LimitStat stat = LimitStat::Max;

  /// True when a limit is set.
  [[nodiscard]] bool enabled() const noexcept { return warn.has_value() || error.has_value(); }
};

/// How a silence limit is learned from a node's own traffic, when none is configured
/// (docs/guide/can-supervision.md, "Learned deadlines"): once an id from the node has
/// `min_gaps` gaps, its period is the `percentile` of its gaps and its limit
/// max(`floor`, `factor` x period); the node's limit is the largest of its periodic ids' limits.
struct LearnRule {
  LimitStat percentile = LimitStat::P99;  ///< which statistic of the gaps is the period
  double factor = 2.0;                    ///< the limit is this many periods (CiA 301: 1.5-2)
  Nanos floor_ns = 250 * kNanosPerMilli;  ///< and at least this
  std::uint32_t min_gaps = 16;            ///< gaps an id needs before its period is learned
};

/// The thresholds the CAN monitor applies to one node, after layering.
struct NodeThresholds {
  bool never_seen_enabled = true;                     ///< check "not initialized"
  StatusLevel never_seen_level = StatusLevel::Error;  ///< level when an expected node is unseen
  bool not_responding_enabled = true;                 ///< check "not responding"
  /// Silence (no frame from the node) that counts as "not responding"; empty: learned with
  /// `learn` from the node's own traffic (the default). A configured limit always wins.
  std::optional<Nanos> not_responding_after_ns;
  LearnRule learn;  ///< how the limit is learned
  /// A request to the node (SDO, RTR, service request) unanswered for longer than this is a
  /// fault: "not responding" when nothing else shows the node alive, WARN otherwise.
  Nanos answer_within_ns = kNanosPerSecond;
  StatusLevel not_responding_level = StatusLevel::Error;
  Limit read_time;   ///< time spent reading a frame from the node (Rx I/O time)
  Limit write_time;  ///< time spent writing a frame to the node (Tx I/O time)
  Limit rx_gap;      ///< time between consecutive frames received from the node
  Limit tx_gap;      ///< time between consecutive frames sent to the node
  /// CANopen (CiA 301), for nodes whose bus or group speaks it (`protocol: canopen`).
  /// Heartbeat consumer time (object 0x1016): no heartbeat for longer is "heartbeat lost" at
  /// `not_responding_level`. Empty: learned (the node's learned silence limit covers its
  /// heartbeat id, 0x700 + node-ID).
  std::optional<Nanos> canopen_heartbeat_ns;
  /// A node outside operational for longer than this is WARN; empty: never.
  std::optional<Nanos> canopen_not_operational_after_ns;
  /// A node reset (boot-up of a running node) keeps the node WARN this long; 0: never WARN.
  Nanos canopen_reset_window_ns = Nanos{300} * kNanosPerSecond;
  /// Level while the node's latest emergency is not "error reset" (0x0000).
  StatusLevel canopen_emergency_level = StatusLevel::Warn;
  /// SAE J1939 (nodes of a bus that decodes J1939): the level while the node's latest DM1
  /// lists an active trouble code, while its malfunction indicator, amber warning or protect
  /// lamp is on, and while its red stop lamp is on.
  StatusLevel j1939_dtc_level = StatusLevel::Warn;
  StatusLevel j1939_lamp_level = StatusLevel::Warn;
  StatusLevel j1939_stop_lamp_level = StatusLevel::Error;
};

/// One layer of a limit, as written: each field replaces the layer below when set.
struct LimitOverride {
  std::optional<bool> enabled;  ///< false: no limit (whatever lower layers say)
  std::optional<Nanos> warn;
  std::optional<Nanos> error;
  std::optional<LimitStat> stat;

  /// Applies this layer on top of `l`.
  void apply_to(Limit& l) const;
};

/// One layer of thresholds (defaults, a group's, a node's), as written in a file.
struct ThresholdOverrides {
  std::optional<bool> never_seen_enabled;
  std::optional<StatusLevel> never_seen_level;
  std::optional<bool> not_responding_enabled;
  /// Set in this layer: a fixed limit, or empty for "learned".
  std::optional<std::optional<Nanos>> not_responding_after_ns;
  std::optional<LimitStat> learn_percentile;
  std::optional<double> learn_factor;
  std::optional<Nanos> learn_floor_ns;
  std::optional<std::uint32_t> learn_min_gaps;
  std::optional<Nanos> answer_within_ns;
  std::optional<StatusLevel> not_responding_level;
  LimitOverride read_time;
  LimitOverride write_time;
  LimitOverride rx_gap;
  LimitOverride tx_gap;
  std::optional<std::optional<Nanos>> canopen_heartbeat_ns;
  std::optional<std::optional<Nanos>> canopen_not_operational_after_ns;
  std::optional<Nanos> canopen_reset_window_ns;
  std::optional<StatusLevel> canopen_emergency_level;
  std::optional<StatusLevel> j1939_dtc_level;
  std::optional<StatusLevel> j1939_lamp_level;
  std::optional<StatusLevel> j1939_stop_lamp_level;

  /// Applies this layer on top of `t`.
  void apply_to(NodeThresholds& t) const;
};

/// A named node: shown by name, expected to be seen, with its own thresholds.
struct NodeConfig {
  std::string name;                 ///< the key in `nodes:`
  std::optional<std::uint8_t> bus;  ///< empty: on any bus
  std::uint32_t node = 0;           ///< as the node mapping numbers it
  bool expected = true;             ///< report "not initialized" when it is never seen
  ThresholdOverrides thresholds;    ///< applied after the defaults and the groups
};

/// A group: its members (statistics and summary row) and the thresholds of its members.
struct GroupConfig {
  GroupSpec members;
  bool expected = true;           ///< the nodes listed in `members.nodes` (not ranges) are expected
  ThresholdOverrides thresholds;  ///< applied to each member, after the defaults
  /// `protocol: canopen` decodes CiA 301 for the members (Auto: not set; the bus decides).
  BusProtocol protocol = BusProtocol::Auto;
};

/// Bus load thresholds: percent of the bitrate (worst-case stuffing can exceed 100).
struct LoadLimit {
  std::optional<double> warn{};
  std::optional<double> error{};
  Stuffing stuffing = Stuffing::Exact;    ///< which count is judged
  LoadFigure figure = LoadFigure::Avg1m;  ///< which figure is judged
};

/// One entry of `buses:` (its keys, as given; `CanConfig::bus_config` layers them).
struct BusConfig {
  std::optional<std::uint8_t> bus{};  ///< empty: `all`
  std::optional<std::uint32_t> bitrate{};
  std::optional<std::uint32_t> data_bitrate{};
  std::optional<BusProtocol> protocol{};
  std::optional<double> load_warn{};
  std::optional<double> load_error{};
  std::optional<Stuffing> load_stuffing{};
  std::optional<LoadFigure> load_figure{};
  /// The SocketCAN interface of this bus ("can0"; a bus entry only, not `all`): its controller's
  /// state, error counters, restarts and bitrate are read live through rtnetlink at the
  /// monitor's pace (vigil/can/can_link.hpp) by the deployment's CAN supervision.
  std::optional<std::string> interface {};
};

/// A bus's settings after layering (`all`, then its own entry).
struct ResolvedBus {
  BusSettings settings;  ///< bitrates and protocol (`Auto` resolved by the tracker)
  LoadLimit load;
};

/// A whole CAN supervision configuration. Defaults: identity mapping, accept every frame,
/// built-in thresholds (see NodeThresholds), no named node, no group, no bus settings.
struct CanConfig {
  NodeMapKind node_map = NodeMapKind::Identity;
  FilterExpr filter;                ///< accept every frame by default
  ThresholdOverrides defaults;      ///< on top of the built-in thresholds
  std::vector<NodeConfig> nodes;    ///< in file order
  std::vector<GroupConfig> groups;  ///< in file order
  std::vector<BusConfig> buses;     ///< `buses:` in file order

  /// The thresholds of node `node` on `bus`: built-in, then `defaults`, then each group that
  /// contains it (file order), then its `nodes` entries.
  [[nodiscard]] NodeThresholds thresholds_for(std::uint8_t bus, std::uint32_t node) const;
  /// The groups' memberships, for `CanAggregator::snapshot`.
  [[nodiscard]] std::vector<GroupSpec> group_specs() const;
  /// The named node for (bus, node), or null.
  [[nodiscard]] const NodeConfig* find_node(std::uint8_t bus, std::uint32_t node) const noexcept;
  /// Bus `bus`'s bitrates, protocol and load thresholds: built-in, `all`, then its entry.
  [[nodiscard]] ResolvedBus bus_config(std::uint8_t bus) const;
  /// What the CAN aggregator's protocol tracker needs: the node map, every bus's settings and
  /// the CANopen nodes of groups with `protocol: canopen`.
  [[nodiscard]] ProtocolOptions protocol_options() const;
};

/// Schema loader of a whole file (the root mapping). Use it with `config::load_file`,
/// `config::load_string` or `config::Reloadable<CanConfig>::open`. Errors are recorded in the
/// document (see vigil/config/node.hpp).
[[nodiscard]] CanConfig load_can_config(const config::Node& root);

/// Loads a CAN configuration file; every error as file:line:col: field: message.
[[nodiscard]] expected<CanConfig, config::ConfigErrors> load_can_config_file(
    const std::filesystem::path& path);

/// Loads a CAN configuration from `text`, named `name` in errors.
[[nodiscard]] expected<CanConfig, config::ConfigErrors> load_can_config_string(
    std::string_view text, std::string name = "<string>");

/// Sub-loader of one filter (a mapping of conditions, all of which must hold; see
/// docs/reference/can-config.md). A null or empty mapping accepts every frame.
[[nodiscard]] FilterExpr load_filter(const config::Node& node);

/// Sub-loader of one layer of thresholds.
[[nodiscard]] ThresholdOverrides load_thresholds(const config::Node& node);

}  // namespace vigil::can
