#include "vigil/can/can_config.hpp"

#include <catch2/catch.hpp>

#include "can_test_support.hpp"
#include "vigil/config/load.hpp"

using namespace vigil::can;
using vigil::kNanosPerMilli;
using vigil::config::ConfigError;
using vigil::config::ConfigErrors;

namespace {
CanConfig ok(std::string_view yaml) {
  auto c = load_can_config_string(yaml, "can.yaml");
  if (!c) FAIL(vigil::config::to_string(c.error()));
  return *c;
}
std::vector<std::string> errors(std::string_view yaml) {
  auto c = load_can_config_string(yaml, "can.yaml");
  REQUIRE_FALSE(c.has_value());
  std::vector<std::string> out;
  for (const ConfigError& e : c.error()) out.push_back(e.to_string());
  return out;
}
Filter filter_of(std::string_view yaml) {
  auto f = Filter::compile(ok(yaml).filter);
  REQUIRE(f.has_value());
  return *f;
}
bool accepts(const Filter& f, const Frame& fr, const NodeMap& m = {}, Direction d = Direction::Rx) {
  return f.matches(fr, d, m);
}
}  // namespace

TEST_CASE("CAN config: an empty file gives the defaults", "[can][config]") {
  const CanConfig c = ok("");
  CHECK(c.node_map == NodeMapKind::Identity);
  CHECK(c.filter.accepts_all());
  CHECK(c.nodes.empty());
  CHECK(c.groups.empty());
  const NodeThresholds t = c.thresholds_for(0, 1);
  CHECK(t.never_seen_enabled);
  CHECK_FALSE(t.not_responding_after_ns.has_value());  // learned from each node's traffic
  CHECK(t.learn.percentile == LimitStat::P99);
  CHECK(t.learn.factor == 2.0);
  CHECK(t.learn.floor_ns == 250 * vigil::kNanosPerMilli);
  CHECK(t.learn.min_gaps == 16);
  CHECK(t.answer_within_ns == vigil::kNanosPerSecond);
  CHECK_FALSE(t.rx_gap.enabled());
  CHECK(ok("filter: {}\n").filter.accepts_all());
  CHECK(ok("filter:\n").filter.accepts_all());
}

TEST_CASE("CAN config: filters in YAML compose bus, ids, ranges, nodes, format, payload",
          "[can][config][filter]") {
  const Filter f = filter_of(R"(
node_map: canopen
filter:
  bus: [0, 1]
  format: standard
  any:
    - ids: [0x181, 0x182]
    - id_range: [0x200, 0x27F]
    - {nodes: [11, 12], direction: tx}
    - all: [{ids: 0x60B}, {payload: {byte: 0, value: 0x2F}}]
  not: {id_mask: {id: 0x700, mask: 0x780}}
)");
  const NodeMap canopen = NodeMap::canopen();
  using vigil::can::test::frame;
  CHECK(accepts(f, frame(0x181), canopen));
  CHECK(accepts(f, frame(0x181, 0, 1), canopen));
  CHECK_FALSE(accepts(f, frame(0x181, 0, 2), canopen));  // bus
  CHECK_FALSE(accepts(f, Frame::classic(0x181, {}, IdFormat::Extended), canopen));
  CHECK(accepts(f, frame(0x23F), canopen));
  CHECK_FALSE(accepts(f, frame(0x183), canopen));
  CHECK(accepts(f, frame(0x58B), canopen, Direction::Tx));  // node 11, Tx
  CHECK_FALSE(accepts(f, frame(0x58B), canopen, Direction::Rx));
  CHECK_FALSE(accepts(f, frame(0x70B), canopen, Direction::Tx));  // heartbeats excluded
  CHECK(accepts(f, frame(0x60B, 0, 0, {0x2F, 0, 0x60}), canopen));
  CHECK_FALSE(accepts(f, frame(0x60B, 0, 0, {0x40, 0, 0x60}), canopen));

  const Filter g = filter_of(R"(
filter:
  format: extended
  functions: [65265]
  fd: false
  remote: false
  node_range: [0x00, 0x20]
  payload: [{byte: 1, value: 0x10, mask: 0xF0}, {byte: 2, value: 0}]
)");
  const NodeMap j1939 = NodeMap::j1939();
  CHECK(accepts(g, Frame::classic(0x18FEF100, {0, 0x1F, 0}, IdFormat::Extended), j1939));
  CHECK_FALSE(accepts(g, Frame::classic(0x18FEF121, {0, 0x1F, 0}, IdFormat::Extended), j1939));
  CHECK_FALSE(accepts(g, Frame::classic(0x18FEF100, {0, 0x2F, 0}, IdFormat::Extended), j1939));
  CHECK_FALSE(accepts(g, Frame::remote(0x18FEF100, 8, IdFormat::Extended), j1939));
}

