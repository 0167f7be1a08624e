#pragma once
/// @file
/// `NodeMap`: which node a CAN frame belongs to, and what the frame is for, derived from its
/// identifier. CAN statistics are kept per (bus, node, direction), so every supervised frame goes
/// through one mapping:
///
/// | mapping  | node                                   | function                              |
/// | -------- | -------------------------------------- | ------------------------------------- |
/// | identity | the identifier itself                  | 0                                     |
/// | canopen  | the node-ID of CiA 301's predefined connection set (NMT, SYNC, TIME, LSS and ids
/// outside the set: no node) | `canopen::Function` | | j1939    | `id & 0xFF` (source address) |
/// the PGN (PDU1: PS is a destination, not in the PGN) | | dronecan | the source node ID
/// (anonymous: no node) | data type ID, with the service bits (`dronecan::kService`, `kRequest`) |
/// | user     | whatever a function returns            | whatever a function returns           |
///
/// Beside the node and function, a mapping says how the node takes part (`NodeAddress::flags`):
/// whether the frame comes from the node or is addressed to it (`kToNode`: CANopen RPDOs and SDO
/// requests), and whether it is a request (`kRequest`: SDO requests, DroneCAN service requests,
/// every remote frame) or the answer to one (`kResponse`: SDO responses, DroneCAN service
/// responses). The CAN monitor judges a node's liveness from the frames that come from it, and
/// does not expect answers when nobody asks (docs/guide/can-supervision.md).
///
/// A `NodeMap` is 24 bytes, trivially copyable, and `map()` is RT-safe: wait-free, no allocation,
/// no system call (a user function must be so too). The sniffer calls it on the I/O thread.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "vigil/can/frame.hpp"

namespace vigil::can {

/// The node of frames that belong to no node (CANopen NMT, SYNC, TIME, LSS, ids outside the
/// predefined connection set; DroneCAN anonymous messages; error frames).
inline constexpr std::uint32_t kNoNode = 0xFFFFFFFFU;

/// How the node of a frame takes part in it (`NodeAddress::flags`, bits).
namespace node_flags {
inline constexpr std::uint8_t kToNode = 1;    ///< addressed to the node (it did not send it)
inline constexpr std::uint8_t kRequest = 2;   ///< asks for an answer (SDO request, RTR, ...)
inline constexpr std::uint8_t kResponse = 4;  ///< answers a request (SDO response, ...)
}  // namespace node_flags

/// What a mapping derives from an identifier.
struct NodeAddress {
  std::uint32_t node = 0;        ///< the node (CANopen node-ID, J1939 source address, ...)
  std::uint32_t function = 0;    ///< what the frame is (CANopen function, J1939 PGN, ...)
  std::uint32_t peer = kNoNode;  ///< the other node, when the id names one (DroneCAN services)
  std::uint8_t flags = 0;        ///< `node_flags` bits; 0: a frame the node sent on its own

  /// Addressed to `node` rather than sent by it.
  [[nodiscard]] constexpr bool to_node() const noexcept {
    return (flags & node_flags::kToNode) != 0;
  }
  /// A request (the node asked is `to_node() ? node : peer`).
  [[nodiscard]] constexpr bool request() const noexcept {
    return (flags & node_flags::kRequest) != 0;
  }
  /// An answer to a request.
  [[nodiscard]] constexpr bool response() const noexcept {
    return (flags & node_flags::kResponse) != 0;
  }

