// The diagnosis graph as pure logic: root causes and dependents, aggregates (and, or, k of n),
// hysteresis, start-up suppression and latches, with times given by hand.
#include "vigil/monitor/diagnosis.hpp"

#include <catch2/catch.hpp>
#include <string>
#include <vector>

using namespace vigil;
using namespace vigil::monitor;

namespace {

constexpr Nanos kS = kNanosPerSecond;

Report unit(std::string name, StatusLevel level = StatusLevel::Ok,
            std::vector<std::string> depends_on = {}) {
  Report r;
  r.kind = ReportKind::Unit;
  r.unit_kind = "test";
  r.name = std::move(name);
  if (level != StatusLevel::Ok) r.status.merge(level, r.name + " is broken");
  r.depends_on = std::move(depends_on);
  return r;
}

const Report& get(const ReportSet& s, std::string_view name) {
  const Report* r = s.find(name);
  REQUIRE(r != nullptr);
  return *r;
}

// The demo's shape: a group that needs its nodes, a supervision that needs its components.
ReportSet robot(StatusLevel drive_5, StatusLevel encoder = StatusLevel::Ok) {
  ReportSet s;
  s.components.push_back(unit("encoder", encoder));
  s.components.push_back(unit("can0/drive_5", drive_5));
  s.components.push_back(unit("can0/drive_6"));
  const StatusLevel group = drive_5 == StatusLevel::Ok ? StatusLevel::Ok : StatusLevel::Error;
  s.components.push_back(unit("can group right_arm", group, {"can0/drive_5", "can0/drive_6"}));
  s.components.push_back(unit("supervision chain", encoder, {"encoder"}));
  return s;
}

}  // namespace

TEST_CASE("The default graph names a failed node as its group's root cause",
          "[monitor][diagnosis]") {
  DiagnosisGraph g;
  ReportSet s = robot(StatusLevel::Error);
  g.apply(s, 0);
  CHECK(s.root_causes == std::vector<std::string>{"can0/drive_5"});
  CHECK(get(s, "can group right_arm").caused_by == std::vector<std::string>{"can0/drive_5"});
  CHECK(get(s, "can0/drive_5").caused_by.empty());
  CHECK(get(s, "can group right_arm").status.level() == StatusLevel::Error);  // still shown

  ReportSet two = robot(StatusLevel::Error, StatusLevel::Error);
  g.apply(two, kS);
  CHECK(two.root_causes == std::vector<std::string>{"encoder", "can0/drive_5"});
  CHECK(get(two, "supervision chain").caused_by == std::vector<std::string>{"encoder"});

  ReportSet healthy = robot(StatusLevel::Ok);
  g.apply(healthy, 2 * kS);
  CHECK(healthy.root_causes.empty());
  for (const Report& r : healthy.components) CHECK(r.caused_by.empty());
}

TEST_CASE("Root causes are found through chains, and a failure of its own is a root",
          "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.units.push_back({.name = "controller", .depends_on = {"can group right_arm"}});
  DiagnosisGraph g(c);
  ReportSet s = robot(StatusLevel::Error);
  s.components.push_back(unit("controller", StatusLevel::Warn));
  s.components.push_back(unit("planner", StatusLevel::Warn, {"encoder"}));  // encoder is OK
  g.apply(s, 0);
  // controller -> right_arm -> drive_5: the controller's root is the node, not the group.
  CHECK(get(s, "controller").caused_by == std::vector<std::string>{"can0/drive_5"});
  CHECK(get(s, "can group right_arm").caused_by == std::vector<std::string>{"can0/drive_5"});
  // The planner needs the encoder, which is OK: its own fault is a root.
  CHECK(get(s, "planner").caused_by.empty());
  CHECK(s.root_causes == std::vector<std::string>{"can0/drive_5", "planner"});
}

TEST_CASE("Without contributor edges only the configured ones count", "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.contributor_edges = false;
  DiagnosisGraph g(c);
  ReportSet s = robot(StatusLevel::Error);
  g.apply(s, 0);
  CHECK(s.root_causes == std::vector<std::string>{"can0/drive_5", "can group right_arm"});
}

