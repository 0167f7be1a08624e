// What CAN supervision reads in the frames: bus load (frame lengths as canbusload counts them),
// controller state from error frames, CANopen (CiA 301) NMT, heartbeat, guarding, emergencies;
// and that a replay (`vigil can-stats`) finds the same as the live pipeline.
#include "vigil/can/protocol.hpp"

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
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

// The record the CAN aggregator hands the tracker for frame `f` received at `time`.
FrameRecord record_of(const Frame& f, Nanos time) {
  FrameRecord r;
  r.time_ns = time;
  r.id = f.id;
  r.extended = f.extended;
  r.rtr = f.rtr;
  r.length = f.length;
  std::copy_n(f.data.begin(), 8, r.data.begin());
  return r;
}

std::vector<std::uint8_t> bits_of_byte(std::uint8_t b) {
  std::vector<std::uint8_t> v;
  for (int i = 7; i >= 0; --i) v.push_back(static_cast<std::uint8_t>((b >> i) & 1));
  return v;
}

// An independent, naive count of a Classical CAN frame's bits (a string of '0'/'1', the CRC by
// polynomial division over the string, stuffing by scanning it), to check the library's.
std::uint32_t naive_exact_bits(const Frame& f) {
  std::string s = "0";
  const auto add = [&](std::uint32_t v, int n) {
    for (int i = n - 1; i >= 0; --i) s += ((v >> i) & 1) != 0 ? '1' : '0';
  };
  if (f.extended) {
    add(f.id >> 18, 11);
    s += "11";
    add(f.id & 0x3FFFF, 18);
    s += f.rtr ? "1" : "0";
    s += "00";
  } else {
    add(f.id, 11);
    s += f.rtr ? "1" : "0";
    s += "00";
  }
  add(std::min<std::uint32_t>(f.length, 15), 4);
  for (std::size_t i = 0; i < f.data_size(); ++i) add(f.data[i], 8);
  // CRC: remainder of (message * x^15) divided by 0xC599 (x^15 + 0x4599), over GF(2).
  std::string div = s + std::string(15, '0');
  const std::string poly = "1100010110011001";
  for (std::size_t i = 0; i + 15 < div.size(); ++i) {
    if (div[i] == '1') {
      for (std::size_t k = 0; k < poly.size(); ++k) div[i + k] = div[i + k] == poly[k] ? '0' : '1';
    }
  }
  s += div.substr(div.size() - 15);
  std::uint32_t stuffed = 0;
  std::string run;
  char last = 'x';
  int count = 0;
  for (const char c : s) {
    count = c == last ? count + 1 : 1;
    last = c;
    if (count == 5) {
      ++stuffed;
      last = c == '0' ? '1' : '0';
      count = 1;
    }
  }
  return static_cast<std::uint32_t>(s.size()) + stuffed + 13;
}

Frame at(Frame f, Nanos t, std::uint8_t bus = 0) {
  f.timestamp = t;
  f.bus = bus;
  return f;
}

}  // namespace

TEST_CASE("CRC-15 matches the reference values of ISO 11898-1's generator", "[can][protocol]") {
  // The CRC of one byte (leading zero bits change nothing) is the byte's entry of the table
  // can-utils' canframelen.c lists for the generator 0x4599: 0x01 -> 0x4599, 0x02 -> 0x4EAB,
  // 0x03 -> 0x0B32, 0x10 -> 0x2D97, 0xFF -> 0x0095.
  CHECK(can_crc15(bits_of_byte(0x01)) == 0x4599);
  CHECK(can_crc15(bits_of_byte(0x02)) == 0x4EAB);
  CHECK(can_crc15(bits_of_byte(0x03)) == 0x0B32);
  CHECK(can_crc15(bits_of_byte(0x10)) == 0x2D97);
  CHECK(can_crc15(bits_of_byte(0xFF)) == 0x0095);
  // A message followed by its CRC divides evenly: its CRC is 0.
  std::array<std::uint8_t, 128> bits{};
  const Frame f = Frame::classic(0x123, {0xDE, 0xAD, 0xBE, 0xEF});
  const std::size_t n =
      classic_frame_bits(FrameShape{.id = f.id, .length = f.length, .data = f.payload()}, bits);
  REQUIRE(n == 1 + 11 + 3 + 4 + 32 + 15);
  CHECK(can_crc15(std::span<const std::uint8_t>(bits.data(), n)) == 0);
}

TEST_CASE("Frame lengths: canbusload's three modes on hand-computed frames", "[can][protocol]") {
  // ISO 11898-1 base format: SOF 1, id 11, RTR 1, IDE 1, r0 1, DLC 4, data 8n, CRC 15, CRC
  // delimiter 1, ACK 1, ACK delimiter 1, EOF 7, intermission 3 = 47 + 8n.
  const Frame sff8 = Frame::classic(0x181, {1, 2, 3, 4, 5, 6, 7, 8});
  CHECK(frame_bits(sff8, Stuffing::None).nominal == 111);
  CHECK(frame_bits(sff8, Stuffing::WorstCase).nominal == 135);  // 55 + 10n
  // Extended: + SRR, IDE, 18 id bits, r1 = 67 + 8n; worst 80 + 10n.
  const Frame eff8 = Frame::classic(0x18FEF121, {1, 2, 3, 4, 5, 6, 7, 8}, IdFormat::Extended);
  CHECK(frame_bits(eff8, Stuffing::None).nominal == 131);
  CHECK(frame_bits(eff8, Stuffing::WorstCase).nominal == 160);
  // Id 0, DLC 0: SOF to the end of the DLC are 19 dominant bits, their CRC is 0: 34 dominant
  // bits in a row, a stuff bit after every 5 (6 of them), + 13 = 53.
  const Frame zero = Frame::classic(0x000, {});
  CHECK(frame_bits(zero, Stuffing::None).nominal == 47);
  CHECK(frame_bits(zero, Stuffing::Exact).nominal == 53);
  // A remote frame has no data field whatever its DLC.
  CHECK(frame_bits(Frame::remote(0x705, 1), Stuffing::None).nominal == 47);
  // Exact lies between none and worst case, and equals an independent naive count.
  for (const Frame& f : {sff8, eff8, zero, Frame::classic(0x7FF, {0xFF, 0xFF, 0x00, 0x00}),
                         Frame::classic(0x555, {0x55, 0xAA}), Frame::remote(0x705, 1)}) {
    const std::uint32_t exact = frame_bits(f, Stuffing::Exact).nominal;
    CHECK(exact == naive_exact_bits(f));
    CHECK(exact >= frame_bits(f, Stuffing::None).nominal);
    CHECK(exact <= frame_bits(f, Stuffing::WorstCase).nominal);
  }
  // 0x7FF with 0xFF data: long recessive runs, more stuffing than 0x555/0x55.
  CHECK(stuff_bits(std::vector<std::uint8_t>(10, 1)) == 2);
  CHECK(stuff_bits(std::vector<std::uint8_t>{0, 1, 0, 1, 0, 1}) == 0);
  CHECK(stuff_bits(std::vector<std::uint8_t>{1, 1, 1, 1, 1, 0, 0, 0, 0}) == 2);  // 11111 (0) 0000
  // Error frames are no frames on the wire.
  CHECK(frame_bits(Frame::error_frame(0x4, {0, 0x10}), Stuffing::Exact).total() == 0);
}

