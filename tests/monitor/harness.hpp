#pragma once
// End-to-end harness for monitor tests: real Task<Derived> components driven by ManualActivity on
// a fake clock, a Supervisor stepped by hand, and a Monitor stepped by hand, all on that clock.

#include <atomic>
#include <memory>
#include <stdexcept>
#include <string>

#include "vigil/exec/manual_activity.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/task.hpp"

namespace vigil::test {

/// A clock the test moves by hand. Thread-safe.
class FakeClock {
 public:
  explicit FakeClock(Nanos start = kNanosPerSecond) : t_(start) {}
  [[nodiscard]] Clock clock() const noexcept { return Clock{&FakeClock::read, this}; }
  [[nodiscard]] Nanos now() const noexcept { return t_.load(std::memory_order_relaxed); }
  void advance(Nanos d) noexcept { t_.fetch_add(d, std::memory_order_relaxed); }
  /// Moves forward to `t` (never backward).
  void advance_to(Nanos t) noexcept {
    Nanos cur = now();
    while (cur < t && !t_.compare_exchange_weak(cur, t, std::memory_order_relaxed)) {
    }
  }

 private:
  static Nanos read(const void* ctx) noexcept {
    return static_cast<const FakeClock*>(ctx)->t_.load(std::memory_order_relaxed);
  }
  std::atomic<Nanos> t_;
};

/// A component whose update takes `work_ns` of fake time and throws on request.
template <class Traits = DefaultTaskTraits>
class BasicProbe : public Task<BasicProbe<Traits>, Traits> {
 public:
  BasicProbe(std::string name, Registry<task::Message>& registry, FakeClock& clock,
             SupervisionOptions options = {.detectors = Detectors::None,
                                           .overhead_sample_every = 0})
      : Task<BasicProbe<Traits>, Traits>(std::move(name), options, registry), clock_(clock) {}

  void on_update() {
    clock_.advance(work_ns);
    if (throw_next) {
      throw_next = false;
      throw std::runtime_error("boom: \"quoted\"\nsecond line");
    }
  }

  Nanos work_ns = 0;
  bool throw_next = false;

 private:
  FakeClock& clock_;
};
using Probe = BasicProbe<>;

/// Registry, aggregator, supervisor and monitor on one fake clock.
struct Harness {
  explicit Harness(MonitorOptions options = {}) : monitor(aggregator, with_clock(options)) {
    monitor.set_supervisor(&supervisor);
  }

  MonitorOptions with_clock(MonitorOptions o) const {
    o.clock = clock.clock();
    o.read_thread_stats = false;
    return o;
  }

  /// Drains every port, then runs one monitor cycle.
  ReportSet step() {
    supervisor.step();
    return monitor.step();
  }

  /// Runs one cycle of `a` at its release time.
  void cycle(ManualActivity& a) {
    clock.advance_to(a.next_release());
    a.step();
  }

  FakeClock clock;
  Registry<task::Message> registry;
  // No warm-up: the tests count every cycle in the statistics; no watchdog: the starvation
  // tests see the monitor's view alone (both have their own tests, tests/supervisor).
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{
      .clock = clock.clock(), .warmup_ns = 0, .watchdog = {.enabled = false}}};
  supervisor::ComponentDrainLoop supervisor{registry, aggregator,
                                            supervisor::DrainOptions{.clock = clock.clock()}};
  Monitor monitor;
};

/// A periodic probe on a manual activity, configured and started.
struct PeriodicProbe {
  PeriodicProbe(Harness& h, const std::string& name, Nanos period_ns)
      : probe(name, h.registry, h.clock),
        activity(probe, ManualConfig{.name = name + "_activity",
                                     .period_ns = period_ns,
                                     .clock = h.clock.clock()}) {
    probe.configure();
    activity.start();
  }
  Probe probe;
  ManualActivity activity;
};

}  // namespace vigil::test
