#pragma once
/// @file
/// `CanAggregator`: the CAN supervisor's handler. It turns the sniffers' records and tables into
/// statistics per (bus, id, direction), per (bus, node, direction) and per category (all nodes,
/// and user groups such as "left arm" = nodes 11-14), and hands out consistent snapshots.
///
/// Where each figure comes from:
///  - frames, first and last time seen (liveness): the sniffers' RT-side tables, read once per
///    supervisor cycle: exact whatever the port dropped;
///  - timing (`CompactRunningStats`: count, min, max, mean, EWMA, percentiles) of the time
///    spent in the read/write call and of the gaps between consecutive frames: the records
///    drained from the ports. Each gap is measured exactly on the RT side (from the table's
///    last-seen time), so a dropped record removes a sample but never distorts one; `records`
///    says how many samples arrived, and `frames - records` how many were lost to a full port;
///  - categories and groups: the node statistics of their members merged
///    (`CompactRunningStats::merge`): a group's gap distribution is that of its nodes' gaps, not
///    the gap between any two frames.
///
/// Percentiles have `RunningStats`' bounded error (< 2^-5, upper bound). For offline replay,
/// `CanAggregatorOptions::exact_percentiles` keeps every gap instead of histograms, so that the
/// snapshot's gap percentiles are exact (min, max and mean are always exact).
///
/// Memory is bounded: at most `max_ids` id keys and `max_nodes` node keys are aggregated (a
/// record whose key the sniffer's table could not hold, or that finds the aggregator full, is
/// counted, not aggregated). A key costs about 1 KB live (its two distributions keep the buckets
/// of the range seen only, `CompactRunningStats`: ~0.5 KB inline, 256 bytes of counters per
/// power of two of values seen), about 0.5 KB in exact mode plus 8 bytes per gap (16 per frame:
/// its id's and its node's).
///
/// Design: the supervisor thread is the only writer. One mutex guards the statistics; the
/// supervisor holds it while it applies one port's batch (begin .. end) and a reader while it
/// builds a snapshot. Keys are few (ids and nodes of a bus), so snapshots copy summaries, not
/// histograms. Not RT-safe (supervisor and reader threads only).

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "vigil/bus/registry.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/can/protocol.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#include "vigil/supervisor/running_stats.hpp"

namespace vigil::can {

/// A set of nodes whose statistics are also reported together (and whose thresholds the CAN
/// monitor applies to each member). Membership: on `bus` (any bus when empty), node in `nodes`
/// or in one of `node_ranges`.
struct GroupSpec {
  std::string name{};                  ///< e.g. "left_arm"
  std::optional<std::uint8_t> bus{};   ///< empty: nodes on any bus
  std::vector<std::uint32_t> nodes{};  ///< explicit members
  /// Inclusive ranges of members, e.g. {11, 14}.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> node_ranges{};

  /// Whether node `node` on bus `bus` belongs to the group. O(members).
  [[nodiscard]] bool contains(std::uint8_t bus_index, std::uint32_t node) const noexcept;
};

/// Statistics of one id key: (bus, id, format, direction), data, remote (RTR) or error frames.
struct IdStats {
  std::uint8_t bus = 0;
  std::uint32_t id = 0;  ///< identifier; the error class for error frames
  bool extended = false;
  bool rtr = false;    ///< the remote frames (RTR) of this id
  bool error = false;  ///< the error frames of this error class (no node, no timing)
  Direction direction = Direction::Rx;
  std::uint32_t node = 0;        ///< mapped node (`kNoNode`: none)
  std::uint32_t function = 0;    ///< mapped function
  std::uint32_t peer = kNoNode;  ///< mapped peer (e.g. a DroneCAN service's destination)
  std::uint8_t flags = 0;        ///< mapped `node_flags` (to the node, request, response)

