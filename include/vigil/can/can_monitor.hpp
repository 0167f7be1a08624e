#pragma once
/// @file
/// `CanMonitor`: judges every CAN node from the CAN aggregator's statistics and the thresholds
/// of a `CanConfig`, and `CanReport`, what it produces: one status per node, an overall status,
/// and the statistics judged. The export module prints it as text or JSON
/// (vigil/export/can_report.hpp).
///
/// The checks, per node (bus, node), in this order:
///  1. never seen ("not initialized"): an expected node (named in `nodes:` or listed in a
///     group's `nodes:`) from which no frame ever came;
///  2. not responding: a node that sent frames, then stayed silent (the time its frames were
///     observed up to - its latest frame, both from the sniffers' exact tables; see "Silence"
///     below) for longer than its limit: `not_responding.after` when
///     configured, else the limit learned from its own traffic (`LearnRule`): per id, once it
///     has `min_gaps` gaps, max(floor, factor x percentile of its gaps); the node's limit is the
///     largest over its periodic ids. Until one of its ids is learned the node is "learning"
///     (not judged); a node that only answers requests (SDO responses, RTR answers, DroneCAN
///     service responses) is "on request": silent while nobody asks is no fault, a request
///     unanswered for longer than `answer_within` is;
///  3. read time, write time, Rx gap, Tx gap: the chosen statistic (`stat`, max by default) of
///     the distribution above `warn` / `error` (strictly above: equal passes);
///  4. custom checks added with `add_check`.
/// Liveness and counts come from the sniffers' tables, so they are exact even when the ports
/// dropped records; timing checks and learned periods use the records that arrived. Replay
/// and live supervision apply the same rules.
///
/// Silence: a node's silence is measured on the frames' own clock, from its latest frame to the
/// time up to which the sniffers' tables have been read (`CanSnapshot::observed_ns`: the start
/// of the CAN supervisor's latest cycle; for a key the tables could not hold, the latest drain
/// that emptied its port), never to `now` while frames may wait unread. A CAN supervisor that
/// runs late therefore shortens silences instead of lengthening them: it can delay a verdict,
/// never invent one. A node that really stops is reported as soon as the observation passes its
/// latest frame plus its limit. The observer's own delay (`CanReport::observer_lag_ns`, now -
/// observed) is a separate finding: the overall status is Stale when it exceeds
/// `CanMonitorOptions::stale_after_ns`.
///
/// Buses: the load against its thresholds, and the controller's state: error passive WARN, bus
/// off ERROR, error warning an OK message. The state is the one netlink read live when the bus
/// names its interface (`buses.<bus>.interface`, `set_links`; a stopped interface is WARN, one
/// that cannot be read WARN with the reason), else the one the latest error frames gave. The
/// bitrate for the load is the configured one; without one, the interface's (netlink); both
/// given and different is WARN (the configured one is used).
///
/// Overall status: the worst node status, plus WARN when no frame (or no valid frame) was seen,
/// for frames the sniffers could not track (table full) and for error frames, Stale when the
/// observation is late (above); dropped records and learning nodes are reported as OK messages.
///
/// Threads: `evaluate` from any non-RT thread; `set_config` and `add_check` are thread-safe
/// against `evaluate`. Not RT-safe (allocates).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_link.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// The kinds of the units CAN supervision reports (`Report::unit_kind`): one per node
/// ("can0/drive_5") and one per group ("can group left_arm").
inline constexpr std::string_view kNodeUnit = "can_node";
inline constexpr std::string_view kGroupUnit = "can_group";
/// The kind of the unit of one bus ("can bus 0"): its load, controller state, error frames.
inline constexpr std::string_view kBusUnit = "can_bus";

/// How a node's liveness stands.
enum class Liveness : std::uint8_t {
  NoNode,         ///< the frames that belong to no node (never judged)
  NeverSeen,      ///< no frame came from it (only, perhaps, frames to it)
  Learning,       ///< frames came from it, but none of its ids has its period learned yet
  OnRequest,      ///< it only answers requests: not judged by silence
  Responding,     ///< within its silence limit
  NotResponding,  ///< silent beyond its limit, or a request to it went unanswered
  OnEvent,        ///< it only sends protocol events (emergencies, ...): not judged by silence
};

/// "no node", "never seen", "learning", "on request", "responding", "not responding",
/// "on event".
[[nodiscard]] std::string_view to_string(Liveness l) noexcept;

