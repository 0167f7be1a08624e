#include "vigil/export/json_report.hpp"

#include <catch2/catch.hpp>
#include <set>

#include "monitor/harness.hpp"
#include "support/json_reader.hpp"

using namespace vigil;
using vigil::test::Json;
using vigil::test::JsonParser;

namespace {

ReportSet sample_reports() {
  static test::Harness h;  // kept alive: the reports refer to nothing, but keep it simple
  static test::PeriodicProbe healthy(h, "healthy", kNanosPerMilli);
  static test::PeriodicProbe thrower(h, "thr\"ower", kNanosPerMilli);
  static test::Probe idle("idle", h.registry, h.clock);
  static bool once = [] {
    healthy.probe.work_ns = 100 * kNanosPerMicro;
    for (int i = 0; i < 10; ++i) h.cycle(healthy.activity);
    h.supervisor.step();
    for (int i = 0; i < 3; ++i) h.cycle(thrower.activity);
    thrower.probe.throw_next = true;
    h.cycle(thrower.activity);
    return true;
  }();
  (void)once;
  return h.step();
}

void require_stats(const Json& s) {
  REQUIRE(s.is_object());
  for (const char* k :
       {"count", "last", "min", "mean", "ewma", "max", "p50", "p90", "p99", "p999"}) {
    INFO(k);
    REQUIRE(s.has(k));
    CHECK(s[k].is_number());
  }
}

}  // namespace

TEST_CASE("The JSON report follows schema 2", "[export][json_report]") {
  const ReportSet set = sample_reports();
  const std::string text = to_json(set);
  CHECK(text.find('\n') == std::string::npos);  // compact: one line
  const Json doc = JsonParser::parse(text);     // throws if not valid JSON

  CHECK(doc["schema"].number_text() == "2");
  CHECK(doc["generator"].str().rfind("vigil ", 0) == 0);
  CHECK(doc["cycle"].is_integer());
  CHECK(doc["time_ns"].is_integer());
  CHECK(doc["status"].str() == "ERROR");
  const auto& components = doc["components"].array();
  REQUIRE(components.size() == set.components.size());

  const std::set<std::string> levels{"OK", "WARN", "ERROR", "STALE"};
  for (const Json& c : components) {
    INFO(c["name"].str());
    CHECK(c["name"].is_string());
    CHECK(levels.count(c["status"].str()) == 1);
    for (const Json& m : c["messages"].array()) CHECK(m.is_string());
    CHECK(c["findings"].array().size() == c["messages"].array().size());
    CHECK(c["state"].is_string());
    CHECK(c["period_ns"].is_integer());
    CHECK(c["kind"].is_string());
    CHECK(c["alive"].is_bool());
    CHECK(c["configured"].is_bool());
    for (const char* k : {"id", "priority", "cpu", "tid", "tasks_on_thread"}) {
      CHECK(c[k].is_integer());
    }
    for (const char* k : {"activity", "policy", "requested_policy"}) CHECK(c[k].is_string());
    const Json& counters = c["counters"];
    for (const char* k :
         {"cycles", "samples", "overruns", "missed_cycles", "rt_losses", "exceptions", "dropped"}) {
      INFO(k);
      CHECK(counters[k].is_integer());
    }
    for (const char* cause :
         {"allocation", "blocking", "minor_fault", "major_fault", "mode_switch"}) {
      CHECK(counters["rt_losses_by_cause"][cause].is_integer());
    }
    const Json& window = c["window"];
    CHECK(window["first"].is_bool());
    for (const char* k : {"duration_ns", "cycles", "overruns", "missed_cycles", "rt_losses",
                          "exceptions", "dropped"}) {
      CHECK(window[k].is_integer());
    }
    const Json& timing = c["timing"];
    for (const char* k :
         {"execution_ns", "total_ns", "latency_ns", "measured_period_ns", "overhead_ns"}) {
      INFO(k);
      require_stats(timing[k]);
    }
    CHECK(timing["overhead_share"].is_number());
    CHECK((timing["silence_ns"].is_null() || timing["silence_ns"].is_integer()));
    CHECK(c["port"]["capacity"].is_integer());
    CHECK(c["port"]["high_water"].is_integer());
    CHECK((c["exception"].is_null() || c["exception"].is_object()));
    CHECK((c["thread"].is_null() || c["thread"].is_object()));
    for (const Json& kv : c["values"].array()) {
      CHECK(kv["key"].is_string());
      CHECK(kv["value"].is_string());
    }
  }
}