TEST_CASE("Frame lengths: CAN FD as canbusload counts it, the data phase apart",
          "[can][protocol]") {
  std::vector<std::uint8_t> bytes(64, 0xA5);
  const Frame brs = Frame::fd_frame(0x123, bytes, IdFormat::Standard, {.brs = true});
  // 1 + 11 + 21 (CRC, 16 bytes or more) + 5 + 12 + 512 = 562, of which BRS to CRC delimiter
  // 1 + 1 + 4 + 21 + 512 = 539 at the data bitrate.
  const FrameBits none = frame_bits(brs, Stuffing::None);
  CHECK(none.total() == 562);
  CHECK(none.data == 539);
  const FrameBits worst = frame_bits(brs, Stuffing::WorstCase);
  CHECK(worst.total() == 562 * 5 / 4);
  CHECK(worst.data == 539 * 5 / 4);
  // Exact counts CAN FD as the worst case (canbusload has no exact CAN FD count).
  CHECK(frame_bits(brs, Stuffing::Exact).total() == worst.total());
  // Without BRS everything runs at the nominal bitrate; 8 bytes: CRC 17.
  const Frame plain = Frame::fd_frame(0x123, {1, 2, 3, 4, 5, 6, 7, 8});
  CHECK(frame_bits(plain, Stuffing::None).nominal == 1 + 11 + 17 + 5 + 12 + 64);
  CHECK(frame_bits(plain, Stuffing::None).data == 0);
}

TEST_CASE("Bus load per second, 1/5/15-minute averages and peak, as canbusload",
          "[can][protocol]") {
  ProtocolOptions o;
  o.all_buses.bitrate = 125000;
  ProtocolTracker t(o);
  // Second 10: 1000 frames of 111 bits (no stuffing) = 111000 bits of 125000 = 88.8 %.
  for (int i = 0; i < 1000; ++i) {
    FrameRecord r;
    r.time_ns = 10 * kNanosPerSecond + i * kNanosPerMilli;
    r.id = 0x181;
    r.length = 8;
    t.on(r);
  }
  t.advance(11 * kNanosPerSecond);
  ProtocolSnapshot s = t.snapshot();
  REQUIRE(s.buses.size() == 1);
  const BusLoad& l = s.buses[0].load[static_cast<std::size_t>(Stuffing::None)][2];
  CHECK(l.frames == 1000);
  CHECK(l.bits == 111000);
  CHECK(l.last_second == Approx(88.8));
  CHECK(l.peak == Approx(88.8));
  CHECK(l.avg_1m == Approx(88.8 * (1 - std::exp(-1.0 / 60))));
  CHECK(l.avg_15m == Approx(88.8 * (1 - std::exp(-1.0 / 900))));
  CHECK(s.buses[0].load[static_cast<std::size_t>(Stuffing::None)][1].frames == 0);  // no Tx
  // A minute of silence: 60 empty seconds decay the 1-minute average by e^-1; the latest
  // second was empty.
  t.advance(71 * kNanosPerSecond);
  s = t.snapshot();
  const BusLoad& later = s.buses[0].load[static_cast<std::size_t>(Stuffing::None)][2];
  CHECK(later.last_second == 0);
  CHECK(later.avg_1m == Approx(88.8 * (1 - std::exp(-1.0 / 60)) * std::exp(-1.0)));
  CHECK(later.peak == Approx(88.8));
  CHECK(later.mean == Approx(88.8 / 61));
  // Without a bitrate only bits are counted.
  ProtocolTracker unknown;
  FrameRecord r;
  r.id = 0x181;
  unknown.on(r);
  CHECK_FALSE(unknown.snapshot().buses[0].load[0][2].known);
  CHECK(unknown.snapshot().buses[0].load[0][2].bits == 47);
}

TEST_CASE("Error frames: classes decoded and counted, controller state and its events",
          "[can][protocol]") {
  ProtocolTracker t;
  const auto feed = [&](const Frame& f, Nanos time) {
    FrameRecord r;
    r.time_ns = time;
    r.error = true;
    r.id = f.id;
    r.length = f.length;
    std::copy_n(f.data.begin(), 8, r.data.begin());
    t.on(r);
  };
  // Controller: rx/tx warning, then tx passive with error counters 130/5 (CAN_ERR_CNT), then a
  // protocol violation (stuff error in the data field), no ACK, bus off, restarted.
  feed(Frame::error_frame(error_class::kCrtl, {0, 0x08}), 1);
  feed(Frame::error_frame(error_class::kCrtl | error_class::kCnt, {0, 0x20, 0, 0, 0, 0, 130, 5}),
       2);
  feed(Frame::error_frame(error_class::kProt | error_class::kBusError, {0, 0, 0x04, 0x0A}), 3);
  feed(Frame::error_frame(error_class::kAck), 4);
  feed(Frame::error_frame(error_class::kBusOff), 5);
  feed(Frame::error_frame(error_class::kRestarted), 6);
  feed(Frame::error_frame(error_class::kTrx, {0, 0, 0, 0, 0x04}), 7);
  const ProtocolSnapshot s = t.snapshot();
  REQUIRE(s.buses.size() == 1);
  const ControllerStats& c = s.buses[0].controller;
  CHECK(c.error_frames == 7);
  CHECK(c.by_class[2] == 2);        // controller
  CHECK(c.by_class[3] == 1);        // protocol
  CHECK(c.by_class[5] == 1);        // no ack
  CHECK(c.by_class[6] == 1);        // bus off
  CHECK(c.protocol_types[2] == 1);  // stuff
  REQUIRE(c.protocol_locations.size() == 1);
  CHECK(protocol_location_name(c.protocol_locations[0].first) == "data section");
  CHECK(c.tx_errors == 130);
  CHECK(c.rx_errors == 5);
  CHECK(c.warnings == 1);
  CHECK(c.passives == 1);
  CHECK(c.bus_offs == 1);
  CHECK(c.restarts == 1);
  CHECK(c.state == ControllerState::ErrorActive);
  REQUIRE(c.transceiver.has_value());
  CHECK(transceiver_name(*c.transceiver) == "CANH no wire");
  REQUIRE(s.recent_events.size() == 4);
  CHECK(s.recent_events[0].kind == ProtocolEventKind::ErrorWarning);
  CHECK(s.recent_events[1].kind == ProtocolEventKind::ErrorPassive);
  CHECK(s.recent_events[1].severity == 1);
  CHECK(s.recent_events[2].kind == ProtocolEventKind::BusOff);
  CHECK(s.recent_events[2].severity == 2);
  CHECK(s.recent_events[2].time_ns == 5);
  CHECK(s.recent_events[3].kind == ProtocolEventKind::ErrorActive);
  CHECK(describe_error_frame(error_class::kCrtl | error_class::kCnt,
                             std::vector<std::uint8_t>{0, 0x30, 0, 0, 0, 0, 130, 5}) ==
        "controller: rx passive, tx passive; error counters tx 130 rx 5");
  CHECK(describe_error_frame(error_class::kProt, std::vector<std::uint8_t>{0, 0, 0x84, 0x19}) ==
        "protocol: stuff, on transmission at ACK slot");
  // A short error frame reads only the bytes it has.
  CHECK(describe_error_frame(error_class::kCrtl, {}) == "controller");
}

