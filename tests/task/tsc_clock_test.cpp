// The optional TSC clock (vigil/platform/tsc.hpp) as supervision uses it: calibration against the
// monotonic clock, the fallback when the TSC cannot be used, and a supervised cycle on the TSC
// clock that allocates nothing. Linked with vigil::alloc_guard.
#include <catch2/catch.hpp>
#include <vector>

#include "vigil/exec/manual_activity.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/tsc.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::task;
namespace pf = vigil::platform;

namespace {

// Puts the process back on the monotonic clock whatever a test did.
struct MonotonicAfter {
  ~MonotonicAfter() {
    pf::force_tsc_unusable_for_testing({});
    (void)pf::select_clock(pf::ClockSource::Monotonic);
  }
};

class Empty : public Task<Empty> {
 public:
  explicit Empty(Registry<Message>& r)
      : Task("tsc_empty", {.detectors = Detectors::Allocation}, r) {}
  void on_update() { ++updates; }
  int updates = 0;
};

std::vector<CycleSample> samples_of(Port<Message, kDefaultPortCapacity>& port) {
  std::vector<CycleSample> out;
  Message m;
  while (port.pop(&m, 1) == 1) {
    if (const auto* s = std::get_if<CycleSample>(&m); s != nullptr && !s->totals_only) {
      out.push_back(*s);
    }
  }
  return out;
}

}  // namespace

TEST_CASE("tsc_to_ns is the linear map of its calibration", "[task][tsc]") {
  // 0.5 ns per tick (2 GHz): mult = 2^31.
  const pf::TscCalibration c{1'000, 5'000, std::uint64_t{1} << 31};
  CHECK(pf::tsc_to_ns(c, 1'000) == 5'000);
  CHECK(pf::tsc_to_ns(c, 3'000) == 6'000);
  CHECK(pf::tsc_to_ns(c, 0) == 4'500);  // before the base: the map extends backwards
  // A day of ticks at 3 GHz does not overflow the product.
  const pf::TscCalibration g{0, 0, static_cast<std::uint64_t>(4294967296.0 / 3.0)};
  const std::uint64_t day = 3ULL * 86'400 * 1'000'000'000;
  CHECK(std::llabs(pf::tsc_to_ns(g, day) - 86'400 * kNanosPerSecond) < kNanosPerMilli);
}

TEST_CASE("The TSC clock, when usable, agrees with the monotonic clock", "[task][tsc]") {
  MonotonicAfter restore;
  const pf::TscSupport support = pf::tsc_support();
  if (!support.usable) {
    WARN("skipped: " << support.reason);
    CHECK_FALSE(support.reason.empty());
    return;
  }
  const pf::ClockSelection sel = pf::select_clock(pf::ClockSource::Tsc);
  REQUIRE(sel.active == pf::ClockSource::Tsc);
  CHECK(sel.reason.empty());
  CHECK(sel.tsc_ghz > 0.1);
  CHECK(pf::active_clock() == pf::ClockSource::Tsc);
  // Bound: 50 us. The calibration's error is ~0.1 ppm after 50 ms (pairs read within ~100 ns),
  // and a pair read here has the same uncertainty; a preempted read is retried.
  constexpr Nanos kBound = 50 * kNanosPerMicro;
  for (int round = 0; round < 5; ++round) {
    Nanos best = kNanosPerSecond;
    for (int i = 0; i < 20; ++i) {
      const Nanos a = pf::now_ns();
      const Nanos t = pf::tsc_now_ns();
      const Nanos b = pf::now_ns();
      if (b - a < 2 * kNanosPerMicro)
        best = std::min<Nanos>(best, std::llabs(t - (a + (b - a) / 2)));
    }
    INFO("round " << round << ": |tsc - monotonic| = " << best << " ns");
    CHECK(best < kBound);
    pf::sleep_until(pf::now_ns() + 20 * kNanosPerMilli);
    pf::recalibrate_tsc();
  }
  // Supervision's clock is now the TSC, and it never goes backwards across re-calibrations.
  Nanos prev = Clock::system().now();
  for (int i = 0; i < 100'000; ++i) {
    const Nanos t = Clock::system().now();
    REQUIRE(t >= prev);
    prev = t;
  }
}

TEST_CASE("A TSC that cannot be used falls back to the monotonic clock and says why",
          "[task][tsc]") {
  MonotonicAfter restore;
  pf::force_tsc_unusable_for_testing("test: TSC not invariant");
  const pf::TscSupport support = pf::tsc_support();
  CHECK_FALSE(support.usable);
  CHECK(support.reason == "test: TSC not invariant");
  const pf::ClockSelection sel = pf::select_clock(pf::ClockSource::Tsc);
  CHECK(sel.requested == pf::ClockSource::Tsc);
  CHECK(sel.active == pf::ClockSource::Monotonic);
  CHECK(sel.reason.find("test: TSC not invariant") != std::string::npos);
  CHECK(sel.reason.find("monotonic") != std::string::npos);
  CHECK(pf::active_clock() == pf::ClockSource::Monotonic);
  // Supervision still runs, on the monotonic clock.
  Registry<Message> reg;
  Empty task(reg);
  ManualActivity act(task, {.name = "m", .period_ns = kNanosPerMilli});
  REQUIRE(task.configure());
  REQUIRE(act.start());
  const Nanos before = pf::now_ns();
  REQUIRE(act.step());
  const auto s = samples_of(*task.port());
  REQUIRE(s.size() == 1);
  CHECK(s[0].start_ns >= before);
  CHECK(s[0].end_ns <= pf::now_ns());
}

#if !defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Supervised cycles on the TSC clock allocate nothing and stamp monotonic time",
          "[task][tsc][alloc]") {
  MonotonicAfter restore;
  REQUIRE(pf::allocation_counting_available());
  const pf::ClockSelection sel = pf::select_clock(pf::ClockSource::Tsc);
  if (sel.active != pf::ClockSource::Tsc) WARN("TSC not usable here, measured on: " << sel.reason);
  Registry<Message> reg;
  Empty task(reg);
  ManualActivity act(task, {.name = "m", .period_ns = kNanosPerMilli});
  REQUIRE(task.configure());
  REQUIRE(act.start());
  REQUIRE(act.step());  // the first cycle may touch lazily initialised state
  (void)samples_of(*task.port());
  const Nanos t0 = pf::now_ns();
  const auto before = pf::thread_allocations();
  for (int i = 0; i < 200; ++i) REQUIRE(act.step());
  const auto allocations = pf::thread_allocations() - before;
  const Nanos t1 = pf::now_ns();
  CHECK(allocations == 0);
  CHECK(task.updates == 201);
  const auto s = samples_of(*task.port());
  REQUIRE(s.size() == 200);
  for (const auto& x : s) {
    CHECK(x.counters.loss(LossCause::Allocation) == 0);
    CHECK(x.end_ns >= x.start_ns);
    // Converted TSC time within the monotonic interval of the loop, give or take the bound.
    CHECK(x.start_ns > t0 - 50 * kNanosPerMicro);
    CHECK(x.end_ns < t1 + 50 * kNanosPerMicro);
  }
}
#endif
