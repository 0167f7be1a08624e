// Events, the watchdog, latched faults, warm-up and the flight recorder, on a fake clock shared
// by the components and the supervisor: nothing sleeps.
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

using namespace vigil;
using namespace vigil::supervisor;

namespace {

std::vector<Event> of_kind(const std::vector<Event>& all, EventKind k) {
  std::vector<Event> out;
  for (const auto& e : all) {
    if (e.kind == k) out.push_back(e);
  }
  return out;
}

// A component on a 1 ms ManualActivity and a supervisor stepped by hand, all on one fake clock.
struct Rig {
  explicit Rig(AggregatorOptions o = {}, std::string name = "p")
      : agg(with_clock(std::move(o), fc)),
        sup(reg, agg),
        probe(std::move(name), {}, reg),
        act(probe, {.name = "m", .period_ns = kNanosPerMilli, .clock = fc.clock()}) {
    REQUIRE(probe.configure());
    REQUIRE(act.start(fc.now()));
  }
  static AggregatorOptions with_clock(AggregatorOptions o, const vigil::test::FakeClock& c) {
    o.clock = c.clock();
    return o;
  }
  // Runs `n` cycles, each released on time and lasting `work` on the fake clock.
  void cycles(int n, Nanos work = 100 * kNanosPerMicro) {
    probe.work = [this, work] { fc.advance(work); };
    for (int i = 0; i < n; ++i) {
      fc.set(std::max(fc.now(), act.next_release()));
      act.step();
    }
  }
  vigil::test::FakeClock fc;
  Registry<task::Message> reg;
  ComponentAggregator agg;
  ComponentDrainLoop sup;
  vigil::test::Probe probe;
  ManualActivity act;
};

}  // namespace

TEST_CASE("An exception becomes an event with its cycle, fault time and detection time",
          "[supervisor][events]") {
  Rig r;
  std::mutex m;
  std::vector<Event> got;
  r.agg.events().subscribe([&](const Event& e) {
    std::lock_guard lock(m);
    got.push_back(e);
  });
  r.cycles(50);
  r.sup.step();
  r.probe.script.throw_update_at = 51;
  r.cycles(1);
  const auto s0 = r.agg.find("p");
  REQUIRE(s0.has_value());
  r.fc.advance(3 * kNanosPerMilli);  // the supervisor's next step comes 3 ms after the fault
  const Nanos before = r.fc.now();
  r.sup.step();
  const Nanos after = r.fc.now();
  const auto s = r.agg.find("p");
  REQUIRE(s.has_value());
  REQUIRE(s->last.cycle() == 51);

  const auto all = r.agg.events().since(0);
  const auto ex = of_kind(all, EventKind::Exception);
  REQUIRE(ex.size() == 1);
  CHECK(ex[0].component == "p");
  CHECK(ex[0].severity == EventSeverity::Error);
  CHECK(ex[0].cycle == 51);
  CHECK(ex[0].fault_ns == s->last.end_ns);  // the faulting cycle's end
  CHECK(ex[0].detected_ns >= before);
  CHECK(ex[0].detected_ns <= after);
  CHECK(ex[0].latency_ns() == ex[0].detected_ns - s->last.end_ns);
  CHECK_THAT(ex[0].detail,
             Catch::Contains("std::out_of_range") && Catch::Contains("update failed at cycle 51"));
  CHECK(ex[0].latched);
  CHECK(ex[0].traced);
  const auto fault = of_kind(all, EventKind::FaultState);
  REQUIRE(fault.size() == 1);
  CHECK(fault[0].detail.starts_with("Running -> Exception"));
  CHECK_FALSE(fault[0].latched);  // the latch was raised by the exception

  CHECK(s->latch.active);
  CHECK(s->latch.first_kind == EventKind::Exception);
  CHECK(s->latch.last_kind == EventKind::FaultState);
  CHECK(s->latch.count == 2);
  CHECK(s->latch.first_ns == ex[0].detected_ns);

  // The subscriber got the same events, in order.
  REQUIRE(r.agg.events().flush());
  std::lock_guard lock(m);
  REQUIRE(got.size() == all.size());
  for (std::size_t i = 0; i < got.size(); ++i) CHECK(got[i].seq == all[i].seq);
}

