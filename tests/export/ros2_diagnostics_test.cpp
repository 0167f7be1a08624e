#include "vigil/export/ros2_diagnostics.hpp"

#include <fmt/format.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "vigil/config/load.hpp"
#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/task.hpp"

#ifdef VIGIL_TEST_FASTDDS
#include "ros2_fastdds_subscriber.hpp"
#endif

using namespace vigil;
using namespace vigil::exporter;

namespace {

// A domain of its own for each test, so that runs in parallel (or a robot on the same host)
// do not see each other's samples.
int random_domain() {
  std::random_device rd;
  return 20 + static_cast<int>(rd() % 180);
}

// Cyclone DDS on loopback only. The container's `lo` has no MULTICAST flag, so discovery is
// unicast: participant indices (auto) give well-known ports, and 127.0.0.1 is the peer to ask.
std::string loopback_config() {
  return "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/>"
         "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
         "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20"
         "</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
         "</Domain></CycloneDDS>";
}

constexpr std::int64_t kStamp = 1'700'000'123'456'789'012;

// Every field set, every level, strings that CDR must carry as they are (UTF-8, quotes,
// separators, an empty one), a status without values.
DiagnosticArrayMessage sample_message() {
  DiagnosticArrayMessage m;
  m.sec = 1'700'000'123;
  m.nanosec = 456'789'012;
  m.frame_id = "base_link";
  m.status.push_back({0,
                      "vigil: motor_left",
                      "OK",
                      "tid 4242 cpu 1",
                      {{"kind", "component"}, {"cycles", "123456"}, {"period", "1.00 ms"}}});
  m.status.push_back({1,
                      "vigil: planner",
                      "near overrun; 3 rt losses",
                      "tid 77 cpu any",
                      {{"latency_p99", "12.5 µs"}, {"note", "quote \" and ; and = kept"}}});
  m.status.push_back({2,
                      "vigil: can0/drive_5",
                      "exception: std::runtime_error: boom",
                      "can0:drive_5",
                      {{"empty", ""}}});
  m.status.push_back({3, "vigil: can group left_arm", "silent for 2.0 s", "", {}});
  return m;
}

struct Started {
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  OutputContext context{aggregator};
  std::vector<std::string> warnings;
  Ros2DiagnosticsOutput output;