TEST_CASE("Controller state judges the bus: error passive WARN, bus off ERROR",
          "[can][protocol][monitor]") {
  test::Pipeline<> p;
  p.read(test::frame(0x181, 1 * kNanosPerMilli));
  p.sniffer.on_read(at(Frame::error_frame(error_class::kCrtl, {0, 0x20}), 2 * kNanosPerMilli),
                    2 * kNanosPerMilli, 2 * kNanosPerMilli);
  CanMonitor monitor;
  CanReport r = monitor.evaluate(p.step(), 3 * kNanosPerMilli);
  REQUIRE(r.buses.size() == 1);
  CHECK(r.buses[0].status.level() == StatusLevel::Warn);
  CHECK(r.buses[0].status.summary().find("controller error passive") != std::string::npos);
  CHECK(r.status.level() >= StatusLevel::Warn);
  p.sniffer.on_read(at(Frame::error_frame(error_class::kBusOff), 4 * kNanosPerMilli),
                    4 * kNanosPerMilli, 4 * kNanosPerMilli);
  r = monitor.evaluate(p.step(), 5 * kNanosPerMilli);
  CHECK(r.buses[0].status.level() == StatusLevel::Error);
  CHECK(r.status.level() == StatusLevel::Error);
  CHECK(r.snapshot.error_records == 2);
  CHECK(r.snapshot.records == 1);  // error frames are not timing records
}

TEST_CASE("Bus load thresholds from the configuration", "[can][protocol][monitor]") {
  const auto cfg = load_can_config_string(
      "buses:\n"
      "  all: {bitrate: 125k, load: {warn: 50, error: 80, stuffing: none, figure: last_second}}\n"
      "  1: {bitrate: 1M}\n");
  REQUIRE(cfg.has_value());
  CHECK(cfg->bus_config(0).settings.bitrate == 125000);
  CHECK(cfg->bus_config(1).settings.bitrate == 1000000);
  CHECK(cfg->bus_config(1).load.warn == 50);  // from `all`
  test::Pipeline<4096> p({}, CanAggregatorOptions{.protocol = cfg->protocol_options()});
  // 700 frames of 111 bits in second 0 on bus 0 (62.2 % of 125k), and on bus 1 (7.8 % of 1M).
  for (int i = 0; i < 700; ++i) {
    p.read(test::frame(0x181, i * kNanosPerMilli, 0, {1, 2, 3, 4, 5, 6, 7, 8}));
    p.read(test::frame(0x181, i * kNanosPerMilli, 1, {1, 2, 3, 4, 5, 6, 7, 8}));
  }
  p.step_at(kNanosPerSecond);
  CanMonitor monitor(*cfg);
  CanReport r = monitor.evaluate(p.aggregator, kNanosPerSecond);
  REQUIRE(r.buses.size() == 2);
  CHECK(r.buses[0].judged_load == Approx(62.16));
  CHECK(r.buses[0].status.level() == StatusLevel::Warn);
  CHECK(r.buses[0].status.summary() == "bus load 62.2% (last_second, none stuffing) above 50%");
  CHECK(r.buses[1].status.level() == StatusLevel::Ok);
  // Errors of the file are reported with their place.
  const auto bad = load_can_config_string(
      "buses:\n  x: {bitrate: 125k}\n  0: {bitrate: fast, load: {warn: 90, error: 80}}\n",
      "b.yaml");
  REQUIRE_FALSE(bad.has_value());
  const std::string text = vigil::config::to_string(bad.error());
  CHECK(text.find("'x': a bus is 'all' or a bus index 0-255") != std::string::npos);
  CHECK(text.find("expected a bitrate such as 500000, '500k' or '1M', got 'fast'") !=
        std::string::npos);
  CHECK(text.find("must not be above error (80)") != std::string::npos);
}

TEST_CASE("CANopen: NMT states from heartbeats, resets, emergencies, NMT commands, guarding",
          "[can][protocol][canopen]") {
  ProtocolTracker t;
  Nanos now = 0;
  const auto feed = [&](const Frame& f, NodeMapKind map = NodeMapKind::CanOpen) {
    t.on(record_of(f, now += kNanosPerMilli), map);
  };
  feed(Frame::classic(0x705, {0x00}));                             // boot-up
  feed(Frame::classic(0x705, {0x7F}));                             // pre-operational
  feed(Frame::classic(0x000, {0x01, 0x05}));                       // NMT start node 5
  feed(Frame::classic(0x705, {0x05}));                             // operational
  feed(Frame::classic(0x705, {0x05}));                             // no change
  feed(Frame::classic(0x085, {0x30, 0x81, 0x11, 1, 2, 3, 4, 5}));  // EMCY 0x8130
  feed(Frame::classic(0x705, {0x00}));              // boot-up while operational: a reset
  feed(Frame::classic(0x085, {0x00, 0x10, 0x01}));  // EMCY of 3 bytes: malformed, decoded
  feed(Frame::classic(0x705, {0x12}));              // unknown state byte: malformed
  feed(Frame::classic(0x705, {}));                  // no state byte: malformed
  // Node guarding of node 6: the toggle bit alternates 0, 1, then 1 again (an error).
  for (const std::uint8_t b : {0x05, 0x85, 0x85}) {
    feed(Frame::remote(0x706, 1));
    feed(Frame::classic(0x706, {b}));
  }
  // Identity mapping without `protocol: canopen`: nothing decoded.
  feed(Frame::classic(0x707, {0x05}), NodeMapKind::Identity);

  const ProtocolSnapshot s = t.snapshot();
  const canopen::NodeStats* n5 = s.find_canopen(0, 5);
  REQUIRE(n5 != nullptr);
  CHECK(n5->state == canopen::NmtState::BootUp);
  CHECK(n5->boot_ups == 2);
  CHECK(n5->resets == 1);
  CHECK(n5->heartbeats == 5);
  CHECK(n5->emergencies == 2);
  CHECK(n5->malformed_emergencies == 1);
  CHECK(n5->malformed_heartbeats == 2);
  CHECK(n5->last_malformed == "heartbeat without a state byte");
  REQUIRE(n5->last_emergency.has_value());
  CHECK(n5->last_emergency->code == 0x1000);
  CHECK(n5->last_emergency->describe() ==
        "0x1000 generic error, register 0x01 (generic) (short: 3 bytes of 8)");
  const canopen::NodeStats* n6 = s.find_canopen(0, 6);
  REQUIRE(n6 != nullptr);
  CHECK(n6->guard_requests == 3);
  CHECK(n6->guard_responses == 3);
  CHECK(n6->toggle_errors == 1);
  CHECK(n6->state == canopen::NmtState::Operational);
  CHECK(s.find_canopen(0, 7) == nullptr);

  std::vector<std::string> seen;
  for (const ProtocolEvent& e : s.recent_events) {
    seen.push_back(std::string(to_string(e.kind)) + " " +
                   (e.node == kNoNode ? std::string("-") : std::to_string(e.node)) + ": " +
                   e.detail);
  }
  CHECK(seen == std::vector<std::string>{
                    "nmt_state 5: unknown -> boot-up",
                    "nmt_state 5: boot-up -> pre-operational",
                    "nmt_command 5: start remote node (0x01) to node 5",
                    "nmt_state 5: pre-operational -> operational",
                    "emergency 5: 0x8130 communication: life guard error or heartbeat error, "
                    "register 0x11 (generic, communication), manufacturer 01 02 03 04 05",
                    "node_reset 5: boot-up while operational: node reset (1 so far)",
                    "emergency 5: 0x1000 generic error, register 0x01 (generic) (short: 3 "
                    "bytes of 8)",
                    "nmt_state 6: unknown -> operational",
                });
}

