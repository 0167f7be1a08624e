#include "vigil/supervisor/drain_loop.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

using namespace vigil;
using namespace vigil::supervisor;
using vigil::test::Probe;

TEST_CASE("A component started before the supervisor exists is supervised from the start",
          "[supervisor][pipeline]") {
  Registry<task::Message> reg;
  Probe p("early", {}, reg);
  ManualActivity act(p);
  REQUIRE(p.configure());
  REQUIRE(act.start());
  for (int i = 0; i < 10; ++i) act.step();
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg);
  CHECK(sup.step() == 14);  // configure and start: TaskInfo + StateChange each; 10 samples
  const auto s = agg.find("early");
  REQUIRE(s.has_value());
  CHECK(s->has_info);
  CHECK(s->state == TaskState::Running);
  CHECK(s->counters.cycles == 10);
  CHECK(s->samples == 10);
}

namespace {
// Waits (up to 10 s) until `done()`: what a test needs to have happened, not a time that a loaded
// machine may not give its threads.
template <class F>
bool eventually(F done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}
}  // namespace

TEST_CASE("Components join and leave while everything runs", "[supervisor][pipeline]") {
  // Each phase lasts until it has happened (cycles run, drains made), not a fixed time: under a
  // loaded machine a 1 ms component may run only a few cycles in 30 ms.
  Registry<task::Message> reg;
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg, {.period_ns = kNanosPerMilli});
  REQUIRE(sup.start().has_value());
  auto a = std::make_unique<Probe>("a", SupervisionOptions{}, reg);
  PeriodicActivity aa(*a, {.name = "a", .period_ns = kNanosPerMilli});
  REQUIRE(a->configure());
  REQUIRE(aa.start().has_value());
  REQUIRE(eventually([&] { return a->cycles() >= 20 && sup.stats().cycles >= 5; }));
  {
    Probe late("late", {}, reg);  // joins while a and the supervisor run
    PeriodicActivity al(late, {.name = "late", .period_ns = kNanosPerMilli});
    REQUIRE(late.configure());
    REQUIRE(al.start().has_value());
    const auto drains = sup.stats().cycles;
    REQUIRE(eventually([&] { return late.cycles() >= 20 && sup.stats().cycles >= drains + 6; }));
    al.stop();
    // `late` leaves here, while a still runs.
  }
  const auto before = a->cycles();
  REQUIRE(eventually([&] { return a->cycles() >= before + 10; }));  // a runs on alone
  aa.stop();
  const auto a_cycles = a->cycles();
  sup.stop();  // a last full drain
  const auto late = agg.find("late");
  REQUIRE(late.has_value());
  CHECK_FALSE(late->alive);
  INFO("missed " << late->counters.missed_cycles << " samples " << late->samples);
  CHECK(late->counters.cycles > 10);
  CHECK(late->state == TaskState::Stopped);
  const auto sa = agg.find("a");
  REQUIRE(sa.has_value());
  CHECK(sa->alive);
  CHECK(sa->counters.cycles == a_cycles);
  CHECK(sa->counters.dropped == 0);
  CHECK(sup.stats().cycles > 10);
}

namespace {
struct Cap8 {
  static constexpr std::size_t port_capacity = 8;
};
}  // namespace

TEST_CASE("Counters stay exact when the port drops samples (capacity 8, supervisor paused)",
          "[supervisor][pipeline]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::BasicProbe<Cap8> p("lossy", {.detectors = Detectors::Allocation}, reg);
  ManualActivity act(p, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  std::uint64_t injected_overruns = 0;
  std::uint64_t injected_missed = 0;
  p.work = [&] {
    if (p.updates % 7 == 0) {
      fc.advance(2500);  // overrun by 1.5 periods: 2 releases skipped... counted below
    } else {
      fc.advance(100);
    }
  };
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  for (std::uint64_t i = 1; i <= 100000; ++i) {
    fc.set(act.next_release());
    act.step();
    if (i % 7 == 0) {
      ++injected_overruns;
      injected_missed += 2;
    }
  }
  // The supervisor was "paused": nothing drained during the run. Now resume.
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg);
  sup.step();
  // One more cycle after resuming carries the final cumulative counters.
  fc.set(act.next_release());
  act.step();
  sup.step();
  const auto s = agg.find("lossy");
  REQUIRE(s.has_value());
  CHECK(s->counters.cycles == 100001);
  CHECK(s->counters.overruns == injected_overruns);
  CHECK(s->counters.missed_cycles == injected_missed);
  CHECK(s->counters.dropped > 99000);
  CHECK(s->counters.dropped == p.port()->dropped());
  CHECK(s->samples < 20);  // only timing detail was lost
}
