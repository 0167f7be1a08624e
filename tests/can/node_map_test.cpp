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

TEST_CASE("CANopen mapping: CiA 301's predefined connection set", "[can][node_map]") {
  using namespace vigil::can::canopen;
  using vigil::can::kNoNode;
  namespace flags = vigil::can::node_flags;
  constexpr NodeMap m = NodeMap::canopen();
  // Services of a node: from it, or addressed to it.
  STATIC_REQUIRE(m.map(0x18B, false) == NodeAddress{11, kTpdo1});  // TPDO1 of node 11
  CHECK(m.map(0x08B, false) == NodeAddress{11, kEmcy});            // EMCY of node 11
  CHECK(m.map(0x48B, false) == NodeAddress{11, kTpdo4});
  CHECK(m.map(0x20B, false) == NodeAddress{11, kRpdo1, kNoNode, flags::kToNode});
  CHECK(m.map(0x50B, false) == NodeAddress{11, kRpdo4, kNoNode, flags::kToNode});
  CHECK(m.map(0x60B, false) ==
        NodeAddress{11, kSdoRx, kNoNode, flags::kToNode | flags::kRequest});  // SDO request
  CHECK(m.map(0x58B, false) == NodeAddress{11, kSdoTx, kNoNode, flags::kResponse});
  CHECK(m.map(0x70B, false) == NodeAddress{11, kErrorControl});  // heartbeat of node 11
  CHECK(m.map(0x77F, false) == NodeAddress{127, kErrorControl});
  // A remote frame on 0x70B is node guarding: a request to node 11.
  CHECK(m.map(0x70B, false, true) ==
        NodeAddress{11, kErrorControl, kNoNode, flags::kToNode | flags::kRequest});
  // Services of the network: no node.
  CHECK(m.map(0x000, false) == NodeAddress{kNoNode, kNmt});
  CHECK(m.map(0x080, false) == NodeAddress{kNoNode, kSync});
  CHECK(m.map(0x100, false) == NodeAddress{kNoNode, kTime});
  CHECK(m.map(0x7E4, false) == NodeAddress{kNoNode, kLssResponse});
  CHECK(m.map(0x7E5, false) == NodeAddress{kNoNode, kLssRequest});
  // Outside the set: "other", no node and no function it does not have.
  for (const std::uint32_t id : {0x001U, 0x07FU, 0x101U, 0x17FU, 0x180U, 0x200U, 0x580U, 0x600U,
                                 0x680U, 0x6FFU, 0x700U, 0x780U, 0x7E3U, 0x7E6U, 0x7FFU}) {
    INFO(id);
    CHECK(m.map(id, false) == NodeAddress{kNoNode, kOther});
  }
  CHECK(m.map(0x18B, true) == NodeAddress{kNoNode, kOther});  // 29-bit: not CANopen
  CHECK(m.map(0x70B, false, true).request());
  CHECK(format_function(NodeMapKind::CanOpen, kTpdo1) == "TPDO1");
  CHECK(format_function(NodeMapKind::CanOpen, kErrorControl) == "NMT error control");
  CHECK(format_function(NodeMapKind::CanOpen, kSdoTx) == "SDO response");
  CHECK(format_function(NodeMapKind::CanOpen, kSync) == "SYNC");
  CHECK(format_function(NodeMapKind::CanOpen, kEmcy) == "EMCY");
  CHECK(format_function(NodeMapKind::CanOpen, kOther) == "other");
  CHECK(format_node(NodeMapKind::CanOpen, 11) == "11");
  CHECK(format_node(NodeMapKind::CanOpen, kNoNode) == "-");
}

TEST_CASE("DroneCAN mapping: messages, services, anonymous frames", "[can][node_map][dronecan]") {
  namespace dc = vigil::can::dronecan;
  namespace flags = vigil::can::node_flags;
  using vigil::can::kNoNode;
  constexpr NodeMap m = NodeMap::dronecan();
  // uavcan.protocol.NodeStatus (341) from node 10, priority 16.
  constexpr std::uint32_t status = dc::message_id(16, 341, 10);
  STATIC_REQUIRE(status == 0x1001550A);
  STATIC_REQUIRE(m.map(status, true) == NodeAddress{10, 341});
  constexpr auto d = dc::decode(status);
  STATIC_REQUIRE(!d.service && d.type_id == 341 && d.source == 10 && d.priority == 16);
  // esc.Status (1034) from ESC node 20.
  CHECK(m.map(dc::message_id(24, 1034, 20), true) == NodeAddress{20, 1034});
  // GetNodeInfo (service 1): request from 10 to 20, response from 20 to 10.
  const std::uint32_t req = dc::service_id(30, 1, true, 20, 10);
  const std::uint32_t resp = dc::service_id(30, 1, false, 10, 20);
  CHECK(req == 0x1E01948A);  // priority 30, service 1, request, to 20, service bit, from 10
  const auto rd = dc::decode(req);
  CHECK(rd.service);
  CHECK(rd.request);
  CHECK(rd.type_id == 1);
  CHECK(rd.destination == 20);
  CHECK(rd.source == 10);
  CHECK(m.map(req, true) == NodeAddress{10, dc::kService | 1, 20, flags::kRequest});
  CHECK(m.map(resp, true) == NodeAddress{20, dc::kService | 1, 10, flags::kResponse});
  // Anonymous message (source 0): no node.
  const std::uint32_t anon = (24U << 24) | (0x1234U << 10) | (1U << 8);
  CHECK(dc::decode(anon).anonymous);
  CHECK(dc::decode(anon).discriminator == 0x1234);
  CHECK(m.map(anon, true) == NodeAddress{kNoNode, dc::kAnonymous | 1});
  // 11-bit ids are not DroneCAN.
  CHECK(m.map(0x123, false) == NodeAddress{kNoNode, dc::kOther});
  CHECK(format_function(NodeMapKind::DroneCan, 341) == "341 NodeStatus");
  CHECK(format_function(NodeMapKind::DroneCan, 1034) == "1034 esc.Status");
  CHECK(format_function(NodeMapKind::DroneCan, dc::kService | 1) == "service 1 GetNodeInfo");
  CHECK(format_function(NodeMapKind::DroneCan, 20007) == "message 20007");
  CHECK(format_node(NodeMapKind::DroneCan, 20) == "20");
  CHECK(vigil::can::parse_node_map_kind("dronecan") == NodeMapKind::DroneCan);
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