TEST_CASE("CANopen emergency classes of CiA 301", "[can][protocol][canopen]") {
  CHECK(canopen::emergency_class(0x0000) == "error reset or no error");
  CHECK(canopen::emergency_class(0x1000) == "generic error");
  CHECK(canopen::emergency_class(0x2310) == "current, device output side");
  CHECK(canopen::emergency_class(0x2400) == "current");
  CHECK(canopen::emergency_class(0x3210) == "voltage inside the device");
  CHECK(canopen::emergency_class(0x4210) == "temperature: device");
  CHECK(canopen::emergency_class(0x5000) == "device hardware");
  CHECK(canopen::emergency_class(0x6100) == "device software: internal");
  CHECK(canopen::emergency_class(0x7000) == "additional modules");
  CHECK(canopen::emergency_class(0x8110) == "communication: CAN overrun (objects lost)");
  CHECK(canopen::emergency_class(0x8120) == "communication: CAN in error passive mode");
  CHECK(canopen::emergency_class(0x8140) == "communication: recovered from bus off");
  CHECK(canopen::emergency_class(0x9000) == "external error");
  CHECK(canopen::emergency_class(0xF001) == "additional functions");
  CHECK(canopen::emergency_class(0xFF42) == "device specific");
  CHECK(canopen::emergency_class(0xA000) == "not defined by CiA 301");
  CHECK(canopen::error_register_names(0x91) == "generic, communication, manufacturer");
  CHECK(canopen::nmt_command_name(0x81) == "reset node");
  CHECK(canopen::nmt_command_name(0x82) == "reset communication");
  CHECK(canopen::nmt_command_name(0x80) == "enter pre-operational");
  CHECK(canopen::nmt_command_name(0x02) == "stop remote node");
}

TEST_CASE("CANopen findings judge the node: reset, emergency, not operational, heartbeat",
          "[can][protocol][canopen][monitor]") {
  const auto cfg = load_can_config_string(
      "node_map: canopen\n"
      "defaults: {canopen: {not_operational_after: 2s, reset_window: 10s}}\n"
      "nodes:\n"
      "  drive: {node: 5, thresholds: {canopen: {heartbeat: 150ms}}}\n"
      "  io: {node: 6}\n");
  REQUIRE(cfg.has_value());
  test::Pipeline<> p({.node_map = NodeMap::canopen()});
  p.read(test::frame(0x705, 1 * kNanosPerMilli, 0, {0x05}));
  p.read(test::frame(0x705, 100 * kNanosPerMilli, 0, {0x00}));  // reset
  p.read(test::frame(0x706, 100 * kNanosPerMilli, 0, {0x7F}));  // pre-operational
  p.read(test::frame(0x086, 110 * kNanosPerMilli, 0, {0x10, 0x42, 0x01, 0, 0, 0, 0, 0}));
  CanMonitor monitor(*cfg);
  p.step_at(200 * kNanosPerMilli);
  CanReport r = monitor.evaluate(p.aggregator, 200 * kNanosPerMilli);
  const NodeReport* drive = r.find("drive");
  REQUIRE(drive != nullptr);
  REQUIRE(drive->canopen.has_value());
  CHECK(drive->status.level() == StatusLevel::Warn);
  CHECK(drive->status.summary().find("node reset: boot-up of a running node 100ms ago (1 reset "
                                     "so far)") != std::string::npos);
  const NodeReport* io = r.find("io");
  REQUIRE(io != nullptr);
  CHECK(io->status.level() == StatusLevel::Warn);
  CHECK(io->status.summary().find("emergency 0x4210 temperature: device") != std::string::npos);
  // 400 ms: the drive's heartbeat (150 ms consumer time) is lost: ERROR. 3 s: io has been
  // pre-operational for 2.9 s, above 2 s.
  p.step_at(3 * kNanosPerSecond);
  r = monitor.evaluate(p.aggregator, 3 * kNanosPerSecond);
  CHECK(r.find("drive")->status.level() == StatusLevel::Error);
  CHECK(r.find("drive")->status.summary().find("heartbeat lost: none for 2.90s (consumer time "
                                               "150ms)") != std::string::npos);
  CHECK(r.find("io")->status.summary().find("not operational: pre-operational for 2.90s (limit "
                                            "2s)") != std::string::npos);
  // An emergency "error reset" (0x0000) ends the emergency's WARN.
  p.read(test::frame(0x086, 3100 * kNanosPerMilli, 0, {0, 0, 0, 0, 0, 0, 0, 0}));
  p.read(test::frame(0x706, 3100 * kNanosPerMilli, 0, {0x05}));
  p.step_at(3200 * kNanosPerMilli);
  r = monitor.evaluate(p.aggregator, 3200 * kNanosPerMilli);
  CHECK(r.find("io")->status.level() == StatusLevel::Ok);
  // The text and JSON forms carry the findings.
  const std::string text = vigil::exporter::format_can_report(r);
  CHECK(text.find("\nCANopen\n") != std::string::npos);
  CHECK(text.find("node_reset") != std::string::npos);
  const std::string json = vigil::exporter::can_report_json(r);
  CHECK(json.find("\"nmt_state\":\"operational\"") != std::string::npos);
  CHECK(json.find("\"resets\":1") != std::string::npos);
}

