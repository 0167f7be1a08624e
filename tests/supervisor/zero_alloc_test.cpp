// Linked with vigil::alloc_guard: every malloc-family call of the process is counted per thread.
#include <atomic>
#include <catch2/catch.hpp>
#include <stdexcept>
#include <thread>

#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/safe_state.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::supervisor;

#if defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Allocation counting is unavailable under sanitizers", "[supervisor][alloc]") {
  WARN("skipped: sanitizers interpose malloc themselves");
  CHECK_FALSE(platform::allocation_counting_available());
}
#else
namespace {
using Typed = TypedManualActivity<vigil::test::Probe>;
using Erased = ManualActivity;

template <class TestType>
void million_cycles_allocate_nothing() {
  REQUIRE(platform::allocation_counting_available());
  Registry<task::Message> reg;
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg, {.period_ns = kNanosPerMilli});
  REQUIRE(sup.start().has_value());
  std::uint64_t allocations = ~std::uint64_t{0};
  std::uint64_t loss_count = ~std::uint64_t{0};
  std::uint64_t cycles = 0;
  std::thread component([&] {
    vigil::test::Probe p("clean", {.detectors = Detectors::Allocation}, reg);
    TestType act(p, {.name = "m", .period_ns = kNanosPerMilli});
    p.configure();
    act.start();
    act.step();  // the first cycle may touch lazily initialised state
    const auto before = platform::thread_allocations();
    for (int i = 0; i < 1'000'000; ++i) act.step();
    allocations = platform::thread_allocations() - before;
    loss_count = 0;
    cycles = p.cycles();
    act.stop();
  });
  component.join();
  sup.stop();
  CHECK(allocations == 0);
  CHECK(cycles == 1'000'001);
  const auto s = agg.find("clean");
  REQUIRE(s.has_value());
  CHECK(s->counters.cycles == 1'000'001);
  CHECK(s->counters.losses[static_cast<int>(platform::LossCause::Allocation)] == loss_count);
}
}  // namespace

// Through TaskCore's virtual hook (ManualActivity) and inlined (TypedManualActivity). (A plain
// TEST_CASE, not TEMPLATE_TEST_CASE: the cobalt build registers tests from their sources.)
TEST_CASE("1,000,000 supervised cycles allocate nothing on the component's thread",
          "[supervisor][alloc]") {
  SECTION("ManualActivity") { million_cycles_allocate_nothing<Erased>(); }
  SECTION("TypedManualActivity") { million_cycles_allocate_nothing<Typed>(); }
}

namespace {
// Three checkpoints per cycle, one of them reported twice with the cycle's own time, one id it
// did not declare every 100th cycle (a misuse).
class Checkpointed : public vigil::Task<Checkpointed> {
 public:
  Checkpointed(std::string name, Registry<task::Message>& reg)
      : Task(std::move(name), {.detectors = Detectors::Allocation}, reg) {}
  CheckpointId read, compute, write;
  std::uint64_t n = 0;
  bool on_configure() {
    read = declare_checkpoint("read");
    compute = declare_checkpoint("compute");
    write = declare_checkpoint("write");
    return true;
  }
  void on_update() {
    checkpoint(read);
    checkpoint(compute, cycle().start_ns);
    checkpoint(write);
    if (++n % 100 == 0) checkpoint(CheckpointId{});
  }
};
}  // namespace

