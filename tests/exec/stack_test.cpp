// Activities' threads get the stack their configuration names (kDefaultActivityStackBytes unless
// set), and activities sharing a thread share its stack.
#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

#include "support/probe.hpp"
#include "support/stack.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/exec/triggered_activity.hpp"

using namespace vigil;
using vigil::test::Probe;

namespace {
/// A probe that records the stack size of the thread its update runs on.
struct StackProbe {
  explicit StackProbe(std::string name, Registry<task::Message>& reg)
      : probe(std::move(name), {}, reg) {
    probe.work = [this] { bytes.store(vigil::test::current_stack_bytes()); };
    REQUIRE(probe.configure());
  }
  std::size_t wait_bytes() {
    const auto deadline = platform::now_ns() + 10 * kNanosPerSecond;
    while (bytes.load() == 0 && platform::now_ns() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return bytes.load();
  }
  Probe probe;
  std::atomic<std::size_t> bytes{0};
};
}  // namespace

TEST_CASE("A periodic activity's thread has the configured stack", "[exec][periodic][memory]") {
  STATIC_REQUIRE(kDefaultActivityStackBytes == 512 * 1024);
  STATIC_REQUIRE(PeriodicConfig{}.stack_bytes == kDefaultActivityStackBytes);
  Registry<task::Message> reg;
  StackProbe dflt("dflt", reg), big("big", reg), sys("sys", reg);
  // Threads of their own (equal activities would share one thread, and so one stack).
  PeriodicActivity a(dflt.probe,
                     {.name = "stack_default", .period_ns = kNanosPerMilli, .share_thread = false});
  PeriodicActivity b(big.probe, {.name = "stack_big",
                                 .period_ns = kNanosPerMilli,
                                 .share_thread = false,
                                 .stack_bytes = 1 << 20});
  PeriodicActivity c(sys.probe, {.name = "stack_system",
                                 .period_ns = kNanosPerMilli,
                                 .share_thread = false,
                                 .stack_bytes = 0});
  REQUIRE(a.start().has_value());
  REQUIRE(b.start().has_value());
  REQUIRE(c.start().has_value());
  const std::size_t system = vigil::test::system_default_stack_bytes();
  REQUIRE(system > 4 * kDefaultActivityStackBytes);  // so that stack_serves tells them apart
  CHECK(vigil::test::stack_serves(dflt.wait_bytes(), kDefaultActivityStackBytes));
  CHECK(vigil::test::stack_serves(big.wait_bytes(), std::size_t{1} << 20));
  CHECK(sys.wait_bytes() >= system);
}

TEST_CASE("Activities sharing a thread share its stack, and asking for more fails start()",
          "[exec][periodic][memory]") {
  Registry<task::Message> reg;
  Probe first("first", {}, reg), smaller("smaller", {}, reg), larger("larger", {}, reg);
  REQUIRE(first.configure());
  REQUIRE(smaller.configure());
  REQUIRE(larger.configure());
  const PeriodicConfig base{.name = "shared_stack", .period_ns = 3 * kNanosPerMilli};
  PeriodicConfig small_cfg = base;
  small_cfg.stack_bytes = 128 * 1024;
  PeriodicConfig large_cfg = base;
  large_cfg.stack_bytes = 4 << 20;
  PeriodicActivity a(first, base), b(smaller, small_cfg), c(larger, large_cfg);
  REQUIRE(a.start().has_value());
  REQUIRE(b.start().has_value());  // fits in the running thread's 512 KiB
  CHECK(a.info().tid == b.info().tid);
  const auto r = c.start();
  REQUIRE_FALSE(r.has_value());
  CHECK_THAT(r.error().message, Catch::Contains("asks for a 4194304-byte stack"));
  CHECK_THAT(r.error().message, Catch::Contains("524288-byte stack"));
  CHECK(larger.state() == TaskState::Stopped);
  // With a thread of its own it runs.
  large_cfg.share_thread = false;
  PeriodicActivity d(larger, large_cfg);
  CHECK(d.start().has_value());
}

TEST_CASE("A triggered activity's thread has the configured stack", "[exec][triggered][memory]") {
  STATIC_REQUIRE(TriggeredConfig{}.stack_bytes == kDefaultActivityStackBytes);
  Registry<task::Message> reg;
  StackProbe p("trig_stack", reg);
  TriggeredActivity act(p.probe, {.name = "trig_stack", .stack_bytes = 192 * 1024});
  REQUIRE(act.start().has_value());
  act.trigger();
  CHECK(vigil::test::stack_serves(p.wait_bytes(), 192 * 1024));
}
