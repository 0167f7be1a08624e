// SAE J1939 in the protocol tracker: DM1 trouble codes (J1939-73) single frame and through the
// transport protocol (J1939-21, BAM and RTS/CTS), address claims (J1939-81), malformed input,
// bounds, and the same findings live and in replay. Every expected value below was computed by
// hand from the byte layouts the specifications give (see the comments).
#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "can_stats.hpp"  // apps/vigil: the can-stats command
#include "can_test_support.hpp"
#include "support/shared_data.hpp"
#include "vigil/can/can_config.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/can/log/candump.hpp"
#include "vigil/can/protocol.hpp"
#include "vigil/can/replay.hpp"
#include "vigil/export/can_report.hpp"
#include "vigil/supervisor/events.hpp"

using namespace vigil::can;
using vigil::kNanosPerMilli;
using vigil::kNanosPerSecond;
using vigil::Nanos;
using vigil::StatusLevel;

namespace {

constexpr const char* kTruckLog = "can/j1939_truck_candump-2022-03-29.log";

std::filesystem::path dm1_log() {
  return std::filesystem::path(VIGIL_CAN_TEST_DATA_DIR) / "j1939_dm1.log";
}

std::filesystem::path dm2_log() {
  return std::filesystem::path(VIGIL_CAN_TEST_DATA_DIR) / "j1939_dm2.log";
}

Frame ext(std::uint32_t id, std::initializer_list<std::uint8_t> data, Nanos t) {
  Frame f = Frame::classic(id, data, IdFormat::Extended);
  f.timestamp = t;
  return f;
}

std::vector<std::string> event_lines(const ProtocolSnapshot& s) {
  std::vector<std::string> out;
  for (const ProtocolEvent& e : s.recent_events) {
    constexpr const char* kHex = "0123456789ABCDEF";
    out.push_back(std::string(to_string(e.kind)) + " 0x" + kHex[(e.node >> 4) & 0xF] +
                  kHex[e.node & 0xF] + " " + std::to_string(e.severity));
  }
  return out;
}

ProtocolSnapshot replay_dm1_log(ProtocolOptions o = {},
                                const std::filesystem::path& log = dm1_log()) {
  LogReplay replay({.node_map = NodeMap::j1939(), .protocol = std::move(o)});
  const std::vector<std::filesystem::path> files{log};
  REQUIRE(replay.feed_files(files).has_value());
  return replay.snapshot().protocol;
}

}  // namespace

TEST_CASE("J1939 DM1: lamps and DTCs decoded from hand-computed payloads", "[can][j1939]") {
  std::string error;
  // Lamps 0x04: MIL 00 off, red stop 00 off, amber warning 01 on, protect 00 off. DTC 64 00 01
  // 03: SPN 0x64 = 100, FMI 1, CM 0, 3 occurrences; FF FF padding.
  const std::vector<std::uint8_t> single{0x04, 0xFF, 0x64, 0x00, 0x01, 0x03, 0xFF, 0xFF};
  auto d = j1939::decode_dm1(single, true, error);
  REQUIRE(d.has_value());
  CHECK(d->lamps.mil == j1939::Lamp::Off);
  CHECK(d->lamps.red_stop == j1939::Lamp::Off);
  CHECK(d->lamps.amber_warning == j1939::Lamp::On);
  CHECK(d->lamps.protect == j1939::Lamp::Off);
  REQUIRE(d->dtcs.size() == 1);
  CHECK(d->dtcs[0] == j1939::Dtc{.spn = 100, .fmi = 1, .occurrences = 3});
  CHECK(d->dtcs[0].describe() ==
        "SPN 100 FMI 1 (data valid but below normal operational range - most severe level), 3 "
        "occurrences");
  // A 19-bit SPN: A5 A5 AC FF = SPN 0xA5 | 0xA5 << 8 | (0xAC >> 5 = 5) << 16 = 0x5A5A5 =
  // 370085, FMI 0xAC & 0x1F = 12, CM 1, occurrence count 127 (not available). Red stop lamp
  // (bits 6-5 of 0x10 = 01) on. Then SPN 110 FMI 0 x5, SPN 0x7029E (459422) FMI 3 x2.
  const std::vector<std::uint8_t> multi{0x10, 0xFF, 0xA5, 0xA5, 0xAC, 0xFF, 0x6E,
                                        0x00, 0x00, 0x05, 0x9E, 0x02, 0xE3, 0x02};
  d = j1939::decode_dm1(multi, false, error);
  REQUIRE(d.has_value());
  CHECK(d->lamps.red_stop == j1939::Lamp::On);
  REQUIRE(d->dtcs.size() == 3);
  CHECK(d->dtcs[0] ==
        j1939::Dtc{.spn = 370085, .fmi = 12, .occurrences = 127, .conversion_method = true});
  CHECK(d->dtcs[1] == j1939::Dtc{.spn = 110, .fmi = 0, .occurrences = 5});
  CHECK(d->dtcs[2] == j1939::Dtc{.spn = 459422, .fmi = 3, .occurrences = 2});
  // No DTC: all zeros (J1939-73), or all ones.
  d = j1939::decode_dm1(std::vector<std::uint8_t>{0, 0xFF, 0, 0, 0, 0, 0xFF, 0xFF}, true, error);
  REQUIRE(d.has_value());
  CHECK(d->dtcs.empty());
  CHECK(d->lamps.any_on() == false);
  // Malformed: short, a multi-packet length that is not 2 + 4n.
  CHECK_FALSE(
      j1939::decode_dm1(std::vector<std::uint8_t>{0, 0xFF, 0, 0, 0}, true, error).has_value());
  CHECK(error == "DM1 of 5 bytes (at least 6: lamps and one DTC)");
  CHECK_FALSE(j1939::decode_dm1(std::vector<std::uint8_t>(13, 0), false, error).has_value());
  CHECK(error == "DM1 of 13 bytes (2 + 4 per DTC expected)");
  CHECK(j1939::fmi_name(31) == "condition exists");
  CHECK(j1939::fmi_name(25) == "reserved");
}

