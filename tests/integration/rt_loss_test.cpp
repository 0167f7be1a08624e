// Real-time-loss detection per component (allocations, blocking, page faults) and thread
// statistics that agree with /proc.
#include <sched.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

#include "support/drain.hpp"
#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "support/proc_reader.hpp"
#include "vigil/build_config.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/triggered_activity.hpp"
#include "vigil/platform/thread_stats.hpp"

using namespace vigil;
using vigil::test::Probe;

namespace {
struct Run {
  std::array<std::uint64_t, task::kLossCauses> totals{};
  std::vector<task::RealTimeLoss> losses;
  std::uint64_t cycles = 0;
};

// Runs `cycles` cycles of `p` on a ManualActivity in this thread, draining the port as it goes
// so that no message is dropped.
Run run(Probe& p, std::uint64_t cycles) {
  ManualActivity act(p, {.name = "m"});
  REQUIRE(p.configure());
  REQUIRE(act.start());
  Run r;
  auto consume = [&] {
    for (const auto& m : vigil::test::drain(*p.port())) {
      if (const auto* l = std::get_if<task::RealTimeLoss>(&m)) r.losses.push_back(*l);
      if (const auto* s = std::get_if<task::CycleSample>(&m)) {
        r.totals = s->counters.losses;
        r.cycles = s->cycle();
      }
    }
  };
  for (std::uint64_t i = 0; i < cycles; ++i) {
    act.step();
    if (i % 64 == 0) consume();
  }
  consume();
  CHECK(p.port()->dropped() == 0);
  return r;
}

std::uint64_t of(const Run& r, platform::LossCause c) {
  return r.totals[static_cast<std::size_t>(c)];
}

// Cobalt: the blocking and page-fault detectors read zero (getrusage would relax a primary-mode
// thread; the mode-switch detector replaces them, docs/guide/rt-loss-detection.md), so there the
// cases below check that they stay at zero instead.
constexpr bool kCobalt = VIGIL_PLATFORM_COBALT != 0;
}  // namespace