TEST_CASE("Replay and live pipeline find the same protocol findings", "[can][protocol][replay]") {
  // One stream of frames: CANopen heartbeats with a reset, emergencies, NMT commands, error
  // frames (error passive, bus off, restarted) and enough traffic for bus load over 3 seconds.
  std::vector<Frame> frames;
  Nanos t = 1'000 * kNanosPerSecond;
  const auto add = [&](Frame f) {
    t += 7 * kNanosPerMilli;
    frames.push_back(at(f, t));
  };
  add(Frame::classic(0x000, {0x82, 0x00}));
  for (int i = 0; i < 300; ++i) {
    add(Frame::classic(0x181 + static_cast<std::uint32_t>(i % 3),
                       {static_cast<std::uint8_t>(i), 0x55, 0xAA, 0x0F}));
    if (i % 50 == 0) add(Frame::classic(0x701 + static_cast<std::uint32_t>(i % 3), {0x05}));
    if (i == 120) add(Frame::classic(0x702, {0x00}));
    if (i == 130) add(Frame::classic(0x082, {0x10, 0x81, 0x11, 0, 0, 0, 0, 0}));
    if (i == 140) add(Frame::error_frame(error_class::kCrtl, {0, 0x20}));
    if (i == 150) add(Frame::error_frame(error_class::kBusOff));
    if (i == 160) add(Frame::error_frame(error_class::kRestarted));
    if (i == 170) add(Frame::classic(0x083, {0x10}));  // short EMCY
  }
  CanConfig cfg;
  cfg.node_map = NodeMapKind::CanOpen;
  cfg.buses.push_back(BusConfig{.bitrate = 250000});
  const CanMonitor monitor(cfg);

  // Live: a sniffer, its port, the CAN supervisor stepped every 100 ms of frame time.
  test::Pipeline<4096> live({.node_map = NodeMap::canopen()},
                            CanAggregatorOptions{.protocol = cfg.protocol_options()});
  Nanos next_step = frames.front().timestamp + 100 * kNanosPerMilli;
  for (const Frame& f : frames) {
    while (f.timestamp >= next_step) {
      live.step_at(next_step);
      next_step += 100 * kNanosPerMilli;
    }
    live.read(f);
  }
  live.step_at(t);
  const CanReport lr = monitor.evaluate(live.aggregator, t);

  // Replay: the same frames through a candump log and `vigil can-stats`'s pipeline.
  LogReplay replay({.node_map = NodeMap::canopen(), .protocol = cfg.protocol_options()});
  for (const Frame& f : frames) replay.feed(f, Direction::Rx);
  const CanReport rr = replay.report(monitor, t);

  const ProtocolSnapshot& a = lr.snapshot.protocol;
  const ProtocolSnapshot& b = rr.snapshot.protocol;
  REQUIRE(a.recent_events.size() == b.recent_events.size());
  CHECK(a.recent_events.size() >= 8);
  for (std::size_t i = 0; i < a.recent_events.size(); ++i) {
    CHECK(a.recent_events[i].kind == b.recent_events[i].kind);
    CHECK(a.recent_events[i].time_ns == b.recent_events[i].time_ns);
    CHECK(a.recent_events[i].detail == b.recent_events[i].detail);
  }
  REQUIRE(a.canopen.size() == b.canopen.size());
  for (std::size_t i = 0; i < a.canopen.size(); ++i) {
    CHECK(a.canopen[i].resets == b.canopen[i].resets);
    CHECK(a.canopen[i].emergencies == b.canopen[i].emergencies);
    CHECK(a.canopen[i].malformed_emergencies == b.canopen[i].malformed_emergencies);
    CHECK(a.canopen[i].state == b.canopen[i].state);
  }
  CHECK(b.find_canopen(0, 2)->resets == 1);
  CHECK(b.find_canopen(0, 3)->malformed_emergencies == 1);
  REQUIRE(a.buses.size() == 1);
  REQUIRE(b.buses.size() == 1);
  for (std::size_t m = 0; m < kStuffingModes; ++m) {
    CHECK(a.buses[0].load[m][2].bits == b.buses[0].load[m][2].bits);
    CHECK(a.buses[0].load[m][2].peak == Approx(b.buses[0].load[m][2].peak));
    CHECK(a.buses[0].load[m][2].avg_1m == Approx(b.buses[0].load[m][2].avg_1m));
  }
  CHECK(a.buses[0].controller.bus_offs == 1);
  CHECK(b.buses[0].controller.bus_offs == 1);
  CHECK(lr.find(0, 2)->status.level() == rr.find(0, 2)->status.level());
  CHECK(rr.find(0, 2)->status.level() == StatusLevel::Warn);  // its reset
}