TEST_CASE("J1939 DM2: previously active DTCs decoded like DM1, named DM2 in errors",
          "[can][j1939][dm2]") {
  std::string error;
  // Lamps 0x44: MIL 01 on (bits 8-7), amber warning 01 on (bits 4-3). DTC 00 F0 EE 01: SPN
  // 0x00 | 0xF0 << 8 | (0xEE >> 5 = 7) << 16 = 0x7F000 = 520192, FMI 0xEE & 0x1F = 14, CM 0,
  // 1 occurrence. DTC 21 06 1F FE: SPN 0x621 = 1569, FMI 31, CM 1, 126 occurrences.
  const std::vector<std::uint8_t> two{0x44, 0xFF, 0x00, 0xF0, 0xEE, 0x01, 0x21, 0x06, 0x1F, 0xFE};
  const auto d = j1939::decode_dm2(two, false, error);
  REQUIRE(d.has_value());
  CHECK(d->lamps.mil == j1939::Lamp::On);
  CHECK(d->lamps.amber_warning == j1939::Lamp::On);
  CHECK(d->lamps.red_stop == j1939::Lamp::Off);
  REQUIRE(d->dtcs.size() == 2);
  CHECK(d->dtcs[0] == j1939::Dtc{.spn = 520192, .fmi = 14, .occurrences = 1});
  CHECK(d->dtcs[1] ==
        j1939::Dtc{.spn = 1569, .fmi = 31, .occurrences = 126, .conversion_method = true});
  CHECK_FALSE(j1939::decode_dm2(std::vector<std::uint8_t>{0, 0xFF, 0, 0}, true, error).has_value());
  CHECK(error == "DM2 of 4 bytes (at least 6: lamps and one DTC)");
  CHECK_FALSE(j1939::decode_dm2(std::vector<std::uint8_t>(9, 0), false, error).has_value());
  CHECK(error == "DM2 of 9 bytes (2 + 4 per DTC expected)");
}

