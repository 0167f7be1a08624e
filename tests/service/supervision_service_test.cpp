#include "vigil/service/supervision_service.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"

using namespace vigil;

namespace {

std::string read_all(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string out;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, n);
  return out;
}

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// HTTP on any free port, one thread, nothing said.
exporter::HttpOptions quiet_http() {
  exporter::HttpOptions http;
  http.listen.port = 0;
  http.threads = 1;
  http.log = [](const std::string&) {};
  return http;
}

// A new output: one interface (exporter::Output), one registration (add_output). It counts
// what the service tells it.
struct CountingOutput final : exporter::Output {
  int starts = 0;
  int cycles = 0;
  int stops = 0;
  std::uint64_t final_cycles = 0;  // the probe's cycles in the final reports
  bool fail_start = false;
  bool had_extra = true;
  std::thread::id publisher;
  expected<void, Error> start(exporter::OutputContext& /*context*/) override {
    ++starts;
    if (fail_start) return unexpected(Error{"output refused"});
    return {};
  }
  void publish(const exporter::Snapshot& s) override {
    ++cycles;
    had_extra = had_extra && s.reports.find("extra") != nullptr;
    publisher = std::this_thread::get_id();
  }
  void stop(const exporter::Snapshot& s) override {
    ++stops;
    if (const auto* p = s.reports.find("probe")) final_cycles = p->counters.cycles;
  }
};

// A contributor adding one report, "extra", counting its calls and the threads it ran on.
struct Extra final : service::Contributor {
  std::atomic<int> calls{0};
  std::mutex mutex;
  std::set<std::thread::id> threads;
  void contribute(exporter::Snapshot& s) override {
    ++calls;
    {
      std::lock_guard lock(mutex);
      threads.insert(std::this_thread::get_id());
    }
    Report extra;
    extra.kind = ReportKind::Component;
    extra.name = "extra";
    s.reports.components.push_back(std::move(extra));
  }
};

// Runs `n` cycles of `probe` in the calling thread.
void run_cycles(test::Probe& probe, int n) {
  ManualActivity act(probe, {.name = "manual"});
  REQUIRE(probe.configure());
  REQUIRE(act.start());
  for (int i = 0; i < n; ++i) act.step();
  act.stop();
}

}  // namespace

TEST_CASE("The service supervises, then prints the summary and writes the JSON file at stop",
          "[service]") {
  ComponentRegistry reg;
  std::FILE* summary = std::tmpfile();
  REQUIRE(summary != nullptr);
  const auto json = std::filesystem::temp_directory_path() / "vigil_supervision_service_test.json";
  std::filesystem::remove(json);
  {
    SupervisionService service({.registry = &reg,
                                .monitor_thread = false,
                                .summary_file = summary,
                                .color = ColorMode::Never,
                                .json_file = json.string()});
    REQUIRE(service.start());
    CHECK(service.running());
    test::Probe probe("probe", {}, reg);
    run_cycles(probe, 25);
    const ReportSet final_reports = service.stop();
    CHECK_FALSE(service.running());
    const Report* r = final_reports.find("probe");
    REQUIRE(r != nullptr);
    CHECK(r->counters.cycles == 25);
    CHECK(final_reports.find("vigil.supervisor") != nullptr);
    // A second stop publishes nothing more and returns the same reports.
    CHECK(service.stop().cycle == final_reports.cycle);
  }
  const std::string text = read_all(summary);
  std::fclose(summary);
  CHECK(text.find("probe") != std::string::npos);
  CHECK(text.find("STATUS") != std::string::npos);  // the summary's header, printed once
  CHECK(text.find("STATUS") == text.rfind("STATUS"));
  const std::string doc = read_file(json);
  CHECK(doc.find("\"schema\": 2") != std::string::npos);
  CHECK(doc.find("\"name\": \"probe\"") != std::string::npos);
  std::filesystem::remove(json);
}