TEST_CASE("CAN config: filter errors name file, line, column and field", "[can][config][filter]") {
  const auto e = errors(R"(filter:
  bus: 256
  ids: [0x181, 0x20000000]
  id_range: [0x300, 0x200]
  direction: out
  idz: [1]
  payload: {byte: 64, value: 1}
  any: {ids: 1}
  id_mask: {id: 0x100}
)");
  CHECK(e == std::vector<std::string>{
                 "can.yaml:2:8: filter.bus: must be between 0 and 255, got '256'",
                 "can.yaml:3:16: filter.ids[1]: must be at most 0x1FFFFFFF, got '0x20000000'",
                 "can.yaml:4:14: filter.id_range[0]: lo (0x300) must not be above hi (0x200)",
                 "can.yaml:5:14: filter.direction: 'out' is not one of rx, tx",
                 "can.yaml:6:3: filter.idz: unknown key; did you mean 'ids'?",
                 "can.yaml:7:19: filter.payload.byte: must be between 0 and 63, got '64'",
                 "can.yaml:8:8: filter.any: expected a sequence of filters",
                 "can.yaml:9:12: filter.id_mask.mask: required key is missing",
             });
}

TEST_CASE("CAN config: nodes, groups and threshold errors", "[can][config]") {
  const auto e = errors(R"(node_map: canopn
defaults:
  rx_gap: {warn: 20ms, error: 10ms}
  read_time: {warn: 5 parsecs, stat: p95}
  not_responding: {after: 0s, level: FATAL}
nodes:
  elbow: {bus: 1}
groups:
  arm: {bus: 0}
  legs: {node_range: [5], nodez: [1]}
)");
  for (const std::string& line : e) UNSCOPED_INFO(line);
  REQUIRE(e.size() == 10);
  CHECK(e[0] ==
        "can.yaml:1:11: node_map: 'canopn' is not one of identity, canopen, j1939, dronecan; "
        "did you mean 'canopen'?");
  CHECK(e[1] == "can.yaml:3:18: defaults.rx_gap.warn: must not be above error (10ms)");
  CHECK(e[2].rfind("can.yaml:4:21: defaults.read_time.warn: '5 parsecs' has an unknown unit", 0) ==
        0);
  CHECK(e[3].rfind("can.yaml:4:38: defaults.read_time.stat: 'p95' is not one of", 0) == 0);
  CHECK(e[4] == "can.yaml:5:27: defaults.not_responding.after: must be positive, got '0s'");
  CHECK(e[5].rfind("can.yaml:5:38: defaults.not_responding.level: 'FATAL' is not one of OK, "
                   "WARN, ERROR",
                   0) == 0);
  CHECK(e[6] == "can.yaml:7:10: nodes.elbow.node: required key is missing");
  CHECK(e[7] == "can.yaml:9:8: groups.arm: a group needs 'nodes' or 'node_range'");
  CHECK(e[8] == "can.yaml:10:22: groups.legs.node_range: expected two values [lo, hi], got 1");
  CHECK(e[9] == "can.yaml:10:27: groups.legs.nodez: unknown key; did you mean 'nodes'?");
}

TEST_CASE("CAN config: a complete file", "[can][config]") {
  const CanConfig c = ok(R"(
node_map: j1939
filter: {format: extended}
defaults:
  never_seen: {level: WARN}
  not_responding: {after: 250ms}
  rx_gap: {warn: 150ms, error: 3s, stat: p99}
nodes:
  engine: {node: 0x00, bus: 0}
  brakes: {node: 0x0B}
  body: {node: 0x21, expected: false, thresholds: {not_responding: {after: 2s}}}
groups:
  powertrain: {nodes: [0x00, 0x03], thresholds: {rx_gap: {warn: 30ms}}}
  all_ecus: {node_range: [0, 0xFD], expected: false}
)");
  CHECK(c.node_map == NodeMapKind::J1939);
  CHECK(c.filter.to_string() == "extended()");
  REQUIRE(c.nodes.size() == 3);
  CHECK(c.nodes[0].name == "engine");
  CHECK(c.nodes[0].bus == std::uint8_t{0});
  CHECK_FALSE(c.nodes[1].bus.has_value());
  CHECK_FALSE(c.nodes[2].expected);
  REQUIRE(c.groups.size() == 2);
  CHECK(c.groups[0].members.nodes == std::vector<std::uint32_t>{0, 3});
  CHECK(c.groups[1].members.node_ranges.front() == std::make_pair(0U, 0xFDU));
  const auto specs = c.group_specs();
  REQUIRE(specs.size() == 2);
  CHECK(specs[1].name == "all_ecus");
  const NodeThresholds engine = c.thresholds_for(0, 0);
  CHECK(engine.never_seen_level == vigil::StatusLevel::Warn);
  CHECK(engine.rx_gap.warn == 30 * kNanosPerMilli);
  CHECK(engine.rx_gap.error == 3 * vigil::kNanosPerSecond);
  CHECK(engine.rx_gap.stat == LimitStat::P99);
  CHECK(c.thresholds_for(0, 0x21).not_responding_after_ns == 2 * vigil::kNanosPerSecond);
  CHECK(c.thresholds_for(0, 0x0B).not_responding_after_ns == 250 * kNanosPerMilli);
}