/// What an id key's frames are, for liveness.
enum class Traffic : std::uint8_t {
  Periodic,   ///< from its node on its own; period learned (`IdVerdict::period_ns`)
  Learning,   ///< from its node on its own; fewer gaps than `min_gaps` so far
  OnRequest,  ///< from its node, answering requests (responses, RTR answers)
  Requests,   ///< from its node, asking another node (e.g. DroneCAN service requests)
  ToNode,     ///< addressed to its node (requests, commands such as CANopen RPDOs)
  Network,    ///< belongs to no node (NMT, SYNC, TIME, LSS, "other", anonymous)
  Sent,       ///< sent by the supervising side itself (direction Tx)
  Errors,     ///< error frames
  /// From its node when something happens, by its bus's protocol (`event_driven`): CANopen
  /// emergencies, SDO, NMT commands and LSS; J1939 transport protocol, address claims, requests,
  /// acknowledgements and DM2; DroneCAN service frames. No period is learned from them.
  Events,
};

/// "periodic", "learning", "on request", "requests", "to node", "network", "sent", "errors",
/// "events".
[[nodiscard]] std::string_view to_string(Traffic t) noexcept;

/// Whether a frame identifier is event-driven by the protocol `p` of its bus (what
/// `Traffic::Events` holds): CANopen emergencies 0x081-0x0FF, SDO 0x581-0x5FF and 0x601-0x67F,
/// NMT commands 0x000, LSS 0x7E4/0x7E5 (11-bit); J1939 parameter groups TP.CM 0xEC00, TP.DT
/// 0xEB00, ETP.CM 0xC800, ETP.DT 0xC700, address claimed 0xEE00, request 0xEA00,
/// acknowledgement 0xE800 and DM2 0xFECB (29-bit); DroneCAN service frames (29-bit, bit 7).
/// Pure, O(1).
[[nodiscard]] bool event_driven(BusProtocol p, std::uint32_t id, bool extended) noexcept;

/// What the monitor says about one id key (same order as `CanSnapshot::ids`).
struct IdVerdict {
  Traffic traffic = Traffic::Network;
  Nanos period_ns = -1;   ///< learned period (Periodic), else -1
  Nanos limit_ns = -1;    ///< learned silence limit (Periodic), else -1
  Nanos silence_ns = -1;  ///< observed - latest frame (Rx keys), else -1 (see "Silence")
  bool overdue = false;   ///< a periodic id silent beyond its own limit (information only)
};

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
  /// Observed (`CanReport::observed_ns`) - latest frame from it; -1 when none came.
  Nanos silence_ns = -1;
  Liveness liveness = Liveness::NeverSeen;
  Nanos silence_limit_ns = -1;  ///< the limit judged against; -1 when none applies
  bool limit_learned = false;   ///< the limit was learned (else configured)
  /// Index in `CanReport::snapshot.ids` of the id whose learned limit is the node's; -1 when
  /// none (configured, or not learned).
  std::ptrdiff_t limit_id = -1;
  std::uint64_t to_node_frames = 0;  ///< frames addressed to it (or sent to it, Tx)
  /// Age of the latest request to it not answered yet, at the observed time; -1: none.
  Nanos unanswered_ns = -1;
  NodeThresholds thresholds;  ///< as resolved for this node
  /// What its CANopen messages said (node map `canopen`, and its bus or group decodes CANopen).
  std::optional<canopen::NodeStats> canopen;
  /// What its DroneCAN NodeStatus said (node map `dronecan`, a bus decoding DroneCAN).
  std::optional<dronecan::NodeStats> dronecan;
  /// What its J1939 messages said: DM1 trouble codes and lamps, its address claim (node map
  /// `j1939`, a bus decoding J1939). An unnamed node with an address claim is named after it.
  std::optional<j1939::NodeStats> j1939;
  Status status;

  /// A node of the mapping (not the frames of no node).
  [[nodiscard]] bool is_node() const noexcept { return liveness != Liveness::NoNode; }
};

/// What the monitor says about one bus: its load, its controller's state (error frames, and
/// live through netlink when the bus names its interface).
struct BusReport {
  std::uint8_t bus = 0;
  /// Its bitrates, protocol and load thresholds; `config.settings.bitrate` is the interface's
  /// (netlink) when the configuration gives none (`bitrate_from_link`).
  ResolvedBus config;
  BusProtocolStats stats;  ///< from `CanSnapshot::protocol`
  /// The latest netlink reading of its interface (`buses.<bus>.interface`), if it has one.
  std::optional<LinkReading> link;
  /// The controller's state judged: the live one when netlink read it (`link`), else the one
  /// the error frames gave (`stats.controller.state`).
  ControllerState controller_state = ControllerState::Unknown;
  bool live_state = false;         ///< `controller_state` comes from netlink
  bool bitrate_from_link = false;  ///< the bitrate used for the load is the interface's
  /// The load judged: `config.load.figure` of the `config.load.stuffing` count, both directions
  /// (percent; NaN when the bitrate is not known).
  double judged_load = 0;
  Status status;  ///< load above its thresholds; error passive WARN, bus off ERROR
};