TEST_CASE("vigil can-stats reports the protocol findings of a log, text and JSON",
          "[can][protocol][replay]") {
  const auto dir = std::filesystem::temp_directory_path() / "vigil_can_protocol_stats";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::string log;
  Nanos t = 1'700'000'000 * kNanosPerSecond;
  const auto line = [&](const Frame& f) {
    t += 10 * kNanosPerMilli;
    write_candump_line(log, at(f, t), "can0");
  };
  line(Frame::classic(0x705, {0x05}));
  line(Frame::classic(0x705, {0x00}));
  line(Frame::classic(0x085, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0}));
  line(Frame::error_frame(error_class::kBusOff));
  std::ofstream(dir / "net.log") << log;
  std::ofstream(dir / "can.yaml") << "buses: {all: {bitrate: 500k}}\n";
  vigil::app::CanStatsOptions o;
  o.files = {dir / "net.log"};
  o.config = dir / "can.yaml";
  o.node_map = NodeMapKind::CanOpen;
  std::ostringstream out;
  std::ostringstream err;
  CHECK(vigil::app::run_can_stats(o, out, err) == 0);
  const std::string text = out.str();
  CHECK(text.find("findings: 1 CANopen node, 1 reset, 1 emergency, 0 error passive, 1 bus off") !=
        std::string::npos);
  CHECK(text.find("0x2310 current, device output side") != std::string::npos);
  CHECK(text.find("bus_off") != std::string::npos);
  o.json = true;
  std::ostringstream jout;
  CHECK(vigil::app::run_can_stats(o, jout, err) == 0);
  const std::string json = jout.str();
  CHECK(json.find("\"kind\": \"node_reset\"") != std::string::npos);
  CHECK(json.find("\"bus_offs\": 1") != std::string::npos);
  CHECK(json.find("\"bitrate\": 500000") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("Bus load of the real J1939 truck capture: every frame 29-bit DLC 8",
          "[can][protocol][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  CanConfig cfg;
  cfg.buses.push_back(BusConfig{.bitrate = 250000});
  LogReplay replay({.node_map = NodeMap::j1939(), .protocol = cfg.protocol_options()});
  const std::vector<std::filesystem::path> files{vigil::test::shared_data(kTruckLog)};
  REQUIRE(replay.feed_files(files).has_value());
  const ProtocolSnapshot s = replay.snapshot().protocol;
  REQUIRE(s.buses.size() == 1);
  // The README: 19535 frames, all extended with 8 data bytes: 131 bits each without stuffing,
  // 160 in the worst case.
  const auto& load = s.buses[0].load;
  CHECK(load[0][2].frames == 19535);
  CHECK(load[0][2].bits == 19535ULL * 131);
  CHECK(load[1][2].bits == 19535ULL * 160);
  CHECK(load[2][2].bits > 19535ULL * 131);
  CHECK(load[2][2].bits < 19535ULL * 160);
  // Exact equals the naive count, frame by frame.
  const auto log = read_candump_file(files[0]);
  REQUIRE(log.has_value());
  std::uint64_t naive = 0;
  for (const LogEntry& e : log->entries) naive += naive_exact_bits(e.frame);
  CHECK(load[2][2].bits == naive);
  // Ids from 20 ms to 1 s on a 250 kbit/s bus: a light load, never above 30 % in a second.
  CHECK(load[2][2].peak > 5);
  CHECK(load[2][2].peak < 30);
}

TEST_CASE("Protocol event kinds have their names", "[can][protocol]") {
  using vigil::supervisor::EventKind;
  CHECK(std::string(to_string(EventKind::NmtState)) == "nmt_state");
  CHECK(std::string(to_string(EventKind::NodeReset)) == "node_reset");
  CHECK(std::string(to_string(EventKind::Emergency)) == "emergency");
  CHECK(std::string(to_string(EventKind::NmtCommand)) == "nmt_command");
  CHECK(std::string(to_string(EventKind::ErrorWarning)) == "error_warning");
  CHECK(std::string(to_string(EventKind::ErrorPassive)) == "error_passive");
  CHECK(std::string(to_string(EventKind::BusOff)) == "bus_off");
  CHECK(std::string(to_string(EventKind::ErrorActive)) == "error_active");
}

TEST_CASE("Protocol memory is bounded: events and CANopen nodes", "[can][protocol]") {
  ProtocolOptions o;
  o.max_events = 4;
  o.max_nodes = 2;
  ProtocolTracker t(o);
  for (std::uint32_t node = 1; node <= 5; ++node) {
    FrameRecord r;
    r.id = 0x700 + node;
    r.length = 1;
    r.data[0] = 0x05;
    t.on(r, NodeMapKind::CanOpen);
  }
  const ProtocolSnapshot s = t.snapshot();
  CHECK(s.canopen.size() == 2);
  CHECK(s.untracked_nodes == 3);
  CHECK(s.recent_events.size() == 2);
  // 10 NMT commands: 4 kept, 6 counted as dropped beyond the 2 state events.
  for (int i = 0; i < 10; ++i) {
    FrameRecord r;
    r.id = 0;
    r.length = 2;
    r.data[0] = 0x01;
    t.on(r, NodeMapKind::CanOpen);
  }
  const ProtocolSnapshot s2 = t.snapshot();
  CHECK(s2.events == 12);
  CHECK(s2.recent_events.size() == 4);
  CHECK(s2.events_dropped == 8);
  CHECK(t.events_after(10).size() == 2);
}

namespace {

// A DroneCAN NodeStatus frame from `node`: uptime, health, mode, vendor status, then the tail
// byte of a single-frame transfer (start, end, toggle 0, transfer ID `tid`).
Frame node_status(std::uint8_t node, std::uint32_t uptime, std::uint8_t health, std::uint8_t mode,
                  std::uint16_t vendor = 0, std::uint8_t tid = 0) {
  return Frame::classic(
      dronecan::message_id(16, dronecan::kNodeStatus, node),
      {static_cast<std::uint8_t>(uptime), static_cast<std::uint8_t>(uptime >> 8),
       static_cast<std::uint8_t>(uptime >> 16), static_cast<std::uint8_t>(uptime >> 24),
       static_cast<std::uint8_t>(health << 6 | mode << 3), static_cast<std::uint8_t>(vendor),
       static_cast<std::uint8_t>(vendor >> 8), static_cast<std::uint8_t>(0xC0 | (tid & 0x1F))},
      IdFormat::Extended);
}

}  // namespace

TEST_CASE("DroneCAN NodeStatus: health, mode, uptime, and a restart when the uptime goes back",
          "[can][protocol][dronecan]") {
  // The payload as a receiver logged it (uptime 28 s, all else 0, tail byte C0).
  const std::vector<std::uint8_t> logged{0x1C, 0, 0, 0, 0, 0, 0, 0xC0};
  const auto st = dronecan::decode_node_status(logged);
  REQUIRE(st.has_value());
  CHECK(st->uptime_s == 28);
  CHECK(st->health == dronecan::Health::Ok);
  // Health 2 bits from the top of byte 4, mode 3 bits, sub-mode 3 bits.
  const auto b =
      dronecan::decode_node_status(std::vector<std::uint8_t>{0, 0, 0, 0, 0xCD, 0x34, 0x12});
  REQUIRE(b.has_value());
  CHECK(b->health == dronecan::Health::Critical);  // 0xCD = 11 001 101
  CHECK(b->mode == 1);
  CHECK(b->sub_mode == 5);
  CHECK(b->vendor_status == 0x1234);
  CHECK_FALSE(dronecan::decode_node_status(std::vector<std::uint8_t>{1, 2, 3}).has_value());

  const auto cfg = load_can_config_string("node_map: dronecan\nnodes: {esc: {node: 20}}\n");
  REQUIRE(cfg.has_value());
  test::Pipeline<> p({.node_map = NodeMap::dronecan()});
  Nanos t = 0;
  const auto send = [&](const Frame& f) { p.read(at(f, t += kNanosPerSecond)); };
  send(node_status(20, 100, 0, 0));
  send(node_status(20, 101, 1, 0, 0x00AB));  // WARNING
  send(node_status(20, 102, 1, 0, 0x00AB));
  send(node_status(20, 3, 0, 1));   // uptime back: restart, OK, initialization
  send(node_status(21, 50, 2, 0));  // ERROR from its first status
  Frame short_frame = node_status(21, 51, 2, 0);
  short_frame.length = 5;
  send(short_frame);
  send(node_status(22, 10, 0, 0) /* healthy */);
  CanMonitor monitor(*cfg);
  const CanReport r = monitor.evaluate(p.step(), t);
  const ProtocolSnapshot& s = r.snapshot.protocol;
  const dronecan::NodeStats* esc = s.find_dronecan(0, 20);
  REQUIRE(esc != nullptr);
  CHECK(esc->statuses == 4);
  CHECK(esc->restarts == 1);
  CHECK(esc->uptime_s == 3);
  CHECK(esc->mode == 1);
  CHECK(s.find_dronecan(0, 21)->malformed == 1);
  std::vector<std::string> seen;
  for (const ProtocolEvent& e : s.recent_events) {
    seen.push_back(std::string(to_string(e.kind)) + " " + std::to_string(e.node) + ": " + e.detail);
  }
  CHECK(seen == std::vector<std::string>{
                    "node_health 20: health OK -> WARNING (mode operational)",
                    "node_reset 20: uptime went back from 102 s to 3 s: node restart (1 so far)",
                    "node_health 20: health WARNING -> OK (mode initialization)",
                    "node_health 21: health unknown -> ERROR (mode operational)",
                });
  const NodeReport* n20 = r.find("esc");
  REQUIRE(n20 != nullptr);
  REQUIRE(n20->dronecan.has_value());
  CHECK(n20->status.level() == StatusLevel::Warn);
  CHECK(n20->status.summary().find("node restart: its uptime went back") != std::string::npos);
  CHECK(r.find(0, 21)->status.level() == StatusLevel::Error);
  CHECK(r.find(0, 21)->status.summary().find("NodeStatus health ERROR") != std::string::npos);
  CHECK(r.find(0, 22)->status.level() == StatusLevel::Ok);
  const std::string text = vigil::exporter::format_can_report(r);
  CHECK(text.find("\nDroneCAN\n") != std::string::npos);
  CHECK(vigil::exporter::can_report_json(r).find("\"health\":\"ERROR\"") != std::string::npos);
  CHECK(std::string(to_string(vigil::supervisor::EventKind::NodeHealth)) == "node_health");
}

TEST_CASE("Exact bit count: the packed, table-driven count equals the bit-by-bit one",
          "[can][protocol]") {
  // Random frames of every shape (and runs of equal bits: 0x00 / 0xFF bytes, ids of all ones).
  std::uint64_t x = 0x9E3779B97F4A7C15ULL;
  const auto next = [&] {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    return x;
  };
  for (int i = 0; i < 20000; ++i) {
    std::array<std::uint8_t, 8> data{};
    const std::uint64_t r = next();
    for (std::size_t k = 0; k < 8; ++k) {
      const std::uint64_t pick = (r >> (8 * k)) & 3U;
      data[k] = pick == 0 ? 0x00 : pick == 1 ? 0xFF : static_cast<std::uint8_t>(next());
    }
    const bool extended = (r & 1U) != 0;
    const std::uint32_t mask = extended ? 0x1FFFFFFFU : 0x7FFU;
    const std::uint32_t id = (r & 2U) != 0 ? mask : static_cast<std::uint32_t>(next()) & mask;
    const FrameShape f{.id = id,
                       .extended = extended,
                       .rtr = (r & 4U) != 0 && (r & 8U) != 0,
                       .length = static_cast<std::uint8_t>(next() % 16),
                       .data = data};
    std::array<std::uint8_t, 128> bits{};
    const std::size_t n = classic_frame_bits(f, bits);
    const std::span<const std::uint8_t> used(bits.data(), n);
    INFO("frame " << i << " id " << id << " extended " << extended);
    REQUIRE(exact_classic_bits(f) == n + stuff_bits(used));
  }
}

TEST_CASE("Protocol evidence: what one frame says of its bus's protocol", "[can][protocol]") {
  using B = BusProtocol;
  const auto ev = [](std::uint32_t id, bool ext, std::vector<std::uint8_t> d, bool rtr = false) {
    return detect_protocol_evidence(id, ext, rtr, d);
  };
  // CiA 301 heartbeats and boot-up: 0x700 + node-ID, one byte, an NMT state.
  CHECK(ev(0x705, false, {0x05}) == B::CanOpen);
  CHECK(ev(0x77F, false, {0x7F}) == B::CanOpen);
  CHECK(ev(0x701, false, {0x00}) == B::CanOpen);
  CHECK(ev(0x701, false, {0x04}) == B::CanOpen);
  CHECK(ev(0x700, false, {0x05}) == B::None);        // node-ID 0 is no node
  CHECK(ev(0x780, false, {0x05}) == B::None);        // beyond 0x77F
  CHECK(ev(0x705, false, {0x12}) == B::None);        // no NMT state
  CHECK(ev(0x705, false, {0x05, 0x00}) == B::None);  // two bytes
  CHECK(ev(0x705, false, {}, true) == B::None);      // a guarding request
  CHECK(ev(0x705, true, {0x05}) == B::None);         // 29-bit
  // DroneCAN NodeStatus (type 341 in bits 8-23, message, node 10), single-frame tail 0xC0 | tid.
  const std::uint32_t ns = (16U << 24) | (341U << 8) | 10U;
  CHECK(ev(ns, true, {1, 0, 0, 0, 0, 0, 0, 0xC3}) == B::DroneCan);
  CHECK(ev(ns, true, {1, 0, 0, 0, 0, 0, 0, 0x83}) == B::None);  // not a single-frame transfer
  CHECK(ev(ns | 0x80U, true, {1, 0, 0, 0, 0, 0, 0, 0xC3}) == B::None);  // a service frame
  // J1939 parameter groups only J1939 uses: EEC1 from the engine, CCVS, DM1, address claimed.
  CHECK(ev(0x0CF00400, true, {0, 0, 0, 0, 0, 0, 0, 0}) == B::J1939);
  CHECK(ev(0x18FEF121, true, {0, 0, 0, 0, 0, 0, 0, 0}) == B::J1939);
  CHECK(ev(0x18FECA00, true, {0, 0, 0, 0, 0, 0, 0, 0}) == B::J1939);
  CHECK(ev(0x18EEFF80, true, {0, 0, 0, 0, 0, 0, 0, 0}) == B::J1939);
  CHECK(ev(0x18FF0000, true, {0, 0, 0, 0, 0, 0, 0, 0}) == B::None);  // proprietary B: anyone's
  CHECK(ev(0x0CF004, false, {}) == B::None);
}

TEST_CASE("protocol auto with an identity mapping: the traffic decides, none stays none",
          "[can][protocol][canopen]") {
  Nanos now = 0;
  const auto rec = [&](const Frame& f) { return record_of(f, now += kNanosPerMilli); };
  SECTION("two heartbeats of one node make the bus CANopen; its reset and emergency follow") {
    ProtocolTracker t;
    t.on(rec(Frame::classic(0x705, {0x05})));
    t.on(rec(Frame::classic(0x706, {0x05})));  // another node: not yet
    CHECK_FALSE(t.snapshot().buses.at(0).detected);
    CHECK(t.snapshot().buses.at(0).settings.protocol == BusProtocol::None);
    t.on(rec(Frame::classic(0x705, {0x05})));  // node 5 again: CANopen
    auto s = t.snapshot();
    CHECK(s.buses.at(0).detected);
    CHECK(s.buses.at(0).settings.protocol == BusProtocol::CanOpen);
    CHECK(s.buses.at(0).detected_from.find("node 5 (0x705)") != std::string::npos);
    t.on(rec(Frame::classic(0x085, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0})));
    t.on(rec(Frame::classic(0x705, {0x00})));  // boot-up while operational
    s = t.snapshot();
    const canopen::NodeStats* n = s.find_canopen(0, 5);
    REQUIRE(n != nullptr);
    CHECK(n->resets == 1);
    CHECK(n->emergencies == 1);
    // A new configuration keeps what the traffic said.
    t.set_options(ProtocolOptions{});
    CHECK(t.snapshot().buses.at(0).settings.protocol == BusProtocol::CanOpen);
  }
  SECTION("protocol none is never overruled by the traffic") {
    ProtocolTracker t(ProtocolOptions{.all_buses = {.protocol = BusProtocol::None}});
    for (int i = 0; i < 5; ++i) t.on(rec(Frame::classic(0x705, {0x05})));
    t.on(rec(Frame::classic(0x085, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0})));
    const auto s = t.snapshot();
    CHECK_FALSE(s.buses.at(0).detected);
    CHECK(s.buses.at(0).settings.protocol == BusProtocol::None);
    CHECK(s.canopen.empty());
  }
  SECTION("two J1939 parameter groups make the bus J1939; its DM1 is read") {
    ProtocolTracker t;
    t.on(rec(Frame::classic(0x0CF00400, {0, 0, 0, 0, 0, 0, 0, 0}, IdFormat::Extended)));
    CHECK_FALSE(t.snapshot().buses.at(0).detected);
    t.on(rec(Frame::classic(0x18FEF121, {0, 0, 0, 0, 0, 0, 0, 0}, IdFormat::Extended)));
    CHECK(t.snapshot().buses.at(0).settings.protocol == BusProtocol::J1939);
    // DM1 from 0x00: amber lamp on, SPN 100 FMI 1 occurrence 3.
    t.on(rec(
        Frame::classic(0x18FECA00, {0x04, 0xFF, 100, 0, 0x01, 3, 0xFF, 0xFF}, IdFormat::Extended)));
    const ProtocolSnapshot s = t.snapshot();
    const j1939::NodeStats* n = s.find_j1939(0, 0x00);
    REQUIRE(n != nullptr);
    CHECK(n->active.size() == 1);
  }
  SECTION("two DroneCAN NodeStatus messages make the bus DroneCAN") {
    ProtocolTracker t;
    const std::uint32_t ns = (16U << 24) | (341U << 8) | 10U;
    t.on(rec(Frame::classic(ns, {5, 0, 0, 0, 0, 0, 0, 0xC0}, IdFormat::Extended)));
    t.on(rec(Frame::classic(ns, {6, 0, 0, 0, 0, 0, 0, 0xC1}, IdFormat::Extended)));
    t.on(rec(Frame::classic(ns, {7, 0, 0, 0, 0, 0, 0, 0xC2}, IdFormat::Extended)));
    const auto s = t.snapshot();
    CHECK(s.buses.at(0).settings.protocol == BusProtocol::DroneCan);
    CHECK(s.find_dronecan(0, 10) != nullptr);
  }
}