// tests/can/data/j1939_dm2.log, line by line:
//   0.000 single-frame DM2 of 0x00: lamps off, DTC BE 00 02 07 = SPN 190 FMI 2 x7;
//   0.100 single-frame DM1 of 0x00: amber warning lamp, SPN 100 FMI 1 x3 (active);
//   0.200-0.300 BAM of 0x0B: a 14-byte DM2 (TP.CM 20 0E 00 02 FF CB FE 00: 14 bytes, 2
//   packets, PGN 0x00FECB) with lamps 0x44 and DTCs 00 F0 EE 01 (SPN 520192 FMI 14 x1), 64 00
//   01 03 (SPN 100 FMI 1 x3), 21 06 1F FE (SPN 1569 FMI 31 x126, CM 1);
//   0.400-0.440 RTS/CTS from 0x21 to 0xF9: a 10-byte DM2 (lamps 0x10, SPN 110 FMI 0 x5, SPN
//   190 FMI 2 x1), CTS for 2 packets from 1, EndOfMsgAck;
//   1.000 DM2 of 0x00 without DTC (all zeros): its list empties, with no event;
//   2.000 a DM2 of 4 bytes from 0x0B: malformed, its list stays.
TEST_CASE("J1939 DM2 through a single frame, BAM and RTS/CTS: per node, no events",
          "[can][j1939][dm2]") {
  const ProtocolSnapshot s = replay_dm1_log({}, dm2_log());
  // Only the DM1's code is an event: DM2 lists the past.
  CHECK(event_lines(s) == std::vector<std::string>{"dtc_active 0x00 1"});
  const j1939::NodeStats* engine = s.find_j1939(0, 0x00);
  REQUIRE(engine != nullptr);
  CHECK(engine->dm2s == 2);
  CHECK(engine->last_dm2_ns == 1700000001 * kNanosPerSecond);
  CHECK(engine->previously_active.empty());  // the latest DM2 has none
  CHECK(engine->dm1s == 1);
  REQUIRE(engine->active.size() == 1);  // DM1 and DM2 are kept apart
  CHECK(engine->active[0] == j1939::Dtc{.spn = 100, .fmi = 1, .occurrences = 3});
  const j1939::NodeStats* brakes = s.find_j1939(0, 0x0B);
  REQUIRE(brakes != nullptr);
  CHECK(brakes->dm2s == 1);
  CHECK(brakes->dm1s == 0);
  CHECK(brakes->active.empty());
  CHECK(brakes->dm2_lamps.mil == j1939::Lamp::On);
  CHECK(brakes->dm2_lamps.amber_warning == j1939::Lamp::On);
  CHECK(brakes->previously_active ==
        std::vector<j1939::Dtc>{
            {.spn = 520192, .fmi = 14, .occurrences = 1},
            {.spn = 100, .fmi = 1, .occurrences = 3},
            {.spn = 1569, .fmi = 31, .occurrences = 126, .conversion_method = true}});
  CHECK(brakes->tp_messages == 1);
  CHECK(brakes->malformed == 1);
  CHECK(brakes->last_malformed == "DM2 of 4 bytes (at least 6: lamps and one DTC)");
  const j1939::NodeStats* body = s.find_j1939(0, 0x21);
  REQUIRE(body != nullptr);
  CHECK(body->previously_active ==
        std::vector<j1939::Dtc>{{.spn = 110, .fmi = 0, .occurrences = 5},
                                {.spn = 190, .fmi = 2, .occurrences = 1}});
  CHECK(body->tp_messages == 1);
  CHECK(body->malformed == 0);
  CHECK(s.find_j1939(0, 0xF9) == nullptr);
  CHECK(s.tp_sessions_open == 0);

  // Bounded like the active codes: `max_dtcs`, the rest counted.
  const ProtocolSnapshot b = replay_dm1_log({.max_dtcs = 2}, dm2_log());
  CHECK(b.find_j1939(0, 0x0B)->previously_active.size() == 2);
  CHECK(b.find_j1939(0, 0x0B)->previously_active_untracked == 1);
  CHECK(b.find_j1939(0, 0x21)->previously_active_untracked == 0);

  // A DM2 does not judge the node: 0x21 has previously active codes only and stays OK.
  LogReplay replay({.node_map = NodeMap::j1939()});
  const std::vector<std::filesystem::path> files{dm2_log()};
  REQUIRE(replay.feed_files(files).has_value());
  CanConfig cfg;
  cfg.node_map = NodeMapKind::J1939;
  const CanReport r = replay.report(CanMonitor(cfg), replay.last_ns());
  const NodeReport* rbody = r.find(0, 0x21);
  REQUIRE(rbody != nullptr);
  CHECK(rbody->status.summary().find("DTC") == std::string::npos);
  CHECK(r.find(0, 0x00)->status.summary().find("active DTC") != std::string::npos);  // DM1's
}

TEST_CASE("vigil can-stats reports J1939 DM2 previously active codes, text and JSON",
          "[can][j1939][dm2][replay]") {
  vigil::app::CanStatsOptions o;
  o.files = {dm2_log()};
  o.node_map = NodeMapKind::J1939;
  std::ostringstream out;
  std::ostringstream err;
  CHECK(vigil::app::run_can_stats(o, out, err) == 0);
  const std::string text = out.str();
  CHECK(text.find("J1939: 1 node with DM1, 1 active DTC (1 appeared), 5 previously active (DM2 "
                  "from 3 nodes), 0 address claims") != std::string::npos);
  CHECK(text.find("PREVIOUSLY ACTIVE DTCS") != std::string::npos);
  CHECK(text.find("SPN 520192 FMI 14 x1, SPN 100 FMI 1 x3, SPN 1569 FMI 31 x126") !=
        std::string::npos);
  o.json = true;
  std::ostringstream jout;
  CHECK(vigil::app::run_can_stats(o, jout, err) == 0);
  const std::string json = jout.str();
  CHECK(json.find("\"previously_active_dtcs\": 5") != std::string::npos);
  CHECK(json.find("\"dm2s\": 2") != std::string::npos);
  CHECK(json.find("\"previously_active_dtcs\": [") != std::string::npos);
  CHECK(json.find("\"spn\": 1569") != std::string::npos);
}