TEST_CASE("Outputs and contributors see every cycle and the final reports", "[service]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .monitor_thread = false, .summary_file = nullptr});
  auto& out = service.add_output<CountingOutput>();
  auto& extra = static_cast<Extra&>(service.add_contributor(std::make_unique<Extra>()));
  CHECK(service.reports().components.empty());  // no cycle yet
  REQUIRE(service.start());
  CHECK(out.starts == 1);
  test::Probe probe("probe", {}, reg);
  run_cycles(probe, 10);
  const ReportSet stepped = service.step();  // one monitor cycle in this thread
  CHECK(stepped.find("extra") != nullptr);
  CHECK(service.reports().find("extra") != nullptr);
  CHECK(service.snapshot()->cycle == stepped.cycle);
  CHECK(out.cycles == 1);
  CHECK(extra.calls == 1);  // reading the reports runs no contributor again
  const ReportSet final_reports = service.stop();
  CHECK(out.had_extra);
  CHECK(out.cycles == 1);  // the final snapshot goes to stop(), not publish()
  CHECK(out.stops == 1);
  CHECK(out.final_cycles == 10);
  CHECK(extra.calls == 2);  // the final cycle
  CHECK(final_reports.find("extra") != nullptr);
}

TEST_CASE("With HTTP on, each contributor runs once per monitor cycle, on the monitor's thread",
          "[service][http]") {
  ComponentRegistry reg;
  const exporter::HttpOptions http = quiet_http();
  SupervisionService service({.registry = &reg,
                              .supervisor_period_ns = kNanosPerMilli,
                              .monitor_period_ns = 20 * kNanosPerMilli,
                              .summary_file = nullptr,
                              .http = http});
  auto& extra = static_cast<Extra&>(service.add_contributor(std::make_unique<Extra>()));
  auto& out = service.add_output<CountingOutput>();
  REQUIRE(service.start());
  REQUIRE(service.http() != nullptr);
  // Readers of every kind while the monitor cycles: the service, the HTTP endpoints.
  for (int i = 0; i < 30; ++i) {
    (void)service.reports();
    (void)service.http()->answer("GET /api/v1/reports HTTP/1.1\r\nHost: localhost\r\n\r\n");
    (void)service.http()->answer("GET /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const ReportSet final_reports = service.stop();
  // One call per monitor cycle, the final one included: the monitor's cycles are counted by
  // the monitor's own report.
  const Report* mon = final_reports.find("vigil.monitor");
  REQUIRE(mon != nullptr);
  CHECK(extra.calls == static_cast<int>(mon->counters.cycles));
  CHECK(out.cycles + 1 == extra.calls);  // every published cycle, and the final one
  std::lock_guard lock(extra.mutex);
  CHECK(extra.threads.size() == 2);  // the monitor's thread, and stop()'s caller for the last
  CHECK(extra.threads.count(out.publisher) == 1);
}

TEST_CASE("The HTTP snapshot's buckets are of the same monitor cycle as its reports",
          "[service][http]") {
  ComponentRegistry reg;
  const exporter::HttpOptions http = quiet_http();
  SupervisionServiceOptions options{
      .registry = &reg, .monitor_thread = false, .summary_file = nullptr, .http = http};
  options.aggregator.warmup_ns = 0;  // every cycle in the statistics
  SupervisionService service(std::move(options));
  test::Probe probe("probe", {}, reg);
  REQUIRE(probe.configure());
  ManualActivity act(probe, {.name = "manual"});
  REQUIRE(act.start());
  // The supervisor's thread drains; the monitor runs only when stepped.
  REQUIRE(service.start());
  const auto drained = [&](std::uint64_t n) {
    for (int i = 0; i < 2000; ++i) {
      const auto p = service.aggregator().find("probe");
      if (p && p->counters.cycles == n) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  };
  for (int i = 0; i < 5; ++i) act.step();
  REQUIRE(drained(5));
  const ReportSet stepped = service.step();
  // More cycles are drained after that monitor cycle: the snapshot served must not mix them in.
  for (int i = 0; i < 7; ++i) act.step();
  REQUIRE(drained(12));
  const auto snap = service.http()->snapshot();
  REQUIRE(snap != nullptr);
  CHECK(snap->reports.cycle == stepped.cycle);
  CHECK(service.snapshot()->cycle == stepped.cycle);
  const Report* rep = snap->reports.find("probe");
  REQUIRE(rep != nullptr);
  const auto* buckets = snap->histograms_of(*rep);
  REQUIRE(buckets != nullptr);
  CHECK(buckets->cycle == stepped.cycle);
  CHECK(rep->execution_ns.count == 5);
  CHECK(buckets->execution.count == rep->execution_ns.count);
  REQUIRE(act.stop());
  service.stop();
}

TEST_CASE("An output that fails to start fails start() and leaves nothing running", "[service]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .summary_file = nullptr});
  auto& out = service.add_output<CountingOutput>();
  out.fail_start = true;
  const auto r = service.start();
  REQUIRE_FALSE(r);
  CHECK(r.error().message == "output refused");
  CHECK_FALSE(service.running());
  CHECK_FALSE(service.supervisor()->running());
  CHECK_FALSE(service.monitor().running());
}

TEST_CASE("The monitor runs on its own thread by default and the destructor stops everything",
          "[service]") {
  ComponentRegistry reg;
  std::atomic<int> finals{0};  // written by the monitor's thread, read here
  {
    SupervisionService service({.registry = &reg,
                                .supervisor_period_ns = kNanosPerMilli,
                                .monitor_period_ns = 5 * kNanosPerMilli,
                                .summary_file = nullptr});
    service.add_output<exporter::CallbackOutput>([&](const exporter::Snapshot& s) {
      if (s.reports.find("probe") != nullptr) ++finals;
    });
    REQUIRE(service.start());
    CHECK(service.supervisor()->running());
    CHECK(service.monitor().running());
    test::Probe probe("probe", {}, reg);
    run_cycles(probe, 3);
    for (int i = 0; i < 2000 && finals == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    CHECK(finals > 0);  // a cycle of the monitor's own thread reported the probe
  }
  CHECK(finals > 0);
}

TEST_CASE("start() twice is refused while running, the service starts again after stop()",
          "[service]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .monitor_thread = false, .summary_file = nullptr});
  auto& out = service.add_output<CountingOutput>();
  REQUIRE(service.start());
  const auto again = service.start();
  REQUIRE_FALSE(again);
  CHECK(again.error().message.find("already running") != std::string::npos);
  CHECK(out.starts == 1);  // the outputs were not started twice
  CHECK(service.running());
  service.stop();
  CHECK(out.stops == 1);
  REQUIRE(service.start());  // a stopped service may run again
  CHECK(out.starts == 2);
  service.stop();
  CHECK(out.stops == 2);
}

TEST_CASE("The HTTP server and the textfile are outputs of the service", "[service][http]") {
  ComponentRegistry reg;
  const auto prom = std::filesystem::temp_directory_path() / "vigil_supervision_service_test.prom";
  std::filesystem::remove(prom);
  exporter::HttpOptions http;
  http.listen.port = 0;  // any free port
  http.threads = 1;
  http.log = [](const std::string&) {};
  SupervisionService service({.registry = &reg,
                              .supervisor_period_ns = kNanosPerMilli,
                              .monitor_thread = false,
                              .summary_file = nullptr,
                              .http = http,
                              .prom_textfile = prom});
  service.add_contributor(std::make_unique<Extra>());
  CHECK(service.http() == nullptr);  // before start
  REQUIRE(service.start());
  REQUIRE(service.http() != nullptr);
  CHECK(service.http()->running());
  CHECK(service.http()->address().port != 0);
  test::Probe probe("probe", {}, reg);
  run_cycles(probe, 5);
  // step() runs the monitor on what the supervisor's thread has drained so far: wait for it.
  for (int i = 0; i < 2000; ++i) {
    const auto p = service.aggregator().find("probe");
    if (p && p->counters.cycles == 5) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  service.step();
  const auto snap = service.http()->snapshot();
  REQUIRE(snap != nullptr);
  CHECK(snap->reports.find("probe") != nullptr);
  CHECK(snap->reports.find("extra") != nullptr);  // the contributors' reports are served too
  const std::string text = read_file(prom);
  CHECK(text.find("probe") != std::string::npos);

  // A second service cannot bind the same port: its start() fails and nothing runs.
  exporter::HttpOptions taken = http;
  taken.listen.port = service.http()->address().port;
  SupervisionService other({.registry = &reg, .summary_file = nullptr, .http = taken});
  const auto r = other.start();
  CHECK_FALSE(r);
  CHECK_FALSE(other.running());
  CHECK_FALSE(other.supervisor()->running());
  CHECK(other.http() == nullptr);

  service.stop();
  CHECK(service.http() == nullptr);
  std::filesystem::remove(prom);
}