TEST_CASE("vigil can-stats with no node mapping finds a CANopen network's resets and emergencies",
          "[can][protocol][replay]") {
  const auto dir = std::filesystem::temp_directory_path() / "vigil_can_protocol_auto";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::string log;
  Nanos t = 1'700'000'000 * kNanosPerSecond;
  for (int i = 0; i < 100; ++i) {  // 10 s of heartbeats at 100 ms from nodes 1-3
    t += 100 * kNanosPerMilli;
    for (std::uint32_t n = 1; n <= 3; ++n) {
      std::uint8_t state = 0x05;
      if (n == 2 && i >= 50 && i < 55) continue;  // node 2 reboots
      if (n == 2 && i == 55) state = 0x00;
      if (n == 2 && i > 55 && i < 58) state = 0x7F;
      write_candump_line(log, at(Frame::classic(0x700 + n, {state}), t + n * 1000), "can0");
    }
    if (i == 30) {
      write_candump_line(
          log, at(Frame::classic(0x083, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0}), t + 9000), "can0");
    }
  }
  std::ofstream(dir / "net.log") << log;
  vigil::app::CanStatsOptions o;
  o.files = {dir / "net.log"};
  std::ostringstream out;
  std::ostringstream err;
  CHECK(vigil::app::run_can_stats(o, out, err) == 0);
  const std::string text = out.str();
  CHECK(text.find("protocol: can0 canopen, recognised from CANopen heartbeats of node 1") !=
        std::string::npos);
  CHECK(text.find("findings: 3 CANopen nodes, 1 reset, 1 emergency") != std::string::npos);
  o.json = true;
  std::ostringstream jout;
  CHECK(vigil::app::run_can_stats(o, jout, err) == 0);
  CHECK(jout.str().find("\"protocol_detected\": true") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("Emergencies are events: a burst that ends is no silence, and no node's limit grows",
          "[can][protocol][canopen]") {
  // Heartbeats of nodes 1-3 every 100 ms for 120 s; node 3 sends 30 emergencies (each with its
  // "error reset") at irregular times in the first 50 s, then none: healthy.
  struct Entry {
    Frame frame;
    Direction direction;
  };
  std::vector<Entry> entries;
  const Nanos t0 = 1'000 * kNanosPerSecond;
  for (int i = 0; i < 1200; ++i) {
    const Nanos t = t0 + i * 100 * kNanosPerMilli;
    for (std::uint32_t n = 1; n <= 3; ++n) {
      entries.push_back({at(Frame::classic(0x700 + n, {0x05}), t + n * 1000), Direction::Rx});
    }
  }
  std::uint64_t x = 12345;  // a fixed pseudo-random sequence
  for (int k = 0; k < 30; ++k) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    const Nanos t = t0 + static_cast<Nanos>((x >> 33) % 50'000) * kNanosPerMilli + 7;
    entries.push_back(
        {at(Frame::classic(0x083, {0x10, 0x00, 0x01, 0, 0, 0, 0, 0}), t), Direction::Rx});
    entries.push_back(
        {at(Frame::classic(0x083, {0x00, 0x00, 0x00, 0, 0, 0, 0, 0}), t + 500'000), Direction::Rx});
  }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.frame.timestamp < b.frame.timestamp; });
  for (const NodeMap& map : {NodeMap::identity(), NodeMap::canopen()}) {
    LogReplay replay({.node_map = map});
    for (const Entry& e : entries) replay.feed(e.frame, e.direction);
    const CanReport r = replay.report(CanMonitor(CanConfig{}));
    INFO(vigil::exporter::format_can_report(r));
    CHECK(r.status.level() == StatusLevel::Ok);
    const ProtocolSnapshot& p = r.snapshot.protocol;
    REQUIRE(p.find_canopen(0, 3) != nullptr);
    CHECK(p.find_canopen(0, 3)->emergencies == 60);
    if (map.kind() == NodeMapKind::Identity) {
      const NodeReport* emcy = r.find(0, 0x083);
      REQUIRE(emcy != nullptr);
      CHECK(emcy->liveness == Liveness::OnEvent);
    } else {
      // Node 3's limit is its heartbeat's (2 x 100 ms, at the 250 ms floor), not the bursts'.
      const NodeReport* n3 = r.find(0, 3);
      REQUIRE(n3 != nullptr);
      CHECK(n3->silence_limit_ns == 250 * kNanosPerMilli);
    }
  }
}

TEST_CASE("Event-driven identifiers by protocol", "[can][protocol]") {
  CHECK(event_driven(BusProtocol::CanOpen, 0x085, false));
  CHECK(event_driven(BusProtocol::CanOpen, 0x000, false));
  CHECK(event_driven(BusProtocol::CanOpen, 0x585, false));
  CHECK(event_driven(BusProtocol::CanOpen, 0x605, false));
  CHECK(event_driven(BusProtocol::CanOpen, 0x7E5, false));
  CHECK_FALSE(event_driven(BusProtocol::CanOpen, 0x185, false));  // a TPDO
  CHECK_FALSE(event_driven(BusProtocol::CanOpen, 0x705, false));  // a heartbeat
  CHECK_FALSE(event_driven(BusProtocol::CanOpen, 0x085, true));
  CHECK_FALSE(event_driven(BusProtocol::None, 0x085, false));
  CHECK(event_driven(BusProtocol::J1939, 0x18ECFF00, true));        // TP.CM (BAM)
  CHECK(event_driven(BusProtocol::J1939, 0x18EBFF00, true));        // TP.DT
  CHECK(event_driven(BusProtocol::J1939, 0x18EEFF00, true));        // address claimed
  CHECK(event_driven(BusProtocol::J1939, 0x18EA0021, true));        // request
  CHECK(event_driven(BusProtocol::J1939, 0x18FECB00, true));        // DM2
  CHECK_FALSE(event_driven(BusProtocol::J1939, 0x0CF00400, true));  // EEC1
  CHECK_FALSE(event_driven(BusProtocol::J1939, 0x18FECA00, true));  // DM1: once a second
  CHECK(event_driven(BusProtocol::DroneCan, 0x1E0A8A85U, true));    // a service frame
  CHECK_FALSE(event_driven(BusProtocol::DroneCan, (16U << 24) | (341U << 8) | 10U, true));
  CHECK(to_string(Traffic::Events) == "events");
  CHECK(to_string(Liveness::OnEvent) == "on event");
}