TEST_CASE("J1939 NAME of an address claim decoded field by field", "[can][j1939]") {
  // identity 0x12345, manufacturer 0x123, ECU instance 1, function instance 2, function 0,
  // vehicle system 3, its instance 4, industry group 1, arbitrary address capable: bytes
  // 45 23 61 24 (0x24612345 = 0x12345 | 0x123 << 21), 0x11 (1 | 2 << 3), 0x00, 0x06 (3 << 1),
  // 0x94 (4 | 1 << 4 | 1 << 7).
  const std::array<std::uint8_t, 8> b{0x45, 0x23, 0x61, 0x24, 0x11, 0x00, 0x06, 0x94};
  const j1939::Name n = j1939::decode_name(b);
  CHECK(n.raw == 0x9406001124612345ULL);
  CHECK(n.identity == 0x12345);
  CHECK(n.manufacturer == 0x123);
  CHECK(n.ecu_instance == 1);
  CHECK(n.function_instance == 2);
  CHECK(n.function == 0);
  CHECK(n.vehicle_system == 3);
  CHECK(n.vehicle_system_instance == 4);
  CHECK(n.industry_group == 1);
  CHECK(n.arbitrary_address);
  CHECK(n.label() == "engine #2");
  CHECK(n.describe() ==
        "engine #2, function instance 2, ECU instance 1, manufacturer 291, identity 74565, "
        "industry group 1 (on-highway), vehicle system 3 instance 4, arbitrary address capable");
  CHECK(j1939::function_name(9) == "brakes - system controller");
  CHECK(j1939::function_name(200).empty());
}

// tests/can/data/j1939_dm1.log, line by line:
//   0.000 address claim of 0x00 (the NAME above), 0.010 of 0x0B (identity 77, manufacturer
//   0x2AB, function 9 "brakes - system controller", vehicle system 2, industry group 1);
//   0.100 single-frame DM1 of 0x00: amber warning lamp, SPN 100 FMI 1 x3;
//   0.200-0.300 BAM of 0x0B: the 14-byte DM1 above (red stop lamp, 3 DTCs) in 2 packets;
//   0.400-0.440 RTS/CTS from 0x00 to 0xF9: a 10-byte DM1 (SPN 100 FMI 1 x4, SPN 190 FMI 2 x1),
//   CTS for 2 packets from 1, EndOfMsgAck;
//   1.000 DM1 of 0x00 without DTC: both codes cleared;
//   then the bad input of 0x21: 2.000 a DM1 of 5 bytes; 2.100 BAM of a 13-byte DM1 (odd) and
//   a 3rd packet of 2; 3.000 BAM whose 2nd packet comes at 4.000 (T1 timed out, then a packet
//   without a session); 5.000 BAM then packet 2 first (sequence gap); 6.000 BAM, packet 1, a new
//   BAM at 6.100 (interleaved), never completed (timed out at 7.000); 7.000 a good DM1.
TEST_CASE("J1939 DM1 through single frames, BAM and RTS/CTS: codes appear and clear as events",
          "[can][j1939]") {
  const ProtocolSnapshot s = replay_dm1_log();
  CHECK(event_lines(s) == std::vector<std::string>{
                              "address_claim 0x00 0",
                              "address_claim 0x0B 0",
                              "dtc_active 0x00 1",
                              "dtc_active 0x0B 2",
                              "dtc_active 0x0B 2",
                              "dtc_active 0x0B 2",
                              "dtc_active 0x00 1",
                              "dtc_cleared 0x00 0",
                              "dtc_cleared 0x00 0",
                          });
  CHECK(s.recent_events[3].detail ==
        "SPN 370085 FMI 12 (bad intelligent device or component), occurrence count n/a, SPN "
        "conversion method 1 (decoded as version 4); lamps: MIL off, red stop on, amber warning "
        "off, protect off");
  CHECK(s.recent_events[6].detail.rfind("SPN 190 FMI 2 (data erratic", 0) == 0);
  const j1939::NodeStats* engine = s.find_j1939(0, 0x00);
  REQUIRE(engine != nullptr);
  REQUIRE(engine->name.has_value());
  CHECK(engine->name->identity == 0x12345);
  CHECK(engine->dm1s == 3);
  CHECK(engine->active.empty());
  CHECK(engine->dtcs_appeared == 2);
  CHECK(engine->dtcs_cleared == 2);
  CHECK(engine->tp_messages == 1);  // the RTS/CTS one
  CHECK(engine->malformed == 0);
  const j1939::NodeStats* brakes = s.find_j1939(0, 0x0B);
  REQUIRE(brakes != nullptr);
  CHECK(brakes->name->function == 9);
  CHECK(brakes->active.size() == 3);
  CHECK(brakes->lamps.red_stop == j1939::Lamp::On);
  CHECK(brakes->malformed == 0);
  CHECK(s.find_j1939(0, 0xF9) == nullptr);  // it only answered (CTS, EndOfMsgAck)
  const j1939::NodeStats* body = s.find_j1939(0, 0x21);
  REQUIRE(body != nullptr);
  // Short DM1, odd DM1, a packet beyond the count, a timeout, a packet without a session, a
  // sequence gap, an interleaved BAM, a second timeout.
  CHECK(body->malformed == 8);
  CHECK(body->tp_timeouts == 2);
  CHECK(body->dm1s == 1);
  CHECK(body->active.empty());
  CHECK(s.tp_sessions_open == 0);
}