  friend constexpr bool operator==(const NodeAddress&, const NodeAddress&) = default;
};

/// The kinds of mapping. The numeric values are stable (they appear in JSON as names only).
enum class NodeMapKind : std::uint8_t {
  Identity,  ///< node = identifier, function = 0
  CanOpen,   ///< CiA 301 predefined connection set
  J1939,     ///< SAE J1939-21: node = source address (id & 0xFF), function = PGN
  User,      ///< a user function
  DroneCan,  ///< DroneCAN / UAVCAN v0: node = source node ID, function = data type ID
};

/// "identity", "canopen", "j1939", "dronecan", "user". RT-safe: yes.
[[nodiscard]] constexpr std::string_view to_string(NodeMapKind k) noexcept {
  switch (k) {
    case NodeMapKind::Identity:
      return "identity";
    case NodeMapKind::CanOpen:
      return "canopen";
    case NodeMapKind::J1939:
      return "j1939";
    case NodeMapKind::DroneCan:
      return "dronecan";
    case NodeMapKind::User:
      return "user";
  }
  return "?";
}

/// Parses "identity", "canopen", "j1939" or "dronecan" (exact spelling; "user" cannot be named
/// in text). RT-safe: yes.
[[nodiscard]] constexpr std::optional<NodeMapKind> parse_node_map_kind(
    std::string_view text) noexcept {
  if (text == "identity") return NodeMapKind::Identity;
  if (text == "canopen") return NodeMapKind::CanOpen;
  if (text == "j1939") return NodeMapKind::J1939;
  if (text == "dronecan") return NodeMapKind::DroneCan;
  return std::nullopt;
}

/// CANopen (CiA 301) predefined connection set.
namespace canopen {

/// The function of a CANopen identifier. Node services keep their function code (`id >> 7`);
/// services of the network (no node) have codes of their own.
enum Function : std::uint32_t {
  kNmt = 0,            ///< 0x000: NMT node control (network)
  kEmcy = 1,           ///< 0x081-0x0FF: emergency of node n
  kTime = 2,           ///< 0x100: TIME (network)
  kTpdo1 = 3,          ///< 0x181-0x1FF
  kRpdo1 = 4,          ///< 0x201-0x27F (to the node)
  kTpdo2 = 5,          ///< 0x281-0x2FF
  kRpdo2 = 6,          ///< 0x301-0x37F
  kTpdo3 = 7,          ///< 0x381-0x3FF
  kRpdo3 = 8,          ///< 0x401-0x47F
  kTpdo4 = 9,          ///< 0x481-0x4FF
  kRpdo4 = 10,         ///< 0x501-0x57F
  kSdoTx = 11,         ///< 0x581-0x5FF: SDO server -> client (the node's answers)
  kSdoRx = 12,         ///< 0x601-0x67F: SDO client -> server (requests to the node)
  kErrorControl = 14,  ///< 0x701-0x77F: heartbeat, boot-up, node guarding
  kSync = 16,          ///< 0x080: SYNC (network)
  kLssResponse = 17,   ///< 0x7E4: LSS slave -> master (network)
  kLssRequest = 18,    ///< 0x7E5: LSS master -> slave (network)
  kOther = 0xFFFF,     ///< outside the predefined connection set (and every 29-bit id)
};

/// The CANopen node and function of an identifier. RT-safe: yes.
[[nodiscard]] constexpr NodeAddress map(std::uint32_t id, bool extended) noexcept {
  using namespace node_flags;
  if (extended || id > kMaxStandardId) return {kNoNode, kOther};
  const std::uint32_t code = id >> 7;
  const std::uint32_t node = id & 0x7FU;
  switch (id) {
    case 0x000:
      return {kNoNode, kNmt};
    case 0x080:
      return {kNoNode, kSync};
    case 0x100:
      return {kNoNode, kTime};
    case 0x7E4:
      return {kNoNode, kLssResponse};
    case 0x7E5:
      return {kNoNode, kLssRequest};
    default:
      break;
  }
  if (node == 0) return {kNoNode, kOther};  // node-IDs are 1..127
  switch (code) {
    case kEmcy:
    case kTpdo1:
    case kTpdo2:
    case kTpdo3:
    case kTpdo4:
    case kErrorControl:
      return {node, code};
    case kRpdo1:
    case kRpdo2:
    case kRpdo3:
    case kRpdo4:
      return {node, code, kNoNode, kToNode};
    case kSdoTx:
      return {node, code, kNoNode, kResponse};
    case kSdoRx:
      return {node, code, kNoNode, static_cast<std::uint8_t>(kToNode | kRequest)};
    default:
      return {kNoNode, kOther};  // 0x001-0x07F, 0x101-0x17F, 0x680-0x6FF, 0x780-0x7FF
  }
}

}  // namespace canopen

/// DroneCAN / UAVCAN v0 (29-bit identifiers, DroneCAN specification "CAN bus transport layer").
namespace dronecan {

/// `NodeAddress::function` bit of service frames (the low 8 bits are the service type ID).
inline constexpr std::uint32_t kService = 0x10000;
/// `NodeAddress::function` bit of anonymous messages (the low 2 bits are the type ID's).
inline constexpr std::uint32_t kAnonymous = 0x20000;
/// `NodeAddress::function` of 11-bit identifiers, which DroneCAN does not use.
inline constexpr std::uint32_t kOther = 0xFFFFFFFFU;

/// The fields of a DroneCAN identifier.
struct Id {
  std::uint8_t priority = 0;        ///< bits 24-28 (0 highest)
  bool service = false;             ///< bit 7: service frame, else message frame
  bool request = false;             ///< service frames: bit 15, request (else response)
  std::uint16_t type_id = 0;        ///< message type ID (16 bits), service type ID (8 bits)
  std::uint8_t source = 0;          ///< bits 0-6; 0 in an anonymous message
  std::uint8_t destination = 0;     ///< service frames: bits 8-14
  bool anonymous = false;           ///< message frame with source node ID 0
  std::uint16_t discriminator = 0;  ///< anonymous messages: bits 10-23

