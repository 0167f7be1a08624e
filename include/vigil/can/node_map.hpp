#pragma once
/// @file
/// `NodeMap`: which node sent (or receives) a CAN frame, and what the frame is for, derived from
/// its identifier. CAN statistics are kept per (bus, node, direction), so every supervised frame
/// goes through one mapping:
///
/// | mapping  | node                         | function                                   |
/// | -------- | ---------------------------- | ------------------------------------------ |
/// | identity | the identifier itself        | 0                                          |
/// | canopen  | `id & 0x7F` (node-ID)        | `id >> 7` (function code: 3 = TPDO1, ...)  |
/// | j1939    | `id & 0xFF` (source address) | the PGN (PDU1: PS is a destination, not in the PGN)
/// | | user     | whatever a function returns  | whatever a function returns                |
///
/// A `NodeMap` is 24 bytes, trivially copyable, and `map()` is RT-safe: wait-free, no allocation,
/// no system call (a user function must be so too). The sniffer calls it on the I/O thread.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "vigil/can/frame.hpp"

namespace vigil::can {

/// What a mapping derives from an identifier.
struct NodeAddress {
  std::uint32_t node = 0;      ///< the node (CANopen node-ID, J1939 source address, ...)
  std::uint32_t function = 0;  ///< what the frame is (CANopen function code, J1939 PGN, ...)

  friend constexpr bool operator==(const NodeAddress&, const NodeAddress&) = default;
};

/// The kinds of mapping. The numeric values are stable (they appear in JSON as names only).
enum class NodeMapKind : std::uint8_t {
  Identity,  ///< node = identifier, function = 0
  CanOpen,   ///< CiA 301 pre-defined connection set: node = id & 0x7F, function = id >> 7
  J1939,     ///< SAE J1939-21: node = source address (id & 0xFF), function = PGN
  User,      ///< a user function
};

/// "identity", "canopen", "j1939", "user". RT-safe: yes.
[[nodiscard]] constexpr std::string_view to_string(NodeMapKind k) noexcept {
  switch (k) {
    case NodeMapKind::Identity:
      return "identity";
    case NodeMapKind::CanOpen:
      return "canopen";
    case NodeMapKind::J1939:
      return "j1939";
    case NodeMapKind::User:
      return "user";
  }
  return "?";
}

/// Parses "identity", "canopen" or "j1939" (exact spelling; "user" cannot be named in text).
/// RT-safe: yes.
[[nodiscard]] constexpr std::optional<NodeMapKind> parse_node_map_kind(
    std::string_view text) noexcept {
  if (text == "identity") return NodeMapKind::Identity;
  if (text == "canopen") return NodeMapKind::CanOpen;
  if (text == "j1939") return NodeMapKind::J1939;
  return std::nullopt;
}

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

/// A user mapping: gets the identifier and its format, returns the node and function. Must be
/// RT-safe (it runs on the CAN I/O thread for every frame) and must not throw.
using NodeMapFn = NodeAddress (*)(std::uint32_t id, bool extended, const void* ctx) noexcept;

/**
 * A mapping from identifiers to (node, function). A small value: copy it freely.
 *
 * @code
 * auto m = vigil::can::NodeMap::canopen();
 * m.map(0x18B, false)   // {node 11, function 3 (TPDO1)}
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
  /// node = id & 0x7F, function = id >> 7 (the CANopen function code for 11-bit ids).
  [[nodiscard]] static constexpr NodeMap canopen() noexcept {
    return NodeMap(NodeMapKind::CanOpen, nullptr, nullptr);
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
      case NodeMapKind::Identity:
      case NodeMapKind::User:
        break;
    }
    return identity();
  }

  /// The node and function of identifier `id`. RT-safe: yes (when a user function is).
  [[nodiscard]] constexpr NodeAddress map(std::uint32_t id, bool extended) const noexcept {
    switch (kind_) {
      case NodeMapKind::Identity:
        return {id, 0};
      case NodeMapKind::CanOpen:
        return {id & 0x7FU, id >> 7};
      case NodeMapKind::J1939:
        return {id & 0xFFU, decode_j1939(id).pgn};
      case NodeMapKind::User:
        return fn_(id, extended, ctx_);
    }
    return {id, 0};
  }
  /// Same, for a frame. RT-safe: yes (when a user function is).
  [[nodiscard]] constexpr NodeAddress map(const Frame& f) const noexcept {
    return map(f.id, f.extended);
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

/// A node for people, as the mapping numbers it: CANopen node-IDs in decimal ("11"), J1939
/// source addresses as two hex digits ("0x0B"), identities and user nodes in hex ("0x18B").
/// Not RT-safe (allocates).
[[nodiscard]] std::string format_node(NodeMapKind kind, std::uint32_t node);

/// A function for people: CANopen function codes by name ("TPDO1", "NMT error control"),
/// J1939 PGNs as "PGN 61444 (0xF004)", identity "-", user functions in hex. Not RT-safe.
[[nodiscard]] std::string format_function(NodeMapKind kind, std::uint32_t function);

}  // namespace vigil::can
