#include "vigil/export/http_server.hpp"

#include <httplib.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "export/exposition.hpp"
#include "monitor/harness.hpp"
#include "support/json_reader.hpp"
#include "vigil/export/diagnostics.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/textfile.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/service/supervision_service.hpp"

using namespace vigil;
using namespace vigil::exporter;
using vigil::test::Json;
using vigil::test::JsonParser;

namespace {

struct Fixture {
  test::Harness h;
  test::PeriodicProbe motor{h, "motor", kNanosPerMilli};
  test::PeriodicProbe arm{h, "can0/arm", 2 * kNanosPerMilli};  // a name with a slash

  Fixture() {
    motor.probe.work_ns = 40 * kNanosPerMicro;
    for (int i = 0; i < 100; ++i) h.cycle(motor.activity);
    for (int i = 0; i < 3; ++i) h.cycle(arm.activity);
    arm.probe.throw_next = true;
    h.cycle(arm.activity);
  }
};

HttpOptions quiet_options() {
  HttpOptions o;
  o.listen.port = 0;  // any free port
  o.log = [](const std::string&) {};
  return o;
}

httplib::Client client(const HttpServer& s) {
  httplib::Client c("127.0.0.1", s.address().port);
  c.set_connection_timeout(5);
  c.set_read_timeout(5);
  return c;
}

}  // namespace

TEST_CASE("parse_listen reads [ADDR:]PORT and names what is wrong", "[export][http]") {
  auto a = parse_listen("9479");
  REQUIRE(a);
  CHECK(a->host == "127.0.0.1");
  CHECK(a->port == 9479);
  CHECK(a->loopback());
  a = parse_listen("0.0.0.0:80");
  REQUIRE(a);
  CHECK(a->host == "0.0.0.0");
  CHECK(!a->loopback());
  a = parse_listen("[::1]:9000");
  REQUIRE(a);
  CHECK(a->host == "::1");
  CHECK(a->loopback());
  CHECK(a->to_string() == "[::1]:9000");
  CHECK(parse_listen("localhost:0")->loopback());
  CHECK(!parse_listen(""));
  CHECK(parse_listen("70000").error().find("0..65535") != std::string::npos);
  CHECK(parse_listen("host:port").error().find("port") != std::string::npos);
  CHECK(parse_listen(":80").error().find("empty") != std::string::npos);
  CHECK(parse_listen("::1:80").error().find("[ADDR]:PORT") != std::string::npos);
  CHECK(!parse_listen("[::1]80"));
}

