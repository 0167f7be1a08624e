#pragma once
// Generators of CAN captures shaped like real buses, for the tests of the CAN monitor's
// judgement (learned deadlines, request/response traffic, protocol maps). Each generator is
// deterministic (seeded jitter) and returns the frames of a passive capture (every frame Rx, as
// `candump -l` on the bus records it), sorted by time.
//
//  - canopen_capture: a CANopen network (CiA 301): NMT start, SYNC every 100 ms, heartbeats every
//    1.4 s, TPDOs (one node's every 10 ms; one that goes quiet for minutes), an EMCY, SDO
//    request/response bursts, a node supervised by node guarding (RTR requests answered with a
//    toggle bit) instead of a heartbeat;
//  - dronecan_capture: a DroneCAN (UAVCAN v0) drone: a flight controller broadcasting NodeStatus
//    and esc.RawCommand, four ESCs answering with esc.Status and NodeStatus, GetNodeInfo
//    request/response pairs whose responses are multi-frame transfers (tail bytes, toggles,
//    transfer CRC);
//  - j1939_capture: a truck's J1939 bus: engine (EEC1 every 20 ms, ET1 every 1 s), brakes (EBC1
//    every 100 ms), body controller (CCVS every 100 ms).
// Each can make one node stop at a given time (it sends nothing, answers nothing afterwards),
// while the others (and the requests to the stopped node) go on.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/log/reader.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can::test {

/// Capture start: 2023-11-14 22:13:20 UTC, as a real log's epoch timestamps.
inline constexpr Nanos kCaptureStart = 1'700'000'000 * kNanosPerSecond;

/// A node that stops at `at` (from the capture's start).
struct NodeStop {
  std::uint32_t node = 0;
  Nanos at = 0;
};

/// A CANopen network: nodes 1-4 produce heartbeats, node 5 is guarded.
struct CanOpenBus {
  Nanos duration = 5 * 60 * kNanosPerSecond;
  Nanos heartbeat = 1400 * kNanosPerMilli;  ///< producer heartbeat time of nodes 1-4
  Nanos guard_time = kNanosPerSecond;       ///< node guarding period of node 5
  std::optional<NodeStop> stop{};
  std::uint64_t seed = 1;
};

/// A DroneCAN drone: flight controller node 10, ESCs 20-23.
struct DroneCanBus {
  Nanos duration = 3 * 60 * kNanosPerSecond;
  std::optional<NodeStop> stop{};
  std::uint64_t seed = 2;
};

/// A J1939 truck: engine 0x00, brakes 0x0B, body controller 0x21.
struct J1939Bus {
  Nanos duration = 5 * 60 * kNanosPerSecond;
  std::optional<NodeStop> stop{};
  std::uint64_t seed = 3;
};

[[nodiscard]] std::vector<LogEntry> canopen_capture(const CanOpenBus& bus);
[[nodiscard]] std::vector<LogEntry> dronecan_capture(const DroneCanBus& bus);
[[nodiscard]] std::vector<LogEntry> j1939_capture(const J1939Bus& bus);

/// The capture as a `candump -l` log (interface `can0`), for the command-line tests.
[[nodiscard]] std::string to_candump(const std::vector<LogEntry>& entries);

/// The time of the last frame `node` sent (as `from` tells), or -1.
using FromNode = bool (*)(const Frame& f, std::uint32_t node);
[[nodiscard]] Nanos last_frame_of(const std::vector<LogEntry>& entries, std::uint32_t node,
                                  FromNode from);

/// `from` predicates for `last_frame_of`: CANopen (TPDO, EMCY, SDO response, heartbeat and
/// guarding answers of the node), DroneCAN (source node ID), J1939 (source address).
[[nodiscard]] bool canopen_from(const Frame& f, std::uint32_t node);
[[nodiscard]] bool dronecan_from(const Frame& f, std::uint32_t node);
[[nodiscard]] bool j1939_from(const Frame& f, std::uint32_t node);

}  // namespace vigil::can::test
