#pragma once
/// @file
/// Offline replay of CAN logs through the live pipeline (sniffer -> CAN supervisor -> CAN
/// aggregator -> CAN monitor), with the logs' timestamps as the clock: what `vigil can-stats`
/// runs (the export module prints it: vigil/export/can_report.hpp).
///
/// A replay feeds each frame to a real `Sniffer` with begin = end = the frame's timestamp and
/// steps the supervisor whenever the sniffer's port could be full, so nothing is dropped; the
/// aggregator keeps every gap (`exact_percentiles`) so that the figures printed for a log are
/// exact: frame counts, per-id and per-node gap min / median / max / mean. Several files are
/// merged in timestamp order.
///
/// Nothing here is RT-safe: it is tooling (file I/O, allocation).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/filter.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/log/reader.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::can {

/// The text format of a log file.
enum class LogFormat : std::uint8_t {
  Auto,     ///< `.trc` (any case) is a PEAK trace, anything else a candump log
  Candump,  ///< `candump -l` (candump.hpp)
  Trc,      ///< PEAK trace (trc.hpp)
};

/// Options of a replay.
struct ReplayOptions {
  NodeMap node_map = NodeMap::identity();       ///< how ids map to nodes
  FilterExpr filter{};                          ///< frames outside it are not supervised
  Direction default_direction = Direction::Rx;  ///< for log lines that carry none
  bool exact_percentiles = true;                ///< keep every gap: exact percentiles
  /// Id keys tracked (the sniffer's id table and the aggregator): frames of more distinct ids
  /// are counted as untracked, so memory stays bounded whatever the log holds.
  std::size_t max_ids = 8192;
  /// Node keys tracked, likewise.
  std::size_t max_nodes = 4096;
  ReaderOptions reader{};  ///< what the log readers do with bad lines
  /// Bitrates, protocols and event bounds of the protocol decoding (bus load, error frames,
  /// CANopen), as live: `CanConfig::protocol_options()`. A replay keeps up to 65536 events.
  ProtocolOptions protocol{.max_events = 65536};
};

/// What was read from one file.
struct ReplayFile {
  std::filesystem::path path;
  LogFormat format = LogFormat::Candump;  ///< as detected
  std::uint64_t frames = 0;               ///< frames read from it
  std::uint64_t malformed = 0;            ///< malformed lines skipped
  std::uint64_t skipped = 0;              ///< well-formed records that are not frames (TRC)
  std::vector<ParseError> errors;         ///< the first malformed lines
};

/**
 * A replay pipeline. Feed it frames (`feed`) or whole logs (`feed_files`), then ask for the
 * statistics or a monitor report at the log's last timestamp.
 *
 * Memory: the sniffer's tables (`max_ids`, `max_nodes`, about 100 bytes a key), about 200
 * bytes per tracked key in the aggregator, and 16 bytes per frame for the exact gaps; frames
 * of keys beyond the tables are counted (`untracked_ids`, `untracked_nodes`), not kept.
 *
 * @code
 * vigil::can::LogReplay replay({.node_map = vigil::can::NodeMap::j1939()});
 * if (auto r = replay.feed_files(std::vector<std::filesystem::path>{"truck.log"}); !r)
 * fail(r.error()); vigil::can::CanSnapshot s = replay.snapshot();
 * @endcode
 * Not thread-safe (one thread drives a replay).
 */
class LogReplay {
 public:
  /// Capacity of the replay sniffer's port; the supervisor is stepped before it can overflow.
  static constexpr std::size_t kPortCapacity = 4096;

  /// A pipeline with `options`. A filter that does not compile is ignored (accept-all):
  /// validate it first (`Filter::compile`, or `load_can_config`, which does).
  explicit LogReplay(ReplayOptions options = {});
  ~LogReplay();
  LogReplay(const LogReplay&) = delete;
  LogReplay& operator=(const LogReplay&) = delete;

  /// Feeds one frame, going in direction `d`, at `f.timestamp`.
  void feed(const Frame& f, Direction d);

  /// Reads `files` (merged by timestamp) and feeds every frame. Candump interface names become
  /// bus indices in order of first appearance over all files (`bus_names()`); TRC buses are
  /// named "bus1", "bus2"... Fails (with the file's name) when a file cannot be opened or read;
  /// malformed lines are skipped and reported in `files()` unless the reader options say Stop.
  [[nodiscard]] expected<void, Error> feed_files(std::span<const std::filesystem::path> files,
                                                 LogFormat format = LogFormat::Auto);

  /// Hands everything fed so far to the aggregator (the snapshot/report calls do it too).
  void flush();

  /// The statistics, with categories for `groups`.
  [[nodiscard]] CanSnapshot snapshot(std::span<const GroupSpec> groups = {});
  /// The monitor's report at `last_ns()` (the log's end). A replay without frames, or whose
  /// lines were all malformed, is a WARN that says so.
  [[nodiscard]] CanReport report(const CanMonitor& monitor);
  /// The monitor's report at `now` (on the log's clock), e.g. to judge a log while it is fed.
  /// Says that the log was read up to `now`: every frame before it has been fed, so silences
  /// are judged up to `now` (the live monitor judges up to what its supervisor has read).
  [[nodiscard]] CanReport report(const CanMonitor& monitor, Nanos now);

  /// Frames fed so far.
  [[nodiscard]] std::uint64_t frames() const noexcept;
  /// Earliest and latest timestamps fed (0 before the first frame).
  [[nodiscard]] Nanos first_ns() const noexcept;
  [[nodiscard]] Nanos last_ns() const noexcept;
  /// The files read by `feed_files`, in the order given.
  [[nodiscard]] const std::vector<ReplayFile>& files() const noexcept;
  /// Bus names by bus index (candump interfaces, TRC "busN").
  [[nodiscard]] const std::vector<std::string>& bus_names() const noexcept;
  /// The sniffer's exact counters.
  [[nodiscard]] SnifferTotals totals() const noexcept;
  /// The aggregator.
  [[nodiscard]] const CanAggregator& aggregator() const noexcept;

  struct Impl;  ///< defined in replay.cpp

 private:
  std::unique_ptr<Impl> impl_;
};

/// The format of `path` under `format` (Auto: by extension).
[[nodiscard]] LogFormat detect_log_format(const std::filesystem::path& path,
                                          LogFormat format = LogFormat::Auto);

/// "candump" or "trc" ("auto" for Auto).
[[nodiscard]] std::string_view to_string(LogFormat f) noexcept;

}  // namespace vigil::can