TEST_CASE("The server serves every endpoint from the published snapshot", "[export][http]") {
  Fixture f;
  HttpServer server(quiet_options());
  REQUIRE(server.start());
  REQUIRE(server.address().port > 0);
  CHECK(server.address().host == "127.0.0.1");
  auto c = client(server);

  // Before the first publication.
  auto r = c.Get("/api/v1/reports");
  REQUIRE(r);
  CHECK(r->status == 503);
  r = c.Get("/healthz");
  REQUIRE(r);
  CHECK(r->status == 503);
  r = c.Get("/metrics");
  REQUIRE(r);
  CHECK(r->status == 200);

  const ReportSet reports = f.h.step();
  server.publish(reports, collect_histograms(f.h.aggregator));

  r = c.Get("/metrics");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(r->get_header_value("Content-Type").starts_with("text/plain; version=0.0.4"));
  CHECK(r->body.find("vigil_component_cycles_total{component=\"motor\"} 100") != std::string::npos);
  (void)test::parse_exposition(r->body, false);

  r = c.Get("/metrics", {{"Accept", "application/openmetrics-text; version=1.0.0"}});
  REQUIRE(r);
  CHECK(r->get_header_value("Content-Type").starts_with("application/openmetrics-text"));
  CHECK(r->body.ends_with("# EOF\n"));
  (void)test::parse_exposition(r->body, true);

  r = c.Get("/api/v1/reports");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(r->get_header_value("Content-Type").starts_with("application/json"));
  Json doc = JsonParser::parse(r->body);
  CHECK(doc["schema"].number_text() == "2");
  CHECK(doc["components"].array().size() == reports.components.size());

  // One component by name, its slash taken as it is or percent-encoded.
  for (const char* path : {"/api/v1/reports/can0/arm", "/api/v1/reports/can0%2Farm"}) {
    INFO(path);
    r = c.Get(path);
    REQUIRE(r);
    CHECK(r->status == 200);
    doc = JsonParser::parse(r->body);
    CHECK(doc["component"]["name"].str() == "can0/arm");
    CHECK(doc["component"]["status"].str() == "ERROR");
  }
  r = c.Get("/api/v1/reports/nobody");
  REQUIRE(r);
  CHECK(r->status == 404);
  CHECK(JsonParser::parse(r->body)["error"].str().find("nobody") != std::string::npos);

  r = c.Get("/api/v1/diagnostics");
  REQUIRE(r);
  doc = JsonParser::parse(r->body);
  CHECK(doc["header"]["stamp"]["sec"].is_integer());
  CHECK(doc["header"]["stamp"]["nanosec"].is_integer());
  CHECK(doc["status"].array().size() == reports.components.size());

  r = c.Get("/api/v1/histograms");
  REQUIRE(r);
  doc = JsonParser::parse(r->body);
  CHECK(doc["bounds_s"].array().size() == kBucketBounds);
  REQUIRE(doc["components"].array().size() == 2);
  CHECK(doc["components"].array()[0]["execution"]["buckets"].array().size() == kBucketBounds + 1);
  CHECK(doc["components"].array()[0]["execution"]["count"].number_text() == "100");

  server.publish(f.h.step(), {});
  r = c.Get("/api/v1/history");
  REQUIRE(r);
  doc = JsonParser::parse(r->body);
  CHECK(doc["time_s"].array().size() == 2);
  CHECK(doc["components"]["motor"]["execution_p99_s"].array().size() == 2);
  CHECK(doc["components"]["can0/arm"]["overruns"].array().size() == 2);

  r = c.Get("/healthz");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(JsonParser::parse(r->body)["status"].str() == "ok");
  CHECK(JsonParser::parse(r->body)["worst"].str() == "ERROR");

  r = c.Get("/");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(r->get_header_value("Content-Type").starts_with("text/html"));
  CHECK(r->body.find("data-refresh-ms=\"500\"") != std::string::npos);
  CHECK(r->get_header_value("Content-Security-Policy").find("default-src 'self'") !=
        std::string::npos);
  r = c.Get("/static/dashboard.js");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(r->body.find("/api/v1/reports") != std::string::npos);

  CHECK(server.stats().requests >= 10);  // (the count follows the response: the last may lag)
  server.stop();
  CHECK(!server.running());
}

