// Supervisor throughput: drain + visit + aggregate, in messages per second on one core, and the
// CPU share of a supervisor for 1,000 components at 1 kHz.
//
// throughput: `components` ports (capacity 256, as a Task's) are pre-filled with `per_port`
// CycleSamples each (consecutive cycles, a sampled overhead on one in 16, as a component sends),
// outside the timing; then one `DrainLoop<Message, ComponentAggregator>::step()` is timed.
// per_port = 10 is what a 1 kHz component queues in the supervisor's 10 ms period; 256 is a
// full port. Value = messages / CPU time of the thread in step() (the cost of reading the CPU
// clock subtracted), summed over the iterations of a repetition (the mean, not the median: the
// statistics' bulk updates, every few hundred cycles of a component, are in it). `drain_visit_only`
// runs the same supervisor with a handler that only reads each message, to split drain + visit from
// aggregation.
//
// cpu_share: measured directly. A producer thread (pinned to VIGIL_BENCH_CPU) pushes one sample
// into each of 1,000 ports every millisecond; a supervisor thread (pinned to the consumer CPU)
// calls step() every 10 ms, as DrainLoop::start() does. Value = the supervisor thread's CPU time
// (CLOCK_THREAD_CPUTIME_ID, system calls included) / wall time, in % of one core, over 1 s.
// `cpu_share_1kHz/drain_visit_only`: the same with a handler that only reads each message, the
// part of that share that is the drain across cores (the rest is the aggregation).
//
// registry_leave: what a member's leaving costs a registry of 1,000 and 10,000 members (ns per
// leave, all members leaving in join order), the teardown of a large system.
#include <algorithm>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/drain_loop.hpp"

namespace vigil::bench {
namespace {

constexpr std::size_t kCapacity = kDefaultPortCapacity;
// Issue 21's goals: >= 40 M messages/s at 1,000 components x 10 messages per drain (and fewer
// components), >= 25 M at 10,000 x 10; <= 5 % of a core at 1,000 components x 1 kHz.
constexpr double kGoalMessagesPerSecond = 40e6;
constexpr double kGoalMessagesPerSecond10k = 25e6;
constexpr double kGoalCpuSharePercent = 5.0;

struct Components {
  explicit Components(std::size_t n) {
    members.reserve(n);
    next.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      members.push_back(registry.join<kCapacity>("c" + std::to_string(i)));
    }
  }

  /// One sample, as CycleRecorder::post builds it, for component i.
  task::Message sample(std::size_t i, Nanos now) {
    const std::uint64_t c = ++next[i];
    task::CycleSample s;
    s.counters.cycles = c;
    s.release_ns = now;
    s.start_ns = now + 2'000 + static_cast<Nanos>(c % 7) * 100;
    s.end_ns = s.start_ns + 50'000 + static_cast<Nanos>(c % 13) * 1'000;
    s.overhead_ns = c % 16 == 1 ? 120 : 0;
    s.state = TaskState::Running;
    return task::Message{s};
  }

  /// Pushes `per_port` samples into every port (producer side; nothing else is pushing).
  std::size_t fill(std::size_t per_port) {
    std::size_t pushed = 0;
    // Each component's releases move forward, as a real component's do (never back to now when
    // a fill started within the span of the previous one).
    Nanos t = std::max(platform::now_ns(), last_release);
    for (std::size_t k = 0; k < per_port; ++k) {
      t += kNanosPerMilli;
      for (std::size_t i = 0; i < members.size(); ++i) {
        pushed += members[i].port()->try_push(sample(i, t)) ? 1 : 0;
      }
    }
    last_release = t;
    return pushed;
  }

