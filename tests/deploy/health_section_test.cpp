// The `health:` section of a deployment: parsing, errors with their location, checkpoints checked
// against what components declare, and a System that supervises it (with an optional component
// that never starts).
#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/supervisor/health_supervision.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

// Declares "read" and "write" when built; passes both every cycle.
class Stepper : public Task<Stepper> {
 public:
  explicit Stepper(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        read_(declare_checkpoint("read")),
        write_(declare_checkpoint("write")) {}
  void on_update() {
    checkpoint(read_);
    checkpoint(write_);
  }

 private:
  CheckpointId read_, write_;
};

// Declares "late" only when configured.
class LateDeclarer : public Task<LateDeclarer> {
 public:
  explicit LateDeclarer(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  bool on_configure() {
    late_ = declare_checkpoint("late");
    return true;
  }
  void on_update() { checkpoint(late_); }

 private:
  CheckpointId late_;
};

// Refuses to start.
class Refuser : public Task<Refuser> {
 public:
  explicit Refuser(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  bool on_start() { return false; }
  void on_update() {}
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Stepper>("test.stepper") && f.add<LateDeclarer>("test.late") &&
                           f.add<Refuser>("test.refuser");
  (void)once;
  return f;
}

constexpr const char* kHead = R"(activities: [{name: a, period: 1ms}]
components:
  - {name: drive, type: test.stepper, activity: a}
  - {name: camera.front, type: test.stepper, activity: a}
supervision: {lock_memory: false, monitor_period: 50ms}
)";

std::string errors_of(const std::string& health) {
  auto d = load_deployment_string(std::string(kHead) + health, "h.yaml", factory());
  REQUIRE_FALSE(d.has_value());
  return config::to_string(d.error());
}

}  // namespace

TEST_CASE("A health section parses into the three kinds of supervision", "[deploy][health]") {
  auto d = load_deployment_string(std::string(kHead) + R"(health:
  settle: 50us
  alive:
    - {name: drive_rate, checkpoint: drive, reference_cycle: 10ms, expected: 10, min_margin: 2,
       max_margin: 3, tolerance: 1, startup_grace: 2s}
  deadline:
    - {name: chain, start: camera.front.read, end: {component: drive, checkpoint: write},
       min: 10us, max: 2ms, tolerance: 2}
  logical:
    - name: seq
      initial: drive.read
      final: [drive.write]
      transitions: [[drive.read, drive.write], "drive.write -> drive.read"]
)",
                                  "h.yaml", factory());
  REQUIRE(d.has_value());
  const health::HealthConfig& c = d->health.config;
  CHECK(c.settle_ns == 50 * kNanosPerMicro);
  REQUIRE(c.alive.size() == 1);
  CHECK(c.alive[0].checkpoint == health::CheckpointRef("drive"));  // its cycles
  CHECK(c.alive[0].reference_cycle_ns == 10 * kNanosPerMilli);
  CHECK(c.alive[0].expected_indications == 10);
  CHECK(c.alive[0].min_margin == 2);
  CHECK(c.alive[0].max_margin == 3);
  CHECK(c.alive[0].failed_cycles_tolerance == 1);
  CHECK(c.alive[0].startup_grace_ns == 2 * kNanosPerSecond);
  REQUIRE(c.deadline.size() == 1);
  // The longest component name that prefixes the text: "camera.front", checkpoint "read".
  CHECK(c.deadline[0].start == health::CheckpointRef("camera.front", "read"));
  CHECK(c.deadline[0].end == health::CheckpointRef("drive", "write"));
  CHECK(c.deadline[0].min_ns == 10 * kNanosPerMicro);
  CHECK(c.deadline[0].max_ns == 2 * kNanosPerMilli);
  CHECK(c.deadline[0].failed_tolerance == 2);
  REQUIRE(c.logical.size() == 1);
  CHECK(c.logical[0].initial.size() == 1);
  REQUIRE(c.logical[0].transitions.size() == 2);
  CHECK(c.logical[0].transitions[1].from == health::CheckpointRef("drive", "write"));
  CHECK(c.logical[0].transitions[1].to == health::CheckpointRef("drive", "read"));
}

