// The `diagnosis:` section of a deployment: parsing, errors at their line and column (unit names
// checked when the system is built), and a System whose reports carry the graph's results.
#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

class Idle : public Task<Idle> {
 public:
  explicit Idle(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};

// Throws from its first cycle: ERROR (an exception) at once.
class Thrower : public Task<Thrower> {
 public:
  explicit Thrower(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() { throw std::runtime_error("broken on purpose"); }
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Idle>("test.idle") && f.add<Thrower>("test.thrower");
  (void)once;
  return f;
}

constexpr const char* kHead = R"(activities: [{name: a, period: 1ms}]
components:
  - {name: sensor, type: test.thrower, activity: a}
  - {name: planner, type: test.idle, activity: a}
  - {name: logger, type: test.idle, activity: a}
supervision: {lock_memory: false, monitor_period: 50ms}
)";

std::string errors_of(const std::string& section) {
  auto d = load_deployment_string(std::string(kHead) + section, "g.yaml", factory());
  if (!d) return config::to_string(d.error());
  auto sys = System::create(std::move(*d), factory());
  REQUIRE_FALSE(sys.has_value());
  return config::to_string(sys.error());
}

}  // namespace

TEST_CASE("A diagnosis section parses into the graph's configuration", "[deploy][diagnosis]") {
  auto d = load_deployment_string(std::string(kHead) + R"(diagnosis:
  startup: 2s
  hysteresis: {raise_after: 100ms, clear_after: 3s}
  units:
    - {name: planner, depends_on: [sensor], latch: true,
       hysteresis: {clear_after: 1s, raise_after_cycles: 2, clear_after_cycles: 3}}
  aggregates:
    - {name: inputs, op: k_of_n, k: 1, members: [sensor, logger], depends_on: [planner]}
    - {name: all, members: [sensor, planner, logger]}
)",
                                  "g.yaml", factory());
  REQUIRE(d.has_value());
  const monitor::DiagnosisConfig& c = d->diagnosis.config;
  CHECK(d->diagnosis.defined);
  CHECK(c.startup_ns == 2 * kNanosPerSecond);
  CHECK(c.hysteresis.raise_after_ns == 100 * kNanosPerMilli);
  CHECK(c.hysteresis.clear_after_ns == 3 * kNanosPerSecond);
  REQUIRE(c.units.size() == 1);
  CHECK(c.units[0].depends_on == std::vector<std::string>{"sensor"});
  CHECK(c.units[0].latch);
  REQUIRE(c.units[0].hysteresis.has_value());
  CHECK(c.units[0].hysteresis->clear_after_ns == kNanosPerSecond);
  CHECK(c.units[0].hysteresis->raise_after_cycles == 2);
  CHECK(c.units[0].hysteresis->clear_after_cycles == 3);
  REQUIRE(c.aggregates.size() == 2);
  CHECK(c.aggregates[0].op == monitor::AggregateOp::KOfN);
  CHECK(c.aggregates[0].k == 1);
  CHECK(c.aggregates[1].op == monitor::AggregateOp::And);  // the default
}

TEST_CASE("A bad diagnosis section is an error at its line and column", "[deploy][diagnosis]") {
  SECTION("a unit the system does not have, with a suggestion") {
    const std::string e = errors_of(R"(diagnosis:
  units: [{name: planner, depends_on: [sensr]}]
)");
    CHECK_THAT(e, Catch::Contains("g.yaml:8:40:") &&
                      Catch::Contains("no unit named 'sensr'; did you mean 'sensor'?"));
  }
  SECTION("a cycle") {
    const std::string e = errors_of(R"(diagnosis:
  units:
    - {name: planner, depends_on: [logger]}
    - {name: logger, depends_on: [planner]}
)");
    CHECK_THAT(e,
               Catch::Contains("g.yaml:8:") &&
                   Catch::Contains("the dependencies form a cycle: logger -> planner -> logger"));
  }
  SECTION("k above the members, and k without k_of_n") {
    const std::string e = errors_of(R"(diagnosis:
  aggregates:
    - {name: x, op: k_of_n, k: 3, members: [sensor, logger]}
    - {name: y, op: or, k: 1, members: [sensor]}
)");
    CHECK_THAT(
        e, Catch::Contains("g.yaml:9:32:") && Catch::Contains("k = 3 is more than its 2 members"));
    CHECK_THAT(e, Catch::Contains("g.yaml:10:28:") && Catch::Contains("k is for op: k_of_n"));
  }
  SECTION("a name configured twice, an unknown op") {
    const std::string e = errors_of(R"(diagnosis:
  units: [{name: planner}, {name: planner}]
  aggregates: [{name: z, op: xor, members: [sensor]}]
)");
    CHECK_THAT(e, Catch::Contains("'planner' is configured twice (first at line 8)"));
    CHECK_THAT(e, Catch::Contains("g.yaml:9:"));
  }
}

TEST_CASE("A System's reports carry the graph: aggregates, root causes, dependents",
          "[deploy][diagnosis]") {
  auto d = load_deployment_string(std::string(kHead) + R"(diagnosis:
  units: [{name: planner, depends_on: [sensor]}]
  aggregates:
    - {name: inputs, op: or, members: [sensor, logger]}
    - {name: all, members: [sensor, logger]}
)",
                                  "g.yaml", factory());
  REQUIRE(d.has_value());
  auto sys = System::create(std::move(*d), factory());
  REQUIRE(sys.has_value());
  System& s = **sys;
  REQUIRE(s.start().has_value());
  ReportSet r;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < until) {
    r = s.reports();
    if (const Report* sensor = r.find("sensor");
        sensor != nullptr && sensor->status.level() == StatusLevel::Error) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  s.stop();
  REQUIRE(r.find("sensor") != nullptr);
  REQUIRE(r.find("sensor")->status.level() == StatusLevel::Error);
  CHECK(r.root_causes == std::vector<std::string>{"sensor"});
  const Report* all = r.find("all");
  REQUIRE(all != nullptr);
  CHECK(all->unit_kind == "aggregate");
  CHECK(all->status.level() == StatusLevel::Error);
  CHECK(all->caused_by == std::vector<std::string>{"sensor"});
  const Report* inputs = r.find("inputs");
  REQUIRE(inputs != nullptr);
  CHECK(inputs->status.level() == StatusLevel::Ok);  // the logger is fine
  CHECK(r.find("planner")->status.ok());             // OK: nothing to explain
}
