// The CAN monitor's report as text and JSON (vigil/export/can_report.hpp).
#include "vigil/export/can_report.hpp"

#include <catch2/catch.hpp>

#include "can/can_test_support.hpp"
#include "support/json_reader.hpp"

using namespace vigil::can;
using vigil::kNanosPerMicro;
using vigil::kNanosPerMilli;
using vigil::can::test::frame;
using vigil::can::test::Pipeline;

namespace {
CanConfig config_of(std::string_view yaml) {
  auto c = load_can_config_string(yaml, "test.yaml");
  if (!c) FAIL(vigil::config::to_string(c.error()));
  return *c;
}
}  // namespace

TEST_CASE("CAN report as text and JSON", "[export][can]") {
  Pipeline<256> p({.node_map = NodeMap::canopen()});
  for (int i = 1; i <= 20; ++i) {
    p.read(frame(0x181, i * kNanosPerMilli), 10 * kNanosPerMicro);
    p.write(frame(0x201, i * kNanosPerMilli), 20 * kNanosPerMicro);
  }
  p.supervisor.step();
  const CanMonitor monitor(config_of(R"(
nodes: {base: {node: 1}, "ghost \"node\"": {node: 7}}
groups: {arm: {nodes: [1, 2], expected: false}}
)"));
  const CanReport r = monitor.evaluate(p.aggregator, 20 * kNanosPerMilli);
  const std::string text = vigil::exporter::format_can_report(r, {.bus_names = {"can0"}});
  INFO(text);
  CHECK(text.find("CAN status: ERROR") == 0);
  CHECK(text.find("\nSummary\nCATEGORY") != std::string::npos);
  CHECK(text.find("group arm") != std::string::npos);
  CHECK(text.find("ghost \"node\"") != std::string::npos);
  CHECK(text.find("not initialized: never seen") != std::string::npos);
  CHECK(text.find("TPDO1") != std::string::npos);
  CHECK(text.find("can0") != std::string::npos);

  const auto j = vigil::test::JsonParser::parse(vigil::exporter::can_report_json(r, 2, {"can0"}));
  CHECK(j["schema"].number() == 1);
  CHECK(j["status"].str() == "ERROR");
  CHECK(j["node_map"].str() == "canopen");
  CHECK(j["totals"]["frames"].number() == 40);
  const auto& summary = j["summary"].array();
  REQUIRE(summary.size() == 4);  // all Rx, all Tx, arm Rx, arm Tx
  CHECK(summary[0]["category"].str() == "all");
  CHECK(summary[0]["io_us"]["mean"].number() == Approx(10.0));
  CHECK(summary[0]["gap_us"]["min"].number() == Approx(1000.0));
  const auto& nodes = j["nodes"].array();
  REQUIRE(nodes.size() == 2);
  CHECK(nodes[0]["name"].str() == "base");
  CHECK(nodes[0]["bus_name"].str() == "can0");
  CHECK(nodes[0]["rx"]["frames"].number() == 20);
  CHECK(nodes[0]["tx"]["io_ns"]["max"].number() == 20000);
  CHECK(nodes[1]["name"].str() == "ghost \"node\"");
  CHECK(nodes[1]["bus"].is_null());
  CHECK(nodes[1]["status"].str() == "ERROR");
  CHECK(nodes[1]["rx"].is_null());
  const auto& ids = j["ids"].array();
  REQUIRE(ids.size() == 2);
  CHECK(ids[0]["id"].str() == "181");
  CHECK(ids[0]["gap_ns"]["p50"].number() == 1'000'000);
  CHECK(j["sniffers"][0]["name"].str() == "test-bus");
}