  friend constexpr bool operator==(const Id&, const Id&) = default;
};

/// Splits a DroneCAN identifier. Bits above 28 are ignored. RT-safe: yes.
[[nodiscard]] constexpr Id decode(std::uint32_t id) noexcept {
  Id d;
  d.priority = static_cast<std::uint8_t>((id >> 24) & 0x1F);
  d.service = ((id >> 7) & 1U) != 0;
  d.source = static_cast<std::uint8_t>(id & 0x7F);
  if (d.service) {
    d.type_id = static_cast<std::uint16_t>((id >> 16) & 0xFF);
    d.request = ((id >> 15) & 1U) != 0;
    d.destination = static_cast<std::uint8_t>((id >> 8) & 0x7F);
  } else if (d.source == 0) {
    d.anonymous = true;
    d.type_id = static_cast<std::uint16_t>((id >> 8) & 0x3);
    d.discriminator = static_cast<std::uint16_t>((id >> 10) & 0x3FFF);
  } else {
    d.type_id = static_cast<std::uint16_t>((id >> 8) & 0xFFFF);
  }
  return d;
}

/// A message identifier: `priority`, `type_id`, `source` (1..127). RT-safe: yes.
[[nodiscard]] constexpr std::uint32_t message_id(std::uint8_t priority, std::uint16_t type_id,
                                                 std::uint8_t source) noexcept {
  return (std::uint32_t{priority} & 0x1F) << 24 | std::uint32_t{type_id} << 8 |
         (std::uint32_t{source} & 0x7F);
}

/// A service identifier (request or response) from `source` to `destination`. RT-safe: yes.
[[nodiscard]] constexpr std::uint32_t service_id(std::uint8_t priority, std::uint8_t type_id,
                                                 bool request, std::uint8_t destination,
                                                 std::uint8_t source) noexcept {
  return (std::uint32_t{priority} & 0x1F) << 24 | std::uint32_t{type_id} << 16 |
         std::uint32_t{request} << 15 | (std::uint32_t{destination} & 0x7F) << 8 | 0x80U |
         (std::uint32_t{source} & 0x7F);
}

/// The DroneCAN node and function of an identifier: node = source node ID (anonymous
/// messages: no node), peer = the destination of a service frame, flags kRequest / kResponse on
/// service frames. 11-bit identifiers are not DroneCAN: no node. RT-safe: yes.
[[nodiscard]] constexpr NodeAddress map(std::uint32_t id, bool extended) noexcept {
  if (!extended || id > kMaxExtendedId) return {kNoNode, kOther};
  const Id d = decode(id);
  if (d.service) {
    return {d.source, kService | d.type_id, d.destination,
            d.request ? node_flags::kRequest : node_flags::kResponse};
  }
  if (d.anonymous) return {kNoNode, kAnonymous | d.type_id};
  return {d.source, d.type_id};
}

}  // namespace dronecan

/// The fields of a 29-bit SAE J1939 identifier (J1939-21 §5.2).
struct J1939Id {
  std::uint8_t priority = 0;      ///< bits 26-28
  bool edp = false;               ///< extended data page, bit 25
  bool dp = false;                ///< data page, bit 24
  std::uint8_t pdu_format = 0;    ///< PF, bits 16-23
  std::uint8_t pdu_specific = 0;  ///< PS, bits 8-15: destination (PDU1) or group extension
  std::uint8_t source = 0;        ///< SA, bits 0-7
  std::uint32_t pgn = 0;          ///< parameter group number (18 bits)
  std::uint8_t destination = 0;   ///< PS for PDU1; 0xFF (global) for PDU2
  [[nodiscard]] constexpr bool pdu1() const noexcept { return pdu_format < 240; }

