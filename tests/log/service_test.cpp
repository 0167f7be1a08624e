// The supervisor side: formatting, rate limit, drops, recent lines, reports, sinks.
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "log_support.hpp"
#include "vigil/export/log_report.hpp"
#include "vigil/log/log.hpp"
#include "vigil/log/service.hpp"
#include "vigil/log/sinks.hpp"
#include "vigil/monitor/report.hpp"

using namespace vigil;
using vigil::test::LogBench;

namespace {

/// A sink that keeps every line, unformatted.
struct Collect final : log::Sink {
  void write(const log::Line& l) noexcept override { lines.push_back(l); }
  void flush() noexcept override { ++flushes; }
  std::vector<log::Line> lines;
  int flushes = 0;
};

void feed(log::LogService& s, std::uint32_t id, const std::string& name,
          const std::vector<log::LogRecord>& rs) {
  for (const auto& r : rs) s.on_record(id, name, r);
}

std::string read_file(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("The service formats records into lines with component, cycle and time",
          "[log][service]") {
  log::LogService service;
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  LogBench<> b("svc_motor", 42, 3'500'000'000);
  const int line = __LINE__ + 1;
  VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", 3, 2.41);
  feed(service, 7, "svc_motor", b.records());
  REQUIRE(sink->lines.size() == 1);
  const log::Line& l = sink->lines[0];
  CHECK(l.component == "svc_motor");
  CHECK(l.level == log::Level::Warn);
  CHECK(l.cycle == 42);
  CHECK(l.time_ns == 3'500'000'000);
  CHECK(l.text == "joint 3 limit reached: 2.41 rad");
  CHECK(l.line == static_cast<std::uint32_t>(line));
  CHECK(log::format_line(l) ==
        "[     3.500000] WARN  svc_motor #42: joint 3 limit reached: 2.41 rad");
  CHECK(log::format_line(l, {.component = false, .source = true}) ==
        "[     3.500000] WARN  #42: joint 3 limit reached: 2.41 rad (service_test.cpp:" +
            std::to_string(line) + ")");
  service.on_supervisor_cycle(0);
  CHECK(sink->flushes == 1);  // the sinks are flushed after a supervisor cycle that wrote
  service.on_supervisor_cycle(0);
  CHECK(sink->flushes == 1);
  const auto recent = service.recent("svc_motor", 10);
  REQUIRE(recent.size() == 1);
  CHECK(recent[0] == l);
  CHECK(service.stats("svc_motor").lines == 1);
}

TEST_CASE("recent() keeps the last lines per component, oldest first", "[log][service]") {
  log::LogService service({.rate_limit = 0, .recent = 3});
  LogBench<> a("recent_a");
  LogBench<> b("recent_b");  // the current source: b
  for (int i = 0; i < 5; ++i) VIGIL_LOG_INFO("b{}", i);
  feed(service, 2, "recent_b", b.records());
  const auto r = service.recent("recent_b", 10);
  REQUIRE(r.size() == 3);
  CHECK(r[0].text == "b2");
  CHECK(r[2].text == "b4");
  const auto two = service.recent("recent_b", 2);
  REQUIRE(two.size() == 2);
  CHECK(two[0].text == "b3");
  CHECK(service.recent("recent_a", 5).empty());
  CHECK(service.recent("nobody", 5).empty());
  CHECK(service.components() == std::vector<std::string>{"recent_b"});
}

TEST_CASE("The rate limit passes N lines per second per call site and counts the rest",
          "[log][rate]") {
  log::LogService service({.rate_limit = 5});
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  LogBench<256> b("rate_motor");
  const auto flood = [](int i) { VIGIL_LOG_WARN("flood {}", i); };  // one call site
  // 20 lines from one call site within one second (1 kHz), and 3 from another.
  for (int i = 0; i < 20; ++i) {
    b.at(static_cast<std::uint64_t>(i + 1), kNanosPerSecond + i * kNanosPerMilli);
    flood(i);
    if (i < 3) VIGIL_LOG_INFO("other {}", i);
  }
  feed(service, 1, "rate_motor", b.records());
  std::vector<std::string> texts;
  for (const auto& l : sink->lines) texts.push_back(l.text);
  REQUIRE(texts.size() == 8);  // 5 floods + 3 others: the other site has its own limit
  CHECK(texts[0] == "flood 0");
  CHECK(service.stats("rate_motor").suppressed == 15);
  CHECK(service.stats("rate_motor").lines == 8);

  // The next line of the site, a second later, first reports what was suppressed.
  b.at(1001, 2 * kNanosPerSecond + 5 * kNanosPerMilli);
  flood(1000);
  feed(service, 1, "rate_motor", b.records());
  REQUIRE(sink->lines.size() == 10);
  const log::Line& s = sink->lines[8];
  CHECK(s.text == "... 15 lines suppressed (rate limit 5/s)");
  CHECK(s.suppressed == 15);
  CHECK(s.level == log::Level::Warn);
  CHECK(s.cycle == 20);  // the last suppressed line's cycle
  CHECK(s.component == "rate_motor");
  CHECK(sink->lines[9].text == "flood 1000");
}

TEST_CASE("A quiet call site's suppressed count is reported by the supervisor cycle or flush",
          "[log][rate]") {
  log::LogService service({.rate_limit = 2});
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  LogBench<> b("rate_quiet", 1, 10 * kNanosPerSecond);
  for (int i = 0; i < 5; ++i) VIGIL_LOG_INFO("x {}", i);
  feed(service, 1, "rate_quiet", b.records());
  CHECK(sink->lines.size() == 2);
  service.on_supervisor_cycle(10 * kNanosPerSecond + kNanosPerSecond / 2);  // window still open
  CHECK(sink->lines.size() == 2);
  service.on_supervisor_cycle(11 * kNanosPerSecond);
  REQUIRE(sink->lines.size() == 3);
  CHECK(sink->lines[2].text == "... 3 lines suppressed (rate limit 2/s)");

  // flush() reports what is pending at once.
  for (int i = 0; i < 5; ++i) VIGIL_LOG_INFO("y {}", i);
  feed(service, 1, "rate_quiet", b.records());
  CHECK(sink->lines.size() == 5);
  service.flush();
  REQUIRE(sink->lines.size() == 6);
  CHECK(sink->lines[5].suppressed == 3);
}

TEST_CASE("Each component has its own rate window for a shared call site", "[log][rate]") {
  log::LogService service({.rate_limit = 1});
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  LogBench<> b("rate_shared");
  for (int i = 0; i < 2; ++i) VIGIL_LOG_INFO("shared");
  const auto rs = b.records();  // same call site, fed as two components
  feed(service, 1, "rate_left", rs);
  feed(service, 2, "rate_right", rs);
  CHECK(sink->lines.size() == 2);
  CHECK(service.stats("rate_left").suppressed == 1);
  CHECK(service.stats("rate_right").suppressed == 1);
}

TEST_CASE("Dropped records are reported as a line and counted", "[log][drops]") {
  log::LogService service({.rate_limit = 0});
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  LogBench<2> b("svc_drops", 3, 1'000);
  for (int i = 0; i < 5; ++i) VIGIL_LOG_INFO("n {}", i);  // 2 pushed, 3 dropped
  feed(service, 4, "svc_drops", b.records());
  CHECK(service.stats("svc_drops").dropped == 3);  // not reported by a record yet: read live
  b.at(4, 2'000);
  VIGIL_LOG_INFO("later");
  feed(service, 4, "svc_drops", b.records());
  REQUIRE(sink->lines.size() == 4);
  CHECK(sink->lines[2].text == "... 3 log records dropped (port full)");
  CHECK(sink->lines[2].dropped == 3);
  CHECK(sink->lines[2].level == log::Level::Warn);
  CHECK(sink->lines[3].text == "later");
  CHECK(service.stats("svc_drops").dropped == 3);
}

TEST_CASE("contribute() adds counts and recent lines to the component reports", "[log][service]") {
  log::LogService service;
  LogBench<> b("svc_report", 12, 2 * kNanosPerSecond);
  VIGIL_LOG_ERROR("encoder checksum {:#06x}, expected {:#06x}", 0xBEEFU, 0x1234U);
  feed(service, 1, "svc_report", b.records());
  ReportSet reports;
  reports.components.resize(2);
  reports.components[0].name = "svc_report";
  reports.components[1].name = "silent";
  vigil::exporter::add_log_lines(service, reports);
  const Report& r = reports.components[0];
  REQUIRE(r.value("log.lines") != nullptr);
  CHECK(*r.value("log.lines") == "1");
  CHECK(*r.value("log.dropped") == "0");
  REQUIRE(r.value("log") != nullptr);
  CHECK(*r.value("log") == "[     2.000000] ERROR #12: encoder checksum 0xbeef, expected 0x1234");
  CHECK(reports.components[1].values.empty());
}

TEST_CASE("TailSink keeps the last lines for a live view", "[log][sinks]") {
  log::TailSink tail(2);
  log::Line l;
  l.component = "c";
  for (int i = 0; i < 3; ++i) {
    l.text = "t" + std::to_string(i);
    tail.write(l);
  }
  const auto lines = tail.lines();
  REQUIRE(lines.size() == 2);
  CHECK(lines[0].ends_with("t1"));
  CHECK(lines[1].ends_with("t2"));
  CHECK(tail.total() == 3);
}

TEST_CASE("The rotating file sink rotates by size and keeps N files", "[log][sinks]") {
  const auto dir =
      std::filesystem::temp_directory_path() / ("vigil_log_rotate_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto path = dir / "vigil.log";
  auto sink = log::RotatingFileSink::open(
      {.path = path.string(), .max_bytes = 200, .max_files = 3, .format = {}});
  REQUIRE(sink.has_value());
  log::Line l;
  l.component = "rot";
  for (int i = 0; i < 40; ++i) {
    l.cycle = static_cast<std::uint64_t>(i);
    l.text = "line " + std::to_string(i);
    (*sink)->write(l);
  }
  (*sink)->flush();
  CHECK((*sink)->errors() == 0);
  CHECK((*sink)->rotations() > 2);
  CHECK(std::filesystem::exists(path));
  CHECK(std::filesystem::exists(dir / "vigil.log.1"));
  CHECK(std::filesystem::exists(dir / "vigil.log.2"));
  CHECK_FALSE(std::filesystem::exists(dir / "vigil.log.3"));  // N = 3 files in all
  for (const char* f : {"vigil.log", "vigil.log.1", "vigil.log.2"}) {
    CHECK(std::filesystem::file_size(dir / f) <= 200);
  }
  const std::string current = read_file(path);
  CHECK(current.find("line 39") != std::string::npos);  // the newest lines are in `path`
  CHECK(read_file(dir / "vigil.log.2").find("line 0\n") == std::string::npos);  // oldest gone
  const std::string previous = read_file(dir / "vigil.log.1");
  CHECK(previous.find("#") != std::string::npos);
  sink->reset();

  // Reopening appends.
  auto again = log::RotatingFileSink::open({.path = path.string(), .max_bytes = 200});
  REQUIRE(again.has_value());
  CHECK((*again)->size() == std::filesystem::file_size(path));
  again->reset();
  std::filesystem::remove_all(dir);
}

TEST_CASE("A rotating file that cannot be opened is an error naming it", "[log][sinks]") {
  auto bad = log::RotatingFileSink::open({.path = "/nonexistent-dir/sub/vigil.log"});
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().message.find("/nonexistent-dir/sub/vigil.log") != std::string::npos);
  CHECK(bad.error().message.find("cannot open") != std::string::npos);
  auto zero = log::RotatingFileSink::open({.path = "x.log", .max_bytes = 0});
  REQUIRE_FALSE(zero.has_value());
  CHECK(zero.error().message.find("max_bytes") != std::string::npos);
}