  /// A request (an SDO request, a remote frame, a DroneCAN service request).
  [[nodiscard]] bool request() const noexcept { return (flags & node_flags::kRequest) != 0; }
  std::uint64_t frames = 0;      ///< exact when `exact_count`, else the records received
  bool exact_count = true;       ///< false when the sniffer's id table had no room for it
  Nanos first_ns = 0;            ///< first frame (exact when `exact_count`)
  Nanos last_ns = 0;             ///< latest frame (exact when `exact_count`)
  std::uint64_t records = 0;     ///< timing records received (frames - records were dropped)
  StatsSummary io_ns;            ///< time spent in the read/write call
  StatsSummary gap_ns;           ///< time between consecutive frames of this id
  bool gap_exact = false;        ///< gap percentiles are exact (exact_percentiles)
  std::uint8_t last_length = 0;  ///< length of the latest record's frame
  std::array<std::uint8_t, 8> last_data{};  ///< its first 8 data bytes
};

/// Statistics of one (bus, node, direction): the original's per-node metrics and more.
struct NodeStats {
  std::uint8_t bus = 0;
  std::uint32_t node = 0;
  Direction direction = Direction::Rx;
  std::uint64_t frames = 0;         ///< exact when `exact_count` (messages in or out)
  std::uint64_t remote_frames = 0;  ///< of which remote frames (RTR)
  bool exact_count = true;          ///< false when the sniffer's node table had no room for it
  Nanos first_ns = 0;               ///< first frame
  Nanos last_ns = 0;                ///< latest frame (liveness)
  std::uint64_t records = 0;        ///< timing records received
  std::size_t ids = 0;              ///< distinct identifiers seen for this node and direction
  StatsSummary io_ns;               ///< time spent reading (Rx) or writing (Tx)
  StatsSummary gap_ns;     ///< time between consecutive frames from (Rx) / to (Tx) the node
  bool gap_exact = false;  ///< gap percentiles are exact (exact_percentiles)
};

/// One row of the summary table: every node ("all"), or a group, in one direction.
struct CategoryStats {
  std::string name;  ///< "all" or the group's name
  bool group = false;
  Direction direction = Direction::Rx;
  std::size_t nodes = 0;            ///< member nodes with frames in this direction (not kNoNode)
  std::uint64_t frames = 0;         ///< sum over the members
  std::uint64_t remote_frames = 0;  ///< sum over the members
  std::uint64_t records = 0;        ///< sum over the members
  Nanos last_ns = 0;                ///< latest frame of any member
  StatsSummary io_ns;               ///< the members' I/O times, merged
  StatsSummary gap_ns;              ///< the members' gaps, merged
};

/// What the aggregator knows about one sniffer.
struct SnifferInfo {
  std::uint32_t port_id = 0;
  std::string name;
  bool alive = true;  ///< false once the sniffer left
  NodeMapKind node_map = NodeMapKind::Identity;
  std::string filter;  ///< the current filter as text
  SnifferTotals totals;
  std::size_t ids = 0;  ///< keys in its id table
  std::size_t max_ids = 0;
  std::size_t nodes = 0;  ///< keys in its node table
  std::size_t max_nodes = 0;
  std::size_t port_capacity = 0;
  /// Start of the latest supervisor cycle that read its tables: every frame it handled before
  /// then is counted (supervisor clock, the frames' clock). -1 before the first.
  Nanos observed_ns = -1;
  /// Start of the latest supervisor cycle whose drain emptied its port: every record it pushed
  /// before then is aggregated. -1 before the first.
  Nanos drained_ns = -1;
};

/// Everything the aggregator knows at one moment. Plain values: copy freely.
struct CanSnapshot {
  std::uint64_t cycle = 0;    ///< supervisor cycles applied so far
  std::uint64_t records = 0;  ///< timing records aggregated so far
  /// Records not aggregated per id / per node: their key was untracked by the sniffer, or the
  /// aggregator held `max_ids` / `max_nodes` keys already.
  std::uint64_t unaggregated_id_records = 0;
  std::uint64_t unaggregated_node_records = 0;
  std::size_t max_ids = 0;    ///< the aggregator's id keys at most
  std::size_t max_nodes = 0;  ///< the aggregator's node keys at most
  /// The time up to which every live sniffer's frames are counted in the tables: the earliest
  /// `SnifferInfo::observed_ns` of the live sniffers (the liveness of exact keys is judged up
  /// to it). -1 when unknown (no cycle yet, or every sniffer left: nothing more can come).
  Nanos observed_ns = -1;
  /// The time up to which every live sniffer's records are aggregated: the earliest
  /// `SnifferInfo::drained_ns` (the liveness of keys the tables could not hold is judged up to
  /// it). -1 when unknown.
  Nanos drained_ns = -1;
  SnifferTotals totals;               ///< summed over every sniffer seen
  std::vector<SnifferInfo> sniffers;  ///< by port id
  std::vector<IdStats> ids;           ///< by bus, id, format, direction, error, remote
  std::vector<NodeStats> nodes;       ///< by bus, node, direction
  /// "all" Rx then Tx, then each group Rx then Tx (groups in the order given). Rows without
  /// frames are left out, except one (Rx) row for a group that has none at all.
  std::vector<CategoryStats> categories;
  /// What the frames themselves said: bus load, controller state (error frames), CANopen
  /// (vigil/can/protocol.hpp). Decoded on the CAN supervisor's thread from the records.
  ProtocolSnapshot protocol;
  /// Error frames the CAN supervisor decoded (their records).
  std::uint64_t error_records = 0;

