// Stack sizes in a deployment: per activity (`stack`), for the supervisor and the monitor
// (`supervision.supervisor_stack`, `monitor_stack`), validated like every other key; and the
// supervisor's and monitor's threads really get them.
#include <pthread.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

#include "support/stack.hpp"
#include "vigil/deploy/deployment.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {
class Nop : public Task<Nop> {
 public:
  explicit Nop(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};

ComponentFactory& nop_factory() {
  static ComponentFactory f;
  static const bool once = f.add<Nop>("test.nop", "does nothing");
  (void)once;
  return f;
}

std::string stack_errors(std::string_view yaml) {
  auto d = load_deployment_string(yaml, "s.yaml", nop_factory());
  REQUIRE_FALSE(d.has_value());
  return config::to_string(d.error());
}

std::size_t wait_for(const std::atomic<std::size_t>& v) {
  const auto deadline = platform::now_ns() + 10 * kNanosPerSecond;
  while (v.load() == 0 && platform::now_ns() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return v.load();
}
}  // namespace

TEST_CASE("Deployment stack keys take sizes with binary units, or 'system'",
          "[deploy][deployment][memory]") {
  auto d = load_deployment_string(R"(
activities:
  - {name: a, period: 1ms, stack: 1MiB}
  - {name: b, period: 1ms, stack: system}
  - {name: c, period: 1ms}
  - {name: d, period: 1ms, stack: 96 KiB}
components:
  - {name: x, type: test.nop, activity: a}
supervision: {supervisor_stack: 128KiB, monitor_stack: 1.5MiB}
)",
                                  "s.yaml", nop_factory());
  REQUIRE(d.has_value());
  CHECK(d->activities[0].config.stack_bytes == 1024 * 1024);
  CHECK(d->activities[1].config.stack_bytes == 0);
  CHECK(d->activities[2].config.stack_bytes == kDefaultActivityStackBytes);
  CHECK(d->activities[3].config.stack_bytes == 96 * 1024);
  CHECK(d->supervision.supervisor_stack_bytes == 128 * 1024);
  CHECK(d->supervision.monitor_stack_bytes == 1536 * 1024);

  auto defaults = load_deployment_string(
      "activities: [{name: a, period: 1ms}]\ncomponents: [{name: x, type: test.nop, activity: "
      "a}]\n",
      "s.yaml", nop_factory());
  REQUIRE(defaults.has_value());
  CHECK(defaults->supervision.supervisor_stack_bytes == platform::kDefaultStackBytes);
  CHECK(defaults->supervision.monitor_stack_bytes == platform::kDefaultStackBytes);
}

TEST_CASE("Bad stack sizes are errors at file:line:col, never a silent default",
          "[deploy][deployment][memory]") {
  const std::string e = stack_errors(R"(activities:
  - {name: a, period: 1ms, stack: 512KB}
  - {name: b, period: 1ms, stack: 65536}
  - {name: c, period: 1ms, stack: 8KiB}
  - {name: d, period: 1ms, stack: 1.3KiB}
  - {name: e, period: 1ms, stack_size: 65536}
  - {name: f, period: 1ms, stack: 2TiB}
components:
  - {name: x, type: test.nop, activity: a}
supervision: {supervisor_stack: lots, monitor_stack: 4GiB}
)");
  CHECK_THAT(e, Catch::Contains("s.yaml:2:35: activities[0].stack: '512KB': unknown unit 'KB'; "
                                "did you mean 'KiB'"));
  CHECK_THAT(e, Catch::Contains("s.yaml:3:35: activities[1].stack: '65536' has no unit: write "
                                "it with B, KiB, MiB or GiB (e.g. 65536B or 64KiB)"));
  CHECK_THAT(e, Catch::Contains("s.yaml:4:35: activities[2].stack: a thread stack must be "
                                "between 16KiB and 1GiB (or 'system'), got '8KiB'"));
  CHECK_THAT(e,
             Catch::Contains("s.yaml:5:35: activities[3].stack: '1.3KiB' is not a whole number"));
  CHECK_THAT(e, Catch::Contains("s.yaml:6:28: activities[4].stack_size: unknown key"));
  CHECK_THAT(e, Catch::Contains("activities[5].stack: '2TiB': unknown unit 'TiB'"));
  CHECK_THAT(e, Catch::Contains("supervision.supervisor_stack: 'lots' is not a size"));
  CHECK_THAT(e, Catch::Contains("supervision.monitor_stack: a thread stack must be between"));
}

TEST_CASE("The supervisor's and the monitor's threads get their configured stacks",
          "[supervisor][monitor][memory]") {
  STATIC_REQUIRE(supervisor::DrainOptions{}.stack_bytes == platform::kDefaultStackBytes);
  STATIC_REQUIRE(MonitorOptions{}.stack_bytes == platform::kDefaultStackBytes);

  struct StackHandler : supervisor::ComponentAggregator {
    void on_cycle(const supervisor::DrainCycle& c) {
      supervisor::ComponentAggregator::on_cycle(c);
      bytes.store(vigil::test::current_stack_bytes());
    }
    std::atomic<std::size_t> bytes{0};
  };
  Registry<task::Message> reg;
  StackHandler handler;
  supervisor::DrainLoop<task::Message, StackHandler> sup(
      reg, handler, {.period_ns = kNanosPerMilli, .stack_bytes = 160 * 1024});
  REQUIRE(sup.start().has_value());
  CHECK(vigil::test::stack_serves(wait_for(handler.bytes), 160 * 1024));
  sup.stop();

  supervisor::ComponentAggregator agg;
  Monitor mon(agg, {.period_ns = kNanosPerMilli, .stack_bytes = 384 * 1024});
  std::atomic<std::size_t> monitor_bytes{0};
  mon.subscribe([&](const ReportSet&) { monitor_bytes.store(vigil::test::current_stack_bytes()); });
  REQUIRE(mon.start().has_value());
  CHECK(vigil::test::stack_serves(wait_for(monitor_bytes), 384 * 1024));
  mon.stop();
}