TEST_CASE("J1939 findings judge the node: DTC WARN, red stop lamp ERROR, claimed names",
          "[can][j1939][monitor]") {
  LogReplay replay({.node_map = NodeMap::j1939()});
  const std::vector<std::filesystem::path> files{dm1_log()};
  REQUIRE(replay.feed_files(files).has_value());
  CanConfig cfg;
  cfg.node_map = NodeMapKind::J1939;
  const CanMonitor monitor(cfg);
  const CanReport r = replay.report(monitor, replay.last_ns());
  const NodeReport* brakes = r.find(0, 0x0B);
  REQUIRE(brakes != nullptr);
  REQUIRE(brakes->j1939.has_value());
  CHECK(brakes->name == "brakes - system controller (0x0B)");
  CHECK(brakes->status.level() == StatusLevel::Error);
  CHECK(brakes->status.summary().find("red stop lamp on") != std::string::npos);
  CHECK(brakes->status.summary().find("3 active DTCs (DM1): SPN 370085 FMI 12; SPN 110 FMI 0") !=
        std::string::npos);
  const NodeReport* engine = r.find(0, 0x00);
  REQUIRE(engine != nullptr);
  CHECK(engine->name == "engine #2 (0x00)");
  CHECK(engine->status.summary().find("DTC") == std::string::npos);  // all cleared
  const NodeReport* body = r.find(0, 0x21);
  REQUIRE(body != nullptr);
  CHECK(body->status.summary().find("malformed J1939 input: 8") != std::string::npos);

  // The levels are configurable: amber lamp and DTCs OK, red stop WARN.
  const auto lenient = load_can_config_string(
      "node_map: j1939\n"
      "defaults: {j1939: {dtc_level: OK, lamp_level: OK, stop_lamp_level: WARN}}\n");
  REQUIRE(lenient.has_value());
  const CanReport r2 = replay.report(CanMonitor(*lenient), replay.last_ns());
  CHECK(r2.find(0, 0x0B)->status.level() == StatusLevel::Warn);
  const auto bad = load_can_config_string("defaults: {j1939: {dtc_level: loud}}\n");
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().front().to_string().find("dtc_level") != std::string::npos);
}

