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
#include <utility>
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
// `more`: the listener's further arguments ("0 16": also read ros_discovery_info, 16-byte gids).
std::vector<std::string> listen(int domain, int count, const std::function<void()>& publish,
                                const std::string& more = "") {
  const std::string cmd = "CYCLONEDDS_URI='" + loopback_config() + "' " VIGIL_ROS2_LISTENER " " +
                          std::to_string(domain) + " " + std::to_string(count) + " 30 " + more;
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

TEST_CASE("ROS 2 node names, namespaces and distributions are checked as rmw does",
          "[export][ros2]") {
  for (const char* good : {"vigil", "arm_health", "_x", "V2", "a_b_c_1"}) {
    CHECK(check_ros_node_name(good));
  }
  for (const char* bad : {"", "2d", "my node", "a-b", "a/b", "ü"}) {
    const auto r = check_ros_node_name(bad);
    REQUIRE(!r);
    CHECK(r.error().message.find("node_name '") == 0);
  }
  CHECK(!check_ros_node_name(std::string(256, 'a')));
  CHECK(check_ros_node_name(std::string(255, 'a')));
  for (const char* good : {"/", "/robot", "/robot/arm_1", "/_a"}) CHECK(check_ros_namespace(good));
  for (const char* bad :
       {"", "robot", "/robot/", "//robot", "/robot//arm", "/1robot", "/a/2b", "/a b", "/a-b"}) {
    const auto r = check_ros_namespace(bad);
    REQUIRE(!r);
    CHECK(r.error().message.find("node_namespace '") == 0);
  }
  CHECK(!check_ros_namespace("/" + std::string(245, 'a')));
  // rmw_dds_common/msg/Gid.msg: char[24] up to Humble, char[16] since Iron.
  for (const char* d : {"foxy", "galactic", "humble"}) CHECK(ros_gid_size(d).value() == 24);
  for (const char* d : {"iron", "jazzy", "kilted", "lyrical", "rolling"}) {
    CHECK(ros_gid_size(d).value() == 16);
  }
  const auto noetic = ros_gid_size("noetic", "ROS_DISTRO");
  REQUIRE(!noetic);
  CHECK(noetic.error().message.find("ROS_DISTRO='noetic'") == 0);
}

TEST_CASE("A bad node name or distribution is said, an unknown ROS_DISTRO only warns",
          "[export][ros2]") {
  Started name(Ros2Options{.domain_id = 1, .node_name = "my node"});
  CHECK(!name.output.active());
  REQUIRE(name.warnings.size() == 1);
  CHECK(name.warnings[0].find("node_name 'my node'") != std::string::npos);
  Started ns(Ros2Options{.domain_id = 1, .node_namespace = "robot"});
  CHECK(!ns.output.active());
  REQUIRE(ns.warnings.size() == 1);
  CHECK(ns.warnings[0].find("node_namespace 'robot'") != std::string::npos);
  Started distro(Ros2Options{.domain_id = 1, .ros_distro = "noetic"});
  CHECK(!distro.output.active());
  REQUIRE(distro.warnings.size() == 1);
  CHECK(distro.warnings[0].find("ros_distro='noetic'") != std::string::npos);
  if (!ros2_output_built()) return;
  // ROS_DISTRO is the environment's, not vigil's setting: a name vigil does not know is a warning
  // and Iron's layout (16 bytes) is used; a known one picks its layout; ros_distro wins.
  ::setenv("ROS_DISTRO", "lunar", 1);
  {
    Started env(Ros2Options{.domain_id = random_domain(), .dds_config = loopback_config()});
    CHECK(env.output.active());
    REQUIRE(env.warnings.size() == 1);
    CHECK(env.warnings[0].find("ROS_DISTRO='lunar'") != std::string::npos);
    CHECK(env.output.gid_size() == 16);
    CHECK(env.output.node() == "/vigil");
    CHECK(env.output.error().empty());
    env.output.stop(Snapshot{});
  }
  ::setenv("ROS_DISTRO", "humble", 1);
  {
    Started env(Ros2Options{.domain_id = random_domain(), .dds_config = loopback_config()});
    CHECK(env.warnings.empty());
    CHECK(env.output.gid_size() == 24);
    env.output.stop(Snapshot{});
    Started opt(Ros2Options{
        .domain_id = random_domain(), .dds_config = loopback_config(), .ros_distro = "jazzy"});
    CHECK(opt.output.gid_size() == 16);
    opt.output.stop(Snapshot{});
  }
  ::unsetenv("ROS_DISTRO");
  Started off(
      Ros2Options{.domain_id = random_domain(), .dds_config = loopback_config(), .node = false});
  CHECK(off.output.active());
  CHECK(off.output.node().empty());
  CHECK(off.output.gid_size() == 0);
  off.output.stop(Snapshot{});
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
  const auto named = deployment(
      "  ros2: {node_name: arm_health, node_namespace: /robot, ros_distro: humble, node: true}");
  REQUIRE(named);
  CHECK(named->outputs.ros2->node);
  CHECK(named->outputs.ros2->node_name == "arm_health");
  CHECK(named->outputs.ros2->node_namespace == "/robot");
  CHECK(named->outputs.ros2->ros_distro == "humble");
  CHECK(bare->outputs.ros2->node);
  CHECK(bare->outputs.ros2->node_name == "vigil");
  CHECK(bare->outputs.ros2->node_namespace == "/");
  CHECK(bare->outputs.ros2->ros_distro.empty());
  CHECK(!deployment("  ros2: {node: false}")->outputs.ros2->node);
  for (const char* wrong :
       {"{node_name: 'my node'}", "{node_name: 2d}", "{node_name: ''}", "{node_namespace: robot}",
        "{node_namespace: /robot/}", "{ros_distro: noetic}", "{ros_distro: Jazzy}"}) {
    const auto r = deployment(std::string("  ros2: ") + wrong);
    REQUIRE(!r);
    const std::string said = config::to_string(r.error());
    INFO(said);
    CHECK(said.find("d.yaml:6:") != std::string::npos);
    const std::string key = std::string(wrong).substr(1, std::string(wrong).find(':') - 1);
    CHECK(said.find(key) != std::string::npos);
  }
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
                                 "domain {}, node /vigil",
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

#ifdef VIGIL_ROS2_LISTENER
namespace {
// The value of the string field `key` that follows `after` in a JSON line.
std::string field(const std::string& line, const std::string& after, const std::string& key) {
  const std::size_t from = line.find(after);
  if (from == std::string::npos) return {};
  const std::string k = "\"" + key + "\":\"";
  const std::size_t at = line.find(k, from);
  if (at == std::string::npos) return {};
  const std::size_t start = at + k.size();
  return line.substr(start, line.find('"', start) - start);
}
}  // namespace
#endif

TEST_CASE("ros_discovery_info names the node of the /diagnostics writer, as rmw computes gids",
          "[export][ros2]") {
#ifndef VIGIL_ROS2_LISTENER
  WARN("skipped: cyclonedds-dev absent (vigil was built without Cyclone DDS)");
#else
  // Jazzy's layout (16-byte gids), then Humble's (24): each read by a subscriber of that layout.
  for (const auto& [distro, size] : {std::pair{"jazzy", 16}, std::pair{"humble", 24}}) {
    INFO(distro);
    const int domain = random_domain();
    Started s(Ros2Options{.domain_id = domain,
                          .dds_config = loopback_config(),
                          .events = false,
                          .node_name = "arm_health",
                          .node_namespace = "/robot",
                          .ros_distro = distro});
    REQUIRE(s.output.active());
    CHECK(s.warnings.empty());
    CHECK(s.output.node() == "/robot/arm_health");
    CHECK(s.output.gid_size() == size);
    const auto lines = listen(
        domain, 1, [&] { (void)s.output.write(sample_message()); }, "0 " + std::to_string(size));
    REQUIRE(lines.size() == 2);
    const std::string& line =
        lines[0].find("ros_discovery_info") != std::string::npos ? lines[0] : lines[1];
    // The /diagnostics writer's gids as rmw_cyclonedds_cpp derives them from DDS discovery.
    const std::string writer = field(line, "\"publisher\"", "gid");
    const std::string participant = field(line, "\"publisher\"", "participant_gid");
    const std::size_t hex_size = 2 * static_cast<std::size_t>(size);
    REQUIRE(writer.size() == hex_size);
    REQUIRE(participant.size() == hex_size);
    // GUIDs in wire order: the RTPS participant's entity id 0x000001c1, a writer of a keyless
    // user topic 0x......03, the same 12-byte prefix; zeros after the 16 bytes (Humble).
    CHECK(participant.substr(24, 8) == "000001c1");
    CHECK(writer.substr(30, 2) == "03");
    CHECK(writer.substr(0, 24) == participant.substr(0, 24));
    CHECK(participant.substr(32) == std::string(hex_size - 32, '0'));
    CHECK(writer.substr(32) == std::string(hex_size - 32, '0'));
    // What vigil announced: that participant, one node holding that writer and no reader.
    CHECK(line == fmt::format("{{\"ros_discovery_info\":{{\"gid\":\"{0}\",\"nodes\":[{{"
                              "\"namespace\":\"/robot\",\"name\":\"arm_health\",\"readers\":[],"
                              "\"writers\":[\"{1}\"]}}]}},\"publisher\":{{\"gid\":\"{1}\","
                              "\"participant_gid\":\"{0}\"}}}}",
                              participant, writer));
    s.output.stop(Snapshot{});
  }
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

TEST_CASE("A Fast DDS subscriber finds the /diagnostics writer's node in ros_discovery_info",
          "[export][ros2]") {
#if !defined(VIGIL_ROS2_LISTENER)
  WARN("skipped: cyclonedds-dev absent (vigil was built without Cyclone DDS)");
#elif !defined(VIGIL_TEST_FASTDDS)
  WARN("skipped: libfastrtps-dev absent (no Fast DDS subscriber)");
#else
  for (const auto& [distro, size] : {std::pair{"jazzy", 16}, std::pair{"humble", 24}}) {
    INFO(distro);
    const int domain = random_domain();
    test::FastDdsDiagnosticsSubscriber sub(domain, size);
    REQUIRE(sub.error().empty());
    Started s(Ros2Options{.domain_id = domain,
                          .dds_config = loopback_config(),
                          .events = false,
                          .ros_distro = distro});
    REQUIRE(s.output.active());
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while ((sub.writer_gid().empty() || sub.discovery().empty()) &&
           std::chrono::steady_clock::now() < end) {
      (void)s.output.write(sample_message());
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    const std::string writer = sub.writer_gid();
    const auto infos = sub.discovery();
    REQUIRE(writer.size() == static_cast<std::size_t>(size));
    REQUIRE(infos.size() == 1);  // transient local, keep last 1: the one sample
    const test::RosParticipantInfo& info = infos.front();
    // The participant's gid: the writer's GUID prefix with the participant's entity id 0x000001c1
    // (what rmw_fastrtps_cpp reads from DDS discovery as the endpoint's participant).
    std::string participant = writer;
    participant.replace(12, 4, std::string("\x00\x00\x01\xc1", 4));
    CHECK(info.gid == participant);
    REQUIRE(info.nodes.size() == 1);
    CHECK(info.nodes[0].node_namespace == "/");
    CHECK(info.nodes[0].node_name == "vigil");
    CHECK(info.nodes[0].readers.empty());
    CHECK(info.nodes[0].writers == std::vector<std::string>{writer});
    s.output.stop(Snapshot{});
  }
#endif
}
