// The flight record as trace-event JSON, the event file, and the events/clear/trace endpoints.
#include "vigil/export/trace_event.hpp"

#include <httplib.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/json_reader.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/safe_state.hpp"

using namespace vigil;
using namespace vigil::exporter;
using vigil::test::Json;
using vigil::test::JsonParser;

namespace {

supervisor::FlightRecord sample_record() {
  supervisor::FlightRecord r;
  r.component = "encoder";
  r.component_id = 7;
  r.has_info = true;
  r.info.activity.assign("aux");
  r.info.tid = 4242;
  r.info.period_ns = kNanosPerMilli;
  for (std::uint64_t i = 1; i <= 10; ++i) {
    supervisor::CycleRecord c;
    c.cycle = 100 + i;
    c.release_ns = static_cast<Nanos>(i) * kNanosPerMilli;
    c.start_ns = c.release_ns + 50 * kNanosPerMicro;
    c.end_ns = c.start_ns + (i == 10 ? 1500 : 20) * kNanosPerMicro;
    c.flags = i == 10 ? supervisor::CycleRecord::kOverrun : 0;
    c.state = i == 10 ? TaskState::Exception : TaskState::Running;
    r.cycles.push_back(c);
  }
  r.cycles.erase(r.cycles.begin() + 4);  // cycle 105 dropped
  r.event.seq = 3;
  r.event.kind = EventKind::Exception;
  r.event.cycle = 110;
  r.event.fault_ns = r.cycles.back().end_ns;
  r.event.detected_ns = r.event.fault_ns + 4 * kNanosPerMilli;
  r.event.detail = "std::runtime_error in update: \"bad\" checksum";
  r.frozen_ns = r.event.detected_ns;
  return r;
}

std::vector<Json> of_phase(const Json& trace, const std::string& ph) {
  std::vector<Json> out;
  for (const Json& e : trace["traceEvents"].array()) {
    if (e["ph"].str() == ph) out.push_back(e);
  }
  return out;
}

}  // namespace

TEST_CASE("A flight record is trace-event JSON: X per cycle, markers, counters, names",
          "[export][trace]") {
  const supervisor::FlightRecord r = sample_record();
  const Json t = JsonParser::parse(trace_event_json(r));  // throws on invalid JSON
  const auto x = of_phase(t, "X");
  REQUIRE(x.size() == 9);
  CHECK(x.front()["args"]["cycle"].number() == 101);
  CHECK(x.back()["args"]["cycle"].number() == 110);
  CHECK(x.front()["ts"].number() == Approx(1050.0));  // microseconds
  CHECK(x.front()["dur"].number() == Approx(20.0));
  CHECK(x.back()["dur"].number() == Approx(1500.0));
  CHECK(x.back()["name"].str() == "cycle (overrun)");
  CHECK(x.back()["args"]["state"].str() == "Exception");
  CHECK(x.front()["tid"].number() == 4242);
  const auto meta = of_phase(t, "M");
  REQUIRE(meta.size() == 2);
  CHECK(meta[0]["args"]["name"].str() == "vigil: encoder");
  CHECK_THAT(meta[1]["args"]["name"].str(), Catch::StartsWith("encoder (aux"));
  CHECK(of_phase(t, "C").size() == 2 * 9);  // latency and user time per cycle
  const auto marks = of_phase(t, "i");
  // the dropped cycle, the fault, its detection
  REQUIRE(marks.size() == 3);
  CHECK(marks[0]["name"].str() == "1 cycles missing (dropped)");
  CHECK_THAT(marks[1]["name"].str(), Catch::StartsWith("exception: std::runtime_error"));
  CHECK(marks[1]["ts"].number() == Approx(static_cast<double>(r.event.fault_ns) / 1e3));
  CHECK(marks[1]["args"]["cycle"].number() == 110);
  CHECK(marks[2]["ts"].number() == Approx(static_cast<double>(r.event.detected_ns) / 1e3));
  CHECK(t["otherData"]["fault_cycle"].number() == 110);
  CHECK(t["displayTimeUnit"].str() == "ms");
}