  explicit Started(Ros2Options o) : output(with_warnings(std::move(o))) {
    REQUIRE(output.start(context));
  }
  Ros2Options with_warnings(Ros2Options o) {
    o.warn = [this](const std::string& line) { warnings.push_back(line); };
    return o;
  }
};

#ifdef VIGIL_ROS2_LISTENER
// Runs the Cyclone DDS listener (its own process) and returns its lines, publishing `publish`
// every 100 ms until it has printed `count` of them (a volatile reader gets only what is
// written after discovery matched it).
std::vector<std::string> listen(int domain, int count, const std::function<void()>& publish) {
  const std::string cmd = "CYCLONEDDS_URI='" + loopback_config() + "' " VIGIL_ROS2_LISTENER " " +
                          std::to_string(domain) + " " + std::to_string(count) + " 30";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  std::atomic<bool> done{false};
  std::thread writer([&] {
    while (!done.load()) {
      publish();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
  std::vector<std::string> lines;
  std::string line;
  int c = 0;
  while ((c = std::fgetc(p)) != EOF) {
    if (c == '\n') {
      lines.push_back(line);
      line.clear();
    } else {
      line.push_back(static_cast<char>(c));
    }
  }
  done = true;
  writer.join();
  CHECK(::pclose(p) == 0);
  return lines;
}
#endif

}  // namespace

TEST_CASE("ROS_DOMAIN_ID is checked and named when wrong", "[export][ros2]") {
  CHECK(parse_ros_domain_id("0").value() == 0);
  CHECK(parse_ros_domain_id("42").value() == 42);
  CHECK(parse_ros_domain_id("232").value() == 232);
  for (const char* bad : {"", "-1", "233", "7x", " 7", "seven", "99999999999"}) {
    const auto r = parse_ros_domain_id(bad);
    REQUIRE(!r);
    CHECK(r.error().message.find("ROS_DOMAIN_ID") != std::string::npos);
    CHECK(r.error().message.find("0 to 232") != std::string::npos);
  }
}

TEST_CASE("A bad domain makes the ROS 2 output warn and publish nothing", "[export][ros2]") {
  ::setenv("ROS_DOMAIN_ID", "banana", 1);
  {
    Started s(Ros2Options{});
    CHECK(!s.output.active());
    REQUIRE(s.warnings.size() == 1);
    CHECK(s.warnings[0].find("ROS_DOMAIN_ID='banana'") != std::string::npos);
    CHECK(s.output.error().find("ROS_DOMAIN_ID") != std::string::npos);
    CHECK(!s.output.write(sample_message()));
    s.output.publish(Snapshot{});  // supervision goes on: nothing happens
    s.output.stop(Snapshot{});
    CHECK(s.output.published() == 0);
  }
  ::unsetenv("ROS_DOMAIN_ID");
  Started out_of_range(Ros2Options{.domain_id = 300});
  CHECK(!out_of_range.output.active());
  REQUIRE(out_of_range.warnings.size() == 1);
  CHECK(out_of_range.warnings[0].find("domain_id 300") != std::string::npos);
}

namespace {
class Idle : public Task<Idle> {
 public:
  explicit Idle(const deploy::ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};

deploy::ComponentFactory& factory() {
  static deploy::ComponentFactory f;
  static const bool once = f.add<Idle>("test.idle", "does nothing");
  (void)once;
  return f;
}

expected<deploy::DeploymentSpec, config::ConfigErrors> deployment(std::string_view outputs) {
  return deploy::load_deployment_string(std::string(R"(
activities: [{name: a, period: 10ms}]
components: [{name: c, type: test.idle, activity: a}]
supervision: {lock_memory: false}
outputs:
)") + std::string(outputs) + "\n",
                                        "d.yaml", factory());
}
}  // namespace

TEST_CASE("outputs.ros2 in a deployment is parsed and checked", "[export][ros2][deploy]") {
  const auto ok = deployment("  ros2: {domain_id: 7, events: false, dds_config: '<CycloneDDS/>'}");
  REQUIRE(ok);
  REQUIRE(ok->outputs.ros2);
  CHECK(ok->outputs.ros2->domain_id == 7);
  CHECK(!ok->outputs.ros2->events);
  CHECK(ok->outputs.ros2->dds_config == "<CycloneDDS/>");
  const auto bare = deployment("  ros2:");
  REQUIRE(bare);
  REQUIRE(bare->outputs.ros2);
  CHECK(!bare->outputs.ros2->domain_id);
  CHECK(bare->outputs.ros2->events);
  CHECK(bare->outputs.ros2->dds_config.empty());
  const auto none = deployment("  json: f.json");
  REQUIRE(none);
  CHECK(!none->outputs.ros2);
  // Line 6 of the document: the range and the misspelt key, each at its place.
  const auto bad = deployment("  ros2: {domain_id: 233, domian: 1}");
  REQUIRE(!bad);
  const std::string text = config::to_string(bad.error());
  CHECK(text.find("d.yaml:6:") != std::string::npos);
  CHECK(text.find("domain_id") != std::string::npos);
  CHECK(text.find("domian") != std::string::npos);
  CHECK(!deployment("  ros2: {dds_config: ''}"));
  CHECK(!deployment("  ros2: [7]"));
}

TEST_CASE("A deployment's System runs the ROS 2 output", "[export][ros2][deploy]") {
  const int domain = random_domain();
  auto spec = deployment(
      fmt::format("  ros2: {{domain_id: {}, dds_config: '{}'}}", domain, loopback_config()));
  REQUIRE(spec);
  auto system = deploy::System::create(std::move(*spec), factory());
  REQUIRE(system);
  const exporter::Ros2DiagnosticsOutput* out = (*system)->ros2_output();
  REQUIRE(out != nullptr);
  REQUIRE((*system)->start());
  if (ros2_output_built()) {
    CHECK(out->active());
    CHECK(out->domain_id() == domain);
    bool said = false;
    for (const std::string& line : (*system)->log()) {
      said = said || line == fmt::format(
                                 "ROS 2: /diagnostics (DDS topic rt/diagnostics) in "
                                 "domain {}",
                                 domain);
    }
    CHECK(said);
  } else {
    CHECK(!out->active());
    CHECK(out->error().find("without Cyclone DDS") != std::string::npos);
  }
  (*system)->stop();
  if (ros2_output_built()) CHECK(out->published() >= 1);  // the final cycle at least
  CHECK(!out->active());
}

TEST_CASE("Without the DDS module the ROS 2 output says it is unavailable", "[export][ros2]") {
  if (!ros2_output_built()) {  // a build without Cyclone DDS
    Started s(Ros2Options{.domain_id = 1});
    CHECK(!s.output.active());
    REQUIRE(s.warnings.size() == 1);
    CHECK(s.warnings[0].find("without Cyclone DDS") != std::string::npos);
  }
  // A module that is not there (VIGIL_ROS2_MODULE names it): the path and the variable are said.
  // (The module, once loaded by an earlier test, stays loaded: only a fresh process sees this.)
  ::setenv("VIGIL_ROS2_MODULE", "/nonexistent/libvigil_ros2.so", 1);
  const bool fresh = ros2_output_built();
  Started s(Ros2Options{.domain_id = 1});
  ::unsetenv("VIGIL_ROS2_MODULE");
  if (fresh && s.output.active()) {
    SUCCEED("the module was loaded before this test: a loaded module is kept");
    s.output.stop(Snapshot{});
    return;
  }
  CHECK(!s.output.active());
  REQUIRE(s.warnings.size() == 1);
  CHECK(s.warnings[0].find("/nonexistent/libvigil_ros2.so") != std::string::npos);
  CHECK(s.warnings[0].find("VIGIL_ROS2_MODULE") != std::string::npos);
}

TEST_CASE("A Cyclone DDS subscriber receives every field of /diagnostics", "[export][ros2]") {
#ifndef VIGIL_ROS2_LISTENER
  WARN("skipped: cyclonedds-dev absent (vigil was built without Cyclone DDS)");
#else
  const int domain = random_domain();
  Started s(Ros2Options{
      .domain_id = domain, .dds_config = loopback_config(), .events = false, .wall_clock_ns = [] {
        return kStamp;
      }});
  REQUIRE(s.output.active());
  CHECK(s.warnings.empty());
  CHECK(s.output.domain_id() == domain);

  // A message written as it is.
  const DiagnosticArrayMessage m = sample_message();
  const auto lines = listen(domain, 2, [&] { (void)s.output.write(m); });
  REQUIRE(lines.size() == 2);
  CHECK(lines[0] == to_diagnostics_json(m));
  CHECK(lines[1] == to_diagnostics_json(m));

  // A monitor cycle: the reports mapped as /api/v1/diagnostics maps them, stamped by the clock.
  Snapshot snap;
  Report motor;
  motor.name = "motor";
  motor.tid = 4242;
  motor.cpu = 2;
  motor.merge(StatusLevel::Warn, "near overrun");
  Report node;
  node.kind = ReportKind::Unit;
  node.unit_kind = "can_node";
  node.name = "can0/drive_5";
  node.merge(StatusLevel::Stale, "silent");
  node.add_field(Field::of_count("frames_rx", 12));
  snap.reports.components = {motor, node};
  const auto cycle = listen(domain, 1, [&] { s.output.publish(snap); });
  REQUIRE(cycle.size() == 1);
  CHECK(cycle[0] == to_diagnostics_json(to_diagnostic_array(snap.reports, kStamp)));
  CHECK(cycle[0].find("\"sec\":1700000123,\"nanosec\":456789012") != std::string::npos);
  CHECK(s.output.published() >= 3);
  s.output.stop(Snapshot{});
  CHECK(!s.output.active());
#endif
}

TEST_CASE("An event publishes the status it changed at once", "[export][ros2]") {
#ifndef VIGIL_ROS2_LISTENER
  WARN("skipped: cyclonedds-dev absent (vigil was built without Cyclone DDS)");
#else
  const int domain = random_domain();
  Started s(Ros2Options{.domain_id = domain, .dds_config = loopback_config(), .wall_clock_ns = [] {
                          return kStamp;
                        }});
  REQUIRE(s.output.active());
  Snapshot snap;
  Report motor;
  motor.name = "motor";
  motor.tid = 4242;
  motor.cpu = 2;
  motor.merge(StatusLevel::Warn, "near overrun");
  Report other;
  other.name = "other";
  snap.reports.components = {motor, other};
  s.output.publish(snap);  // the latest cycle: what the event's status starts from
  Event e;
  e.kind = EventKind::Exception;
  e.severity = EventSeverity::Error;
  e.component = "motor";
  e.detail = "std::runtime_error: boom";
  // Only events, no more cycles: every sample the listener gets came from one.
  const auto lines = listen(domain, 1, [&] { (void)s.aggregator.events().publish(e); });
  REQUIRE(lines.size() == 1);
  const std::string& line = lines[0];
  // One status, motor's, raised to ERROR, the event as its message, its values kept and the
  // event's kind and sequence number added.
  CHECK(line.find("\"name\":\"vigil: other\"") == std::string::npos);
  CHECK(line.find("\"status\":[{\"level\":2,\"name\":\"vigil: motor\",\"message\":\"ERROR motor: "
                  "exception: std::runtime_error: boom") != std::string::npos);
  CHECK(line.find("\"hardware_id\":\"tid 4242 cpu 2\"") != std::string::npos);
  CHECK(line.find("{\"key\":\"kind\",\"value\":\"component\"}") != std::string::npos);
  CHECK(line.find("{\"key\":\"event\",\"value\":\"exception\"},{\"key\":\"event_seq\",") !=
        std::string::npos);
  CHECK(line.find("\"sec\":1700000123,\"nanosec\":456789012") != std::string::npos);
  s.output.stop(Snapshot{});
#endif
}

TEST_CASE("A Fast DDS subscriber receives every field of /diagnostics over the wire",
          "[export][ros2]") {
#if !defined(VIGIL_ROS2_LISTENER)
  WARN("skipped: cyclonedds-dev absent (vigil was built without Cyclone DDS)");
#elif !defined(VIGIL_TEST_FASTDDS)
  WARN("skipped: libfastrtps-dev absent (no Fast DDS subscriber)");
#else
  const int domain = random_domain();
  test::FastDdsDiagnosticsSubscriber sub(domain);
  REQUIRE(sub.error().empty());
  Started s(Ros2Options{
      .domain_id = domain, .dds_config = loopback_config(), .events = false, .wall_clock_ns = [] {
        return kStamp;
      }});
  REQUIRE(s.output.active());
  const DiagnosticArrayMessage m = sample_message();
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (sub.received().size() < 2 && std::chrono::steady_clock::now() < end) {
    (void)s.output.write(m);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const auto got = sub.received();
  REQUIRE(got.size() >= 2);
  for (const DiagnosticArrayMessage& r : got) CHECK(r == m);
  // The encapsulation of every sample: CDR little-endian, XCDR1 (what rmw_cyclonedds writes).
  CHECK(sub.encapsulations() == std::vector<int>(sub.encapsulations().size(), 0x0001));
  CHECK(s.output.matched() >= 1);
  s.output.stop(Snapshot{});
#endif
}