TEST_CASE("Aggregates combine units: and, or, k of n", "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.aggregates.push_back({.name = "all", .op = AggregateOp::And, .members = {"a", "b", "c"}});
  c.aggregates.push_back({.name = "any", .op = AggregateOp::Or, .members = {"a", "b", "c"}});
  c.aggregates.push_back(
      {.name = "two", .op = AggregateOp::KOfN, .k = 2, .members = {"a", "b", "c"}});
  c.aggregates.push_back(
      {.name = "three", .op = AggregateOp::KOfN, .k = 3, .members = {"a", "b", "ghost"}});
  DiagnosisGraph g(c);
  ReportSet s;
  s.components.push_back(unit("a"));
  s.components.push_back(unit("b", StatusLevel::Warn));
  s.components.push_back(unit("c", StatusLevel::Error));
  g.apply(s, 0);
  CHECK(get(s, "all").status.level() == StatusLevel::Error);    // the worst member
  CHECK(get(s, "any").status.level() == StatusLevel::Ok);       // one member is OK
  CHECK(get(s, "two").status.level() == StatusLevel::Warn);     // the 2nd best member
  CHECK(get(s, "three").status.level() == StatusLevel::Stale);  // an absent member
  CHECK(get(s, "all").unit_kind == kAggregateUnit);
  CHECK_THAT(get(s, "two").status.summary(),
             Catch::Contains("1 of 3 members OK (needs 2): b WARN, c ERROR"));
  CHECK(get(s, "three").status.summary().find("ghost absent") != std::string::npos);
  // A failed aggregate is explained by its failed members.
  CHECK(get(s, "all").caused_by == std::vector<std::string>{"b", "c"});
  CHECK(get(s, "three").caused_by == std::vector<std::string>{"b"});  // ghost is no report
  CHECK(s.root_causes == std::vector<std::string>{"b", "c"});
}

TEST_CASE("Hysteresis: a status must hold before it is shown, and its end before it clears",
          "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.hysteresis = {.raise_after_ns = 2 * kS, .clear_after_ns = 3 * kS};
  DiagnosisGraph g(c);
  const auto shown = [&](StatusLevel raw, Nanos t) {
    ReportSet s;
    s.components.push_back(unit("node", raw));
    g.apply(s, t);
    return get(s, "node").status;
  };
  CHECK(shown(StatusLevel::Ok, 0).level() == StatusLevel::Ok);
  // A one-cycle flicker is never shown.
  const Status held = shown(StatusLevel::Error, 1 * kS);
  CHECK(held.level() == StatusLevel::Ok);
  CHECK_THAT(held.summary(), Catch::Contains("ERROR for 0ns (shown after 2.00s)"));
  CHECK(shown(StatusLevel::Ok, 2 * kS).level() == StatusLevel::Ok);
  // A lasting one is, once it has held 2 s.
  CHECK(shown(StatusLevel::Error, 3 * kS).level() == StatusLevel::Ok);
  CHECK(shown(StatusLevel::Error, 4 * kS).level() == StatusLevel::Ok);
  CHECK(shown(StatusLevel::Error, 5 * kS).level() == StatusLevel::Error);
  // Its end clears it 3 s later, the last reasons kept until then.
  const Status clearing = shown(StatusLevel::Ok, 6 * kS);
  CHECK(clearing.level() == StatusLevel::Error);
  CHECK_THAT(clearing.summary(), Catch::Contains("clearing: OK for 0ns (cleared after 3.00s)") &&
                                     Catch::Contains("node is broken"));
  CHECK(shown(StatusLevel::Ok, 8 * kS).level() == StatusLevel::Error);
  CHECK(shown(StatusLevel::Ok, 9 * kS).level() == StatusLevel::Ok);
}