TEST_CASE("J1939 RTS/CTS: holds, retransmission and aborts as a passive observer", "[can][j1939]") {
  ProtocolTracker t;
  Nanos now = kNanosPerSecond;
  const auto feed = [&](std::uint32_t id, std::initializer_list<std::uint8_t> d, Nanos dt) {
    now += dt;
    const Frame f = ext(id, d, now);
    FrameRecord r;
    r.time_ns = f.timestamp;
    r.id = f.id;
    r.extended = true;
    r.length = f.length;
    std::copy_n(f.data.begin(), 8, r.data.begin());
    t.on(r, NodeMapKind::J1939);
  };
  const Nanos ms = kNanosPerMilli;
  // RTS 0x03 -> 0xF9: a DM1 of 10 bytes, 2 packets.
  feed(0x1CECF903, {16, 10, 0, 2, 1, 0xCA, 0xFE, 0}, 0);
  feed(0x1CEC03F9, {17, 0, 0xFF, 0xFF, 0xFF, 0xCA, 0xFE, 0}, 100 * ms);  // hold (T4)
  feed(0x1CEC03F9, {17, 1, 1, 0xFF, 0xFF, 0xCA, 0xFE, 0}, 1000 * ms);    // within T4
  feed(0x1CEBF903, {1, 0x00, 0xFF, 0x64, 0x00, 0x01, 0x01, 0xBE}, 10 * ms);
  feed(0x1CEC03F9, {17, 1, 1, 0xFF, 0xFF, 0xCA, 0xFE, 0}, 10 * ms);  // packet 1 again
  feed(0x1CEBF903, {1, 0x00, 0xFF, 0x64, 0x00, 0x01, 0x01, 0xBE}, 10 * ms);
  feed(0x1CEC03F9, {17, 1, 2, 0xFF, 0xFF, 0xCA, 0xFE, 0}, 10 * ms);
  feed(0x1CEBF903, {2, 0x00, 0x02, 0x01, 0xFF, 0xFF, 0xFF, 0xFF}, 10 * ms);
  feed(0x1CEC03F9, {19, 10, 0, 2, 0xFF, 0xCA, 0xFE, 0}, 10 * ms);
  ProtocolSnapshot s = t.snapshot();
  const j1939::NodeStats* n = s.find_j1939(0, 0x03);
  REQUIRE(n != nullptr);
  CHECK(n->malformed == 0);
  CHECK(n->tp_messages == 1);
  REQUIRE(n->active.size() == 2);
  CHECK(n->active[1] == j1939::Dtc{.spn = 190, .fmi = 2, .occurrences = 1});
  // A session the receiver aborts is not malformed; a packet the CTS did not clear is.
  feed(0x1CECF903, {16, 10, 0, 2, 1, 0xCA, 0xFE, 0}, 100 * ms);
  feed(0x1CEC03F9, {255, 1, 0xFF, 0xFF, 0xFF, 0xCA, 0xFE, 0}, 10 * ms);
  feed(0x1CECF903, {16, 10, 0, 2, 1, 0xCA, 0xFE, 0}, 100 * ms);
  feed(0x1CEBF903, {1, 0, 0xFF, 0, 0, 0, 0, 0}, 10 * ms);
  s = t.snapshot();
  n = s.find_j1939(0, 0x03);
  CHECK(n->tp_aborts == 1);
  CHECK(n->malformed == 1);
  CHECK(n->last_malformed == "TP.DT packet 1 for PGN 0xFECA not cleared by a CTS");
  // An RTS nobody answers times out after T3.
  feed(0x1CECF903, {16, 10, 0, 2, 1, 0xCA, 0xFE, 0}, 100 * ms);
  t.advance(now + 1200 * ms);
  CHECK(t.snapshot().tp_sessions_open == 1);
  t.advance(now + 1300 * ms);
  s = t.snapshot();
  CHECK(s.tp_sessions_open == 0);
  CHECK(s.find_j1939(0, 0x03)->tp_timeouts == 1);
  CHECK(s.find_j1939(0, 0x03)->last_malformed.find("waiting for T3: a CTS") != std::string::npos);
}

TEST_CASE("J1939 memory is bounded: open TP sessions and remembered DTCs", "[can][j1939]") {
  ProtocolTracker t(ProtocolOptions{.max_tp_sessions = 4, .max_dtcs = 2});
  Nanos now = kNanosPerSecond;
  const auto feed = [&](std::uint32_t id, std::initializer_list<std::uint8_t> d) {
    now += kNanosPerMilli;
    FrameRecord r;
    r.time_ns = now;
    r.id = id;
    r.extended = true;
    r.length = static_cast<std::uint8_t>(d.size());
    std::copy(d.begin(), d.end(), r.data.begin());
    t.on(r, NodeMapKind::J1939);
  };
  for (std::uint32_t sa = 1; sa <= 6; ++sa)
    feed(0x1CECFF00 | sa, {32, 14, 0, 2, 0xFF, 0xCA, 0xFE, 0});
  ProtocolSnapshot s = t.snapshot();
  CHECK(s.tp_sessions_open == 4);
  CHECK(s.find_j1939(0, 5)->malformed == 1);
  CHECK(s.find_j1939(0, 5)->last_malformed ==
        "TP.CM_BAM refused: 4 transport sessions open (the bound)");
  // Source 1 completes a DM1 of 3 DTCs: 2 kept, 1 counted.
  feed(0x1CEBFF01, {1, 0x10, 0xFF, 0xA5, 0xA5, 0xAC, 0xFF, 0x6E});
  feed(0x1CEBFF01, {2, 0x00, 0x00, 0x05, 0x9E, 0x02, 0xE3, 0x02});
  s = t.snapshot();
  CHECK(s.find_j1939(0, 1)->active.size() == 2);
  CHECK(s.find_j1939(0, 1)->dtcs_untracked == 1);
  CHECK(s.recent_events.size() == 2);
  // A flood of BAMs never grows the sessions beyond the bound.
  for (std::uint32_t i = 0; i < 1000; ++i) {
    feed(0x1CECFF00 | (i % 250), {32, 14, 0, 2, 0xFF, 0xCA, 0xFE, 0});
  }
  CHECK(t.snapshot().tp_sessions_open <= 4);
}