TEST_CASE("The watchdog reports a hang one supervisor step after its deadline, then recovery",
          "[supervisor][events][watchdog]") {
  Rig r;
  for (int i = 0; i < 5; ++i) {
    r.cycles(10);
    r.sup.step();
  }
  auto s = r.agg.find("p");
  REQUIRE(s.has_value());
  CHECK(s->deadline_ns == 30 * kNanosPerMilli);  // max(10 x 1 ms, 30 ms)
  const Nanos arrival = s->last_sample_at;
  // The component hangs: no cycle. The supervisor steps every 10 ms.
  r.fc.set(arrival + 30 * kNanosPerMilli);  // exactly the limit: not yet
  r.sup.step();
  CHECK(of_kind(r.agg.events().since(0), EventKind::Deadline).empty());
  r.fc.set(arrival + 38 * kNanosPerMilli);
  r.sup.step();
  const auto d = of_kind(r.agg.events().since(0), EventKind::Deadline);
  REQUIRE(d.size() == 1);
  CHECK(d[0].fault_ns == arrival + 30 * kNanosPerMilli);  // the deadline that passed
  CHECK(d[0].detected_ns == arrival + 38 * kNanosPerMilli);
  CHECK(d[0].cycle == 50);
  CHECK(d[0].latched);
  s = r.agg.find("p");
  CHECK(s->silent);
  CHECK(s->deadline_misses == 1);
  // Still silent: reported once, not at every step.
  r.fc.advance(50 * kNanosPerMilli);
  r.sup.step();
  CHECK(of_kind(r.agg.events().since(0), EventKind::Deadline).size() == 1);
  // It cycles again.
  r.cycles(3);
  r.sup.step();
  const auto rec = of_kind(r.agg.events().since(0), EventKind::Recovered);
  REQUIRE(rec.size() == 1);
  CHECK(rec[0].cycle == 51);
  s = r.agg.find("p");
  CHECK_FALSE(s->silent);
  CHECK(s->latch.active);  // recovery does not clear the latch
  CHECK(s->latch.first_kind == EventKind::Deadline);
}

TEST_CASE("A stopped component is not watched, and the watchdog can be turned off",
          "[supervisor][events][watchdog]") {
  SECTION("stopped") {
    Rig r;
    r.cycles(10);
    r.sup.step();
    REQUIRE(r.act.stop());
    r.sup.step();
    r.fc.advance(kNanosPerSecond);
    r.sup.step();
    CHECK(of_kind(r.agg.events().since(0), EventKind::Deadline).empty());
  }
  SECTION("disabled") {
    Rig r({.watchdog = {.enabled = false}});
    r.cycles(10);
    r.sup.step();
    r.fc.advance(kNanosPerSecond);
    r.sup.step();
    CHECK(of_kind(r.agg.events().since(0), EventKind::Deadline).empty());
    CHECK(r.agg.find("p")->deadline_ns == 0);
  }
}