  /// The node's statistics, or null. O(log n).
  [[nodiscard]] const NodeStats* find_node(std::uint8_t bus, std::uint32_t node,
                                           Direction d) const noexcept;
  /// The statistics of the id's data frames (remote frames: `rtr`), or null. O(log n).
  [[nodiscard]] const IdStats* find_id(std::uint8_t bus, std::uint32_t id, bool extended,
                                       Direction d, bool rtr = false) const noexcept;
};

/// One gap distribution as the aggregator holds it, handed to a visitor of
/// `CanAggregator::visit_gap_distributions` (e.g. to reduce it to Prometheus buckets). Valid
/// only during the visitor's call.
struct GapDistribution {
  std::string_view group;  ///< a group's name; empty for a node
  std::uint8_t bus = 0;    ///< a node's bus (0 for a group)
  std::uint32_t node = 0;  ///< a node's number (`kNoNode`: the frames of no node; 0 for a group)
  Direction direction = Direction::Rx;
  /// Live: the gaps' statistics with their histogram. Null in exact mode.
  const supervisor::CompactRunningStats* stats = nullptr;
  /// Exact mode: every gap, in no particular order (min, max, sum are exact). Empty live.
  std::span<const Nanos> samples{};

  /// Gaps in the distribution.
  [[nodiscard]] std::uint64_t count() const noexcept {
    return stats != nullptr ? stats->count() : samples.size();
  }
};

/// Options of the aggregator.
struct CanAggregatorOptions {
  /// Keep every gap sample so that gap percentiles are exact (offline replay: memory grows by
  /// 16 bytes per frame; no histograms, and no I/O-time percentiles). Live supervision leaves it
  /// off: percentiles within 2^-5.
  bool exact_percentiles = false;
  /// Id keys aggregated at most (records of more are counted in `unaggregated_id_records`).
  std::size_t max_ids = 8192;
  /// Node keys aggregated at most (records of more: `unaggregated_node_records`).
  std::size_t max_nodes = 4096;
  /// Weight of the newest sample in the EWMAs (0 < w <= 1).
  double ewma_weight = supervisor::RunningStats::kDefaultEwmaWeight;
  /// Bitrates, protocols and bounds of the protocol decoding (`CanConfig::protocol_options`).
  ProtocolOptions protocol{};
};

/**
 * The handler of `DrainLoop<CanMessage, CanAggregator>` (alias `CanDrainLoop`).
 *
 * @code
 * vigil::can::CanRegistry can;
 * vigil::can::Sniffer<> sniffer(can, "bus0");
 * vigil::can::CanAggregator stats(can);
 * vigil::can::CanDrainLoop supervisor(can.ports(), stats, {.period_ns = 100 *
 * vigil::kNanosPerMilli}); supervisor.start();                     // or supervisor.step() from
 * your own loop vigil::can::CanSnapshot s = stats.snapshot(groups);
 * @endcode
 *
 * Handler members: supervisor thread only. `snapshot`, `cycles`: any thread.
 */
class CanAggregator {
 public:
  using Entry = bus::RegistryEntry<CanMessage>;

  /// Reads sniffer states from `registry`, which must outlive the aggregator.
  explicit CanAggregator(CanRegistry& registry, CanAggregatorOptions options = {});
  ~CanAggregator();
  CanAggregator(const CanAggregator&) = delete;
  CanAggregator& operator=(const CanAggregator&) = delete;