TEST_CASE("Hysteresis by monitor cycles: a status must hold for N cycles", "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.hysteresis = {.raise_after_cycles = 3, .clear_after_cycles = 2};
  DiagnosisGraph g(c);
  Nanos t = 0;
  const auto shown = [&](StatusLevel raw) {
    ReportSet s;
    s.components.push_back(unit("node", raw));
    g.apply(s, t += kS / 10);
    return get(s, "node").status;
  };
  CHECK(shown(StatusLevel::Ok).ok());
  CHECK(shown(StatusLevel::Error).ok());         // 1 cycle
  const Status two = shown(StatusLevel::Error);  // 2 cycles
  CHECK(two.ok());
  CHECK_THAT(two.summary(), Catch::Contains("ERROR for 100ms and 2 cycles (shown after 0ns and 3 "
                                            "cycles)"));
  CHECK(shown(StatusLevel::Error).level() == StatusLevel::Error);  // 3 cycles: shown
  CHECK(shown(StatusLevel::Ok).level() == StatusLevel::Error);     // clearing, 1 cycle
  CHECK(shown(StatusLevel::Error).level() == StatusLevel::Error);  // back: the count restarts
  CHECK(shown(StatusLevel::Ok).level() == StatusLevel::Error);
  CHECK(shown(StatusLevel::Ok).ok());  // 2 cycles OK: cleared
}

TEST_CASE("Start-up suppression and latches", "[monitor][diagnosis]") {
  DiagnosisConfig c;
  c.startup_ns = 5 * kS;
  c.units.push_back({.name = "node", .latch = true});
  DiagnosisGraph g(c);
  const auto shown = [&](StatusLevel raw, Nanos t) {
    ReportSet s;
    s.components.push_back(unit("node", raw));
    s.components.push_back(unit("other", raw));
    g.apply(s, t);
    return s;
  };
  ReportSet early = shown(StatusLevel::Error, 10 * kS);  // the first cycle: t0 = 10 s
  CHECK(get(early, "node").status.level() == StatusLevel::Ok);
  CHECK_THAT(get(early, "node").status.summary(),
             Catch::Contains("start-up (0ns of 5.00s): ERROR suppressed"));
  CHECK(early.root_causes.empty());
  ReportSet up = shown(StatusLevel::Error, 15 * kS);
  CHECK(get(up, "node").status.level() == StatusLevel::Error);
  // The latched unit stays ERROR after its fault ends; the other clears.
  ReportSet after = shown(StatusLevel::Ok, 16 * kS);
  CHECK(get(after, "node").status.level() == StatusLevel::Error);
  CHECK_THAT(get(after, "node").status.summary(), Catch::Contains("latched (now OK"));
  CHECK(get(after, "other").status.level() == StatusLevel::Ok);
  CHECK(after.root_causes == std::vector<std::string>{"node"});
  CHECK(g.clear("other") == 0);
  CHECK(g.clear("node") == 1);
  CHECK(get(shown(StatusLevel::Ok, 17 * kS), "node").status.level() == StatusLevel::Ok);
}

TEST_CASE("A bad diagnosis configuration is refused with its reason", "[monitor][diagnosis]") {
  const auto error_of = [](const DiagnosisConfig& c) {
    auto r = validate(c);
    REQUIRE_FALSE(r.has_value());
    return r.error().message;
  };
  DiagnosisConfig cycle;
  cycle.units.push_back({.name = "a", .depends_on = {"b"}});
  cycle.units.push_back({.name = "b", .depends_on = {"c"}});
  cycle.units.push_back({.name = "c", .depends_on = {"a"}});
  CHECK(error_of(cycle) == "the dependencies form a cycle: a -> b -> c -> a");
  DiagnosisConfig k;
  k.aggregates.push_back({.name = "x", .op = AggregateOp::KOfN, .k = 3, .members = {"a", "b"}});
  CHECK(error_of(k) == "aggregate 'x': k = 3 is not within 1..2 (its members)");
  DiagnosisConfig twice;
  twice.units.push_back({.name = "a"});
  twice.units.push_back({.name = "a"});
  CHECK(error_of(twice) == "unit 'a' is named twice");
  DiagnosisConfig self;
  self.units.push_back({.name = "a", .depends_on = {"a"}});
  CHECK(error_of(self) == "unit 'a' depends on itself");
  DiagnosisConfig empty;
  empty.aggregates.push_back({.name = "x"});
  CHECK(error_of(empty) == "aggregate 'x' has no members");
  CHECK_THROWS_AS(DiagnosisGraph(cycle), std::invalid_argument);
}