  friend constexpr bool operator==(const J1939Id&, const J1939Id&) = default;
};

/**
 * Splits a J1939 identifier. PDU1 format (PF < 240) is addressed: PS is the destination address
 * and is not part of the PGN (PGN = EDP, DP, PF, 0x00). PDU2 format (PF >= 240) is broadcast: PS
 * is the group extension and is part of the PGN; the destination is global (0xFF).
 *
 * @code
 * decode_j1939(0x0CF00400)  // priority 3, PGN 0xF004 (61444, EEC1), source 0x00
 * decode_j1939(0x18EA0021)  // priority 6, PGN 0xEA00 (request), destination 0x00, source 0x21
 * @endcode
 * Bits above 28 are ignored. RT-safe: yes.
 */
[[nodiscard]] constexpr J1939Id decode_j1939(std::uint32_t id) noexcept {
  J1939Id j;
  j.priority = static_cast<std::uint8_t>((id >> 26) & 0x7);
  j.edp = ((id >> 25) & 1U) != 0;
  j.dp = ((id >> 24) & 1U) != 0;
  j.pdu_format = static_cast<std::uint8_t>((id >> 16) & 0xFF);
  j.pdu_specific = static_cast<std::uint8_t>((id >> 8) & 0xFF);
  j.source = static_cast<std::uint8_t>(id & 0xFF);
  const std::uint32_t page = (id >> 24) & 0x3;  // EDP, DP
  if (j.pdu1()) {
    j.pgn = (page << 16) | (std::uint32_t{j.pdu_format} << 8);
    j.destination = j.pdu_specific;
  } else {
    j.pgn = (page << 16) | (std::uint32_t{j.pdu_format} << 8) | j.pdu_specific;
    j.destination = 0xFF;
  }
  return j;
}

/// A user mapping: gets the identifier and its format, returns the node and function (and, if it
/// wants, the peer and flags). Must be RT-safe (it runs on the CAN I/O thread for every frame)
/// and must not throw.
using NodeMapFn = NodeAddress (*)(std::uint32_t id, bool extended, const void* ctx) noexcept;

/**
 * A mapping from identifiers to (node, function). A small value: copy it freely.
 *
 * @code
 * auto m = vigil::can::NodeMap::canopen();
 * m.map(0x18B, false)   // {node 11, function 3 (TPDO1)}
 * m.map(0x60B, false)   // {node 11, function 12 (SDO request), flags kToNode | kRequest}
 * auto j = vigil::can::NodeMap::j1939();
 * j.map(0x18FEF121, true)  // {node 0x21, function 0xFEF1 (65265)}
 * auto u = vigil::can::NodeMap::user(
 *     [](std::uint32_t id, bool, const void*) noexcept { return NodeAddress{id >> 4, id & 0xF}; });
 * @endcode
 */
class NodeMap {
 public:
  /// The identity mapping (the default).
  constexpr NodeMap() noexcept = default;

