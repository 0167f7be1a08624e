// The `outputs: {http: ...}` key of a deployment (deploy module), read into the HTTP server's
// address.
#include <catch2/catch.hpp>

#include "vigil/deploy/deployment.hpp"
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
