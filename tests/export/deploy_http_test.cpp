// The `outputs: {http: ..., textfile: ...}` keys of a deployment (deploy module): read into the
// HTTP server's address, and started by `deploy::System` for any program that runs the
// deployment.
#include <httplib.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
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

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Idle>("test.idle", "does nothing");
  (void)once;
  return f;
}

std::string with_outputs(std::string_view outputs) {
  return std::string(R"(
activities: [{name: a, period: 10ms}]
components: [{name: c, type: test.idle, activity: a}]
outputs: )") +
         std::string(outputs) + "\n";
}
}  // namespace

TEST_CASE("outputs.http reads listen, threads and dashboard", "[export][deploy]") {
  auto d = load_deployment_string(with_outputs("{http: {listen: 9100}}"), "d.yaml", factory());
  REQUIRE(d);
  REQUIRE(d->outputs.http);
  CHECK(d->outputs.http->listen.host == "127.0.0.1");
  CHECK(d->outputs.http->listen.port == 9100);
  CHECK(d->outputs.http->threads == 3);
  CHECK(d->outputs.http->dashboard);

  d = load_deployment_string(
      with_outputs(
          "{json: f.json, http: {listen: \"0.0.0.0:9200\", threads: 2, dashboard: false}}"),
      "d.yaml", factory());
  REQUIRE(d);
  CHECK(d->outputs.http->listen.host == "0.0.0.0");
  CHECK(d->outputs.http->listen.port == 9200);
  CHECK(d->outputs.http->threads == 2);
  CHECK(!d->outputs.http->dashboard);

  d = load_deployment_string(with_outputs("{json: f.json}"), "d.yaml", factory());
  REQUIRE(d);
  CHECK(!d->outputs.http);
}

TEST_CASE("A bad outputs.http is an error naming file, line and column", "[export][deploy]") {
  const auto errors = [](std::string_view outputs) {
    auto d = load_deployment_string(with_outputs(outputs), "d.yaml", factory());
    REQUIRE(!d);
    return config::to_string(d.error());
  };
  std::string e = errors("{http: {listen: 99999}}");
  CHECK(e.find("d.yaml:4:") != std::string::npos);
  CHECK(e.find("0..65535") != std::string::npos);
  e = errors("{http: {listen: \"::1:80\"}}");
  CHECK(e.find("[ADDR]:PORT") != std::string::npos);
  e = errors("{http: {threads: 2}}");
  CHECK(e.find("listen") != std::string::npos);
  e = errors("{http: {listen: 80, threads: 40}}");
  CHECK(e.find("threads") != std::string::npos);
  e = errors("{http: {listen: 80, port: 81}}");
  CHECK(e.find("port") != std::string::npos);
}

TEST_CASE("outputs.textfile reads a file name", "[export][deploy]") {
  auto d =
      load_deployment_string(with_outputs("{textfile: /tmp/x/vigil.prom}"), "d.yaml", factory());
  REQUIRE(d);
  REQUIRE(d->outputs.textfile);
  CHECK(d->outputs.textfile->string() == "/tmp/x/vigil.prom");
  d = load_deployment_string(with_outputs("{textfile: \"\"}"), "d.yaml", factory());
  REQUIRE(!d);
  CHECK(config::to_string(d.error()).find("d.yaml:4:") != std::string::npos);
  d = load_deployment_string(with_outputs("{textfil: a.prom}"), "d.yaml", factory());
  REQUIRE(!d);
  CHECK(config::to_string(d.error()).find("textfile") != std::string::npos);  // a suggestion
}

