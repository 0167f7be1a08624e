// Each built-in check at the edges of its thresholds, on hand-made snapshots: just at the limit
// (passes: comparisons are strict) and just above it.
#include <catch2/catch.hpp>

#include "vigil/monitor/checks/builtin.hpp"

using namespace vigil;
using namespace vigil::monitor;

namespace {

constexpr Nanos kPeriod = kNanosPerMilli;

supervisor::ComponentSnapshot periodic(SchedPolicy policy = SchedPolicy::Other) {
  supervisor::ComponentSnapshot s;
  s.id = 1;
  s.name = "c";
  s.has_info = true;
  s.info.name = "c";
  s.info.period_ns = kPeriod;
  s.info.policy = policy;
  s.info.requested_policy = policy;
  s.state = TaskState::Running;
  s.has_sample = true;
  return s;
}

template <class C>
Report run(const supervisor::ComponentSnapshot& s, const Thresholds& t = {}, const Window& w = {},
           Nanos silence = -1) {
  C check;
  Report r;
  fill_report(r, s);
  check.run(CheckInput{s, t, w, 0, silence}, r);
  return r;
}

Window window(std::uint64_t cycles, std::uint64_t overruns = 0) {
  Window w;
  w.first = false;
  w.duration_ns = kNanosPerSecond;
  w.cycles = cycles;
  w.overruns = overruns;
  return w;
}

}  // namespace

TEST_CASE("Initialization: no TaskInfo is WARN 'not configured'", "[monitor][checks]") {
  supervisor::ComponentSnapshot s;
  s.name = "c";
  Report r = run<checks::InitializationCheck>(s);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "not configured");

  s.has_info = true;
  CHECK(run<checks::InitializationCheck>(s).status.ok());

  s.has_info = false;
  s.alive = false;  // left before configuring: nothing to say
  CHECK(run<checks::InitializationCheck>(s).status.ok());

  Thresholds off;
  off.initialization.enabled = false;
  s.alive = true;
  CHECK(run<checks::InitializationCheck>(s, off).status.ok());
}

TEST_CASE("Exception: any exception is ERROR with the last type and message", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic();
  CHECK(run<checks::ExceptionCheck>(s).status.ok());

  s.counters.exceptions = 1;
  s.has_exception = true;
  s.last_exception_type = "std::runtime_error";
  s.last_exception.message = "boom";
  s.last_exception.hook = Hook::Update;
  Report r = run<checks::ExceptionCheck>(s);
  CHECK(r.status.level() == StatusLevel::Error);
  CHECK(r.status.summary() == "exception in update: std::runtime_error: boom (1 in total)");
  CHECK(r.values.empty());

  SECTION("not sticky: WARN once recovered, ERROR while in Exception or within the window") {
    Thresholds t;
    t.exception.sticky = false;
    Report recovered = run<checks::ExceptionCheck>(s, t, window(10));
    CHECK(recovered.status.level() == StatusLevel::Warn);
    CHECK(recovered.status.summary() ==
          "recovered after 1 exception; last: std::runtime_error: boom");
    Window w = window(10);
    w.exceptions = 1;
    CHECK(run<checks::ExceptionCheck>(s, t, w).status.level() == StatusLevel::Error);
    s.state = TaskState::Exception;
    CHECK(run<checks::ExceptionCheck>(s, t, window(10)).status.level() == StatusLevel::Error);
  }
  SECTION("FatalError without an exception report is ERROR too") {
    supervisor::ComponentSnapshot f = periodic();
    f.state = TaskState::FatalError;
    Report fr = run<checks::ExceptionCheck>(f);
    CHECK(fr.status.level() == StatusLevel::Error);
    CHECK(fr.status.summary() == "in FatalError");
  }
}