TEST_CASE("J1939: replay and live pipeline find the same trouble codes and claims",
          "[can][j1939][replay]") {
  const auto log = read_candump_file(dm1_log());
  REQUIRE(log.has_value());
  const auto dm2 = read_candump_file(dm2_log());
  REQUIRE(dm2.has_value());
  // The DM1 log's frames, then the DM2 log's 10 s later, among periodic EEC1 frames of the
  // engine every 20 ms.
  std::vector<Frame> frames;
  for (const LogEntry& e : log->entries) frames.push_back(e.frame);
  for (LogEntry e : dm2->entries) {
    e.frame.timestamp += 10 * kNanosPerSecond;
    frames.push_back(e.frame);
  }
  const Nanos first = frames.front().timestamp;
  const Nanos last = frames.back().timestamp;
  for (Nanos t = first + 5 * kNanosPerMilli; t < last; t += 20 * kNanosPerMilli) {
    frames.push_back(ext(0x0CF00400, {0x70, 0x7D, 0x83, 0xC3, 0x12, 0, 0x0F, 0x84}, t));
  }
  std::stable_sort(frames.begin(), frames.end(),
                   [](const Frame& a, const Frame& b) { return a.timestamp < b.timestamp; });
  CanConfig cfg;
  cfg.node_map = NodeMapKind::J1939;
  cfg.buses.push_back(BusConfig{.bitrate = 250000});
  const CanMonitor monitor(cfg);

  test::Pipeline<4096> live({.node_map = NodeMap::j1939()},
                            CanAggregatorOptions{.protocol = cfg.protocol_options()});
  Nanos next_step = first + 100 * kNanosPerMilli;
  for (const Frame& f : frames) {
    while (f.timestamp >= next_step) {
      live.step_at(next_step);
      next_step += 100 * kNanosPerMilli;
    }
    live.read(f);
  }
  live.step_at(last);
  const CanReport lr = monitor.evaluate(live.aggregator, last);

  LogReplay replay({.node_map = NodeMap::j1939(), .protocol = cfg.protocol_options()});
  for (const Frame& f : frames) replay.feed(f, Direction::Rx);
  const CanReport rr = replay.report(monitor, last);

  const ProtocolSnapshot& a = lr.snapshot.protocol;
  const ProtocolSnapshot& b = rr.snapshot.protocol;
  REQUIRE(a.recent_events.size() == b.recent_events.size());
  CHECK(a.recent_events.size() == 10);  // the DM1 log's 9, the DM2 log's DM1: no DM2 event
  for (std::size_t i = 0; i < a.recent_events.size(); ++i) {
    CHECK(a.recent_events[i].kind == b.recent_events[i].kind);
    CHECK(a.recent_events[i].time_ns == b.recent_events[i].time_ns);
    CHECK(a.recent_events[i].detail == b.recent_events[i].detail);
  }
  REQUIRE(a.j1939.size() == b.j1939.size());
  for (std::size_t i = 0; i < a.j1939.size(); ++i) {
    CHECK(a.j1939[i].active == b.j1939[i].active);
    CHECK(a.j1939[i].malformed == b.j1939[i].malformed);
    CHECK(a.j1939[i].tp_timeouts == b.j1939[i].tp_timeouts);
    CHECK(a.j1939[i].name == b.j1939[i].name);
    CHECK(a.j1939[i].dm2s == b.j1939[i].dm2s);
    CHECK(a.j1939[i].previously_active == b.j1939[i].previously_active);
  }
  REQUIRE(a.find_j1939(0, 0x0B) != nullptr);
  CHECK(a.find_j1939(0, 0x0B)->previously_active.size() == 3);
  // Text and JSON: the J1939 table and array are the same.
  const auto section = [](const std::string& s, const std::string& from, const std::string& to) {
    const auto i = s.find(from);
    REQUIRE(i != std::string::npos);
    return s.substr(i, s.find(to, i) - i);
  };
  const std::string lt = vigil::exporter::format_can_report(lr, {.max_events = -1});
  const std::string rt = vigil::exporter::format_can_report(rr, {.max_events = -1});
  CHECK(section(lt, "\nJ1939\n", "\nProtocol events") ==
        section(rt, "\nJ1939\n", "\nProtocol events"));
  CHECK(section(lt, "\nProtocol events", "\n\n") == section(rt, "\nProtocol events", "\n\n"));
  const std::string lj = vigil::exporter::can_report_json(lr);
  const std::string rj = vigil::exporter::can_report_json(rr);
  CHECK(section(lj, "\"j1939\":", "\"protocol\":") == section(rj, "\"j1939\":", "\"protocol\":"));
  CHECK(lr.find(0, 0x0B)->status.level() == StatusLevel::Error);
  CHECK(rr.find(0, 0x0B)->status.level() == StatusLevel::Error);
  CHECK(lr.find(0, 0x0B)->name == rr.find(0, 0x0B)->name);
}

