#pragma once
/// @file
/// What a CAN sniffer produces and how it is sized: the record it pushes for each accepted frame
/// (`FrameRecord`), its options, its exact counters and the entries of its two tables. The
/// sniffer itself is in sniffer.hpp.

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <variant>

#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// The timing of one accepted frame, as the sniffer pushes it to its port. Trivially copyable,
/// 64 bytes.
struct FrameRecord {
  /// The frame's time: its receive timestamp when the I/O gives one (SocketCAN: the kernel's or
  /// the controller's), else when the read/write call returned.
  Nanos time_ns = 0;
  Nanos io_ns = 0;              ///< time spent in the read/write call
  Nanos id_gap_ns = -1;         ///< since the previous frame of its id key; -1 if none
  Nanos node_gap_ns = -1;       ///< since the previous frame of (bus, node, direction); -1 if none
  std::uint64_t id_frames = 0;  ///< frames of its id key so far, this one included;
                                ///< 0 when the id is untracked
  std::uint32_t id = 0;         ///< identifier
  std::uint32_t node = 0;       ///< mapped node
  std::uint32_t function = 0;   ///< mapped function
  std::uint8_t bus = 0;         ///< bus index
  Direction direction = Direction::Rx;
  std::uint8_t length = 0;          ///< DLC or CAN FD length, as in `Frame`
  bool extended : 1 = false;        ///< 29-bit identifier
  bool rtr : 1 = false;             ///< remote frame
  bool fd : 1 = false;              ///< CAN FD frame
  bool id_untracked : 1 = false;    ///< the id table had no room for its key
  bool node_untracked : 1 = false;  ///< the node table had no room for its key
  bool brs : 1 = false;             ///< CAN FD bit rate switch (bus load: data bitrate)
  /// An error frame (SocketCAN's CAN_ERR_FLAG): `id` is its error class, `data` its details;
  /// no node, no timing (the CAN aggregator hands it to the protocol tracker only).
  bool error : 1 = false;
  std::array<std::uint8_t, 8> data{};  ///< the first min(8, data_size) data bytes, zero-padded
};
static_assert(std::is_trivially_copyable_v<FrameRecord> && sizeof(FrameRecord) == 64);

/// What a sniffer's port carries. A variant so that messages can be added without changing
/// the supervisor; today it has one alternative.
using CanMessage = std::variant<FrameRecord>;

/// Options of a sniffer (fixed at construction).
struct SnifferOptions {
  /// Id keys (bus, id, format, direction, data/remote/error) counted exactly; more are counted
  /// in `untracked_ids`.
  std::size_t max_ids = 1024;
  /// (bus, node, direction) keys counted exactly; more are counted in `untracked_nodes`.
  std::size_t max_nodes = 256;
  /// How identifiers map to nodes (for the node table, node filters and the statistics).
  NodeMap node_map = NodeMap::identity();
};

/// A sniffer's cumulative counters (exact). `frames` = `error_frames` + `rejected` + accepted.
/// Every accepted frame and every error frame gives one record: pushed, or counted in
/// `dropped` (error frames are pushed so that the CAN supervisor decodes the controller state).
struct SnifferTotals {
  std::uint64_t frames = 0;           ///< on_read/on_write calls
  std::uint64_t rx = 0;               ///< of which reads
  std::uint64_t tx = 0;               ///< of which writes
  std::uint64_t error_frames = 0;     ///< error frames (counted per bus and error class in the
                                      ///< id table; not filtered or pushed)
  std::uint64_t remote_frames = 0;    ///< accepted remote frames (RTR)
  std::uint64_t rejected = 0;         ///< refused by the filter
  std::uint64_t accepted = 0;         ///< passed the filter (each gives one record)
  std::uint64_t untracked_ids = 0;    ///< accepted, but no room in the id table
  std::uint64_t untracked_nodes = 0;  ///< accepted, but no room in the node table
  std::uint64_t dropped = 0;          ///< records the port dropped (full)
  std::uint64_t filter_changes = 0;   ///< set_filter/clear_filter calls
};

/// One id key of a sniffer's id table: (bus, id, format, direction), and whether its frames
/// are data, remote (RTR) or error frames: exact counts.
struct IdEntry {
  std::uint8_t bus = 0;
  std::uint32_t id = 0;  ///< identifier; the error class for error frames
  bool extended = false;
  bool rtr = false;    ///< remote frames of this id
  bool error = false;  ///< error frames of this error class
  Direction direction = Direction::Rx;
  std::uint32_t node = 0;        ///< mapped node (`kNoNode` for error frames)
  std::uint32_t function = 0;    ///< mapped function
  std::uint32_t peer = kNoNode;  ///< mapped peer
  std::uint8_t flags = 0;        ///< mapped `node_flags`
  std::uint64_t frames = 0;      ///< exact
  Nanos first_ns = 0;            ///< time of the first frame
  Nanos last_ns = 0;             ///< time of the latest frame
};

/// One (bus, node, direction) of a sniffer's node table: exact counts and liveness.
struct NodeEntry {
  std::uint8_t bus = 0;
  std::uint32_t node = 0;
  Direction direction = Direction::Rx;
  std::uint64_t frames = 0;         ///< exact
  std::uint64_t remote_frames = 0;  ///< of which remote frames (RTR), exact
  Nanos first_ns = 0;
  Nanos last_ns = 0;
};

}  // namespace vigil::can