/// One monitor evaluation.
struct CanReport {
  Nanos time_ns = 0;  ///< the "now" the checks used
  /// The time silences are measured up to: `snapshot.observed_ns`, at most `time_ns` (`time_ns`
  /// when the snapshot does not say).
  Nanos observed_ns = 0;
  /// time_ns - observed_ns: how late the observation is (the CAN supervisor's delay, up to one
  /// of its periods when it is on time).
  Nanos observer_lag_ns = 0;
  NodeMapKind node_map = NodeMapKind::Identity;
  Status status;                  ///< overall (see the file comment)
  CanSnapshot snapshot;           ///< the statistics judged (ids, nodes, categories, totals)
  std::vector<IdVerdict> ids;     ///< one per `snapshot.ids`, same order
  std::vector<NodeReport> nodes;  ///< by bus, then node; never-seen any-bus nodes last
  std::vector<BusReport> buses;   ///< by bus: every bus a frame (or error frame) came from

  /// The report of bus `bus`, or null.
  [[nodiscard]] const BusReport* find_bus(std::uint8_t bus) const noexcept;

  /// Nodes counted (the "no node" rows excluded), and of them those OK and those learning.
  [[nodiscard]] std::size_t node_count() const noexcept;
  [[nodiscard]] std::size_t ok_count() const noexcept;
  [[nodiscard]] std::size_t learning_count() const noexcept;

  /// The report of (bus, node), or null. O(n).
  [[nodiscard]] const NodeReport* find(std::uint8_t bus, std::uint32_t node) const noexcept;
  /// The report of the node named `name`, or null. O(n).
  [[nodiscard]] const NodeReport* find(std::string_view name) const noexcept;
};

/// A custom per-node check: merge findings into `out` (the node's status).
using CanNodeCheck =
    std::function<void(const NodeReport& node, const CanReport& report, Status& out)>;

/// Options of a CAN monitor.
struct CanMonitorOptions {
  /// The overall status is Stale when the observation is older than this
  /// (`CanReport::observer_lag_ns`): the CAN supervisor stopped or is starved. 1 s: ten periods
  /// of the 10 Hz CAN supervisor, as the monitor's starvation rule for its own supervisor.
  /// 0: never.
  Nanos stale_after_ns = kNanosPerSecond;
};

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
  explicit CanMonitor(CanConfig config = {}, CanMonitorOptions options = {});

  /// Replaces the configuration (e.g. from a `config::Reloadable<CanConfig>` subscription);
  /// takes effect at the next `evaluate`. Thread-safe.
  void set_config(CanConfig config);
  /// Same, sharing an existing value. Null is ignored. Thread-safe.
  void set_config(std::shared_ptr<const CanConfig> config);
  /// The configuration in use. Thread-safe.
  [[nodiscard]] std::shared_ptr<const CanConfig> config() const;

  /// Adds a check run on every node after the built-in ones. Thread-safe.
  void add_check(std::string name, CanNodeCheck check);
  /// The latest live readings of the buses' interfaces (netlink; the CAN extension reads them
  /// at the monitor's pace), judged with every later evaluation: a bus with one is reported even
  /// before its first frame. Thread-safe.
  void set_links(std::vector<LinkReading> links);

  /// Takes a snapshot of `aggregator` (with the configuration's groups) and judges it at `now`
  /// (the clock of the sniffers' timestamps); silences are measured up to the snapshot's
  /// `observed_ns` (see "Silence" in the file comment). Thread-safe.
  [[nodiscard]] CanReport evaluate(const CanAggregator& aggregator, Nanos now) const;
  /// Judges `snapshot` at `now`. Its categories should come from `config()->group_specs()`.
  [[nodiscard]] CanReport evaluate(CanSnapshot snapshot, Nanos now) const;
  /// The options given at construction.
  [[nodiscard]] const CanMonitorOptions& options() const noexcept { return options_; }

 private:
  CanMonitorOptions options_;
  mutable std::mutex mutex_;
  std::shared_ptr<const CanConfig> config_;
  std::vector<std::pair<std::string, CanNodeCheck>> checks_;
  std::vector<LinkReading> links_;
};

}  // namespace vigil::can