TEST_CASE("vigil can-stats summarises J1939 trouble codes and address claims, text and JSON",
          "[can][j1939][replay]") {
  vigil::app::CanStatsOptions o;
  o.files = {dm1_log()};
  o.node_map = NodeMapKind::J1939;
  std::ostringstream out;
  std::ostringstream err;
  CHECK(vigil::app::run_can_stats(o, out, err) == 0);
  const std::string text = out.str();
  CHECK(text.find("J1939: 3 nodes with DM1, 3 active DTCs (5 appeared), 2 address claims") !=
        std::string::npos);
  CHECK(text.find("\nJ1939\n") != std::string::npos);
  CHECK(text.find("brakes - system controller (0x0B)") != std::string::npos);
  CHECK(text.find("dtc_cleared") != std::string::npos);
  o.json = true;
  std::ostringstream jout;
  CHECK(vigil::app::run_can_stats(o, jout, err) == 0);
  const std::string json = jout.str();
  CHECK(json.find("\"active_dtcs\": 3") != std::string::npos);
  CHECK(json.find("\"address_claims\": 2") != std::string::npos);
  CHECK(json.find("\"spn\": 370085") != std::string::npos);
  CHECK(json.find("\"kind\": \"dtc_active\"") != std::string::npos);
}

TEST_CASE("The J1939 truck capture with the default configuration: no false alarm",
          "[can][j1939][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  LogReplay replay({.node_map = NodeMap::j1939()});
  const std::vector<std::filesystem::path> files{vigil::test::shared_data(kTruckLog)};
  REQUIRE(replay.feed_files(files).has_value());
  CanConfig cfg;
  cfg.node_map = NodeMapKind::J1939;
  const CanReport r = replay.report(CanMonitor(cfg), replay.last_ns());
  const ProtocolSnapshot& s = r.snapshot.protocol;
  // It has no DM1, no transport protocol and no address claim (its 23 ids, README): nothing to
  // find, and nothing malformed.
  CHECK(s.events == 0);
  CHECK(s.tp_sessions_open == 0);
  for (const j1939::NodeStats& n : s.j1939) {
    CHECK(n.malformed == 0);
    CHECK(n.active.empty());
  }
  for (const std::uint32_t sa : {0x00U, 0x21U, 0x0BU}) {
    const NodeReport* n = r.find(0, sa);
    REQUIRE(n != nullptr);
    CHECK_FALSE(n->j1939.has_value());
    CHECK(n->status.summary().find("DTC") == std::string::npos);
  }
  CHECK(std::string(to_string(vigil::supervisor::EventKind::DtcActive)) == "dtc_active");
  CHECK(std::string(to_string(vigil::supervisor::EventKind::DtcCleared)) == "dtc_cleared");
  CHECK(std::string(to_string(vigil::supervisor::EventKind::AddressClaim)) == "address_claim");
}

TEST_CASE("J1939 is a bus's protocol: a group asking for it is an error at its line",
          "[can][j1939][config]") {
  const auto ok = load_can_config_string("buses: {0: {protocol: j1939}}\n");
  REQUIRE(ok.has_value());
  CHECK(ok->protocol_options().settings(0, NodeMapKind::Identity).protocol == BusProtocol::J1939);
  const auto bad = load_can_config_string("groups: {trucks: {nodes: [0], protocol: j1939}}\n");
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().front().to_string().find("a group's protocol is canopen, none or auto, got "
                                             "'j1939'") != std::string::npos);
}