  Registry<task::Message> registry;
  std::vector<bus::Membership<task::Message, kCapacity>> members;
  std::vector<std::uint64_t> next;
  Nanos last_release = 0;
};

/// A handler that only looks at each message: the supervisor's drain + visit without the
/// aggregation, to split the cost.
struct NullHandler {
  using Entry = bus::RegistryEntry<task::Message>;
  void on_join(const Entry&) {}
  void on_leave(const Entry&) {}
  void begin(const Entry&) {}
  void end(const Entry&, const supervisor::PortDrain&) {}
  void on_cycle(const supervisor::DrainCycle&) {}
  template <class M>
  void on(const Entry&, const M& m) {
    if constexpr (std::is_same_v<M, task::CycleSample>) sum += static_cast<std::uint64_t>(m.end_ns);
  }
  std::uint64_t sum = 0;
};

/// An experiment: the aggregator with a clock that costs nothing, to show what its per-message
/// read of the clock (ComponentAggregator::on(CycleSample): last_sample_at) costs.
Nanos frozen_now(const void* /*ctx*/) noexcept { return 1; }
struct AggregatorFrozenClock : supervisor::ComponentAggregator {
  AggregatorFrozenClock()
      : supervisor::ComponentAggregator(
            supervisor::AggregatorOptions{.clock = Clock{&frozen_now}}) {}
};

/// An experiment: the aggregator without the worst cycles per window (the exemplars' source,
/// AggregatorOptions::worst_window_ns = 0), to show what finding them costs the catch-up.
struct AggregatorWithoutWorstCycles : supervisor::ComponentAggregator {
  AggregatorWithoutWorstCycles()
      : supervisor::ComponentAggregator(supervisor::AggregatorOptions{.worst_window_ns = 0}) {}
};

template <class Handler>
void throughput(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto per_port = static_cast<std::size_t>(state.range(1));
  Components comps(n);
  Handler handler;
  supervisor::DrainLoop<task::Message, Handler> supervisor(comps.registry, handler);
  (void)supervisor.step();  // joins
  // Warm-up: until the aggregator's warm-up (100 ms of the components' clock, 1 ms per sample)
  // is over, so that the timed steps are the steady state: records and histograms touched and
  // grown, no sample kept out of the statistics.
  const std::size_t warmup_rounds =
      1 + supervisor::AggregatorOptions{}.warmup_ns / kNanosPerMilli / per_port;
  for (std::size_t r = 0; r < warmup_rounds; ++r) {
    (void)comps.fill(per_port);
    (void)supervisor.step();
  }
  const Nanos clock_cost = cpu_clock_cost();

  double messages = 0;
  double cpu_ns = 0;
  for (auto _ : state) {
    const std::size_t pushed = comps.fill(per_port);
    const Nanos c0 = thread_cpu_ns();
    const Nanos t0 = platform::now_ns();
    const std::size_t visited = supervisor.step();
    const Nanos t1 = platform::now_ns();
    const Nanos c1 = thread_cpu_ns();
    if (visited != pushed) state.SkipWithError("supervisor visited fewer messages than pushed");
    // CPU time of this thread: a step the scheduler preempted (shared machine) is not charged
    // for the time it waited; wall time would be.
    messages += static_cast<double>(visited);
    cpu_ns += static_cast<double>(std::max<Nanos>(c1 - c0 - clock_cost, 1));
    state.SetIterationTime(static_cast<double>(t1 - t0) * 1e-9);
  }
  if constexpr (requires { handler.catch_up(); }) {
    // The cycles the aggregator still keeps waiting for its statistics (up to three quarters of
    // a flight ring per component) are part of the cost: taken now, on the clock.
    const Nanos c0 = thread_cpu_ns();
    handler.catch_up();
    cpu_ns += static_cast<double>(thread_cpu_ns() - c0);
  }
  // All the steps' messages over all their CPU time, not a median of steps: the aggregator
  // takes cycles into its statistics in bulk every few hundred cycles, so a median step would
  // leave that work out.
  const double per_second = messages / (cpu_ns * 1e-9);
  report(state, "msg/s", per_second);
  state.counters["ns_per_msg"] = 1e9 / per_second;
  if constexpr (std::is_same_v<Handler, supervisor::ComponentAggregator>) {
    state.counters["goal_value_min"] =
        n >= 10'000 ? kGoalMessagesPerSecond10k : kGoalMessagesPerSecond;
    using Aggregator = supervisor::ComponentAggregator;
    state.SetLabel(std::string("catch-up: ") + Aggregator::name(Aggregator::instruction_set()));
  }
}

template <class Handler>
void cpu_share(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const Nanos duration = kNanosPerSecond;
  double share_sum = 0;
  double ns_per_msg_sum = 0;
  int runs = 0;
  for (auto _ : state) {
    Components comps(n);
    Handler handler;
    supervisor::DrainLoop<task::Message, Handler> supervisor(comps.registry, handler);
    (void)supervisor.step();
    std::atomic<bool> quit{false};
    Nanos cpu = 0;
    Nanos wall = 0;
    std::uint64_t visited = 0;
    std::thread consumer([&] {
      pin_to_cpu(consumer_cpu());
      const Nanos period = supervisor::DrainOptions{}.period_ns;
      const Nanos c0 = thread_cpu_ns();
      const Nanos w0 = platform::now_ns();
      Nanos next = w0;
      while (!quit.load(std::memory_order_acquire)) {
        visited += supervisor.step();
        next += period;
        const Nanos now = platform::now_ns();
        if (next < now) next = now;
        platform::sleep_until(next);
      }
      visited += supervisor.step();
      // The cycles still waiting for the aggregator's statistics are part of its cost.
      if constexpr (requires { handler.catch_up(); }) handler.catch_up();
      cpu = thread_cpu_ns() - c0;
      wall = platform::now_ns() - w0;
    });
    // Producer: this (pinned) thread plays 1,000 components at 1 kHz.
    const Nanos start = platform::now_ns();
    Nanos release = start;
    while (release - start < duration) {
      release += kNanosPerMilli;
      platform::sleep_until(release);
      for (std::size_t i = 0; i < n; ++i) {
        (void)comps.members[i].port()->try_push(comps.sample(i, release));
      }
    }
    quit.store(true, std::memory_order_release);
    consumer.join();
    const double share = 100.0 * static_cast<double>(cpu) / static_cast<double>(wall);
    share_sum += share;
    ns_per_msg_sum += static_cast<double>(cpu) / static_cast<double>(visited);
    ++runs;
    state.SetIterationTime(static_cast<double>(wall) * 1e-9);
  }
  report(state, "% of a core", share_sum / runs);
  state.counters["cpu_ns_per_msg"] = ns_per_msg_sum / runs;
  if constexpr (std::is_same_v<Handler, supervisor::ComponentAggregator>) {
    state.counters["goal_value_max"] = kGoalCpuSharePercent;
  }
}

// Leaving a registry of `components` members, in the order they joined (each member's port has
// capacity 2, so that the ports' memory does not dominate): ns per leave, median over the
// iterations. Leaving is O(1) (the member list is kept in no order, each entry knows its slot);
// it was a search and a shift of the whole list, quadratic over a teardown.
void registry_leave(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::vector<double> per_leave;
  for (auto _ : state) {
    Registry<task::Message> registry;
    std::vector<bus::Membership<task::Message, 2>> members;
    members.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      members.push_back(registry.join<2>("c" + std::to_string(i)));
    const Nanos t0 = platform::now_ns();
    for (auto& m : members) m.leave();
    const Nanos t1 = platform::now_ns();
    per_leave.push_back(static_cast<double>(t1 - t0) / static_cast<double>(n));
    state.SetIterationTime(static_cast<double>(t1 - t0) * 1e-9);
  }
  report(state, "ns/leave", median(per_leave));
}

}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::registry_leave)
    ->Name("supervisor/registry_leave")
    ->ArgNames({"components"})
    ->Arg(1'000)
    ->Arg(10'000)
    ->Iterations(5)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::throughput<vigil::supervisor::ComponentAggregator>)
    ->Name("supervisor/throughput")
    ->ArgNames({"components", "per_port"})
    ->ArgsProduct({{1, 100, 1'000, 10'000}, {10, 256}})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::throughput<vigil::bench::NullHandler>)
    ->Name("supervisor/drain_visit_only")
    ->ArgNames({"components", "per_port"})
    ->ArgsProduct({{1'000}, {10}})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::throughput<vigil::bench::AggregatorFrozenClock>)
    ->Name("supervisor/experiment:aggregator_without_clock_reads")
    ->ArgNames({"components", "per_port"})
    ->ArgsProduct({{1'000}, {10}})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::throughput<vigil::bench::AggregatorWithoutWorstCycles>)
    ->Name("supervisor/experiment:aggregator_without_worst_cycles")
    ->ArgNames({"components", "per_port"})
    ->ArgsProduct({{1'000}, {10, 256}})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::cpu_share<vigil::supervisor::ComponentAggregator>)
    ->Name("supervisor/cpu_share_1kHz")
    ->ArgNames({"components"})
    ->Arg(1'000)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(vigil::bench::cpu_share<vigil::bench::NullHandler>)
    ->Name("supervisor/cpu_share_1kHz/drain_visit_only")
    ->ArgNames({"components"})
    ->Arg(1'000)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
