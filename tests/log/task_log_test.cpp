// Logging from a real component: Task<Derived>::on_update() and an UpdateGuard scope, drained
// by the supervisor, formatted by the LogService.
#include <catch2/catch.hpp>
#include <memory>
#include <stdexcept>

#include "support/fake_clock.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/log/log.hpp"
#include "vigil/log/service.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;

namespace {

struct Collect final : log::Sink {
  void write(const log::Line& l) noexcept override { lines.push_back(l); }
  std::vector<log::Line> lines;
};

class Joint : public Task<Joint> {
 public:
  Joint(Registry<task::Message>& reg, test::FakeClock& clock)
      : Task("log_joint", {}, reg), clock_(clock) {}
  void on_update() {
    clock_.advance(1'000);  // the update takes 1 us
    ++n_;
    const double q = 2.0 + 0.2 * static_cast<double>(n_);
    if (q > 2.3) VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", 3, q);
    if (n_ == 3) {
      VIGIL_LOG_ERROR("encoder checksum {:#06x}, expected {:#06x}", 0xBEEFU, 0x1234U);
      throw std::runtime_error("encoder checksum mismatch");
    }
  }

 private:
  test::FakeClock& clock_;
  int n_ = 0;  // this cycle's number
};

}  // namespace

TEST_CASE("A Task logs from on_update(), and lines carry its cycle and the cycle's start time",
          "[log][task]") {
  Registry<task::Message> reg;
  supervisor::ComponentAggregator agg;
  log::LogService service;
  auto sink = std::make_shared<Collect>();
  service.add_sink(sink);
  agg.set_log_consumer(&service);
  supervisor::ComponentDrainLoop sup(reg, agg);
  test::FakeClock clock;
  Joint joint(reg, clock);
  ManualActivity act(joint, {.name = "m", .period_ns = kNanosPerMilli, .clock = clock.clock()});
  REQUIRE(joint.configure());
  REQUIRE(act.start());
  std::vector<Nanos> starts;
  for (int i = 0; i < 4; ++i) {
    clock.advance(kNanosPerMilli);
    starts.push_back(clock.now());
    act.step();
  }
  (void)sup.step();
  // Cycle 1: q = 2.2 (nothing); 2: 2.4 (warn); 3: 2.6 (warn), error, throw; then Exception.
  REQUIRE(sink->lines.size() == 3);
  CHECK(sink->lines[0].component == "log_joint");
  CHECK(sink->lines[0].cycle == 2);
  CHECK(sink->lines[0].time_ns == starts[1]);
  CHECK(sink->lines[0].text == "joint 3 limit reached: 2.40 rad");
  CHECK(sink->lines[1].cycle == 3);
  CHECK(sink->lines[2].level == log::Level::Error);
  CHECK(sink->lines[2].text == "encoder checksum 0xbeef, expected 0x1234");
  CHECK(sink->lines[2].time_ns == starts[2]);
  const auto snap = agg.find("log_joint");
  REQUIRE(snap.has_value());
  CHECK(snap->counters.exceptions == 1);
  agg.set_log_consumer(nullptr);
}

TEST_CASE("Code instrumented with an UpdateGuard logs from the guarded scope", "[log][task]") {
  Registry<task::Message> reg;
  supervisor::ComponentAggregator agg;
  log::LogService service;
  agg.set_log_consumer(&service);
  supervisor::ComponentDrainLoop sup(reg, agg);
  Instrumentation drive("log_legacy_drive", {}, reg);
  drive.init({.activity = "drive"});
  for (int i = 0; i < 3; ++i) {
    UpdateGuard guard(drive);
    VIGIL_LOG_INFO("legacy cycle {}", i);
  }
  VIGIL_LOG_INFO("outside the guard: unattributed");
  (void)sup.step();
  const auto lines = service.recent("log_legacy_drive", 10);
  REQUIRE(lines.size() == 3);
  CHECK(lines[0].cycle == 1);
  CHECK(lines[2].cycle == 3);
  CHECK(lines[2].text == "legacy cycle 2");
  agg.set_log_consumer(nullptr);
}

TEST_CASE("Without a log consumer the aggregator ignores records", "[log][task]") {
  Registry<task::Message> reg;
  supervisor::ComponentAggregator agg;
  supervisor::ComponentDrainLoop sup(reg, agg);
  Instrumentation c("log_no_consumer", {}, reg);
  c.init();
  {
    UpdateGuard guard(c);
    VIGIL_LOG_WARN("nobody listens");
  }
  CHECK(sup.step() >= 3);  // info, state change, the record, the sample
  CHECK(agg.find("log_no_consumer")->counters.cycles == 1);
}