#if !defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Allocating on every 100th cycle of 10,000 gives exactly 100 allocation losses",
          "[rt_loss][allocation]") {
  Registry<task::Message> reg;
  Probe p("alloc", {.detectors = Detectors::Allocation}, reg);
  p.script.allocate_every = 100;
  const Run r = run(p, 10'000);
  CHECK(r.cycles == 10'000);
  CHECK(of(r, platform::LossCause::Allocation) == 100);
  REQUIRE(r.losses.size() == 100);
  for (const auto& l : r.losses) {
    CHECK(l.cause == platform::LossCause::Allocation);
    CHECK(l.count == 1);
    CHECK(l.cycle % 100 == 0);  // attributed to the cycle that allocated
  }
}
#endif

#if !defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("The allocation detector counts on across restarts, whatever the activity's clock",
          "[rt_loss][allocation]") {
  // Supervision looks at the clock on the first cycle of each run; the detector is set apart
  // from it and must stay on.
  Registry<task::Message> reg;
  vigil::test::FakeClock fake;
  Probe p("alloc", {.detectors = Detectors::Allocation}, reg);
  p.script.allocate_every = 2;
  REQUIRE(p.configure());
  std::uint64_t losses = 0;
  std::uint64_t cycles = 0;
  for (int run = 0; run < 3; ++run) {  // the process's clock, a replaced one, the process's
    ManualActivity act(
        p, run == 1 ? ManualConfig{.name = "m", .clock = fake.clock()} : ManualConfig{.name = "m"});
    REQUIRE(act.start());
    for (int i = 0; i < 10; ++i) REQUIRE(act.step());
    REQUIRE(act.stop());
    for (const auto& s : vigil::test::cycles_of(vigil::test::drain(*p.port()))) {
      losses = s.counters.loss(platform::LossCause::Allocation);
      cycles = s.cycle();
    }
  }
  CHECK(cycles == 30);
  CHECK(losses == 15);
}
#endif

TEST_CASE("Sleeping 1 ms on every 50th cycle is counted as blocking, in those cycles only",
          "[rt_loss][blocking]") {
  Registry<task::Message> reg;
  Probe p("sleepy", {.detectors = Detectors::Blocking}, reg);
  p.script.sleep_every = 50;
  const Run r = run(p, 2'000);
  if constexpr (kCobalt) {
    CHECK(of(r, platform::LossCause::Blocking) == 0);
    CHECK(r.losses.empty());
    return;
  }
  CHECK(of(r, platform::LossCause::Blocking) >= 40);
  std::uint64_t cycles_with_loss = 0;
  for (const auto& l : r.losses) {
    CHECK(l.cause == platform::LossCause::Blocking);
    CHECK(l.cycle % 50 == 0);
    ++cycles_with_loss;
  }
  CHECK(cycles_with_loss == 40);
}

TEST_CASE("Touching fresh pages is counted as page faults, in those cycles only",
          "[rt_loss][page_faults]") {
  Registry<task::Message> reg;
  Probe p("toucher", {.detectors = Detectors::PageFaults}, reg);
  p.script.touch_pages_every = 100;
  const Run r = run(p, 2'000);
  if constexpr (kCobalt) {
    CHECK(of(r, platform::LossCause::MinorFault) == 0);
    CHECK(of(r, platform::LossCause::MajorFault) == 0);
    CHECK(r.losses.empty());
    return;
  }
  CHECK(of(r, platform::LossCause::MinorFault) >= 20UL * 4);  // 4 fresh pages per touching cycle
  CHECK(of(r, platform::LossCause::MajorFault) == 0);
#if !defined(VIGIL_SANITIZER_BUILD)
  // (AddressSanitizer's shadow memory takes page faults of its own in other cycles.)
  for (const auto& l : r.losses) {
    CHECK(l.cause == platform::LossCause::MinorFault);
    CHECK(l.cycle % 100 == 0);
  }
#endif
}

TEST_CASE("A clean component has no loss of any kind with every detector on", "[rt_loss]") {
  Registry<task::Message> reg;
  Probe p("clean", {.detectors = Detectors::All}, reg);
  const Run r = run(p, 10'000);
  for (int c = 0; c < task::kLossCauses; ++c) {
#if defined(VIGIL_SANITIZER_BUILD)
    // AddressSanitizer's shadow memory takes page faults of its own: not the component's.
    if (c == static_cast<int>(platform::LossCause::MinorFault)) continue;
#endif
    INFO("cause " << platform::to_string(static_cast<platform::LossCause>(c)));
    CHECK(r.totals[static_cast<std::size_t>(c)] == 0);
  }
#if !defined(VIGIL_SANITIZER_BUILD)
  CHECK(r.losses.empty());
#endif
}

TEST_CASE("Detectors are selected per component", "[rt_loss]") {
  Registry<task::Message> reg;
  Probe off("off", {.detectors = Detectors::None}, reg);
  off.script.sleep_every = 10;
  off.script.touch_pages_every = 10;
  const Run r = run(off, 100);
  CHECK(r.losses.empty());
  for (auto v : r.totals) CHECK(v == 0);
}

TEST_CASE("Thread statistics agree with /proc over the same interval", "[rt_loss][thread_stats]") {
  // A triggered activity's thread sleeps between triggers, so it is still while both read.
  Registry<task::Message> reg;
  Probe p("worker", {.detectors = Detectors::Blocking | Detectors::PageFaults}, reg);
  p.script.sleep_every = 2;
  p.script.touch_pages_every = 3;
  TriggeredActivity act(p, {.name = "worker"});
  REQUIRE(p.configure());
  REQUIRE(act.start().has_value());
  const int tid = act.info().tid;
  auto settle = [&](std::uint64_t n) {
    const auto deadline = platform::now_ns() + 5 * kNanosPerSecond;
    while (act.cycles() < n && platform::now_ns() < deadline) std::this_thread::yield();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // back asleep on its futex
  };
  auto read_both = [&] {
    const auto v = platform::read_thread_stats(tid).value();
    const auto k = vigil::test::read_proc_thread(tid);
    return std::pair{v, k};
  };
  settle(0);
  const auto [v0, k0] = read_both();
  for (std::uint64_t i = 1; i <= 12; ++i) {
    act.trigger();
    settle(i);
  }
  const auto [v1, k1] = read_both();
  act.stop();
  CHECK(v1.voluntary_switches - v0.voluntary_switches == k1.voluntary - k0.voluntary);
  CHECK(v1.involuntary_switches - v0.involuntary_switches == k1.involuntary - k0.involuntary);
  CHECK(v1.minor_faults - v0.minor_faults == k1.minflt - k0.minflt);
  CHECK(v1.major_faults - v0.major_faults == k1.majflt - k0.majflt);
  // The component's own counts are the part of the thread's that happened inside on_update.
  CHECK(v1.voluntary_switches - v0.voluntary_switches >= 6);
  CHECK(v1.minor_faults - v0.minor_faults >= 4UL * 4);
}