  /// node = identifier, function = 0.
  [[nodiscard]] static constexpr NodeMap identity() noexcept { return NodeMap(); }
  /// CiA 301's predefined connection set (see `canopen::map`).
  [[nodiscard]] static constexpr NodeMap canopen() noexcept {
    return NodeMap(NodeMapKind::CanOpen, nullptr, nullptr);
  }
  /// DroneCAN / UAVCAN v0 (see `dronecan::map`).
  [[nodiscard]] static constexpr NodeMap dronecan() noexcept {
    return NodeMap(NodeMapKind::DroneCan, nullptr, nullptr);
  }
  /// node = source address, function = PGN (see `decode_j1939`).
  [[nodiscard]] static constexpr NodeMap j1939() noexcept {
    return NodeMap(NodeMapKind::J1939, nullptr, nullptr);
  }
  /// A user function with a context pointer passed back to it (may be null). A null `fn`
  /// gives the identity mapping.
  [[nodiscard]] static constexpr NodeMap user(NodeMapFn fn, const void* ctx = nullptr) noexcept {
    return fn == nullptr ? NodeMap() : NodeMap(NodeMapKind::User, fn, ctx);
  }
  /// The built-in mapping of that kind; `User` gives the identity (it needs a function).
  [[nodiscard]] static constexpr NodeMap of(NodeMapKind kind) noexcept {
    switch (kind) {
      case NodeMapKind::CanOpen:
        return canopen();
      case NodeMapKind::J1939:
        return j1939();
      case NodeMapKind::DroneCan:
        return dronecan();
      case NodeMapKind::Identity:
      case NodeMapKind::User:
        break;
    }
    return identity();
  }

  /// The node and function of a data frame with identifier `id`. RT-safe: yes (when a user
  /// function is).
  [[nodiscard]] constexpr NodeAddress map(std::uint32_t id, bool extended) const noexcept {
    switch (kind_) {
      case NodeMapKind::Identity:
        return {id, 0};
      case NodeMapKind::CanOpen:
        return canopen::map(id, extended);
      case NodeMapKind::J1939:
        return {id & 0xFFU, decode_j1939(id).pgn};
      case NodeMapKind::DroneCan:
        return dronecan::map(id, extended);
      case NodeMapKind::User:
        return fn_(id, extended, ctx_);
    }
    return {id, 0};
  }
  /// Same, for a data or remote frame: a remote frame (RTR) asks the id's node for its data, so
  /// it is a request addressed to that node. RT-safe: yes (when a user function is).
  [[nodiscard]] constexpr NodeAddress map(std::uint32_t id, bool extended,
                                          bool remote) const noexcept {
    NodeAddress a = map(id, extended);
    if (remote && a.node != kNoNode) {
      a.flags = node_flags::kToNode | node_flags::kRequest;
      a.peer = kNoNode;
    }
    return a;
  }
  /// Same, for a frame. RT-safe: yes (when a user function is).
  [[nodiscard]] constexpr NodeAddress map(const Frame& f) const noexcept {
    return map(f.id, f.extended, f.rtr);
  }

  /// Which mapping this is.
  [[nodiscard]] constexpr NodeMapKind kind() const noexcept { return kind_; }

 private:
  constexpr NodeMap(NodeMapKind kind, NodeMapFn fn, const void* ctx) noexcept
      : kind_(kind), fn_(fn), ctx_(ctx) {}

  NodeMapKind kind_ = NodeMapKind::Identity;
  NodeMapFn fn_ = nullptr;
  const void* ctx_ = nullptr;
};

/// A node for people, as the mapping numbers it: CANopen and DroneCAN node-IDs in decimal
/// ("11"), J1939 source addresses as two hex digits ("0x0B"), identities and user nodes in hex
/// ("0x18B"), `kNoNode` as "-". Not RT-safe (allocates).
[[nodiscard]] std::string format_node(NodeMapKind kind, std::uint32_t node);

/// A function for people: CANopen functions by name ("TPDO1", "SDO response", "heartbeat",
/// "other"), J1939 PGNs as "PGN 61444 (0xF004)", DroneCAN data types by ID and, for the
/// standard ones, name ("341 NodeStatus", "service 1 GetNodeInfo"), identity "-", user
/// functions in hex. Not RT-safe.
[[nodiscard]] std::string format_function(NodeMapKind kind, std::uint32_t function);

}  // namespace vigil::can