TEST_CASE("The server is read-only and rejects bad requests with 4xx", "[export][http]") {
  Fixture f;
  HttpServer server(quiet_options());
  REQUIRE(server.start());
  server.publish(f.h.step());
  auto c = client(server);

  auto r = c.Post("/metrics", "x", "text/plain");
  REQUIRE(r);
  CHECK(r->status == 405);
  CHECK(r->get_header_value("Allow") == "GET, HEAD");
  r = c.Put("/api/v1/reports", "x", "text/plain");
  REQUIRE(r);
  CHECK(r->status == 405);
  r = c.Delete("/");
  REQUIRE(r);
  CHECK(r->status == 405);
  r = c.Head("/metrics");
  REQUIRE(r);
  CHECK(r->status == 200);

  r = c.Get("/nope");
  REQUIRE(r);
  CHECK(r->status == 404);
  CHECK(r->body.find("/metrics") != std::string::npos);  // says what exists

  // A 100 KiB header line: cpp-httplib's limit is 8 KiB per line.
  r = c.Get("/metrics", {{"X-Huge", std::string(100 * 1024, 'a')}});
  if (r) {
    CHECK(r->status >= 400);
    CHECK(r->status < 500);
  }  // (or the server closed the connection: also a refusal)

  // A GET with a large body: GET bodies are never read; the request is answered, the body
  // dropped with the connection.
  httplib::Request big;
  big.method = "GET";
  big.path = "/metrics";
  big.body = std::string(64 * 1024, 'b');
  big.set_header("Content-Type", "text/plain");
  httplib::Response res;
  httplib::Error err = httplib::Error::Success;
  if (c.send(big, res, err)) CHECK(res.status == 200);

  // DNS rebinding: a loopback server answers only loopback host names.
  r = c.Get("/metrics", {{"Host", "evil.example:80"}});
  REQUIRE(r);
  CHECK(r->status == 403);
  r = c.Get("/metrics", {{"Host", "localhost:1234"}});
  REQUIRE(r);
  CHECK(r->status == 200);

  // Still serving.
  r = c.Get("/healthz");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(server.stats().client_errors >= 5);
}

TEST_CASE("answer() serves raw request bytes like a connection, without a socket",
          "[export][http]") {
  Fixture f;
  HttpServer server(quiet_options());  // not started: answer() needs no socket
  CHECK(server.answer("GET /healthz HTTP/1.1\r\nHost: localhost\r\n\r\n")
            .starts_with("HTTP/1.1 503 "));  // nothing published yet
  server.publish(f.h.step());
  const auto status = [&](const std::string& request) {
    const std::string r = server.answer(request);
    return r.size() >= 12 && r.starts_with("HTTP/1.") ? std::stoi(r.substr(9, 3)) : -1;
  };
  const std::string ok = server.answer("GET /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n");
  CHECK(ok.starts_with("HTTP/1.1 200 OK\r\n"));
  CHECK(ok.find("X-Content-Type-Options: nosniff") != std::string::npos);
  CHECK(ok.find("vigil_") != std::string::npos);
  CHECK(status("GET /api/v1/reports/can0/arm HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n") == 200);
  CHECK(status("GET /api/v1/reports/nobody HTTP/1.1\r\n\r\n") == 404);
  CHECK(status("POST /metrics HTTP/1.1\r\nContent-Length: 1\r\n\r\nx") == 405);
  CHECK(status("GET /metrics HTTP/1.1\r\nHost: evil.example\r\n\r\n") == 403);
  CHECK(status("GET /nope HTTP/1.1\r\n\r\n") == 404);
  CHECK(status("GET /" + std::string(9000, 'a') + " HTTP/1.1\r\n\r\n") == 414);
  CHECK(status("GARBAGE\r\n\r\n") == 400);
  CHECK(server.answer("").empty());  // no request line: closed without an answer
  CHECK(server.stats().requests >= 9);
  CHECK(server.stats().server_errors == 1);  // the 503 before the first publication
}

TEST_CASE("The HTTP module is opened on demand, and http_module() names it", "[export][http]") {
  // In a test binary the module is this build's (nothing else is installed or named).
  const auto path = http_module();
  REQUIRE(path);
  CHECK(std::filesystem::path(*path).filename() == "libvigil_http.so");
  CHECK(std::filesystem::is_regular_file(*path));
  std::ifstream maps("/proc/self/maps");
  const std::string mapped((std::istreambuf_iterator<char>(maps)),
                           std::istreambuf_iterator<char>());
  CHECK(mapped.find(std::filesystem::canonical(*path).string()) != std::string::npos);
  const auto again = http_module();  // opened once: the same path
  CHECK((again && *again == *path));

  // What crosses the module's boundary: a route's own headers, HEAD without a body.
  Fixture f;
  HttpServer server(quiet_options());
  server.publish(f.h.step());
  const std::string page = server.answer("GET / HTTP/1.1\r\nHost: localhost\r\n\r\n");
  CHECK(page.find("Content-Security-Policy: default-src 'self'") != std::string::npos);
  CHECK(page.find("Cache-Control: no-store") != std::string::npos);
  const std::string head = server.answer("HEAD /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n");
  CHECK(head.starts_with("HTTP/1.1 200 OK\r\n"));
  CHECK(head.find("Content-Length: ") != std::string::npos);
  CHECK(head.ends_with("\r\n\r\n"));  // headers only
  const std::string query =
      server.answer("GET /api/v1/events?after=x HTTP/1.1\r\nHost: localhost\r\n\r\n");
  CHECK(query.starts_with("HTTP/1.1 404 "));  // no event hub given: no such endpoint
}

