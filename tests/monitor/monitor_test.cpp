// End-to-end: real Task<Derived> components on ManualActivity with a fake clock, a supervisor
// and the monitor stepped by hand; and a real thread blocked on a condition variable.
#include "vigil/monitor/monitor.hpp"

#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>

#include "monitor/harness.hpp"
#include "vigil/exec/periodic_activity.hpp"

using namespace vigil;
using namespace vigil::monitor;
using vigil::test::Harness;
using vigil::test::PeriodicProbe;
using vigil::test::Probe;

namespace {

constexpr Nanos kMs = kNanosPerMilli;
constexpr Nanos kUs = kNanosPerMicro;

// Runs `n` cycles of `c`, draining the ports often enough that nothing is dropped.
void run(Harness& h, PeriodicProbe& c, int n) {
  for (int i = 0; i < n; ++i) {
    h.cycle(c.activity);
    if (i % 100 == 99) h.supervisor.step();
  }
}

// A copy: callers often pass a temporary ReportSet.
Report find(const ReportSet& set, std::string_view name) {
  const Report* r = set.find(name);
  REQUIRE(r != nullptr);
  return *r;
}

bool has_message(const Report& r, std::string_view prefix) {
  for (const auto& m : r.status.messages()) {
    if (m.text.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

ThresholdSet only_rates() {
  ThresholdSet t;
  t.defaults.overrun.near_fraction = 0.0;  // look at the overrun rates alone
  return t;
}

}  // namespace

TEST_CASE("A component that never configured is WARN 'not configured'", "[monitor][e2e]") {
  Harness h;
  Probe idle("idle", h.registry, h.clock);
  const ReportSet set = h.step();
  const Report r = find(set, "idle");
  CHECK(r.kind == ReportKind::Component);
  CHECK_FALSE(r.configured);
  CHECK(r.state == TaskState::PreOperational);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "not configured");

  idle.configure();
  CHECK(find(h.step(), "idle").status.ok());
}

TEST_CASE("A healthy periodic component is OK with its data in the report", "[monitor][e2e]") {
  Harness h;
  PeriodicProbe c(h, "motor", kMs);
  c.probe.work_ns = 500 * kUs;
  run(h, c, 100);
  const ReportSet set = h.step();
  const Report r = find(set, "motor");
  CHECK(r.status.ok());
  CHECK(r.status.messages().empty());
  CHECK(r.configured);
  CHECK(r.activity == "motor_activity");
  CHECK(r.period_ns == kMs);
  CHECK(r.state == TaskState::Running);
  CHECK(r.counters.cycles == 100);
  CHECK(r.samples == 100);
  CHECK(r.execution_ns.mean == Approx(500 * kUs));
  CHECK(r.execution_ns.p99 == 500 * kUs);
  CHECK(r.latency_ns.max == 0);
  CHECK(r.measured_period_ns.mean == Approx(kMs));
  CHECK(r.window.first);
  CHECK(r.window.cycles == 100);
  CHECK(r.silence_ns == 0);
  CHECK(r.tasks_on_thread == 0);  // a manual activity has no thread
  CHECK(*r.value("load_ewma") == "50% of period");
  CHECK(set.cycle == 1);
  CHECK(set.time_ns == h.clock.now());
  // The supervisor and the monitor report themselves after the components.
  CHECK(set.components.size() == 3);
  CHECK(set.components[1].kind == ReportKind::Supervisor);
  CHECK(set.components[1].name == "vigil.supervisor");
  CHECK(set.components[2].kind == ReportKind::Monitor);
  CHECK(set.components[2].name == "vigil.monitor");
  CHECK(set.worst() == StatusLevel::Ok);
}

TEST_CASE("An exception in on_update is ERROR with its type and message", "[monitor][e2e]") {
  Harness h;
  PeriodicProbe c(h, "thrower", kMs);
  run(h, c, 5);
  c.probe.throw_next = true;
  run(h, c, 1);
  const Report r = find(h.step(), "thrower");
  CHECK(r.state == TaskState::Exception);
  CHECK(r.status.level() == StatusLevel::Error);
  CHECK_THAT(r.status.summary(),
             Catch::StartsWith("exception in update: std::runtime_error: boom"));
  REQUIRE(r.has_exception);
  CHECK(r.exception.count == 1);
  CHECK(r.exception.type == "std::runtime_error");
  CHECK(r.exception.message == "boom: \"quoted\"\nsecond line");
  CHECK(r.exception.cycle == 5);
}

TEST_CASE("Overrun, end to end: the EWMA of total time at and above 0.9 of the period",
          "[monitor][e2e][overrun]") {
  // One harness per component: components on one fake clock would delay each other.
  const auto after_50_cycles = [](Nanos work) {
    Harness h;
    PeriodicProbe c(h, "c", kMs);
    c.probe.work_ns = work;
    run(h, c, 50);
    return find(h.step(), "c");
  };
  CHECK(after_50_cycles(900 * kUs).status.ok());    // EWMA of a constant is that constant
  const Report r = after_50_cycles(900 * kUs + 1);  // 1 ns above the limit
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(has_message(r, "near overrun"));
  CHECK(r.counters.overruns == 0);
}

TEST_CASE("Overrun, end to end: overrun rates at and above warn and error",
          "[monitor][e2e][overrun]") {
  Harness h;
  h.monitor.set_thresholds(only_rates());
  PeriodicProbe c(h, "c", kMs);
  // A cycle that takes exactly its period does not overrun; 1 ns more does.
  const auto burst = [&](int cycles, int overruns) {
    for (int i = 0; i < cycles; ++i) {
      c.probe.work_ns = i < overruns ? kMs + 1 : kMs / 2;
      h.cycle(c.activity);
      if (i % 100 == 99) h.supervisor.step();
    }
    return find(h.step(), "c");
  };
  c.probe.work_ns = kMs;
  run(h, c, 10);
  CHECK(find(h.step(), "c").status.ok());  // at the period: no overrun

  const Report one = burst(1000, 1);
  CHECK(one.window.overruns == 1);
  CHECK(one.window.missed_cycles == 1);
  CHECK(one.status.level() == StatusLevel::Warn);
  CHECK(one.status.summary() ==
        "overruns: 1 in 1000 cycles (0.1%, WARN above 0%), 1 cycles missed");

  CHECK(burst(1000, 0).status.ok());  // the window moved on

  const Report ten = burst(1000, 100);  // 10 %: at the error rate
  CHECK(ten.status.level() == StatusLevel::Warn);
  const Report more = burst(1000, 101);
  CHECK(more.status.level() == StatusLevel::Error);
  CHECK(more.counters.overruns == 202);
}

TEST_CASE("A slowly rising execution time is flagged by the EWMA before the mean would",
          "[monitor][e2e][overrun]") {
  // The original's case for the weighted mean: a load that creeps up is caught while the
  // arithmetic mean still carries the cheap cycles of the past.
  Harness h;
  PeriodicProbe c(h, "ramp", kMs);
  int flagged_at = -1;
  int mean_crossed_at = -1;
  double mean_when_flagged = 0;
  for (int i = 0; i < 3000 && mean_crossed_at < 0; ++i) {
    c.probe.work_ns = std::min<Nanos>(500 * kUs + i * kUs, 950 * kUs);  // +1 us per cycle
    h.cycle(c.activity);
    if (i % 10 != 9) continue;
    const Report r = find(h.step(), "ramp");
    REQUIRE(r.counters.overruns == 0);
    if (flagged_at < 0 && has_message(r, "near overrun")) {
      flagged_at = i;
      mean_when_flagged = r.total_ns.mean;
    }
    if (mean_crossed_at < 0 && r.total_ns.mean > 0.9 * kMs) mean_crossed_at = i;
  }
  INFO("EWMA flagged at cycle " << flagged_at << ", mean crossed 0.9 at cycle " << mean_crossed_at);
  REQUIRE(flagged_at > 0);
  CHECK(flagged_at < 450);  // within ~20 cycles (1 / 0.05) of the true load crossing 0.9 at 400
  CHECK(mean_when_flagged < 0.8 * kMs);
  REQUIRE(mean_crossed_at > 0);
  CHECK(mean_crossed_at > flagged_at + 1000);
}

TEST_CASE("A 3-cycle spike does not flip the status", "[monitor][e2e][overrun]") {
  Harness h;
  PeriodicProbe c(h, "spiky", kMs);
  c.probe.work_ns = 500 * kUs;
  run(h, c, 200);
  REQUIRE(find(h.step(), "spiky").status.ok());

  c.probe.work_ns = kMs;  // the longest cycle that is not an overrun
  for (int i = 0; i < 3; ++i) {
    h.cycle(c.activity);
    const Report r = find(h.step(), "spiky");
    CHECK(r.status.ok());
    CHECK(r.execution_ns.last == kMs);
  }
  c.probe.work_ns = 500 * kUs;
  for (int i = 0; i < 10; ++i) {
    h.cycle(c.activity);
    CHECK(find(h.step(), "spiky").status.ok());
  }

  // The same load sustained is flagged: 0.5 + 0.5 (1 - 0.95^n) > 0.9 from n = 32.
  c.probe.work_ns = kMs;
  int flipped_after = -1;
  for (int i = 1; i <= 60 && flipped_after < 0; ++i) {
    h.cycle(c.activity);
    if (has_message(find(h.step(), "spiky"), "near overrun")) flipped_after = i;
  }
  CHECK(flipped_after >= 30);
  CHECK(flipped_after <= 36);
}

TEST_CASE("Starvation, fake clock: STALE just above the limit without a cycle",
          "[monitor][e2e][starvation]") {
  Harness h;
  PeriodicProbe c(h, "starved", kMs);
  run(h, c, 10);
  REQUIRE(find(h.step(), "starved").status.ok());
  // Defaults: max(10 periods, 100 ms) = 100 ms, measured from the drain of the latest sample.
  h.clock.advance(100 * kMs);
  const Report at = find(h.step(), "starved");
  CHECK(at.silence_ns == 100 * kMs);
  CHECK(at.status.ok());
  h.clock.advance(1);
  const Report above = find(h.step(), "starved");
  CHECK(above.status.level() == StatusLevel::Stale);
  CHECK(above.status.summary() == "starved: no cycle for 100ms (limit 100ms)");

  run(h, c, 1);  // a cycle again (late)
  CHECK(find(h.step(), "starved").status.level() != StatusLevel::Stale);
}

TEST_CASE("Starvation, fake clock: a component that starts but never cycles goes STALE",
          "[monitor][e2e][starvation]") {
  Harness h;
  PeriodicProbe c(h, "stuck", kMs);  // started, no cycle ever
  const Report first = find(h.step(), "stuck");
  CHECK(first.state == TaskState::Running);
  CHECK(first.silence_ns == 0);
  CHECK(first.status.ok());
  h.clock.advance(100 * kMs + 1);
  CHECK(find(h.step(), "stuck").status.level() == StatusLevel::Stale);

  // Stopped components are not starving.
  c.activity.stop();
  CHECK(find(h.step(), "stuck").status.ok());
}

namespace {

// A component whose update blocks on a condition variable while `block` is set.
class Blocker : public Task<Blocker> {
 public:
  Blocker(std::string name, Registry<task::Message>& registry)
      : Task(std::move(name), {}, registry) {}
  void on_update() {
    cycles.fetch_add(1, std::memory_order_relaxed);
    std::unique_lock lock(mutex_);
    if (!block_) return;
    blocked.store(true);
    cv_.wait(lock, [this] { return !block_; });
    blocked.store(false);
  }
  void set_block(bool b) {
    {
      std::lock_guard lock(mutex_);
      block_ = b;
    }
    cv_.notify_all();
  }
  std::atomic<std::uint64_t> cycles{0};
  std::atomic<bool> blocked{false};

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool block_ = false;
};

template <class Pred>
bool wait_for(Pred pred, std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace

TEST_CASE("Starvation, real thread: the components of a blocked thread go STALE",
          "[monitor][e2e][starvation][thread]") {
  Registry<task::Message> registry;
  supervisor::ComponentAggregator aggregator;
  supervisor::ComponentDrainLoop supervisor(registry, aggregator, {.period_ns = 5 * kMs});
  Monitor monitor(aggregator);
  ThresholdSet t;
  t.defaults.starvation.min_silence_ns = 200 * kMs;  // generous: sanitizers and loaded machines
  t.defaults.overrun.enabled = false;
  monitor.set_thresholds(t);

  Blocker a("blocker_a", registry);
  Blocker b("blocker_b", registry);  // same activity settings: shares a's thread
  REQUIRE(a.configure());
  REQUIRE(b.configure());
  PeriodicActivity pa(a, {.name = "shared", .period_ns = kMs});
  PeriodicActivity pb(b, {.name = "shared", .period_ns = kMs});
  REQUIRE(supervisor.start());
  REQUIRE(pa.start());
  REQUIRE(pb.start());
  REQUIRE(wait_for([&] { return a.cycles.load() > 5 && b.cycles.load() > 5; }));
  // The supervisor's thread may not have seen the components yet: wait until both have data.
  const auto level_of = [](const ReportSet& s, std::string_view name) {
    const Report* r = s.find(name);
    return r == nullptr ? std::optional<StatusLevel>() : r->status.level();
  };
  REQUIRE(wait_for([&] {
    const ReportSet s = monitor.step();
    const Report* ra = s.find("blocker_a");
    const Report* rb = s.find("blocker_b");
    return ra != nullptr && rb != nullptr && ra->counters.cycles > 0 && rb->counters.cycles > 0;
  }));

  ReportSet before = monitor.step();
  const Report ra = find(before, "blocker_a");
  const Report rb = find(before, "blocker_b");
  CHECK(ra.status.level() != StatusLevel::Stale);
  CHECK(ra.tid != 0);
  CHECK(ra.tid == rb.tid);
  CHECK(ra.tasks_on_thread == 2);
  REQUIRE(ra.thread.has_value());  // the thread's OS counters
  CHECK(ra.thread->tid == ra.tid);

  a.set_block(true);
  REQUIRE(wait_for([&] { return a.blocked.load(); }));
  // No cycle of either task from now on; the supervisor keeps draining (nothing).
  REQUIRE(wait_for([&] {
    const ReportSet s = monitor.step();
    return level_of(s, "blocker_a") == StatusLevel::Stale &&
           level_of(s, "blocker_b") == StatusLevel::Stale;
  }));
  const ReportSet during = monitor.step();
  CHECK_THAT(find(during, "blocker_a").status.summary(),
             Catch::StartsWith("starved: no cycle for"));
  CHECK(find(during, "blocker_a").silence_ns > 200 * kMs);

  const std::uint64_t n = a.cycles.load();
  a.set_block(false);
  REQUIRE(wait_for([&] { return a.cycles.load() > n + 5; }));
  REQUIRE(wait_for([&] {
    const ReportSet s = monitor.step();
    return level_of(s, "blocker_a") != StatusLevel::Stale &&
           level_of(s, "blocker_b") != StatusLevel::Stale;
  }));
  pa.stop();
  pb.stop();
  supervisor.stop();
}

namespace {
struct SmallPort {
  static constexpr std::size_t port_capacity = 4;
};
}  // namespace

TEST_CASE("Drops, end to end: WARN with the count, exact counters afterwards", "[monitor][e2e]") {
  Harness h;
  test::BasicProbe<SmallPort> p("small", h.registry, h.clock);
  ManualActivity a(p, {.name = "small", .period_ns = kMs, .clock = h.clock.clock()});
  p.configure();
  a.start();
  REQUIRE(find(h.step(), "small").status.ok());  // identity and state drained

  for (int i = 0; i < 10; ++i) h.cycle(a);  // 4 samples fit, 6 are dropped
  const Report r = find(h.step(), "small");
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "port dropped 6 messages (6 in total)");
  CHECK(r.counters.dropped == 6);

  h.cycle(a);
  const Report after = find(h.step(), "small");
  CHECK(after.status.ok());            // no new drop in the window
  CHECK(after.counters.cycles == 11);  // exact despite the drops
  CHECK(after.counters.dropped == 6);
  CHECK(after.samples == 5);
}

TEST_CASE("The window: since the previous cycle by default, or over window_ns",
          "[monitor][e2e][window]") {
  Harness h;
  ThresholdSet t = only_rates();
  h.monitor.set_thresholds(t);
  PeriodicProbe c(h, "w", 10 * kMs);
  const auto cycles = [&](int n, bool overrun_first) {
    for (int i = 0; i < n; ++i) {
      c.probe.work_ns = overrun_first && i == 0 ? 10 * kMs + 1 : kMs;
      h.cycle(c.activity);
      if (i % 100 == 99) h.supervisor.step();
    }
    return find(h.step(), "w");
  };
  CHECK(cycles(10, true).status.level() == StatusLevel::Warn);
  const Report clean = cycles(10, false);
  CHECK(clean.status.ok());
  CHECK_FALSE(clean.window.first);
  CHECK(clean.window.cycles == 10);

  t.defaults.window_ns = 5 * kNanosPerSecond;
  h.monitor.set_thresholds(t);
  CHECK(cycles(10, true).status.level() == StatusLevel::Warn);
  const Report one_second_later = cycles(100, false);  // 1 s of clean cycles
  CHECK(one_second_later.status.level() == StatusLevel::Warn);
  CHECK(one_second_later.window.overruns == 1);
  const Report six_seconds_later = cycles(500, false);
  CHECK(six_seconds_later.status.ok());
  CHECK(six_seconds_later.window.duration_ns >= 5 * kNanosPerSecond);
}

TEST_CASE("Per-component thresholds override the defaults", "[monitor][e2e][thresholds]") {
  Harness h;
  ThresholdSet t;
  Thresholds strict = t.defaults;
  strict.overrun.near_fraction = 0.25;
  t.components.emplace("strict", strict);
  h.monitor.set_thresholds(t);
  // Period 2 ms: both fit in it even though they share the fake clock (b starts when a ends).
  PeriodicProbe a(h, "strict", 2 * kMs);
  PeriodicProbe b(h, "lenient", 2 * kMs);
  a.probe.work_ns = b.probe.work_ns = 600 * kUs;  // 30 % of the period
  for (int i = 0; i < 20; ++i) {
    h.cycle(a.activity);
    h.cycle(b.activity);
  }
  const ReportSet set = h.step();
  CHECK(find(set, "strict").status.level() == StatusLevel::Warn);
  CHECK(find(set, "lenient").status.ok());
  CHECK(find(set, "lenient").counters.overruns == 0);
}

TEST_CASE("The supervisor is reported, STALE when it stops draining", "[monitor][e2e]") {
  Harness h;
  PeriodicProbe c(h, "c", kMs);
  run(h, c, 10);
  const Report s = find(h.step(), "vigil.supervisor");
  CHECK(s.kind == ReportKind::Supervisor);
  CHECK(s.status.ok());
  CHECK(s.state == TaskState::Running);
  CHECK(s.counters.cycles == 1);
  CHECK(s.period_ns == 10 * kMs);
  CHECK(*s.value("ports") == "1");

  h.clock.advance(100 * kMs);  // limit: max(10 x 10 ms, 100 ms)
  CHECK(find(h.monitor.step(), "vigil.supervisor").status.ok());
  h.clock.advance(1);
  const Report stale = find(h.monitor.step(), "vigil.supervisor");
  CHECK(stale.status.level() == StatusLevel::Stale);
  CHECK(stale.state == TaskState::Stopped);
  CHECK_THAT(stale.status.summary(), Catch::StartsWith("not draining: no cycle for 100ms"));

  h.monitor.set_supervisor(nullptr);
  CHECK(h.monitor.step().find("vigil.supervisor") == nullptr);
}

TEST_CASE("A component that left is reported as left, then forgotten", "[monitor][e2e]") {
  Harness h;
  {
    PeriodicProbe c(h, "gone", kMs);
    run(h, c, 3);
    CHECK(find(h.step(), "gone").alive);
  }
  const Report r = find(h.step(), "gone");
  CHECK_FALSE(r.alive);
  CHECK(r.status.level() != StatusLevel::Stale);
  CHECK(r.counters.cycles == 3);
}

namespace {
struct CycleCountCheck {
  [[nodiscard]] std::string_view name() const { return "cycle_count"; }
  void run(const CheckInput& in, Report& out) const {
    const double max = in.thresholds.custom_value("max_cycles", 5);
    out.add("cycle_count", std::to_string(in.component.counters.cycles));
    if (static_cast<double>(in.component.counters.cycles) > max) {
      out.merge(StatusLevel::Warn, "too many cycles");
    }
  }
};
}  // namespace

TEST_CASE("A custom check registered in one line runs after the built-in ones",
          "[monitor][e2e][check]") {
  Harness h;
  h.monitor.add_check<CycleCountCheck>();
  const auto names = h.monitor.check_names();
  REQUIRE(names.size() == 10);
  CHECK(names.back() == "cycle_count");

  PeriodicProbe c(h, "c", kMs);
  run(h, c, 5);
  CHECK(find(h.step(), "c").status.ok());
  run(h, c, 1);
  const Report r = find(h.step(), "c");
  CHECK(r.status.summary() == "too many cycles");
  CHECK(*r.value("cycle_count") == "6");

  ThresholdSet t;
  t.defaults.custom["max_cycles"] = 100;  // its threshold, from the same configuration
  h.monitor.set_thresholds(t);
  CHECK(find(h.step(), "c").status.ok());

  CHECK(h.monitor.remove_check("cycle_count") == 1);
  CHECK(h.monitor.check_names().size() == 9);
}

TEST_CASE("Without built-in checks, only custom checks run", "[monitor][check]") {
  Harness h(MonitorOptions{.builtin_checks = false});
  CHECK(h.monitor.check_names().empty());
  Probe idle("idle", h.registry, h.clock);
  CHECK(find(h.step(), "idle").status.ok());  // no initialization check
}

TEST_CASE("The monitor thread publishes reports and calls subscribers", "[monitor][thread]") {
  Harness h(MonitorOptions{.period_ns = 2 * kMs, .self_report = true});
  PeriodicProbe c(h, "c", kMs);
  run(h, c, 5);
  h.supervisor.step();
  std::atomic<int> calls{0};
  std::atomic<std::size_t> seen{0};
  const auto id = h.monitor.subscribe([&](const ReportSet& s) {
    seen.store(s.components.size());
    calls.fetch_add(1);
  });
  CHECK(h.monitor.latest().components.empty());  // nothing before the first cycle
  REQUIRE(h.monitor.start());
  CHECK(h.monitor.running());
  REQUIRE(wait_for([&] { return calls.load() >= 3; }));
  // Reading and stepping from another thread while the thread runs.
  const ReportSet manual = h.monitor.step();
  CHECK(manual.find("c") != nullptr);
  const auto reports = h.monitor.reports();
  CHECK(reports.size() == 3);
  CHECK(seen.load() == 3);
  const Report* self = manual.find("vigil.monitor");
  REQUIRE(self != nullptr);
  CHECK(self->state == TaskState::Running);
  CHECK(self->tid != 0);
  h.monitor.stop();
  CHECK_FALSE(h.monitor.running());
  h.monitor.unsubscribe(id);
  const int after = calls.load();
  h.monitor.step();
  CHECK(calls.load() == after);
  h.monitor.stop();  // idempotent
}