TEST_CASE("A latched fault stays until cleared, counts repeats, and auto-clears when asked",
          "[supervisor][events][latch]") {
  SECTION("clear by API") {
    Rig r;
    r.probe.script.throw_update_at = 3;
    r.cycles(3);
    r.sup.step();
    REQUIRE(r.agg.find("p")->latch.active);
    r.fc.advance(5 * kNanosPerSecond);
    r.sup.step();
    CHECK(r.agg.find("p")->latch.active);  // no auto-clear by default
    CHECK(r.agg.clear("p") == 1);
    const auto s = r.agg.find("p");
    CHECK_FALSE(s->latch.active);
    CHECK(s->latch.cleared == 1);
    CHECK(s->latch.raised == 1);
    const auto c = of_kind(r.agg.events().since(0), EventKind::Cleared);
    REQUIRE(c.size() == 1);
    CHECK_THAT(c[0].detail, Catch::StartsWith("cleared: 2 error events since exception"));
    CHECK(r.agg.clear("p") == 0);  // nothing latched any more
    CHECK(r.agg.clear("nobody") == 0);
    // A new fault latches again (restart the component first).
    REQUIRE(r.probe.recover());
    REQUIRE(r.probe.configure());
    REQUIRE(r.act.start(r.fc.now()));
    r.probe.script.throw_update_at = 5;
    r.probe.updates = 0;
    r.cycles(5);
    r.sup.step();
    CHECK(r.agg.find("p")->latch.raised == 2);
    CHECK(r.agg.clear_all() == 1);
  }
  SECTION("auto-clear") {
    Rig r({.auto_clear_ns = kNanosPerSecond});
    r.probe.script.throw_update_at = 3;
    r.cycles(3);
    r.sup.step();
    REQUIRE(r.agg.find("p")->latch.active);
    r.fc.advance(kNanosPerSecond / 2);
    r.sup.step();
    CHECK(r.agg.find("p")->latch.active);
    r.fc.advance(kNanosPerSecond / 2 + 1);
    r.sup.step();
    CHECK_FALSE(r.agg.find("p")->latch.active);
    const auto c = of_kind(r.agg.events().since(0), EventKind::Cleared);
    REQUIRE(c.size() == 1);
    CHECK_THAT(c[0].detail, Catch::StartsWith("auto-clear"));
  }
}

TEST_CASE("Repeated events are folded into one line per component per second, and counted",
          "[supervisor][events]") {
  EventLineLimiter lim(kNanosPerSecond);
  Event e;
  e.component = "a";
  e.kind = EventKind::RealTimeLoss;
  e.severity = EventSeverity::Error;
  e.detected_ns = kNanosPerSecond;
  CHECK_FALSE(lim.line(e).empty());
  for (int i = 1; i <= 5; ++i) {
    e.detected_ns = kNanosPerSecond + i * 100 * kNanosPerMilli;
    CHECK(lim.line(e).empty());
  }
  Event other = e;
  other.component = "b";
  CHECK_FALSE(lim.line(other).empty());  // per component
  e.detected_ns = 2 * kNanosPerSecond;
  const std::string l = lim.line(e);
  CHECK_THAT(l, Catch::Contains("(+5 more events since the previous line)"));
  CHECK(lim.folded() == 5);
}

TEST_CASE("A slow subscriber loses events, counted, and never delays the supervisor",
          "[supervisor][events]") {
  Rig r;
  std::mutex m;
  std::condition_variable cv;
  bool release = false;
  std::atomic<int> slow_calls{0};
  const auto slow = r.agg.events().subscribe(
      [&](const Event&) {
        ++slow_calls;
        std::unique_lock lock(m);
        cv.wait(lock, [&] { return release; });
      },
      4);
  std::atomic<int> fast_calls{0};
  const auto fast = r.agg.events().subscribe([&](const Event&) { ++fast_calls; });
  // 100 components' worth of overrun events: one per drain with overruns.
  for (int i = 0; i < 100; ++i) {
    r.cycles(1, 2 * kNanosPerMilli);  // overruns (after the warm-up: below)
    r.sup.step();
  }
  // The supervisor went on while the slow subscriber was blocked in its first event.
  const std::uint64_t published = r.agg.events().published();
  CHECK(published >= 50);
  const auto st = r.agg.events().stats(slow);
  CHECK(st.lost >= published - 5);  // 1 in the callback + 4 queued
  CHECK(st.capacity == 4);
  {
    std::lock_guard lock(m);
    release = true;
  }
  cv.notify_all();
  REQUIRE(r.agg.events().flush());
  const auto st2 = r.agg.events().stats(slow);
  CHECK(st2.delivered + st2.lost == published);
  CHECK(r.agg.events().stats(fast).lost == 0);
  CHECK(static_cast<std::uint64_t>(fast_calls.load()) == published);
  CHECK(r.agg.events().lost() == st2.lost);
  r.agg.events().unsubscribe(slow);
  r.agg.events().unsubscribe(fast);
}