TEST_CASE("Overrun: the EWMA of total time at and just above near_fraction x period",
          "[monitor][checks][overrun]") {
  supervisor::ComponentSnapshot s = periodic();
  s.total_ns.count = 100;
  s.total_ns.ewma = 0.9 * kPeriod;  // exactly at the limit: passes
  CHECK(run<checks::OverrunCheck>(s).status.ok());
  s.total_ns.ewma = 0.9 * kPeriod + 1.0;  // 1 ns above
  Report r = run<checks::OverrunCheck>(s);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK_THAT(r.status.summary(), Catch::StartsWith("near overrun: EWMA of total time 900us"));

  Thresholds t;
  t.overrun.near_fraction = 0.5;
  s.total_ns.ewma = 0.5 * kPeriod;
  CHECK(run<checks::OverrunCheck>(s, t).status.ok());
  s.total_ns.ewma = 0.5 * kPeriod + 1.0;
  CHECK(run<checks::OverrunCheck>(s, t).status.level() == StatusLevel::Warn);

  t.overrun.near_fraction = 0.0;  // disabled
  s.total_ns.ewma = 10.0 * kPeriod;
  CHECK(run<checks::OverrunCheck>(s, t).status.ok());

  supervisor::ComponentSnapshot aperiodic = s;
  aperiodic.info.period_ns = 0;
  CHECK(run<checks::OverrunCheck>(aperiodic).status.ok());
}

TEST_CASE("Overrun: rates in the window at and just above warn_rate and error_rate",
          "[monitor][checks][overrun]") {
  const supervisor::ComponentSnapshot s = periodic();
  // Defaults: warn above 0 (any overrun), error above 10 %.
  CHECK(run<checks::OverrunCheck>(s, {}, window(1000, 0)).status.ok());
  Report one = run<checks::OverrunCheck>(s, {}, window(1000, 1));
  CHECK(one.status.level() == StatusLevel::Warn);
  CHECK(one.status.summary() == "overruns: 1 in 1000 cycles (0.1%, WARN above 0%)");
  CHECK(run<checks::OverrunCheck>(s, {}, window(1000, 100)).status.level() == StatusLevel::Warn);
  Report many = run<checks::OverrunCheck>(s, {}, window(1000, 101));
  CHECK(many.status.level() == StatusLevel::Error);
  CHECK_THAT(many.status.summary(), Catch::Contains("ERROR above 10%"));

  Thresholds t;
  t.overrun.warn_rate = 0.01;
  t.overrun.error_rate = 0.5;
  CHECK(run<checks::OverrunCheck>(s, t, window(1000, 10)).status.ok());
  CHECK(run<checks::OverrunCheck>(s, t, window(1000, 11)).status.level() == StatusLevel::Warn);
  CHECK(run<checks::OverrunCheck>(s, t, window(1000, 500)).status.level() == StatusLevel::Warn);
  CHECK(run<checks::OverrunCheck>(s, t, window(1000, 501)).status.level() == StatusLevel::Error);

  Window missed = window(10, 2);
  missed.missed_cycles = 3;
  CHECK_THAT(run<checks::OverrunCheck>(s, {}, missed).status.summary(),
             Catch::EndsWith(", 3 cycles missed"));
  CHECK(run<checks::OverrunCheck>(s, {}, window(0, 0)).status.ok());  // no cycle, no rate
}

TEST_CASE("Starvation: silence at and just above max(periods x period, min_silence)",
          "[monitor][checks][starvation]") {
  const supervisor::ComponentSnapshot s = periodic();
  Thresholds t;
  t.starvation.min_silence_ns = 0;
  const Nanos limit = 10 * kPeriod;
  CHECK(checks::starvation_limit(t, kPeriod) == limit);
  CHECK(run<checks::StarvationCheck>(s, t, {}, limit).status.ok());
  Report r = run<checks::StarvationCheck>(s, t, {}, limit + 1);
  CHECK(r.status.level() == StatusLevel::Stale);
  CHECK(r.status.summary() == "starved: no cycle for 10.0ms (limit 10.0ms)");
  CHECK(*r.value("starvation_limit") == "10.0ms");

  SECTION("min_silence is a floor") {
    const Thresholds d;  // 10 periods = 10 ms < 100 ms
    CHECK(checks::starvation_limit(d, kPeriod) == 100 * kNanosPerMilli);
    CHECK(run<checks::StarvationCheck>(s, d, {}, 100 * kNanosPerMilli).status.ok());
    CHECK(run<checks::StarvationCheck>(s, d, {}, 100 * kNanosPerMilli + 1).status.level() ==
          StatusLevel::Stale);
  }
  SECTION("periods scales the limit") {
    Thresholds k = t;
    k.starvation.periods = 2.5;
    CHECK(checks::starvation_limit(k, kPeriod) == 2'500'000);
    CHECK(run<checks::StarvationCheck>(s, k, {}, 2'500'001).status.level() == StatusLevel::Stale);
  }
  SECTION("non-periodic components: aperiodic_silence, off by default") {
    supervisor::ComponentSnapshot a = s;
    a.info.period_ns = 0;
    CHECK(run<checks::StarvationCheck>(a, {}, {}, 3600 * kNanosPerSecond).status.ok());
    Thresholds ap;
    ap.starvation.aperiodic_silence_ns = kNanosPerSecond;
    CHECK(run<checks::StarvationCheck>(a, ap, {}, kNanosPerSecond).status.ok());
    CHECK(run<checks::StarvationCheck>(a, ap, {}, kNanosPerSecond + 1).status.level() ==
          StatusLevel::Stale);
  }
  SECTION("only Running components starve") {
    supervisor::ComponentSnapshot stopped = s;
    stopped.state = TaskState::Stopped;
    CHECK(run<checks::StarvationCheck>(stopped, t, {}, limit * 100).status.ok());
    CHECK(run<checks::StarvationCheck>(s, t, {}, -1).status.ok());  // silence unknown
  }
}

