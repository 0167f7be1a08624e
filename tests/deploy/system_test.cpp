#include "vigil/deploy/system.hpp"

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <thread>

#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {
std::vector<std::string>& events() {
  static std::vector<std::string> e;
  return e;
}
std::mutex& events_mutex() {
  static std::mutex m;
  return m;
}
void record(std::string s) {
  std::lock_guard l(events_mutex());
  events().push_back(std::move(s));
}

class Recorder : public Task<Recorder> {
 public:
  explicit Recorder(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        refuse_(c.parameters.defined() && c.parameters.optional("refuse", false)) {}
  bool on_configure() {
    record("configure " + name());
    return !refuse_;
  }
  bool on_start() {
    record("start " + name());
    return true;
  }
  void on_update() {}
  bool on_stop() {
    record("stop " + name());
    return true;
  }

 private:
  bool refuse_;
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Recorder>("test.recorder");
  (void)once;
  return f;
}

std::unique_ptr<System> make(std::string_view yaml) {
  auto spec = load_deployment_string(yaml, "s.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  return std::move(*sys);
}
}  // namespace

TEST_CASE("A System configures every component before starting any, and stops in reverse",
          "[deploy][system]") {
  events().clear();
  auto sys = make(R"(
activities: [{name: a, period: 2ms}, {name: b, period: 3ms}]
components:
  - {name: one, type: test.recorder, activity: a}
  - {name: two, type: test.recorder, activity: b}
supervision: {lock_memory: false, monitor_period: 50ms}
)");
  REQUIRE(sys->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  sys->stop();
  const ReportSet r = sys->step_monitor();
  const std::vector<std::string> expected{"configure one", "configure two", "start one",
                                          "start two",     "stop two",      "stop one"};
  CHECK(events() == expected);
  REQUIRE(r.find("one") != nullptr);
  CHECK(r.find("one")->counters.cycles > 20);
  CHECK(r.find("two")->counters.cycles > 15);
  CHECK(sys->log().size() >= 3);
}

TEST_CASE("A component that refuses to configure stops the start, nothing is left running",
          "[deploy][system]") {
  events().clear();
  auto sys = make(R"(
activities: [{name: a, period: 2ms}]
components:
  - {name: good, type: test.recorder, activity: a}
  - {name: bad, type: test.recorder, activity: a, parameters: {refuse: true}}
supervision: {lock_memory: false}
)");
  const auto r = sys->start();
  REQUIRE_FALSE(r.has_value());
  CHECK_THAT(r.error().message, Catch::Contains("component 'bad' did not configure"));
  CHECK_FALSE(sys->running());
  for (const auto& e : events()) CHECK(e.rfind("start", 0) != 0);
}

TEST_CASE("The System watches a thresholds file: a good edit applies, a bad one is reported",
          "[deploy][system][thresholds]") {
  const auto dir = std::filesystem::temp_directory_path() / "vigil_system_thresholds";
  std::filesystem::create_directories(dir);
  const auto path = dir / "limits.yaml";
  const auto write = [&](const char* text) {
    std::ofstream(path) << text;
    // A new modification time even on file systems with coarse stamps.
    std::filesystem::last_write_time(
        path, std::filesystem::last_write_time(path) + std::chrono::seconds(1));
  };
  write("defaults:\n  overrun: {near_fraction: 0.9}\n");
  auto spec = load_deployment_string(R"(
activities: [{name: a, period: 2ms}]
components: [{name: one, type: test.recorder, activity: a}]
supervision: {lock_memory: false, thresholds: )" +
                                         path.string() + "}\n",
                                     "s.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  ThresholdFile* file = (*sys)->thresholds_file();
  REQUIRE(file != nullptr);
  Monitor& monitor = (*sys)->monitor();
  CHECK(monitor.thresholds()->defaults.overrun.near_fraction == Approx(0.9));

  write("defaults:\n  overrun: {near_fraction: 0.5}\n");
  ReportSet r = (*sys)->step_monitor();  // the monitor's cycle polls the file
  CHECK(monitor.thresholds()->defaults.overrun.near_fraction == Approx(0.5));
  CHECK(*r.find("vigil.monitor")->value("thresholds_generation") == "2");

  write("defaults:\n  overrun: {near_fraction: 5}\n");
  r = (*sys)->step_monitor();
  CHECK(monitor.thresholds()->defaults.overrun.near_fraction == Approx(0.5));  // kept
  const Report* self = r.find("vigil.monitor");
  REQUIRE(self != nullptr);
  CHECK(self->status.level() == StatusLevel::Warn);
  CHECK_THAT(self->status.summary(), Catch::Contains("thresholds not reloaded (previous ones "
                                                     "kept): " +
                                                     path.string() + ":2:28:"));
  std::filesystem::remove_all(dir);
}