TEST_CASE("100 concurrent scrapers are all served", "[export][http]") {
  Fixture f;
  HttpServer server(quiet_options());
  REQUIRE(server.start());
  server.publish(f.h.step(), collect_histograms(f.h.aggregator));
  std::atomic<int> ok{0};
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::vector<std::thread> clients;
  for (int i = 0; i < 100; ++i) {
    clients.emplace_back([&] {
      httplib::Client c("127.0.0.1", server.address().port);
      c.set_connection_timeout(10);
      c.set_read_timeout(10);
      auto r = c.Get("/metrics");
      if (r && r->status == 200 && r->body.find("vigil_component_status") != std::string::npos) {
        ++ok;
      } else {
        std::lock_guard lock(failures_mutex);
        failures.push_back(r ? "status " + std::to_string(r->status)
                             : httplib::to_string(r.error()));
      }
    });
  }
  // Publications go on while the scrapers read.
  for (int i = 0; i < 20; ++i) server.publish(f.h.step());
  for (auto& t : clients) t.join();
  INFO((failures.empty() ? std::string() : failures.front()));
  CHECK(ok == 100);
}

TEST_CASE("A second server on a taken port fails with a clear error", "[export][http]") {
  HttpServer first(quiet_options());
  REQUIRE(first.start());
  HttpOptions o = quiet_options();
  o.listen.port = first.address().port;
  HttpServer second(o);
  const auto r = second.start();
  REQUIRE(!r);
  CHECK(r.error().message.find("cannot listen on 127.0.0.1:" + std::to_string(o.listen.port)) !=
        std::string::npos);
  CHECK(r.error().message.find("taken") != std::string::npos);
  CHECK(!second.running());
  // The first one still serves.
  auto c = client(first);
  auto res = c.Get("/metrics");
  REQUIRE(res);
  CHECK(res->status == 200);
}

TEST_CASE("Options are validated and a non-loopback address is announced", "[export][http]") {
  HttpOptions o = quiet_options();
  o.threads = 0;
  CHECK(!HttpServer(o).start());
  o = quiet_options();
  o.dashboard_refresh_ns = 5 * kNanosPerSecond;
  CHECK(!HttpServer(o).start());

  std::vector<std::string> lines;
  o = quiet_options();
  o.listen.host = "0.0.0.0";
  o.log = [&](const std::string& l) { lines.push_back(l); };
  HttpServer any(o);
  REQUIRE(any.start());
  REQUIRE(lines.size() == 2);
  CHECK(lines[1].find("not on loopback") != std::string::npos);
  // Not loopback: no Host check.
  auto c = client(any);
  auto r = c.Get("/healthz", {{"Host", "robot-7.example:9479"}});
  REQUIRE(r);
  CHECK(r->status == 503);  // nothing published yet, but not refused

  lines.clear();
  o.listen.host = "127.0.0.1";
  HttpServer local(o);
  REQUIRE(local.start());
  CHECK(lines.size() == 1);
  CHECK(lines[0].find("http://127.0.0.1:") != std::string::npos);
}