TEST_CASE("The JSON report carries each component's data", "[export][json_report]") {
  const Json doc = JsonParser::parse(to_json(sample_reports(), {.indent = 2}));
  std::map<std::string, const Json*> by_name;
  for (const Json& c : doc["components"].array()) by_name[c["name"].str()] = &c;
  REQUIRE(by_name.count("healthy") == 1);
  REQUIRE(by_name.count("thr\"ower") == 1);  // escaped and read back
  REQUIRE(by_name.count("idle") == 1);
  REQUIRE(by_name.count("vigil.supervisor") == 1);
  REQUIRE(by_name.count("vigil.monitor") == 1);

  const Json& h = *by_name["healthy"];
  CHECK(h["status"].str() == "OK");
  CHECK(h["messages"].array().empty());
  CHECK(h["state"].str() == "Running");
  CHECK(h["kind"].str() == "component");
  CHECK(h["period_ns"].number_text() == "1000000");
  CHECK(h["counters"]["cycles"].number_text() == "10");
  CHECK(h["timing"]["execution_ns"]["mean"].number() == 100000.0);
  CHECK(h["timing"]["execution_ns"]["count"].number_text() == "10");
  CHECK(h["exception"].is_null());

  const Json& t = *by_name["thr\"ower"];
  CHECK(t["status"].str() == "ERROR");
  CHECK(t["state"].str() == "Exception");
  CHECK(t["counters"]["exceptions"].number_text() == "1");
  CHECK(t["exception"]["type"].str() == "std::runtime_error");
  CHECK(t["exception"]["message"].str() == "boom: \"quoted\"\nsecond line");
  CHECK(t["exception"]["hook"].str() == "update");
  CHECK(t["findings"][0]["level"].str() == "ERROR");

  const Json& i = *by_name["idle"];
  CHECK(i["status"].str() == "WARN");
  REQUIRE(i["messages"].array().size() == 1);
  CHECK(i["messages"][0].str() == "not configured");
  CHECK_FALSE(i["configured"].boolean());

  CHECK((*by_name["vigil.supervisor"])["kind"].str() == "supervisor");
  CHECK((*by_name["vigil.monitor"])["kind"].str() == "monitor");
}

TEST_CASE("A unit is written with its kind and its fields under their names",
          "[export][json_report]") {
  ReportSet set;
  Report node;
  node.kind = ReportKind::Unit;
  node.unit_kind = "can_node";
  node.name = "can0/drive_5";
  node.state_label = "not responding";
  node.merge(StatusLevel::Error, "silent for 250ms");
  node.add_field(Field::of_count("frames_rx", 120));
  node.add_field(Field::of_duration("silence", 250 * kNanosPerMilli));
  node.add_field(Field::of_distribution("rx_gap", StatsSummary{.count = 3, .p50 = 1'000'000}));
  node.add_field(Field::of_text("limit", "learned"));
  set.components.push_back(node);
  const Json doc = JsonParser::parse(to_json(set));
  const Json& u = doc["components"].array().at(0);
  CHECK(u["kind"].str() == "can_node");
  CHECK(u["state"].str() == "not responding");
  CHECK(u["status"].str() == "ERROR");
  CHECK(u["messages"].array().at(0).str() == "silent for 250ms");
  const Json& f = u["fields"];
  CHECK(f["frames_rx"].number_text() == "120");
  CHECK(f["silence_ns"].number_text() == "250000000");
  require_stats(f["rx_gap_ns"]);
  CHECK(f["rx_gap_ns"]["p50"].number_text() == "1000000");
  CHECK(f["limit"].str() == "learned");
  // None of a component's members: a unit is not a component.
  for (const char* k : {"counters", "timing", "window", "period_ns", "activity"}) {
    INFO(k);
    CHECK_FALSE(u.has(k));
  }
}
