#include "vigil/monitor/thresholds.hpp"

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <unistd.h>

#include "monitor/harness.hpp"
#include "vigil/config/error.hpp"
#include "vigil/config/load.hpp"
#include "vigil/monitor/threshold_file.hpp"

using namespace vigil;
using namespace vigil::monitor;
namespace fs = std::filesystem;

namespace {

const fs::path kData = VIGIL_MONITOR_TEST_DATA;

config::ConfigErrors errors_of(std::string_view yaml) {
  auto r = load_thresholds_string(yaml, "t.yaml");
  REQUIRE_FALSE(r.has_value());
  return r.error();
}

// The one error of `yaml`, as "file:line:col: field: message".
std::string error_of(std::string_view yaml) {
  const auto e = errors_of(yaml);
  REQUIRE(e.size() == 1);
  return e[0].to_string();
}

// A file in a fresh temporary directory, removed at the end of the test.
class TempFile {
 public:
  explicit TempFile(const std::string& name) {
    dir_ = fs::temp_directory_path() /
           ("vigil_monitor_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++));
    fs::create_directories(dir_);
    path_ = dir_ / name;
  }
  ~TempFile() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  // Writes `text` through a temporary file and a rename, as editors and deployment tools do, so
  // that a reader never sees half a file.
  void write(std::string_view text) const {
    const fs::path tmp = path_.string() + ".tmp";
    {
      std::ofstream out(tmp, std::ios::trunc);
      out << text;
    }
    fs::rename(tmp, path_);
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  static inline int counter_ = 0;
  fs::path dir_;
  fs::path path_;
};

}  // namespace

TEST_CASE("An empty document gives the built-in defaults", "[monitor][thresholds]") {
  auto r = load_thresholds_string("", "empty.yaml");
  REQUIRE(r.has_value());
  const Thresholds& d = r->defaults;
  const Thresholds builtin;
  CHECK(d.window_ns == 0);
  CHECK(d.overrun.near_fraction == 0.9);
  CHECK(d.overrun.warn_rate == 0.0);
  CHECK(d.overrun.error_rate == 0.1);
  CHECK(d.starvation.periods == 10.0);
  CHECK(d.starvation.min_silence_ns == 100 * kNanosPerMilli);
  CHECK(d.starvation.aperiodic_silence_ns == 0);
  CHECK(d.realtime.warn_losses == 0);
  CHECK(d.realtime.fifo_only);
  CHECK(d.overhead.warn_share == 0.05);
  CHECK(d.overhead.min_overhead_ns == 1'000);
  CHECK(d.overhead.min_period_share == 0.01);
  CHECK(d.drops.warn_drops == 0);
  CHECK(d.exception.sticky);
  CHECK(r->components.empty());
  CHECK(r->source == "empty.yaml");
  CHECK(&r->for_component("anything") == &r->defaults);
  (void)builtin;
}

TEST_CASE("A thresholds file: defaults, then per-component overrides key by key",
          "[monitor][thresholds]") {
  auto r = load_thresholds_file(kData / "thresholds.yaml");
  REQUIRE(r.has_value());
  const Thresholds& d = r->defaults;
  CHECK(d.window_ns == 2 * kNanosPerSecond);
  CHECK_FALSE(d.exception.sticky);
  CHECK(d.overrun.near_fraction == 0.8);
  CHECK(d.overrun.warn_rate == 0.001);
  CHECK(d.overrun.error_rate == 0.05);
  CHECK(d.starvation.periods == 20.0);
  CHECK(d.starvation.min_silence_ns == 50 * kNanosPerMilli);
  CHECK(d.starvation.aperiodic_silence_ns == 5 * kNanosPerSecond);
  CHECK(d.realtime.warn_losses == 2);
  CHECK_FALSE(d.realtime.fifo_only);
  CHECK(d.overhead.warn_share == 0.1);
  CHECK(d.overhead.min_overhead_ns == 2'000);
  CHECK(d.overhead.min_period_share == 0.02);
  CHECK(d.drops.warn_drops == 10);
  CHECK(d.custom_value("max_temperature", 0) == 80.0);
  CHECK(d.custom_value("unknown", 7) == 7.0);

  const Thresholds& motor = r->for_component("motor");
  CHECK(motor.overrun.near_fraction == 0.95);  // overridden
  CHECK(motor.overrun.error_rate == 0.05);     // inherited from the file's defaults
  CHECK_FALSE(motor.drops.enabled);
  CHECK(motor.drops.warn_drops == 10);
  CHECK(motor.window_ns == 2 * kNanosPerSecond);

  const Thresholds& logger = r->for_component("logger");
  CHECK_FALSE(logger.starvation.enabled);
  CHECK(logger.starvation.min_silence_ns == 50 * kNanosPerMilli);
  CHECK(logger.custom_value("max_temperature", 0) == 90.5);
  CHECK(r->components.size() == 2);
}

TEST_CASE("Threshold errors name file, line, column and field", "[monitor][thresholds]") {
  SECTION("unknown key, with a hint") {
    CHECK(error_of("defaults:\n  overrun:\n    near_fracton: 0.8\n") ==
          "t.yaml:3:5: defaults.overrun.near_fracton: unknown key; did you mean "
          "'near_fraction'?");
    CHECK(error_of("colour: 1\n") ==
          "t.yaml:1:1: colour: unknown key; expected one of: defaults, components");
  }
  SECTION("wrong type") {
    CHECK(error_of("defaults:\n  overrun:\n    near_fraction: abc\n") ==
          "t.yaml:3:20: defaults.overrun.near_fraction: expected a number, got 'abc'");
    CHECK(error_of("defaults:\n  overrun: 3\n") ==
          "t.yaml:2:12: defaults.overrun: expected a mapping, got '3'");
    CHECK(error_of("defaults:\n  drops: {enabled: yes}\n") ==
          "t.yaml:2:20: defaults.drops.enabled: expected true or false, got 'yes'");
  }
  SECTION("out of range") {
    CHECK(error_of("defaults:\n  overrun:\n    near_fraction: 1.5\n") ==
          "t.yaml:3:20: defaults.overrun.near_fraction: must be between 0 and 1, got '1.5'");
    CHECK(error_of("components:\n  arm: {starvation: {periods: 0}}\n") ==
          "t.yaml:2:31: components.arm.starvation.periods: must be between 1 and 1e+06, got "
          "'0'");
    CHECK_THAT(error_of("defaults:\n  overhead: {min_overhead: 2s}\n"),
               Catch::StartsWith("t.yaml:2:28: defaults.overhead.min_overhead: must be between"));
    CHECK(error_of("defaults:\n  overhead: {min_period_share: 2}\n") ==
          "t.yaml:2:32: defaults.overhead.min_period_share: must be between 0 and 1, got '2'");
    CHECK_THAT(error_of("components:\n  motor:\n    drops: {warn_drops: -1}\n"),
               Catch::StartsWith("t.yaml:3:25: components.motor.drops.warn_drops: expected an "
                                 "integer between 0 and"));
  }
  SECTION("durations need a known unit") {
    CHECK(error_of("defaults:\n  starvation:\n    min_silence: 100 mss\n") ==
          "t.yaml:3:18: defaults.starvation.min_silence: '100 mss' has an unknown unit 'mss'; "
          "did you mean 'ms'?");
    CHECK_THAT(error_of("defaults:\n  window: 5\n"),
               Catch::StartsWith("t.yaml:2:11: defaults.window: '5' has no unit"));
  }
  SECTION("error_rate below warn_rate") {
    CHECK(error_of("defaults:\n  overrun: {warn_rate: 0.5, error_rate: 0.2}\n") ==
          "t.yaml:2:41: defaults.overrun.error_rate: must not be below warn_rate (0.5), got "
          "'0.2'");
    // A component that raises only warn_rate above the inherited error rate.
    CHECK(error_of("components:\n  m:\n    overrun: {warn_rate: 0.2}\n") ==
          "t.yaml:3:26: components.m.overrun.warn_rate: must not be above error_rate (0.1), got "
          "'0.2'");
  }
  SECTION("a custom threshold must be a number") {
    CHECK(error_of("defaults:\n  custom: {a: x}\n") ==
          "t.yaml:2:15: defaults.custom.a: expected a number, got 'x'");
  }
  SECTION("YAML syntax") {
    const auto e = errors_of("defaults: [\n");
    REQUIRE(e.size() == 1);
    CHECK(e[0].line == 2);
    CHECK(e[0].column == 1);
  }
}

TEST_CASE("Every error of a file is reported, in file order", "[monitor][thresholds]") {
  const fs::path path = kData / "thresholds_bad.yaml";
  auto r = load_thresholds_file(path);
  REQUIRE_FALSE(r.has_value());
  const auto& e = r.error();
  REQUIRE(e.size() == 4);
  CHECK(e[0].file == path.string());
  CHECK((e[0].line == 3 && e[0].column == 5 && e[0].field == "defaults.overrun.near_fracton"));
  CHECK((e[1].line == 5 && e[1].column == 18 && e[1].field == "defaults.starvation.min_silence"));
  CHECK((e[2].line == 8 && e[2].column == 28 &&
         e[2].field == "components.motor.overhead.warn_share"));
  CHECK((e[3].line == 9 && e[3].column == 25 && e[3].field == "components.motor.drops.warn_drops"));
  CHECK_THAT(e[0].to_string(), Catch::StartsWith(path.string() + ":3:5: "));
}

TEST_CASE("A missing thresholds file is an error naming it", "[monitor][thresholds]") {
  auto r = load_thresholds_file(kData / "no_such_file.yaml");
  REQUIRE_FALSE(r.has_value());
  CHECK_THAT(r.error().at(0).to_string(), Catch::Contains("no_such_file.yaml"));
}

TEST_CASE("A thresholds block can be read from another document", "[monitor][thresholds]") {
  auto doc = config::load_string("monitor:\n  thresholds:\n    overrun: {near_fraction: 0.7}\n",
                                 "deploy.yaml");
  REQUIRE(doc.has_value());
  const Thresholds t = read_thresholds((*doc)["monitor"]["thresholds"]);
  CHECK_FALSE(doc->has_errors());
  CHECK(t.overrun.near_fraction == 0.7);
  CHECK(t.overrun.error_rate == 0.1);
}

// --- reload ---------------------------------------------------------------------------------

TEST_CASE("Monitor thresholds reload: good, bad (previous kept, error reported), fixed",
          "[monitor][thresholds][reload]") {
  using test::Harness;
  using test::PeriodicProbe;
  TempFile file("thresholds.yaml");
  file.write("defaults:\n  overrun: {near_fraction: 0.9}\n");
  Harness h;
  auto watched = ThresholdFile::open(file.path());
  REQUIRE(watched.has_value());
  watched->attach(h.monitor);
  CHECK(h.monitor.thresholds_generation() == 1);
  CHECK(h.monitor.thresholds()->source == file.path().string());

  PeriodicProbe c(h, "c", kNanosPerMilli);
  c.probe.work_ns = 600 * kNanosPerMicro;
  for (int i = 0; i < 20; ++i) h.cycle(c.activity);
  CHECK(h.step().find("c")->status.ok());

  SECTION("explicit reload") {
    file.write("defaults:\n  overrun: {near_fraction: 0.5}\n");
    auto g = watched->reload();
    REQUIRE(g.has_value());
    CHECK(*g == 2);
    CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.5);
    CHECK(h.step().find("c")->status.level() == StatusLevel::Warn);

    file.write("defaults:\n  overrun: {near_fraction: 5}\n");
    auto bad = watched->reload();
    REQUIRE_FALSE(bad.has_value());
    CHECK(bad.error().at(0).to_string() ==
          file.path().string() +
              ":2:28: defaults.overrun.near_fraction: must be between 0 and 1, got '5'");
    CHECK(h.monitor.thresholds_generation() == 2);
    CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.5);  // kept
    CHECK(h.monitor.threshold_errors() == bad.error());
    const ReportSet set = h.step();
    CHECK(set.find("c")->status.level() == StatusLevel::Warn);  // still judged with 0.5
    const Report* self = set.find("vigil.monitor");
    REQUIRE(self != nullptr);
    CHECK(self->status.level() == StatusLevel::Warn);
    CHECK_THAT(self->status.summary(),
               Catch::Contains("thresholds not reloaded (previous ones kept): " +
                               file.path().string() + ":2:28:"));

    file.write("defaults:\n  overrun: {near_fraction: 0.95}\n");
    REQUIRE(watched->reload());
    CHECK(h.monitor.threshold_errors().empty());
    const ReportSet fixed = h.step();
    CHECK(fixed.find("c")->status.ok());
    CHECK(fixed.find("vigil.monitor")->status.ok());
    CHECK(*fixed.find("vigil.monitor")->value("thresholds_generation") == "3");
  }
  SECTION("on file change, polled by the monitor's cycle") {
    file.write("defaults:\n  overrun: {near_fraction: 0.55}\n");
    CHECK(h.step().find("c")->status.level() == StatusLevel::Warn);
    CHECK(h.monitor.thresholds_generation() == 2);

    file.write("defaults:\n  overrun: [0.5]\n");
    const ReportSet bad = h.step();
    CHECK(bad.find("c")->status.level() == StatusLevel::Warn);
    CHECK(bad.find("vigil.monitor")->status.level() == StatusLevel::Warn);
    CHECK(h.monitor.threshold_errors().size() == 1);
    CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.55);
  }
  SECTION("detached, the file no longer changes the monitor's thresholds") {
    watched->detach();
    file.write("defaults:\n  overrun: {near_fraction: 0.55}\n");
    CHECK(h.step().find("c")->status.ok());
    CHECK(h.monitor.thresholds_generation() == 1);
    h.monitor.set_thresholds(ThresholdSet{});
    CHECK(h.monitor.thresholds_generation() == 0);
    CHECK(h.monitor.thresholds()->source.empty());
  }
}

TEST_CASE("A bad first file is refused and the thresholds in use are kept",
          "[monitor][thresholds][reload]") {
  TempFile file("bad.yaml");
  file.write("defaults:\n  overrn: {}\n");
  test::Harness h;
  auto r = ThresholdFile::open(file.path());
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().at(0).line == 2);
  CHECK(r.error().at(0).column == 3);
  CHECK(h.monitor.thresholds()->source.empty());  // still the built-in defaults
  CHECK(h.monitor.thresholds_generation() == 0);
}