  // --- SupervisorHandler (supervisor thread only; called by CanDrainLoop::step) ---
  /// A sniffer's port appeared: starts its record (its state is looked up in the registry).
  void on_join(const Entry& e);
  /// A sniffer left and was drained: reads its tables one last time, releases its state.
  void on_leave(const Entry& e);
  /// Starts applying one port's batch (takes the statistics lock until `end`).
  void begin(const Entry& e);
  /// Adds one record's timing to its id and node. O(1) amortised (hash lookups).
  void on(const Entry& e, const FrameRecord& r);
  /// Ends the batch: reads the sniffer's tables (exact counts), frees replaced filters.
  void end(const Entry& e, const supervisor::PortDrain& d);
  /// Counts supervisor cycles, then calls the cycle hook (`set_cycle_hook`), if any.
  void on_cycle(const supervisor::DrainCycle& c);
  /// The supervisor's thread wakes at the earlier of its next period and this time (monotonic
  /// clock, `wake_at`) for one more cycle; INT64_MAX when none is asked.
  [[nodiscard]] Nanos next_deadline() const noexcept;

  // --- what leaves at the drain's pace (set before the supervisor starts) ---
  /// Called at the end of every supervisor cycle (after the cycle's records and tables are
  /// applied, outside the statistics lock), on the supervisor's thread or `step()`'s caller:
  /// what must not wait for a monitor cycle (CAN events, `deploy::CanExtension`). It may call
  /// the readers below and `wake_at`. Set it before the supervisor starts; exceptions it throws
  /// are caught and counted (`hook_failures`).
  void set_cycle_hook(std::function<void(const supervisor::DrainCycle&)> hook);
  /// Asks for a cycle at `time_ns` (monotonic clock), e.g. when a node's silence limit passes;
  /// replaces the previous request. INT64_MAX: none. Any thread.
  void wake_at(Nanos time_ns) noexcept;
  /// Exceptions the cycle hook threw so far. Any thread.
  [[nodiscard]] std::uint64_t hook_failures() const noexcept;

  // --- readers (any thread) ---
  /// A consistent copy of every statistic, with categories for "all" and for `groups`.
  /// O(ids + nodes * (1 + groups)) plus sorting the gaps in exact mode. Allocates.
  [[nodiscard]] CanSnapshot snapshot(std::span<const GroupSpec> groups = {}) const;
  /// Supervisor cycles applied so far.
  [[nodiscard]] std::uint64_t cycles() const;
  /// Calls `visit` with every node's gap distribution (each (bus, node, direction) with at
  /// least one record), then, for each of `groups` and each direction, the merged gaps of its
  /// members (`GroupSpec::contains`, the frames of no node excluded) when they have any. Holds
  /// the statistics lock during the visit, so the distributions are consistent with each other
  /// (the supervisor waits meanwhile: keep `visit` short, e.g. a bucket reduction). A group
  /// costs one merge of its members' histograms (live) or one copy of their gaps (exact).
  /// Allocates; any non-RT thread; `visit` must not call back into the aggregator.
  void visit_gap_distributions(std::span<const GroupSpec> groups,
                               const std::function<void(const GapDistribution&)>& visit) const;
  /// Replaces the protocol decoding's configuration (bitrates, protocols); counts are kept.
  /// Any thread.
  void set_protocol_options(ProtocolOptions options);
  /// Protocol events (NMT states, resets, emergencies, NMT commands, controller states) with a
  /// sequence number above `after`, oldest first; at most `ProtocolOptions::max_events` are
  /// kept. Any thread.
  [[nodiscard]] std::vector<ProtocolEvent> protocol_events_after(std::uint64_t after) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

static_assert(supervisor::SupervisorHandler<CanAggregator, CanMessage>);

/// The CAN supervisor: drains the sniffers' ports into a `CanAggregator`.
using CanDrainLoop = supervisor::DrainLoop<CanMessage, CanAggregator>;

/// Exact nearest-rank percentiles of `samples` (reordered in place: the ranks are selected with
/// std::nth_element, not sorted): count, min, max, mean, p50, p90, p99, p99.9, with the same
/// rank rule as `RunningStats` (smallest sample with at least q * count samples <= it); `last`
/// and `ewma` are 0. Not RT-safe.
[[nodiscard]] StatsSummary exact_summary(std::vector<Nanos>& samples);

}  // namespace vigil::can