TEST_CASE("RealTime: losses in the window on a FIFO thread, by cause", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic(SchedPolicy::Fifo);
  Window w = window(100);
  CHECK(run<checks::RealTimeCheck>(s, {}, w).status.ok());
  w.losses[static_cast<std::size_t>(platform::LossCause::Allocation)] = 3;
  w.losses[static_cast<std::size_t>(platform::LossCause::Blocking)] = 1;
  s.counters.losses = w.losses;
  s.counters.losses[static_cast<std::size_t>(platform::LossCause::Allocation)] = 7;
  Report r = run<checks::RealTimeCheck>(s, {}, w);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "real-time losses: 3 allocation, 1 blocking (8 in total)");
  CHECK(r.value("latest_loss") == nullptr);  // no RealTimeLoss report arrived
  s.has_loss = true;
  s.last_loss = task::RealTimeLoss{42, platform::LossCause::Blocking, 1};
  r = run<checks::RealTimeCheck>(s, {}, w);
  REQUIRE(r.value("latest_loss") != nullptr);
  CHECK(*r.value("latest_loss") == "cycle 42: 1 blocking");

  Thresholds t;
  t.realtime.warn_losses = 4;  // 4 in the window: at the limit
  CHECK(run<checks::RealTimeCheck>(s, t, w).status.ok());
  w.losses[static_cast<std::size_t>(platform::LossCause::MinorFault)] = 1;  // 5: above
  CHECK(run<checks::RealTimeCheck>(s, t, w).status.level() == StatusLevel::Warn);

  SECTION("OTHER threads are not checked unless fifo_only is false") {
    supervisor::ComponentSnapshot other = s;
    other.info.policy = SchedPolicy::Other;
    CHECK(run<checks::RealTimeCheck>(other, {}, w).status.ok());
    Thresholds all;
    all.realtime.fifo_only = false;
    CHECK(run<checks::RealTimeCheck>(other, all, w).status.level() == StatusLevel::Warn);
  }
}

TEST_CASE("NotRealtime: asked for FIFO, runs OTHER", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic(SchedPolicy::Fifo);
  CHECK(run<checks::NotRealtimeCheck>(s).status.ok());
  s.info.policy = SchedPolicy::Other;
  s.info.realtime_refused = true;
  Report r = run<checks::NotRealtimeCheck>(s);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "not real-time: asked for FIFO, runs OTHER");
  CHECK(run<checks::NotRealtimeCheck>(periodic(SchedPolicy::Other)).status.ok());
}

TEST_CASE("Overhead: supervision share at and just above warn_share", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic();
  CHECK(run<checks::OverheadCheck>(s).status.ok());  // never measured
  // 400 us cycles with 20 us of overhead: above both floors (1 us, 1 % of the 1 ms period).
  s.total_ns.count = 100;
  s.total_ns.mean = 400'000.0;
  s.overhead_ns.count = 10;
  s.overhead_ns.mean = 20'000.0;  // 5 %: at the limit
  CHECK(run<checks::OverheadCheck>(s).status.ok());
  s.overhead_ns.mean = 20'000.01;
  Report r = run<checks::OverheadCheck>(s);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "supervision overhead 5.0% of cycle time (limit 5.0%)");
  s.overhead_ns.mean = 200'000.0;  // 50 %: the share is shown as it is
  CHECK(run<checks::OverheadCheck>(s).status.summary() ==
        "supervision overhead 50% of cycle time (limit 5.0%)");
}