TEST_CASE("A bad health section is an error at its line and column", "[deploy][health]") {
  // Line 6 is the first line of the section's content.
  SECTION("an unknown component, with a suggestion") {
    const std::string e = errors_of(R"(health:
  deadline: [{name: d, start: drvie.read, end: drive.write, max: 1ms}]
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:7:"));
    CHECK_THAT(e, Catch::Contains("no component named 'drvie'; did you mean 'drive'?"));
  }
  SECTION("min above max") {
    const std::string e = errors_of(R"(health:
  deadline: [{name: d, start: drive.read, end: drive.write, min: 3ms, max: 1ms}]
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:7:"));
    CHECK_THAT(e, Catch::Contains("min (3000 us) is above max (1000 us)"));
  }
  SECTION("a zero window") {
    const std::string e = errors_of(R"(health:
  alive: [{name: a, checkpoint: drive, reference_cycle: 0s}]
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:7:"));
    CHECK_THAT(e, Catch::Contains("reference_cycle"));
  }
  SECTION("a graph with an unreachable checkpoint") {
    const std::string e = errors_of(R"(health:
  logical:
    - name: g
      initial: drive.read
      transitions: [[drive.read, drive.write], [camera.front.read, camera.front.write]]
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:8:"));
    CHECK_THAT(e, Catch::Contains("unreachable"));
  }
  SECTION("a graph with no initial checkpoint") {
    const std::string e = errors_of(R"(health:
  logical:
    - {name: g, initial: [], transitions: [[drive.read, drive.write]]}
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:8:"));
    CHECK_THAT(e, Catch::Contains("initial"));
  }
  SECTION("a duplicate name, across kinds") {
    const std::string e = errors_of(R"(health:
  alive: [{name: same, checkpoint: drive, reference_cycle: 10ms}]
  deadline: [{name: same, start: drive.read, end: drive.write, max: 1ms}]
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:8:"));
    CHECK_THAT(e, Catch::Contains("supervision 'same' is defined twice (first at line 7)"));
  }
  SECTION("an unknown key and a malformed transition") {
    const std::string e = errors_of(R"(health:
  alive: [{name: a, checkpoint: drive, reference_cycle: 10ms, expect: 3}]
  logical:
    - {name: g, initial: drive.read, transitions: ["drive.read drive.write"]}
)");
    CHECK_THAT(e, Catch::Contains("h.yaml:7:"));
    CHECK_THAT(e, Catch::Contains("did you mean 'expected'?"));
    CHECK_THAT(e, Catch::Contains("h.yaml:9:"));
    CHECK_THAT(e, Catch::Contains("a transition is [from, to]"));
  }
}

TEST_CASE("A checkpoint no component declares is an error at creation or at start",
          "[deploy][health]") {
  SECTION("declared when built: found by System::create (so by check-config)") {
    auto d = load_deployment_string(std::string(kHead) + R"(health:
  deadline: [{name: d, start: drive.read, end: drive.wirte, max: 1ms}]
)",
                                    "h.yaml", factory());
    REQUIRE(d.has_value());
    auto sys = System::create(std::move(*d), factory());
    REQUIRE_FALSE(sys.has_value());
    const std::string e = config::to_string(sys.error());
    CHECK_THAT(e, Catch::Contains("h.yaml:7:"));
    CHECK_THAT(e, Catch::Contains(
                      "component 'drive' declares no checkpoint 'wirte'; did you mean 'write'?"));
  }
  SECTION("declared when configured: found by start(), nothing left running") {
    auto d = load_deployment_string(R"(activities: [{name: a, period: 1ms}]
components: [{name: late, type: test.late, activity: a}]
supervision: {lock_memory: false}
health:
  alive: [{name: a, checkpoint: late.early, reference_cycle: 10ms}]
)",
                                    "l.yaml", factory());
    REQUIRE(d.has_value());
    auto sys = System::create(std::move(*d), factory());
    REQUIRE(sys.has_value());
    auto started = (*sys)->start();
    REQUIRE_FALSE(started.has_value());
    CHECK_THAT(started.error().message,
               Catch::Contains("l.yaml:5:") &&
                   Catch::Contains("component 'late' declares no checkpoint 'early'"));
    CHECK((*sys)->component("late")->state() != TaskState::Running);
  }
}

TEST_CASE("An optional component that refuses to start is caught by its start-up grace period",
          "[deploy][health]") {
  auto d = load_deployment_string(R"(activities: [{name: a, period: 1ms}]
components:
  - {name: drive, type: test.stepper, activity: a}
  - {name: lidar, type: test.refuser, activity: a, optional: true}
supervision: {lock_memory: false, monitor_period: 50ms}
health:
  alive:
    - {name: lidar_alive, checkpoint: lidar, reference_cycle: 10ms, expected: 10, min_margin: 5,
       max_margin: 5, startup_grace: 100ms}
  deadline: [{name: rw, start: drive.read, end: drive.write, max: 5ms}]
)",
                                  "o.yaml", factory());
  REQUIRE(d.has_value());
  auto sys = System::create(std::move(*d), factory());
  REQUIRE(sys.has_value());
  System& s = **sys;
  REQUIRE(s.start().has_value());  // optional: its refusal does not stop the system
  bool said = false;
  for (const std::string& line : s.log()) {
    said = said || line.find("lidar refused to start (optional") != std::string::npos;
  }
  CHECK(said);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  health::SupervisionStatus st = health::SupervisionStatus::Deactivated;
  while (std::chrono::steady_clock::now() < deadline) {
    st = s.aggregator().health()->status("lidar_alive");
    if (st == health::SupervisionStatus::Expired) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  CHECK(st == health::SupervisionStatus::Expired);
  CHECK(s.aggregator().health()->status("rw") == health::SupervisionStatus::Ok);
  s.stop();
  const auto reports = s.aggregator().health_reports();
  REQUIRE(reports.size() == 2);
  CHECK(reports[0].last_failure.failure == health::FailureKind::NeverStarted);
  CHECK(reports[1].evaluations > 10);  // drive's read -> write pairs
}