TEST_CASE("The dashboard can be turned off", "[export][http]") {
  HttpOptions o = quiet_options();
  o.dashboard = false;
  HttpServer s(o);
  REQUIRE(s.start());
  auto c = client(s);
  auto r = c.Get("/");
  REQUIRE(r);
  CHECK(r->body.find("/metrics") != std::string::npos);
  CHECK(r->body.find("dashboard.js") == std::string::npos);
  r = c.Get("/static/dashboard.js");
  REQUIRE(r);
  CHECK(r->status == 404);
}

TEST_CASE("The HTTP and textfile outputs publish each snapshot", "[export][http]") {
  Fixture f;
  const auto dir = std::filesystem::temp_directory_path() /
                   ("vigil_textfile_" + std::to_string(reinterpret_cast<std::uintptr_t>(&f)));
  std::filesystem::create_directories(dir);
  HttpOutput http_output(quiet_options());
  TextfileOutput textfile(dir / "vigil.prom");
  OutputContext context{f.h.aggregator};
  REQUIRE(http_output.start(context));
  REQUIRE(textfile.start(context));
  HttpServer* http = http_output.server();
  REQUIRE(http != nullptr);
  CHECK(http->snapshot() == nullptr);
  Snapshot s;
  s.reports = f.h.step();  // drains, then a monitor cycle
  s.histograms = collect_histograms(f.h.aggregator);
  s.cycle = s.reports.cycle;
  Report extra;  // what a contributor adds
  extra.kind = ReportKind::Unit;
  extra.unit_kind = "can_group";
  extra.name = "can group extra";
  s.reports.components.push_back(extra);
  http_output.publish(s);
  textfile.publish(s);
  auto snap = http->snapshot();
  REQUIRE(snap != nullptr);
  CHECK(snap->reports.find("can group extra") != nullptr);
  CHECK(snap->histograms.size() == 2);
  CHECK(textfile.error().empty());
  std::ifstream in(dir / "vigil.prom");
  std::stringstream text;
  text << in.rdbuf();
  CHECK(text.str().find("vigil_component_status{component=\"can group extra\"") !=
        std::string::npos);
  CHECK(!std::filesystem::exists(dir / "vigil.prom.tmp"));
  (void)test::parse_exposition(text.str(), false);
  http_output.stop(s);
  CHECK(http_output.server() == nullptr);
  std::filesystem::remove_all(dir);

  // A textfile in a missing directory: the error names it.
  MetricsSnapshot empty;
  const auto bad = write_textfile("/nonexistent-dir/x.prom", empty);
  REQUIRE(!bad);
  CHECK(bad.error().message.find("/nonexistent-dir/x.prom") != std::string::npos);
}

