#include "vigil/service/supervision_service.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
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

// Counts what the service tells an output.
struct CountingOutput final : ReportOutput {
  int starts = 0;
  int cycles = 0;
  int stops = 0;
  std::uint64_t final_cycles = 0;  // the probe's cycles in the final reports
  bool fail_start = false;
  expected<void, Error> start() override {
    ++starts;
    if (fail_start) return unexpected(Error{"output refused"});
    return {};
  }
  void on_reports(const ReportSet& /*r*/) override { ++cycles; }
  void stop(const ReportSet& r) override {
    ++stops;
    if (const auto* p = r.find("probe")) final_cycles = p->counters.cycles;
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
  CHECK(doc.find("\"schema\": 1") != std::string::npos);
  CHECK(doc.find("\"name\": \"probe\"") != std::string::npos);
  std::filesystem::remove(json);
}

TEST_CASE("Subscribers, outputs and contributors see every cycle and the final reports",
          "[service]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .monitor_thread = false, .summary_file = nullptr});
  auto& out = static_cast<CountingOutput&>(service.add_output(std::make_unique<CountingOutput>()));
  int seen = 0;
  bool had_extra = true;
  const auto id = service.subscribe([&](const ReportSet& r) {
    ++seen;
    had_extra = had_extra && r.find("extra") != nullptr;
  });
  service.add_contributor([](ReportSet& r) {
    Report extra;
    extra.kind = ReportKind::Component;
    extra.name = "extra";
    r.components.push_back(std::move(extra));
  });
  REQUIRE(service.start());
  CHECK(out.starts == 1);
  test::Probe probe("probe", {}, reg);
  run_cycles(probe, 10);
  const ReportSet stepped = service.step();  // one monitor cycle in this thread
  CHECK(stepped.find("extra") != nullptr);
  CHECK(service.reports().find("extra") != nullptr);
  CHECK(seen == 1);
  CHECK(out.cycles == 1);
  const ReportSet final_reports = service.stop();
  CHECK(seen == 2);  // the final cycle too
  CHECK(had_extra);
  CHECK(out.cycles == 1);  // the final reports go to stop(), not on_reports()
  CHECK(out.stops == 1);
  CHECK(out.final_cycles == 10);
  CHECK(final_reports.find("extra") != nullptr);
  service.unsubscribe(id);
}

TEST_CASE("An output that fails to start fails start() and leaves nothing running", "[service]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .summary_file = nullptr});
  auto& out = static_cast<CountingOutput&>(service.add_output(std::make_unique<CountingOutput>()));
  out.fail_start = true;
  const auto r = service.start();
  REQUIRE_FALSE(r);
  CHECK(r.error().message == "output refused");
  CHECK_FALSE(service.running());
  CHECK_FALSE(service.supervisor().running());
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
    REQUIRE(service.start());
    CHECK(service.supervisor().running());
    CHECK(service.monitor().running());
    service.subscribe([&](const ReportSet& r) {
      if (r.find("probe") != nullptr) ++finals;
    });
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
  auto& out = static_cast<CountingOutput&>(service.add_output(std::make_unique<CountingOutput>()));
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

TEST_CASE("The HTTP exporter and the textfile are outputs of the service", "[service][http]") {
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
  service.add_contributor([](ReportSet& r) {
    Report extra;
    extra.kind = ReportKind::Component;
    extra.name = "extra";
    r.components.push_back(std::move(extra));
  });
  CHECK(service.exporter() == nullptr);  // before start
  REQUIRE(service.start());
  REQUIRE(service.exporter() != nullptr);
  REQUIRE(service.exporter()->http() != nullptr);
  CHECK(service.exporter()->http()->running());
  CHECK(service.exporter()->http()->address().port != 0);
  test::Probe probe("probe", {}, reg);
  run_cycles(probe, 5);
  // step() runs the monitor on what the supervisor's thread has drained so far: wait for it.
  for (int i = 0; i < 2000; ++i) {
    const auto p = service.aggregator().find("probe");
    if (p && p->counters.cycles == 5) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  service.step();
  const auto snap = service.exporter()->http()->snapshot();
  REQUIRE(snap != nullptr);
  CHECK(snap->reports.find("probe") != nullptr);
  CHECK(snap->reports.find("extra") != nullptr);  // the contributors' reports are served too
  const std::string text = read_file(prom);
  CHECK(text.find("probe") != std::string::npos);

  // A second service cannot bind the same port: its start() fails and nothing runs.
  exporter::HttpOptions taken = http;
  taken.listen.port = service.exporter()->http()->address().port;
  SupervisionService other({.registry = &reg, .summary_file = nullptr, .http = taken});
  const auto r = other.start();
  CHECK_FALSE(r);
  CHECK_FALSE(other.running());
  CHECK_FALSE(other.supervisor().running());
  CHECK(other.exporter() == nullptr);

  service.stop();
  CHECK(service.exporter() == nullptr);
  std::filesystem::remove(prom);
}
