// Fault: the monitor thread stalled for seconds (a custom check, or a subscriber writing to a slow
// disk, blocks one cycle) while components run on their own threads. The supervisor drains on,
// so nothing is dropped and every counter stays exact; no component is judged starved because of
// the monitor's own delay; the monitor reports its stall (its cycle time, WARN) and resumes.
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "vigil/exec/periodic_activity.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;

namespace {

constexpr Nanos kMs = kNanosPerMilli;

class Counter : public Task<Counter> {
 public:
  Counter(std::string name, Registry<task::Message>& registry)
      : Task(std::move(name), {}, registry) {}
  void on_update() { cycles.fetch_add(1, std::memory_order_relaxed); }
  std::atomic<std::uint64_t> cycles{0};
};

// Blocks the monitor's cycle once, while `stall` is set, until release().
struct StallCheck {
  struct Gate {
    std::mutex mutex;
    std::condition_variable cv;
    bool stall = false;
    bool blocked = false;
  };
  Gate* gate;
  [[nodiscard]] std::string_view name() const { return "stall"; }
  void run(const CheckInput&, Report&) const {
    std::unique_lock lock(gate->mutex);
    if (!gate->stall) return;
    gate->blocked = true;
    gate->cv.notify_all();
    gate->cv.wait(lock, [this] { return !gate->stall; });
    gate->blocked = false;
  }
};

template <class Pred>
bool wait_for(Pred pred, std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

const Report* find(const ReportSet& s, std::string_view name) { return s.find(name); }

}  // namespace

TEST_CASE("Monitor thread stalled 1.5 s: counters exact, nothing dropped, the stall reported",
          "[faults][monitor]") {
  Registry<task::Message> registry;
  supervisor::ComponentAggregator aggregator;
  supervisor::ComponentDrainLoop supervisor(registry, aggregator, {.period_ns = 5 * kMs});
  Monitor monitor(aggregator, {.period_ns = 20 * kMs});
  monitor.set_supervisor(&supervisor);
  ThresholdSet t;
  t.defaults.starvation.min_silence_ns = 500 * kMs;  // generous: sanitizers, a loaded machine
  t.defaults.overrun.enabled = false;
  t.defaults.overhead.enabled = false;
  monitor.set_thresholds(t);
  StallCheck::Gate gate;
  monitor.add_check(StallCheck{&gate});

  std::vector<std::unique_ptr<Counter>> counters;
  std::vector<std::unique_ptr<PeriodicActivity>> activities;
  for (int i = 0; i < 4; ++i) {
    counters.push_back(std::make_unique<Counter>("c" + std::to_string(i), registry));
    REQUIRE(counters.back()->configure());
    activities.push_back(std::make_unique<PeriodicActivity>(
        *counters.back(), PeriodicConfig{.name = "t" + std::to_string(i % 2), .period_ns = kMs}));
  }
  REQUIRE(supervisor.start());
  for (auto& a : activities) REQUIRE(a->start());
  REQUIRE(monitor.start());
  REQUIRE(wait_for([&] {
    const ReportSet s = monitor.latest();
    for (int i = 0; i < 4; ++i) {
      const Report* r = find(s, "c" + std::to_string(i));
      if (r == nullptr || r->counters.cycles == 0) return false;
    }
    return true;
  }));

  // Stall the monitor's thread.
  {
    std::lock_guard lock(gate.mutex);
    gate.stall = true;
  }
  {
    std::unique_lock lock(gate.mutex);
    REQUIRE(gate.cv.wait_for(lock, std::chrono::seconds(30), [&] { return gate.blocked; }));
  }
  const std::uint64_t monitor_cycle = monitor.latest().cycle;
  const std::uint64_t drains_before = supervisor.stats().cycles;
  const std::uint64_t messages_before = supervisor.stats().messages;
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  // Stalled: no new reports; the supervisor drained all along.
  CHECK(monitor.latest().cycle == monitor_cycle);
  CHECK(supervisor.stats().cycles > drains_before + 50);
  CHECK(supervisor.stats().messages > messages_before + 1000);
  {
    std::lock_guard lock(gate.mutex);
    gate.stall = false;
  }
  gate.cv.notify_all();

  // Resumed: the monitor reports its stall; no component is starved because of it.
  REQUIRE(wait_for([&] { return monitor.latest().cycle >= monitor_cycle + 3; }));
  const ReportSet after = monitor.latest();
  const Report* self = find(after, "vigil.monitor");
  REQUIRE(self != nullptr);
  CHECK(self->total_ns.max >= 1400 * kMs);
  CHECK(self->status.level() == StatusLevel::Warn);
  CHECK_THAT(self->status.summary(), Catch::Contains("cycle time"));
  for (int i = 0; i < 4; ++i) {
    const Report* r = find(after, "c" + std::to_string(i));
    REQUIRE(r != nullptr);
    CHECK(r->status.level() != StatusLevel::Stale);
  }

  // Stopped: after the last drain, every count is exact and nothing was dropped.
  for (auto& a : activities) a->stop();
  supervisor.stop();
  monitor.stop();
  const ReportSet last = monitor.step();
  for (int i = 0; i < 4; ++i) {
    const Report* r = find(last, "c" + std::to_string(i));
    REQUIRE(r != nullptr);
    CHECK(r->counters.cycles == counters[static_cast<std::size_t>(i)]->cycles.load());
    CHECK(r->counters.dropped == 0);
  }
}