TEST_CASE("Warm-up keeps start-up overruns out of the statistics but in the counters",
          "[supervisor][events][warmup]") {
  Rig r({.warmup_ns = 100 * kNanosPerMilli});
  std::mutex m;
  r.cycles(5, 1500 * kNanosPerMicro);  // start-up: 5 overruns of 1.5 ms
  r.cycles(200, 100 * kNanosPerMicro);
  r.sup.step();
  const auto s = r.agg.find("p");
  REQUIRE(s.has_value());
  CHECK(s->counters.overruns == 5);         // counted
  CHECK(s->warmup_counters.overruns == 5);  // and known to be the warm-up's
  CHECK(s->warmup_cycles > 5);
  CHECK(s->warmup_cycles < 100);
  CHECK(s->execution_ns.count == s->samples - s->warmup_cycles);
  CHECK(s->execution_ns.max == 100 * kNanosPerMicro);  // the 1.5 ms cycles are not in it
  CHECK_FALSE(s->warming_up);
  CHECK(of_kind(r.agg.events().since(0), EventKind::Overrun).empty());
  // After the warm-up, an overrun is an event (Warn, not latched).
  r.cycles(1, 1500 * kNanosPerMicro);
  r.sup.step();
  const auto ov = of_kind(r.agg.events().since(0), EventKind::Overrun);
  REQUIRE(ov.size() == 1);
  CHECK(ov[0].severity == EventSeverity::Warn);
  CHECK_FALSE(r.agg.find("p")->latch.active);
}

TEST_CASE("The flight recorder keeps the last N cycles and freezes them on an ERROR",
          "[supervisor][events][recorder]") {
  Rig r({.recorder = {.cycles = 8}});
  r.cycles(20);
  r.sup.step();
  auto demand = r.agg.flight_record("p");
  REQUIRE(demand.has_value());
  CHECK(demand->on_demand);
  REQUIRE(demand->cycles.size() == 8);
  CHECK(demand->cycles.front().cycle == 13);
  CHECK(demand->cycles.back().cycle == 20);
  CHECK(r.agg.frozen_records().empty());
  CHECK_FALSE(r.agg.flight_record("nobody").has_value());

  r.probe.script.throw_update_at = 21;
  r.cycles(1);
  r.sup.step();
  const auto ex = of_kind(r.agg.events().since(0), EventKind::Exception);
  REQUIRE(ex.size() == 1);
  REQUIRE(ex[0].traced);
  const auto rec = r.agg.frozen_record(ex[0].seq);
  REQUIRE(rec != nullptr);
  CHECK(rec->component == "p");
  CHECK(rec->event.kind == EventKind::Exception);
  CHECK(rec->event.cycle == 21);
  REQUIRE(rec->cycles.size() == 8);
  for (std::size_t i = 0; i < rec->cycles.size(); ++i) {
    CHECK(rec->cycles[i].cycle == 14 + i);
    CHECK(rec->cycles[i].execution_ns() >= 0);
  }
  CHECK(rec->cycles.back().state == TaskState::Exception);
  CHECK(rec->has_info);
  CHECK(rec->info.period_ns == kNanosPerMilli);
  // Later Error events of the same latch freeze nothing more.
  CHECK(r.agg.frozen_records().size() == 1);
}

TEST_CASE("The flight recorder is rate-limited per component", "[supervisor][events][recorder]") {
  Rig r({.recorder = {.cycles = 4, .min_interval_ns = 10 * kNanosPerSecond}});
  for (int round = 0; round < 3; ++round) {
    r.probe.script.throw_update_at = r.probe.updates + 2;
    r.cycles(2);
    r.sup.step();
    (void)r.agg.clear("p");
    REQUIRE(r.probe.recover());
    REQUIRE(r.probe.configure());
    REQUIRE(r.act.start(r.fc.now()));
    r.fc.advance(kNanosPerSecond);
  }
  CHECK(r.agg.find("p")->latch.raised == 3);
  CHECK(r.agg.frozen_records().size() == 1);  // 3 raises within 10 s: one record
  r.fc.advance(10 * kNanosPerSecond);
  r.probe.script.throw_update_at = r.probe.updates + 2;
  r.cycles(2);
  r.sup.step();
  CHECK(r.agg.frozen_records().size() == 2);
}