TEST_CASE("A flight record shows checkpoints as instants and deadline pairs as async slices",
          "[export][trace][health]") {
  supervisor::FlightRecord r = sample_record();
  r.checkpoints = {{"decoded", 1'070'000, 101}, {"decoded", 2'070'000, 102}};
  r.deadlines = {{"sample_to_decode", "logger.sample", "encoder.decoded", 1'000'000, 1'070'000,
                  health::FailureKind::None},
                 {"sample_to_decode", "logger.sample", "encoder.decoded", 10'000'000, 10'500'000,
                  health::FailureKind::DeadlineMissed}};
  const Json t = JsonParser::parse(trace_event_json(r));
  std::vector<Json> cps;
  for (const Json& e : of_phase(t, "i")) {
    if (e.has("cat") && e["cat"].str() == "checkpoint") cps.push_back(e);
  }
  REQUIRE(cps.size() == 2);
  CHECK(cps[0]["name"].str() == "decoded");
  CHECK(cps[0]["ts"].number() == Approx(1070.0));
  CHECK(cps[1]["args"]["cycle"].number() == 102);
  CHECK(cps[0]["tid"].number() == 4242);  // on the component's thread
  const auto begins = of_phase(t, "b");
  const auto ends = of_phase(t, "e");
  REQUIRE(begins.size() == 2);
  REQUIRE(ends.size() == 2);
  CHECK(begins[0]["name"].str() == "deadline sample_to_decode");
  CHECK(begins[0]["cat"].str() == "deadline");
  CHECK(begins[0]["args"]["result"].str() == "ok");
  CHECK(begins[0]["args"]["duration_us"].number() == Approx(70.0));
  CHECK(begins[1]["cat"].str() == "deadline,fault");
  CHECK(begins[1]["args"]["result"].str() == "deadline_missed");
  CHECK(begins[1]["args"]["end"].str() == "encoder.decoded");
  CHECK(ends[1]["ts"].number() == Approx(10500.0));
  CHECK(begins[1]["id"].number() == ends[1]["id"].number());  // each begin meets its end
  CHECK(begins[0]["id"].number() != begins[1]["id"].number());
  CHECK(t["otherData"]["checkpoints"].number() == 2);
  CHECK(t["otherData"]["deadline_spans"].number() == 2);
}

TEST_CASE("Events are one JSON object per line, escaped", "[export][events]") {
  Event e;
  e.seq = 9;
  e.kind = EventKind::Deadline;
  e.severity = EventSeverity::Error;
  e.component = "arm \"left\"";
  e.detail = "line\nbreak";
  e.fault_ns = 1000;
  e.detected_ns = 1500;
  const std::string line = event_json(e);
  CHECK(line.find('\n') == std::string::npos);
  const Json j = JsonParser::parse(line);
  CHECK(j["kind"].str() == "deadline");
  CHECK(j["severity"].str() == "error");
  CHECK(j["component"].str() == "arm \"left\"");
  CHECK(j["detail"].str() == "line\nbreak");
  CHECK(j["latency_ns"].number() == 500);
  CHECK(line.find("\"pid\"") == std::string::npos);  // this process's own component
  // An event about another process (vigil supervise) names it.
  e.kind = EventKind::ProcessExited;
  e.pid = 4321;
  const Json p = JsonParser::parse(event_json(e));
  CHECK(p["kind"].str() == "process_exited");
  CHECK(p["pid"].number() == 4321);
}

TEST_CASE("EventLogWriter writes every event as a JSON line", "[export][events]") {
  const auto path = std::filesystem::temp_directory_path() / "vigil_events_test.jsonl";
  supervisor::EventHub hub;
  {
    auto w = EventLogWriter::start(hub, path);
    REQUIRE(w.has_value());
    for (int i = 0; i < 5; ++i) {
      Event e;
      e.component = "c" + std::to_string(i);
      hub.publish(e);
    }
    REQUIRE(hub.flush());
    CHECK((*w)->written() == 5);
  }
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    CHECK(JsonParser::parse(line)["component"].str() == "c" + std::to_string(n));
    ++n;
  }
  CHECK(n == 5);
  std::filesystem::remove(path);
  CHECK_FALSE(EventLogWriter::start(hub, "/nonexistent-dir/x.jsonl").has_value());
}

