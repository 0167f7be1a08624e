#include "vigil/can/node_map.hpp"

#include <catch2/catch.hpp>

using vigil::can::decode_j1939;
using vigil::can::format_function;
using vigil::can::format_node;
using vigil::can::NodeAddress;
using vigil::can::NodeMap;
using vigil::can::NodeMapKind;

TEST_CASE("Identity mapping: the node is the identifier", "[can][node_map]") {
  constexpr NodeMap m;
  STATIC_REQUIRE(m.kind() == NodeMapKind::Identity);
  STATIC_REQUIRE(m.map(0x123, false) == NodeAddress{0x123, 0});
  CHECK(m.map(0x18FEF121, true) == NodeAddress{0x18FEF121, 0});
  CHECK(NodeMap::of(NodeMapKind::User).kind() == NodeMapKind::Identity);
}

TEST_CASE("CANopen mapping: node-ID in the low 7 bits, function code above", "[can][node_map]") {
  constexpr NodeMap m = NodeMap::canopen();
  STATIC_REQUIRE(m.map(0x18B, false) == NodeAddress{11, 3});  // TPDO1 of node 11
  CHECK(m.map(0x60B, false) == NodeAddress{11, 12});          // RSDO to node 11
  CHECK(m.map(0x58B, false) == NodeAddress{11, 11});          // TSDO from node 11
  CHECK(m.map(0x70B, false) == NodeAddress{11, 14});          // heartbeat of node 11
  CHECK(m.map(0x000, false) == NodeAddress{0, 0});            // NMT
  CHECK(m.map(0x080, false) == NodeAddress{0, 1});            // SYNC
  CHECK(m.map(0x7FF, false) == NodeAddress{0x7F, 15});
  CHECK(format_function(NodeMapKind::CanOpen, 3) == "TPDO1");
  CHECK(format_function(NodeMapKind::CanOpen, 14) == "NMT error control");
  CHECK(format_node(NodeMapKind::CanOpen, 11) == "11");
}

TEST_CASE("J1939 decoding: PDU2 broadcast puts PS in the PGN", "[can][node_map][j1939]") {
  // 0x0CF00400: priority 3, PF 0xF0 (>= 240: PDU2), PS 0x04 (group extension), SA 0x00: EEC1.
  constexpr auto j = decode_j1939(0x0CF00400);
  STATIC_REQUIRE(j.priority == 3);
  STATIC_REQUIRE(!j.pdu1());
  STATIC_REQUIRE(j.pgn == 0xF004);  // 61444
  STATIC_REQUIRE(j.source == 0x00);
  STATIC_REQUIRE(j.destination == 0xFF);
  const auto ccvs = decode_j1939(0x18FEF121);
  CHECK(ccvs.priority == 6);
  CHECK(ccvs.pgn == 65265);  // CCVS
  CHECK(ccvs.source == 0x21);
}

TEST_CASE("J1939 decoding: PDU1 addressed frames keep PS out of the PGN",
          "[can][node_map][j1939]") {
  // 0x18EA0021: request (PF 0xEA = 234 < 240), destination 0x00, from 0x21.
  const auto req = decode_j1939(0x18EA0021);
  CHECK(req.pdu1());
  CHECK(req.pdu_format == 0xEA);
  CHECK(req.pgn == 0xEA00);
  CHECK(req.destination == 0x00);
  CHECK(req.source == 0x21);
  // The same request to another destination has the same PGN.
  CHECK(decode_j1939(0x18EAFF21).pgn == 0xEA00);
  CHECK(decode_j1939(0x18EAFF21).destination == 0xFF);
  // Data page and extended data page are bits 17 and 16 of the PGN.
  CHECK(decode_j1939(0x19FEF121).pgn == 0x1FEF1);
  CHECK(decode_j1939(0x1BFEF121).pgn == 0x3FEF1);
  CHECK(decode_j1939(0x1BFEF121).edp);
  // TP.CM (PF 0xEC), PDU1.
  CHECK(decode_j1939(0x1CECFF00).pgn == 0xEC00);
}

TEST_CASE("J1939 mapping: node = source address, function = PGN", "[can][node_map][j1939]") {
  constexpr NodeMap m = NodeMap::j1939();
  STATIC_REQUIRE(m.map(0x0CF00400, true) == NodeAddress{0x00, 61444});
  CHECK(m.map(0x18FEF121, true) == NodeAddress{0x21, 65265});
  CHECK(m.map(0x18FEFA0B, true) == NodeAddress{0x0B, 0xFEFA});
  CHECK(m.map(0x18EA0021, true) == NodeAddress{0x21, 0xEA00});
  CHECK(format_node(NodeMapKind::J1939, 0x0B) == "0x0B");
  CHECK(format_function(NodeMapKind::J1939, 61444) == "PGN 61444 (0xF004)");
}

namespace {
struct Offset {
  std::uint32_t base;
};
NodeAddress by_block(std::uint32_t id, bool extended, const void* ctx) noexcept {
  const auto* o = static_cast<const Offset*>(ctx);
  return {(id - o->base) >> 4, extended ? 1U : 0U};
}
}  // namespace

TEST_CASE("User mapping: a function with a context", "[can][node_map]") {
  const Offset offset{0x100};
  const NodeMap m = NodeMap::user(&by_block, &offset);
  CHECK(m.kind() == NodeMapKind::User);
  CHECK(m.map(0x123, false) == NodeAddress{2, 0});
  CHECK(m.map(0x15F, true) == NodeAddress{5, 1});
  CHECK(NodeMap::user(nullptr).kind() == NodeMapKind::Identity);
  CHECK(format_node(NodeMapKind::User, 0x2A) == "0x2A");
}

TEST_CASE("Node map names parse and print", "[can][node_map]") {
  CHECK(vigil::can::parse_node_map_kind("canopen") == NodeMapKind::CanOpen);
  CHECK(vigil::can::parse_node_map_kind("j1939") == NodeMapKind::J1939);
  CHECK(vigil::can::parse_node_map_kind("identity") == NodeMapKind::Identity);
  CHECK_FALSE(vigil::can::parse_node_map_kind("CANopen").has_value());
  CHECK_FALSE(vigil::can::parse_node_map_kind("user").has_value());
  CHECK(vigil::can::to_string(NodeMapKind::J1939) == "j1939");
}
