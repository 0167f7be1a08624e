#include "vigil/export/text_report.hpp"

#include <catch2/catch.hpp>
#include <cstdio>

#include "monitor/harness.hpp"

using namespace vigil;

namespace {

// Components on one fake clock delay each other, so the slow one gets a harness of its own and
// the reports are put together as one set.
ReportSet reports() {
  test::Harness h;
  test::PeriodicProbe ok(h, "motor", kNanosPerMilli);
  test::Probe idle("idle", h.registry, h.clock);
  ok.probe.work_ns = 100 * kNanosPerMicro;
  for (int i = 0; i < 10; ++i) h.cycle(ok.activity);
  ReportSet set = h.step();

  test::Harness h2;
  test::PeriodicProbe slow(h2, "arm", 10 * kNanosPerMilli);
  slow.probe.work_ns = 9500 * kNanosPerMicro;  // near overrun
  for (int i = 0; i < 5; ++i) h2.cycle(slow.activity);
  const ReportSet other = h2.step();
  set.components.insert(set.components.begin() + 2, *other.find("arm"));
  return set;
}

std::size_t count_lines(const std::string& s) {
  return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n'));
}

}  // namespace

TEST_CASE("Durations are shown with 3 significant digits and a unit", "[export][text]") {
  CHECK(format_nanos(0) == "0ns");
  CHECK(format_nanos(950) == "950ns");
  CHECK(format_nanos(999.6) == "1.00us");
  CHECK(format_nanos(12'345) == "12.3us");
  CHECK(format_nanos(1'500'000) == "1.50ms");
  CHECK(format_nanos(100'000'001) == "100ms");
  CHECK(format_nanos(2e9) == "2.00s");
  CHECK(format_nanos(-5'000) == "-5.00us");
}

TEST_CASE("The summary has a header and one line per component", "[export][text]") {
  const ReportSet set = reports();
  const std::string s = format_summary(set, false);
  CHECK(count_lines(s) == set.components.size() + 1);
  CHECK(s.find('\x1b') == std::string::npos);
  CHECK(s.rfind("STATUS  NAME", 0) == 0);
  CHECK(s.find("\nOK      motor ") != std::string::npos);
  CHECK(s.find("\nWARN    idle ") != std::string::npos);
  const std::string arm = format_summary_line(*set.find("arm"), false);
  CHECK(arm.rfind("WARN    arm", 0) == 0);
  CHECK(arm.find("Running") != std::string::npos);
  CHECK(arm.find("9.50ms/9.50ms/9.50ms") != std::string::npos);  // user mean/p99/max
  CHECK(arm.find("near overrun") != std::string::npos);
  // Columns line up: every line has its state at the same offset.
  const std::string motor = format_summary_line(*set.find("motor"), false);
  CHECK(motor.find("Running") == arm.find("Running"));
}

TEST_CASE("The summary shows the max beside the p99, so one long cycle explains a high mean",
          "[export][text]") {
  // 999 cycles of 100 us and one of 50 ms: the mean (~150 us) is above the p99 (100 us); the
  // max says which cycle put it there.
  test::Harness h;
  test::PeriodicProbe stall(h, "gripper", 100 * kNanosPerMilli);
  stall.probe.work_ns = 100 * kNanosPerMicro;
  for (int i = 1; i <= 999; ++i) {
    h.cycle(stall.activity);
    if (i % 100 == 0) (void)h.step();  // within the port's capacity
  }
  // The long cycle also wakes up 2 ms late (the only late one): p99 0, max 2 ms.
  stall.probe.work_ns = 50 * kNanosPerMilli;
  h.clock.advance_to(stall.activity.next_release() + 2 * kNanosPerMilli);
  stall.activity.step();
  const ReportSet set = h.step();
  const Report& r = *set.find("gripper");
  REQUIRE(r.execution_ns.count == 1000);
  // A percentile is its bucket's upper bound (within 2^-5 above), the max exact.
  CHECK(r.execution_ns.p99 >= 100 * kNanosPerMicro);
  CHECK(r.execution_ns.p99 < 100 * kNanosPerMicro * 33 / 32);
  CHECK(r.execution_ns.max == 50 * kNanosPerMilli);
  CHECK(r.execution_ns.mean > static_cast<double>(r.execution_ns.p99));
  const std::string line = format_summary_line(r, false);
  INFO(line);
  CHECK(line.find(" " + format_nanos(r.execution_ns.mean) + "/100us/50.0ms ") != std::string::npos);
  CHECK(r.latency_ns.max == 2 * kNanosPerMilli);
  CHECK(line.find(" 0ns/2.00ms ") != std::string::npos);
  // The header names the columns, and they line up with the line's.
  const std::string header = format_summary_header();
  CHECK(header.find("EXEC MEAN/P99/MAX") != std::string::npos);
  CHECK(header.find("LAT P99/MAX") != std::string::npos);
  CHECK(line.find(format_nanos(r.execution_ns.mean) + "/") == header.find("EXEC"));

  // A component with no sample yet shows a dash in both columns.
  test::Harness idle_h;
  test::Probe idle("idle", idle_h.registry, idle_h.clock);
  const ReportSet none = idle_h.step();
  const std::string dash = format_summary_line(*none.find("idle"), false);
  CHECK(dash.substr(header.find("EXEC"), 2) == "- ");
  const std::size_t latency_end = header.find("LAT P99/MAX") + std::string("LAT P99/MAX").size();
  CHECK(dash.substr(latency_end - 2, 2) == " -");  // right-aligned, as the header
}

TEST_CASE("Colours: only the status word, only when asked or on a terminal", "[export][text]") {
  const ReportSet set = reports();
  const std::string c = format_summary_line(*set.find("arm"), true);
  CHECK(c.rfind("\x1b[33mWARN\x1b[0m    arm", 0) == 0);  // yellow, padding outside
  CHECK(format_summary_line(*set.find("motor"), true).rfind("\x1b[32mOK\x1b[0m", 0) == 0);

  CHECK(use_color(ColorMode::Always, nullptr));
  CHECK_FALSE(use_color(ColorMode::Never, stdout));
  std::FILE* f = std::tmpfile();
  REQUIRE(f != nullptr);
  CHECK_FALSE(use_color(ColorMode::Auto, f));  // a file is not a terminal
  print_summary(f, set);                       // Auto: no colour in the file
  std::rewind(f);
  std::string written;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) written.append(buf, n);
  std::fclose(f);
  CHECK(written == format_summary(set, false));
}

TEST_CASE("The detail view lists a component's data as key: value lines", "[export][text]") {
  const ReportSet set = reports();
  const std::string d = format_detail(*set.find("arm"), false);
  CHECK(d.rfind("arm: WARN\n", 0) == 0);
  for (const char* key :
       {"  message: [WARN] near overrun", "  kind: component", "  state: Running",
        "  activity: arm_activity, OTHER, any cpu", "  period: 10.0ms", "  cycles: 5 (5 samples)",
        "  overruns: 0", "  window: since start", "  execution time: mean 9.50ms", "  total time:",
        "  wake-up latency:", "  measured period:", "  overhead: -", "  rt losses: 0",
        "  exceptions: 0", "  dropped: 0", "  silence: 0ns", "  load_ewma: 95% of period"}) {
    INFO(key);
    CHECK(d.find(key) != std::string::npos);
  }
  const std::string idle = format_detail(*set.find("idle"), false);
  CHECK(idle.find("state: PreOperational (not configured)") != std::string::npos);
  const std::string all = format_details(set, true);
  CHECK(all.find("\x1b[") != std::string::npos);
  CHECK(all.find("\n\nvigil.supervisor: ") != std::string::npos);
}

TEST_CASE("Text from components cannot break lines or drive the terminal", "[export][text]") {
  Report r;
  r.name = "evil\x1b[2J";
  r.merge(StatusLevel::Error, "boom\nsecond line\ttab");
  r.add("key", "value\r");
  const std::string line = format_summary_line(r, false);
  CHECK(line.find('\n') == std::string::npos);
  CHECK(line.find('\x1b') == std::string::npos);
  CHECK(line.find("evil\\x1b[2J") != std::string::npos);
  CHECK(line.find("boom\\nsecond line\\ttab") != std::string::npos);
  const std::string detail = format_detail(r, false);
  CHECK(detail.find("  key: value\\x0d\n") != std::string::npos);
  CHECK(detail.find('\x1b') == std::string::npos);
}

TEST_CASE("The supervisor and monitor detail views show their cycles and cycle time",
          "[export][text]") {
  const ReportSet set = reports();
  const std::string d = format_detail(*set.find("vigil.supervisor"), false);
  CHECK(d.find("  kind: supervisor\n") != std::string::npos);
  CHECK(d.find("  cycle time: mean") != std::string::npos);
  CHECK(d.find("  ports: ") != std::string::npos);
  CHECK(d.find("execution time") == std::string::npos);
}

TEST_CASE("Units are shown in a table of their kind, with a column per field", "[export][text]") {
  ReportSet set = reports();
  for (const char* name : {"can0/drive_1", "can0/drive_5"}) {
    Report node;
    node.kind = ReportKind::Unit;
    node.unit_kind = "can_node";
    node.name = name;
    node.state_label = "responding";
    node.add_field(Field::of_count("frames_rx", 1200));
    node.add_field(Field::of_distribution(
        "rx_gap", StatsSummary{.count = 9, .max = 3'000'000, .p50 = 1'000'000, .p99 = 2'000'000}));
    set.components.push_back(node);
  }
  set.components.back().state_label = "not responding";
  set.components.back().merge(StatusLevel::Error, "silent");
  set.components.back().fields.pop_back();  // no gap measured: its cell is "-"
  const std::string s = format_summary(set, false);
  // The components' table first, then the units' own, under their kind.
  const auto units = s.find("\nSTATUS  can_node");
  REQUIRE(units != std::string::npos);
  CHECK(s.find("arm") < units);
  CHECK(s.find("FRAMES RX", units) != std::string::npos);
  CHECK(s.find("RX GAP P50/P99/MAX", units) != std::string::npos);
  CHECK(s.find("CYCLES", units) == std::string::npos);
  const auto five = s.find("can0/drive_5");
  REQUIRE(five != std::string::npos);
  const std::string row = s.substr(five, s.find('\n', five) - five);
  CHECK(row.find("not responding") != std::string::npos);
  CHECK(row.find("1200") != std::string::npos);
  CHECK(row.find(" -  silent") != std::string::npos);
  const std::string one = s.substr(s.find("can0/drive_1"));
  CHECK(one.find("1.00ms/2.00ms/3.00ms") < one.find('\n'));
  // The detail view: its kind and each field by name.
  const std::string d = format_detail(set.components.back(), false);
  CHECK(d.find("  kind: can_node\n") != std::string::npos);
  CHECK(d.find("  frames_rx: 1200\n") != std::string::npos);
  CHECK(d.find("  cycles") == std::string::npos);
}
