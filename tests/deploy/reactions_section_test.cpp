// The `reactions:` section of a deployment: errors at their line and column (names checked when
// the system is built), and a System that reacts: a component's exception raises the safe
// state, a component with `safe_state: stop` stops, one with a fallback runs it.
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/safe_state.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

class Idle : public Task<Idle> {
 public:
  explicit Idle(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};

std::atomic<int> fallback_cycles{0};

// Holds once the safe state is requested.
class Holder : public Task<Holder> {
 public:
  explicit Holder(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
  void on_safe_state() { ++fallback_cycles; }
};

// Throws after 100 ms.
class Thrower : public Task<Thrower> {
 public:
  explicit Thrower(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {
    if (++n_ > 100) throw std::runtime_error("broken on purpose");
  }

 private:
  int n_ = 0;
};

// Registers the CAN writer `bus` when built, as a CAN I/O component would.
class Writer : public Task<Writer> {
 public:
  explicit Writer(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {
    c.system->service().reactions().add_can_writer("bus", [](const can::Frame&) { return true; });
  }
  void on_update() {}
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Idle>("test.idle") && f.add<Thrower>("test.thrower") &&
                           f.add<Holder>("test.holder") && f.add<Writer>("test.writer") &&
                           f.add_handler("notify", [](const service::ReactionContext&) {});
  (void)once;
  return f;
}

constexpr const char* kHead = R"(activities: [{name: a, period: 1ms}]
components:
  - {name: sensor, type: test.thrower, activity: a}
  - {name: planner, type: test.idle, activity: a, safe_state: stop}
  - {name: motor, type: test.holder, activity: a}
  - {name: io, type: test.writer, activity: a}
supervision: {lock_memory: false, monitor_period: 50ms}
)";

std::string errors_of(const std::string& section) {
  auto d = load_deployment_string(std::string(kHead) + section, "r.yaml", factory());
  if (!d) return config::to_string(d.error());
  auto sys = System::create(std::move(*d), factory());
  REQUIRE_FALSE(sys.has_value());
  return config::to_string(sys.error());
}

}  // namespace

TEST_CASE("A bad reactions section is an error at its line and column", "[deploy][reactions]") {
  SECTION("an unknown event kind, with a suggestion") {
    const std::string e = errors_of(R"(reactions:
  rules:
    - {name: x, on: {event: excepton}, safe_state: true}
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:10:29:") &&
                      Catch::Contains("unknown event kind 'excepton'; did you mean 'exception'?"));
  }
  SECTION("a unit the system does not have") {
    const std::string e = errors_of(R"(reactions:
  rules:
    - {name: x, on: {unit: sensr}, safe_state: true}
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:10:28:") &&
                      Catch::Contains("no unit named 'sensr'; did you mean 'sensor'?"));
  }
  SECTION("a handler and a CAN writer nobody registered") {
    const std::string e = errors_of(R"(reactions:
  rules:
    - name: x
      on: {event: exception}
      handlers: [notfy]
      can: [{writer: can9, id: 0x000, data: [2, 5]}]
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:12:18:") &&
                      Catch::Contains("no handler registered by this program named 'notfy'; did "
                                      "you mean 'notify'?"));
    CHECK_THAT(e, Catch::Contains("r.yaml:13:22:") &&
                      Catch::Contains("no CAN writer registered by this program named 'can9'"));
  }
  SECTION("no action, two triggers, a byte out of range, an identifier too large") {
    const std::string e = errors_of(R"(reactions:
  rules:
    - {name: a, on: {event: exception}}
    - {name: b, on: {event: exception, unit: sensor}, safe_state: true}
    - {name: c, on: {event: exception}, can: [{writer: bus, id: 0x800, data: [256]}]}
    - {name: a, on: {unit: sensor, status: OK}, safe_state: true}
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:10:7:") &&
                      Catch::Contains("a reaction needs an action: safe_state, can, watchdog or "
                                      "handlers"));
    CHECK_THAT(e, Catch::Contains("r.yaml:11:") && Catch::Contains("name one trigger"));
    CHECK_THAT(e, Catch::Contains("r.yaml:12:") && Catch::Contains("must be at most 0x7ff"));
    CHECK_THAT(e, Catch::Contains("a byte must be 0..255"));
    CHECK_THAT(e, Catch::Contains("r.yaml:13:") &&
                      Catch::Contains("'a' is configured twice (first at line 10)"));
    CHECK_THAT(e, Catch::Contains("r.yaml:13:") && Catch::Contains("OK"));
  }
  SECTION("a FIFO reaction thread without its priority") {
    const std::string e = errors_of(R"(reactions:
  policy: FIFO
  rules: [{name: x, on: {event: exception}, safe_state: true}]
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:9:3: reactions.priority: required key is missing"));
  }
  SECTION("a reaction on reactions") {
    const std::string e = errors_of(R"(reactions:
  rules: [{name: loop, on: {event: reaction}, safe_state: true}]
)");
    CHECK_THAT(e, Catch::Contains("r.yaml:9:") &&
                      Catch::Contains("a reaction cannot fire on reaction events"));
  }
  SECTION("a component's safe_state that is neither run nor stop") {
    auto d = load_deployment_string(R"(activities: [{name: a, period: 1ms}]
components: [{name: x, type: test.idle, activity: a, safe_state: hold}]
)",
                                    "r.yaml", factory());
    REQUIRE_FALSE(d.has_value());
    CHECK_THAT(config::to_string(d.error()), Catch::Contains("r.yaml:2:66:"));
  }
}

TEST_CASE("A System reacts: the safe state stops one component and switches another",
          "[deploy][reactions]") {
  (void)clear_safe_state();
  fallback_cycles = 0;
  auto d = load_deployment_string(std::string(kHead) + R"(reactions:
  rules:
    - {name: sensor_fault, on: {event: exception, component: sensor}, safe_state: true,
       handlers: [notify], can: [{writer: bus, id: 0x000, data: [2, 0]}]}
)",
                                  "r.yaml", factory());
  REQUIRE(d.has_value());
  auto sys = System::create(std::move(*d), factory());
  REQUIRE(sys.has_value());
  System& s = **sys;
  REQUIRE(s.start().has_value());
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < until &&
         (fallback_cycles.load() < 20 || s.component("planner")->state() != TaskState::Stopped)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  CHECK(safe_state_requested());
  CHECK(s.component("planner")->state() == TaskState::Stopped);
  CHECK(fallback_cycles.load() >= 20);
  CHECK(s.component("io")->state() == TaskState::Running);  // no fallback, not stopped: runs on
  std::this_thread::sleep_for(std::chrono::milliseconds(120));
  const ReportSet r = s.reports();
  s.stop();
  const Report* unit = r.find("vigil.reactions");
  REQUIRE(unit != nullptr);
  const Field* actions = unit->field("actions");
  REQUIRE(actions != nullptr);
  CHECK(actions->count == 3);  // the safe state, the frame, the handler
  (void)clear_safe_state();
}