namespace {
std::string deployment_with_http(std::string_view listen, std::string_view textfile) {
  return std::string(R"(
activities: [{name: a, period: 10ms}]
components: [{name: c, type: test.idle, activity: a}]
supervision: {lock_memory: false, monitor_period: 50ms}
outputs: {http: {listen: ")") +
         std::string(listen) + "\", threads: 2}" +
         (textfile.empty() ? std::string() : ", textfile: " + std::string(textfile)) + "}\n";
}

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

TEST_CASE("A System serves its deployment's outputs.http and textfile", "[export][deploy]") {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("vigil_system_http_" +
                    std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
  std::filesystem::create_directories(dir);
  const auto prom = dir / "vigil.prom";
  auto spec = load_deployment_string(deployment_with_http("127.0.0.1:0", prom.string()),
                                     "system.yaml", factory());
  REQUIRE(spec);
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys);
  System& system = **sys;
  CHECK(system.http() == nullptr);  // started by start(), not by create()
  REQUIRE(system.start());
  REQUIRE(system.http() != nullptr);
  REQUIRE(system.http() != nullptr);
  const int port = system.http()->address().port;
  CHECK(port > 0);
  CHECK(system.http()->options().threads == 2);
  // The server's announcement is in the start log.
  bool announced = false;
  for (const auto& line : system.log()) {
    if (line.find("HTTP on http://127.0.0.1:" + std::to_string(port) + "/") != std::string::npos) {
      announced = true;
    }
  }
  CHECK(announced);

  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(5, 0);
  // /healthz answers 200 once the monitor published its first cycle (every 50 ms).
  int health = 0;
  for (int i = 0; i < 100 && health != 200; ++i) {
    if (auto r = client.Get("/healthz")) health = r->status;
    if (health != 200) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  CHECK(health == 200);
  // The first cycles may come before the supervisor drained the component's first messages:
  // wait (bounded) for a cycle that has it.
  auto metrics = client.Get("/metrics");
  for (int i = 0; i < 100 && metrics &&
                  metrics->body.find("vigil_component_status{component=\"c\"") == std::string::npos;
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    metrics = client.Get("/metrics");
  }
  REQUIRE(metrics);
  CHECK(metrics->status == 200);
  CHECK(metrics->body.find("vigil_component_status{component=\"c\"") != std::string::npos);
  CHECK(metrics->body.find("vigil_component_execution_seconds_bucket{component=\"c\",le=") !=
        std::string::npos);
  auto post = client.Post("/metrics", "", "text/plain");
  REQUIRE(post);
  CHECK(post->status == 405);

  // The textfile is rewritten after every monitor cycle.
  std::string text;
  for (int i = 0;
       i < 100 && text.find("vigil_component_status{component=\"c\"") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    text = read_all(prom);
  }
  CHECK(text.find("vigil_component_status{component=\"c\"") != std::string::npos);

  system.stop();
  CHECK(system.http() == nullptr);  // stopped last
  CHECK(system.output_error().empty());
  CHECK_FALSE(client.Get("/healthz"));  // nobody listens any more
  std::filesystem::remove_all(dir);
}

TEST_CASE("A taken port fails System::start() naming the address, before anything runs",
          "[export][deploy]") {
  auto first_spec =
      load_deployment_string(deployment_with_http("127.0.0.1:0", ""), "first.yaml", factory());
  REQUIRE(first_spec);
  auto first = System::create(std::move(*first_spec), factory());
  REQUIRE(first);
  REQUIRE((*first)->start());
  const int port = (*first)->http()->address().port;

  const std::string address = "127.0.0.1:" + std::to_string(port);
  auto second_spec =
      load_deployment_string(deployment_with_http(address, ""), "second.yaml", factory());
  REQUIRE(second_spec);
  auto second = System::create(std::move(*second_spec), factory());
  REQUIRE(second);
  const auto started = (*second)->start();
  REQUIRE_FALSE(started);
  INFO(started.error().message);
  CHECK(started.error().message.find("outputs.http") != std::string::npos);
  CHECK(started.error().message.find(address) != std::string::npos);
  CHECK(started.error().message.find("taken") != std::string::npos);
  CHECK_FALSE((*second)->running());
  CHECK_FALSE((*second)->monitor().running());
  CHECK((*second)->component("c")->state() != TaskState::Running);
  CHECK((*second)->http() == nullptr);

  // The first still serves (its reports from its first monitor cycle, one period after start).
  httplib::Client client("127.0.0.1", port);
  auto r = client.Get("/api/v1/reports");
  for (int i = 0; i < 100 && r && r->status == 503; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    r = client.Get("/api/v1/reports");
  }
  REQUIRE(r);
  CHECK(r->status == 200);
  (*first)->stop();
}