TEST_CASE("Checkpoint reports allocate nothing on the component's thread, supervised or not",
          "[supervisor][alloc][health]") {
  REQUIRE(platform::allocation_counting_available());
  Registry<task::Message> reg;
  ComponentAggregator agg;
  health::HealthConfig cfg;
  cfg.logical.push_back(
      {.name = "order",
       .initial = {{"cp", "read"}},
       .final = {{"cp", "write"}},
       .transitions = {{{"cp", "read"}, {"cp", "compute"}}, {{"cp", "compute"}, {"cp", "write"}}}});
  REQUIRE(agg.supervise_health(cfg).has_value());
  ComponentDrainLoop sup(reg, agg, {.period_ns = kNanosPerMilli});
  REQUIRE(sup.start().has_value());
  std::uint64_t allocations = ~std::uint64_t{0};
  std::uint32_t misuses = 0;
  bool configured = false;
  std::thread component([&] {
    Checkpointed c("cp", reg);
    TypedManualActivity<Checkpointed> act(c, {.name = "m", .period_ns = kNanosPerMilli});
    configured = c.configure();  // declarations allocate: before the measured cycles
    act.start();
    act.step();
    const auto before = platform::thread_allocations();
    for (int i = 0; i < 100'000; ++i) act.step();
    allocations = platform::thread_allocations() - before;
    misuses = c.checkpoint_misuses();
    act.stop();
  });
  component.join();
  sup.stop();
  REQUIRE(configured);
  CHECK(allocations == 0);
  CHECK(misuses == 1'000);
  const auto s = agg.find("cp");
  REQUIRE(s.has_value());
  CHECK(s->counters.losses[static_cast<int>(platform::LossCause::Allocation)] == 0);
}

TEST_CASE("A periodic thread's cycles allocate nothing", "[supervisor][alloc]") {
  Registry<task::Message> reg;
  vigil::test::Probe p("periodic", {.detectors = Detectors::Allocation}, reg);
  std::atomic<std::uint64_t> at10{0}, at300{0};
  p.work = [&] {
    if (p.updates == 10) at10 = platform::thread_allocations();
    if (p.updates == 300) at300 = platform::thread_allocations();
  };
  PeriodicActivity act(p, {.name = "p", .period_ns = 200 * kNanosPerMicro});
  REQUIRE(p.configure());
  REQUIRE(act.start().has_value());
  const auto deadline = platform::now_ns() + 10 * kNanosPerSecond;
  while (p.cycles() < 300 && platform::now_ns() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  act.stop();
  REQUIRE(p.updates >= 300);
  CHECK(at300.load() - at10.load() == 0);
}

TEST_CASE("Counters stay exact under loss: overruns, exceptions and RT losses",
          "[supervisor][alloc]") {
  // Port of capacity 8, supervisor paused for 100,000 cycles, then resumed.
  // Throwing allocates too (the exception object, its message): measure how much, once.
  const auto a0 = platform::thread_allocations();
  try {
    throw std::runtime_error("injected");
  } catch (const std::exception&) {
  }
  const auto per_throw = platform::thread_allocations() - a0;
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  BasicInstrumentation<8> sup("lossy", {.detectors = Detectors::Allocation}, reg);
  sup.init({.activity = "loop", .period_ns = 1000}, fc.clock());
  std::uint64_t overruns = 0, exceptions = 0, allocations = 0;
  Nanos release = fc.now();
  for (std::uint64_t i = 1; i <= 100'000; ++i) {
    fc.set(release);
    sup.run(
        [&] {
          fc.advance(i % 7 == 0 ? 1500 : 100);
          if (i % 13 == 0) {
            auto* q = new int(3);
            asm volatile("" : : "g"(q) : "memory");
            delete q;
          }
          if (i % 10 == 0) throw std::runtime_error("injected");
        },
        release);
    overruns += i % 7 == 0;
    exceptions += i % 10 == 0;
    allocations += i % 13 == 0;
    release += 2000;
  }
  ComponentAggregator agg;
  ComponentDrainLoop loop(reg, agg);
  loop.step();
  fc.set(release);
  sup.run([] {}, release);  // one more cycle carries the final totals
  loop.step();
  const auto s = agg.find("lossy");
  REQUIRE(s.has_value());
  CHECK(s->counters.cycles == 100'001);
  CHECK(s->counters.overruns == overruns);
  CHECK(s->counters.exceptions == exceptions);
  CHECK(s->counters.losses[static_cast<int>(platform::LossCause::Allocation)] ==
        allocations + per_throw * exceptions);
  CHECK(s->counters.dropped > 100'000);  // samples and loss reports
  CHECK(s->counters.dropped == sup.port()->dropped());
  CHECK(s->has_exception);
  CHECK(s->last_exception.message == std::string_view("injected"));
}

namespace {
// A component with a fallback (vigil/safe_state.hpp).
class Fallback : public Task<Fallback> {
 public:
  Fallback(std::string name, Registry<task::Message>& reg)
      : Task(std::move(name), {.detectors = Detectors::Allocation}, reg) {}
  void on_update() { ++normal; }
  void on_safe_state() { ++held; }
  std::uint64_t normal = 0, held = 0;
};
}  // namespace

TEST_CASE("The safe-state fallback switches without allocating, both ways", "[supervisor][alloc]") {
  REQUIRE(platform::allocation_counting_available());
  (void)clear_safe_state();
  Registry<task::Message> reg;
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg, {.period_ns = kNanosPerMilli});
  REQUIRE(sup.start().has_value());
  std::uint64_t allocations = ~std::uint64_t{0};
  std::uint64_t normal = 0, held = 0;
  std::thread component([&] {
    Fallback f("fallback", reg);
    TypedManualActivity<Fallback> act(f, {.name = "m", .period_ns = kNanosPerMilli});
    f.configure();
    act.start();
    act.step();
    const auto before = platform::thread_allocations();
    for (int i = 0; i < 100'000; ++i) act.step();
    const auto normal_allocations = platform::thread_allocations() - before;
    // The request comes from another thread (a reaction); it allocates there, not here.
    std::thread([] { (void)request_safe_state("test"); }).join();
    const auto mid = platform::thread_allocations();
    for (int i = 0; i < 100'000; ++i) act.step();
    allocations = platform::thread_allocations() - mid + normal_allocations;
    normal = f.normal;
    held = f.held;
    act.stop();
  });
  component.join();
  sup.stop();
  (void)clear_safe_state();
  CHECK(allocations == 0);
  CHECK(normal == 100'001);
  CHECK(held == 100'000);
}
#endif