TEST_CASE("Thresholds reload while the monitor thread runs",
          "[monitor][thresholds][reload][thread]") {
  TempFile file("live.yaml");
  file.write("defaults:\n  overrun: {near_fraction: 0.9}\n");
  test::Harness h(MonitorOptions{.period_ns = kNanosPerMilli});
  auto watched = ThresholdFile::open(file.path());
  REQUIRE(watched.has_value());
  watched->attach(h.monitor);
  test::PeriodicProbe c(h, "c", kNanosPerMilli);
  c.probe.work_ns = 600 * kNanosPerMicro;
  for (int i = 0; i < 20; ++i) h.cycle(c.activity);
  h.supervisor.step();

  std::atomic<int> warn_cycles{0};
  std::atomic<int> cycles{0};
  h.monitor.subscribe([&](const ReportSet& s) {
    cycles.fetch_add(1);
    if (const Report* r = s.find("c"); r != nullptr && r->status.level() == StatusLevel::Warn) {
      warn_cycles.fetch_add(1);
    }
  });
  REQUIRE(h.monitor.start());
  const auto wait_cycles = [&](int n) {
    const int target = cycles.load() + n;
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (cycles.load() < target && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return cycles.load() >= target;
  };
  REQUIRE(wait_cycles(2));
  CHECK(warn_cycles.load() == 0);

  for (int round = 0; round < 5; ++round) {
    // Good, then bad: the bad file never replaces the good thresholds.
    file.write("defaults:\n  overrun: {near_fraction: 0.5}\n");
    REQUIRE(watched->reload());
    file.write("defaults:\n  overrun: {near_fraction: -1}\n");
    CHECK_FALSE(watched->reload().has_value());
    CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.5);
    REQUIRE(wait_cycles(2));  // the thread also polls the (bad) file: same result
    CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.5);
    CHECK_FALSE(h.monitor.threshold_errors().empty());
    file.write("defaults:\n  overrun: {near_fraction: 0.9}\n");
    REQUIRE(watched->reload());
    REQUIRE(wait_cycles(2));
  }
  CHECK(warn_cycles.load() > 0);
  h.monitor.stop();
  CHECK(h.monitor.threshold_errors().empty());
  CHECK(h.monitor.thresholds()->defaults.overrun.near_fraction == 0.9);
  CHECK(h.monitor.step().find("c")->status.ok());
}