TEST_CASE("HTTP: events by long poll, on-demand traces, and the clear endpoint when enabled",
          "[export][http][events]") {
  supervisor::EventHub hub;
  std::string cleared = "-";
  HttpOptions o;
  o.listen.port = 0;
  o.log = [](const std::string&) {};
  o.events = &hub;
  o.trace = [](const std::string& name) -> std::optional<std::string> {
    if (name != "encoder") return std::nullopt;
    return trace_event_json(sample_record());
  };
  o.event_trace = [](std::uint64_t seq) -> std::optional<std::string> {
    if (seq != 17) return std::nullopt;
    return trace_event_json(sample_record());
  };
  o.clear = [&](const std::string& name) -> std::size_t {
    cleared = name;
    return 1;
  };
  HttpServer s(o);
  REQUIRE(s.start().has_value());
  httplib::Client c("127.0.0.1", s.address().port);
  c.set_read_timeout(5);
  Event e;
  e.component = "encoder";
  e.kind = EventKind::Exception;
  hub.publish(e);
  hub.publish(e);
  auto r = c.Get("/api/v1/events?after=1");
  REQUIRE(r);
  CHECK(r->status == 200);
  Json j = JsonParser::parse(r->body);
  CHECK(j["last_seq"].number() == 2);
  REQUIRE(j["events"].array().size() == 1);
  CHECK(j["events"][0]["seq"].number() == 2);
  // A long poll returns as soon as an event arrives.
  std::thread later([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    hub.publish(e);
  });
  r = c.Get("/api/v1/events?after=2&wait=5");
  later.join();
  REQUIRE(r);
  j = JsonParser::parse(r->body);
  REQUIRE(j["events"].array().size() == 1);
  CHECK(j["events"][0]["seq"].number() == 3);
  CHECK(c.Get("/api/v1/events?after=x")->status == 400);

  r = c.Get("/api/v1/trace/encoder");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(JsonParser::parse(r->body)["traceEvents"].array().size() > 10);
  CHECK(c.Get("/api/v1/trace/nobody")->status == 404);
  // The record frozen with an event (an exemplar's trace).
  r = c.Get("/api/v1/events/17/trace");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(r->get_header_value("Content-Disposition").find("vigil-event-17.trace.json") !=
        std::string::npos);
  CHECK(JsonParser::parse(r->body)["traceEvents"].array().size() > 10);
  CHECK(c.Get("/api/v1/events/18/trace")->status == 404);
  for (const char* bad :
       {"/api/v1/events/x/trace", "/api/v1/events/0/trace", "/api/v1/events/17x/trace",
        "/api/v1/events/-1/trace", "/api/v1/events//trace"}) {
    INFO(bad);
    CHECK(c.Get(bad)->status == 404);
  }

  CHECK(c.Post("/api/v1/clear?component=encoder", "", "text/plain")->status == 403);  // no header
  CHECK(cleared == "-");
  r = c.Post("/api/v1/clear?component=encoder", httplib::Headers{{"X-Vigil-Clear", "1"}}, "",
             "text/plain");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(cleared == "encoder");
  CHECK(JsonParser::parse(r->body)["cleared"].number() == 1);
  // `safe_state=1` also ends the safe-state request (the operator's decision).
  REQUIRE(vigil::request_safe_state("test"));
  r = c.Post("/api/v1/clear?safe_state=1", httplib::Headers{{"X-Vigil-Clear", "1"}}, "",
             "text/plain");
  REQUIRE(r);
  CHECK(r->status == 200);
  CHECK(JsonParser::parse(r->body)["safe_state_cleared"].boolean());
  CHECK_FALSE(vigil::safe_state_requested());
  CHECK(c.Post("/api/v1/clear?safe_state=yes", httplib::Headers{{"X-Vigil-Clear", "1"}}, "",
               "text/plain")
            ->status == 400);
  CHECK(c.Post("/api/v1/other", "", "text/plain")->status == 405);
  s.stop();

  SECTION("without a clear function, POST stays refused") {
    HttpOptions ro;
    ro.listen.port = 0;
    ro.log = [](const std::string&) {};
    HttpServer rs(ro);
    REQUIRE(rs.start().has_value());
    httplib::Client rc("127.0.0.1", rs.address().port);
    CHECK(rc.Post("/api/v1/clear", httplib::Headers{{"X-Vigil-Clear", "1"}}, "", "text/plain")
              ->status == 405);
    CHECK(rc.Get("/api/v1/events")->status == 404);
  }
}