TEST_CASE("Overhead: a large share of a tiny cycle is no warning (the floors)",
          "[monitor][checks]") {
  // The false alarm of examples/multi_process: on_update() takes 100 ns, supervision ~400 ns
  // per measured cycle, period 1 ms: an 80 % share of a cycle that costs nothing.
  supervisor::ComponentSnapshot s = periodic();
  s.total_ns.count = 5000;
  s.total_ns.mean = 500.0;
  s.overhead_ns.count = 80;
  s.overhead_ns.mean = 400.0;
  CHECK(run<checks::OverheadCheck>(s).status.ok());

  // Above the absolute floor (1 us) but below 1 % of the period (10 us): still fine.
  s.total_ns.mean = 6'000.0;
  s.overhead_ns.mean = 5'000.0;
  CHECK(run<checks::OverheadCheck>(s).status.ok());
  // The same overhead on a 100 us period is 5 % of it: it warns.
  s.info.period_ns = 100'000;
  CHECK(run<checks::OverheadCheck>(s).status.level() == StatusLevel::Warn);

  // Non-periodic: only the absolute floor applies.
  s.info.period_ns = 0;
  CHECK(run<checks::OverheadCheck>(s).status.level() == StatusLevel::Warn);
  s.total_ns.mean = 1'000.0;
  s.overhead_ns.mean = 1'000.0;  // at the floor: passes (comparisons are strict)
  CHECK(run<checks::OverheadCheck>(s).status.ok());

  // The floors are thresholds: 0 restores the share alone.
  Thresholds t;
  t.overhead.min_overhead_ns = 0;
  t.overhead.min_period_share = 0;
  s.info.period_ns = kPeriod;
  s.total_ns.mean = 500.0;
  s.overhead_ns.mean = 400.0;
  Report r = run<checks::OverheadCheck>(s, t);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "supervision overhead 80% of cycle time (limit 5.0%)");
  t.overhead.min_overhead_ns = 400;  // at the floor again
  CHECK(run<checks::OverheadCheck>(s, t).status.ok());
}

TEST_CASE("Drops: port drops in the window, with the count", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic();
  s.counters.dropped = 15;
  Window w = window(100);
  CHECK(run<checks::DropsCheck>(s, {}, w).status.ok());  // dropped earlier, not now
  w.dropped = 1;
  Report r = run<checks::DropsCheck>(s, {}, w);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "port dropped 1 message (15 in total)");
  Thresholds t;
  t.drops.warn_drops = 10;
  w.dropped = 10;
  CHECK(run<checks::DropsCheck>(s, t, w).status.ok());
  w.dropped = 11;
  CHECK(run<checks::DropsCheck>(s, t, w).status.level() == StatusLevel::Warn);
}

TEST_CASE("Disabled checks say nothing", "[monitor][checks]") {
  supervisor::ComponentSnapshot s = periodic(SchedPolicy::Fifo);
  s.info.policy = SchedPolicy::Other;
  s.counters.exceptions = 3;
  s.total_ns.count = 1;
  s.total_ns.ewma = 2.0 * kPeriod;
  Window w = window(10, 10);
  w.dropped = 5;
  Thresholds t;
  t.exception.enabled = false;
  t.overrun.enabled = false;
  t.starvation.enabled = false;
  t.not_realtime.enabled = false;
  t.drops.enabled = false;
  CheckList list;
  checks::add_builtin_checks(list);
  Report r;
  fill_report(r, s);
  list.run(CheckInput{s, t, w, 0, kNanosPerSecond}, r);
  CHECK(r.status.ok());
  CHECK(r.status.messages().empty());
}

TEST_CASE("The built-in checks run in their documented order", "[monitor][checks]") {
  CheckList list;
  checks::add_builtin_checks(list);
  CHECK(list.names() == std::vector<std::string>{"initialization", "exception", "starvation",
                                                 "overrun", "realtime", "not_realtime", "overhead",
                                                 "drops", "latched"});
}