TEST_CASE("CAN config: a filter loaded on its own", "[can][config][filter]") {
  auto f = vigil::config::load_string("{ids: [1, 2], not: {bus: 1}}", "f.yaml",
                                      [](const vigil::config::Node& n) { return load_filter(n); });
  REQUIRE(f.has_value());
  CHECK(f->to_string() == "all(ids(0x1, 0x2), not(bus(1)))");
  auto bad = vigil::config::load_string(
      "[1, 2]", "f.yaml", [](const vigil::config::Node& n) { return load_filter(n); });
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().front().to_string() == "f.yaml:1:1: expected a mapping of conditions");
}

TEST_CASE("CAN config: LimitStat names and values", "[can][config]") {
  vigil::StatsSummary s;
  s.last = 1;
  s.mean = 2.4;
  s.ewma = 2.6;
  s.max = 9;
  s.p50 = 5;
  s.p90 = 6;
  s.p99 = 7;
  s.p999 = 8;
  CHECK(stat_value(s, LimitStat::Last) == 1);
  CHECK(stat_value(s, LimitStat::Mean) == 2);
  CHECK(stat_value(s, LimitStat::Ewma) == 3);
  CHECK(stat_value(s, LimitStat::Max) == 9);
  CHECK(stat_value(s, LimitStat::P50) == 5);
  CHECK(stat_value(s, LimitStat::P999) == 8);
  CHECK(to_string(LimitStat::P999) == "p999");
}

TEST_CASE("CAN config: learned deadlines, configured limits win, `after: learned` restores",
          "[can][config]") {
  const CanConfig c = ok(R"(
node_map: dronecan
defaults:
  not_responding: {after: 1s}
groups:
  escs: {node_range: [20, 23], expected: false,
         thresholds: {not_responding: {after: learned, factor: 3, floor: 100ms, min_gaps: 8,
                                       percentile: max, answer_within: 500ms}}}
nodes:
  esc_23: {node: 23, thresholds: {not_responding: {after: 2s}}}
)");
  CHECK(c.node_map == NodeMapKind::DroneCan);
  CHECK(c.thresholds_for(0, 10).not_responding_after_ns == vigil::kNanosPerSecond);
  const NodeThresholds esc = c.thresholds_for(0, 20);
  CHECK_FALSE(esc.not_responding_after_ns.has_value());  // learned again in the group
  CHECK(esc.learn.factor == 3.0);
  CHECK(esc.learn.floor_ns == 100 * vigil::kNanosPerMilli);
  CHECK(esc.learn.min_gaps == 8);
  CHECK(esc.learn.percentile == LimitStat::Max);
  CHECK(esc.answer_within_ns == 500 * vigil::kNanosPerMilli);
  CHECK(c.thresholds_for(0, 23).not_responding_after_ns == 2 * vigil::kNanosPerSecond);

  const auto e = errors(R"(defaults:
  not_responding: {after: learnt, factor: 0.5, floor: -1ms, min_gaps: 0, percentile: p95}
)");
  for (const std::string& line : e) UNSCOPED_INFO(line);
  REQUIRE(e.size() == 5);
  INFO(e[0]);
  CHECK(e[0] ==
        "can.yaml:2:27: defaults.not_responding.after: expected a duration such as "
        "'100ms', or 'learned', got 'learnt'");
  CHECK(e[1] ==
        "can.yaml:2:43: defaults.not_responding.factor: must be between 1 and 100, "
        "got '0.5'");
  CHECK(e[2].rfind("can.yaml:2:55: defaults.not_responding.floor:", 0) == 0);
  CHECK(e[3].rfind("can.yaml:2:71: defaults.not_responding.min_gaps: must be between 1 and", 0) ==
        0);
  CHECK(e[4].rfind("can.yaml:2:86: defaults.not_responding.percentile: 'p95' is not one of", 0) ==
        0);
}