TEST_CASE("Diagnostics map reports onto a ROS 2 DiagnosticArray", "[export][diagnostics]") {
  Fixture f;
  ReportSet set = f.h.step();
  Report node;
  node.kind = ReportKind::Unit;
  node.unit_kind = "can_node";
  node.name = "can0/drive_5";
  node.merge(StatusLevel::Stale, "silent");
  node.add_field(Field::of_count("frames_rx", 12));
  set.components.push_back(node);
  const Json doc = JsonParser::parse(to_diagnostics_json(set, 1'700'000'000'250'000'000));
  CHECK(doc["header"]["stamp"]["sec"].number_text() == "1700000000");
  CHECK(doc["header"]["stamp"]["nanosec"].number_text() == "250000000");
  CHECK(doc["header"]["frame_id"].str().empty());
  const auto& status = doc["status"].array();
  REQUIRE(status.size() == set.components.size());
  bool saw_arm = false, saw_node = false;
  for (const Json& s : status) {
    CHECK(s["name"].str().starts_with("vigil: "));
    CHECK(s["level"].is_integer());
    CHECK(s["message"].is_string());
    CHECK(s["hardware_id"].is_string());
    for (const Json& kv : s["values"].array()) {
      CHECK(kv["key"].is_string());
      CHECK(kv["value"].is_string());
    }
    if (s["name"].str() == "vigil: can0/arm") {
      saw_arm = true;
      CHECK(s["level"].number_text() == "2");
      CHECK(s["message"].str().find("exception") != std::string::npos);
    }
    if (s["name"].str() == "vigil: can0/drive_5") {
      saw_node = true;
      CHECK(s["level"].number_text() == "3");
      CHECK(s["hardware_id"].str() == "can0:drive_5");
      // Its fields by their names, after its kind.
      const auto& values = s["values"].array();
      REQUIRE(values.size() >= 3);
      CHECK(values[0]["value"].str() == "can_node");
      CHECK(values[2]["key"].str() == "frames_rx");
      CHECK(values[2]["value"].str() == "12");
    }
    if (s["name"].str() == "vigil: motor") CHECK(s["message"].str() == "OK");
  }
  CHECK(saw_arm);
  CHECK(saw_node);
  Report comp;
  comp.tid = 4242;
  comp.cpu = 1;
  CHECK(hardware_id(comp) == "tid 4242 cpu 1");
  comp.cpu = -1;
  CHECK(hardware_id(comp) == "tid 4242 cpu any");
  Report group;
  group.kind = ReportKind::Unit;
  group.unit_kind = "can_group";
  group.name = "can group left_arm";
  CHECK(hardware_id(group) == "can:left_arm");
  // Negative wall times keep nanosec in [0, 1e9).
  const Json neg = JsonParser::parse(to_diagnostics_json(ReportSet{}, -1));
  CHECK(neg["header"]["stamp"]["sec"].number_text() == "-1");
  CHECK(neg["header"]["stamp"]["nanosec"].number_text() == "999999999");
}

TEST_CASE("HTTP in a program's pipeline with real threads", "[export][http]") {
  Registry<task::Message> registry;
  service::SupervisionService service({.registry = &registry,
                                       .supervisor_period_ns = 5 * kNanosPerMilli,
                                       .monitor_period_ns = 20 * kNanosPerMilli,
                                       .summary_file = nullptr,
                                       .http = quiet_options()});
  REQUIRE(service.start());
  REQUIRE(service.http() != nullptr);
  auto c = client(*service.http());
  int status = 0;
  for (int i = 0; i < 200 && status != 200; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (auto r = c.Get("/healthz")) status = r->status;
  }
  CHECK(status == 200);
  auto r = c.Get("/api/v1/reports/vigil.supervisor");
  REQUIRE(r);
  CHECK(r->status == 200);
  service.stop();  // while clients may still ask: the server stops last
}

TEST_CASE("The server's threads run SCHED_OTHER even when started from a FIFO thread",
          "[export][http]") {
  HttpServer server(quiet_options());
  bool started = false;
  auto fifo = platform::Thread::spawn(
      platform::ThreadConfig{
          .name = "fifo-starter", .policy = platform::SchedPolicy::Fifo, .priority = 10},
      [&] { started = server.start().has_value(); });
  if (!fifo) {
    WARN("SCHED_FIFO refused (" << fifo.error().message << "): starting from this thread");
    started = server.start().has_value();
  } else {
    fifo->join();
  }
  REQUIRE(started);
  // The pool is created by the accepting thread once it runs: wait for the four threads.
  std::vector<int> tids;
  for (int attempt = 0; attempt < 200 && tids.size() < 4; ++attempt) {
    tids.clear();
    for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
      std::ifstream comm(task.path() / "comm");
      std::string name;
      std::getline(comm, name);
      if (name == "vigil-http") tids.push_back(std::stoi(task.path().filename().string()));
    }
    if (tids.size() < 4) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  int http_threads = 0;
  for (int tid : tids) {
    auto stats = platform::read_thread_stats(tid);
    REQUIRE(stats);
    CHECK(stats->policy == platform::SchedPolicy::Other);
    CHECK(stats->priority == 0);
    ++http_threads;
  }
  CHECK(http_threads == 1 + 3);  // the accepting thread and the pool
}
