// Monitor: cost of one monitor cycle (Monitor::step: snapshots, windows, built-in checks, the
// ReportSet), per component and in total, with 1 to 10,000 components.
//
// Each component has sent its identity (threaded, FIFO, 1 ms period) and a state change, and
// between two monitor cycles 10 cycle samples, drained by a supervisor outside the timing. Only
// Monitor::step() is timed. Two settings: `thread_stats:0` runs the checks alone;
// `thread_stats:1` also reads each component thread's OS counters (the default: one /proc read
// per distinct thread per cycle), with the components spread over 16 real threads.
// Value = CPU time of Monitor::step() per component (median over the cycles of a repetition);
// counter cycle_ms = the whole cycle, and share_at_1Hz_pct = % of a core at the monitor's default
// period (1 s).
#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/drain_loop.hpp"

namespace vigil::bench {
namespace {

constexpr std::size_t kCapacity = kDefaultPortCapacity;
constexpr std::size_t kSamplesPerCycle = 10;
constexpr int kThreads = 16;

/// Idle threads whose tids the components claim, so that thread statistics are real reads.
class IdleThreads {
 public:
  explicit IdleThreads(int n) {
    tids_.assign(static_cast<std::size_t>(n), 0);
    for (int i = 0; i < n; ++i) {
      threads_.emplace_back([this, i] {
        std::unique_lock lock(mutex_);
        tids_[static_cast<std::size_t>(i)] = platform::current_tid();
        ++ready_;
        cv_.notify_all();
        cv_.wait(lock, [this] { return quit_; });
      });
    }
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return ready_ == n; });
  }
  ~IdleThreads() {
    {
      std::lock_guard lock(mutex_);
      quit_ = true;
    }
    cv_.notify_all();
    for (auto& t : threads_) t.join();
  }
  [[nodiscard]] int tid(std::size_t i) const { return tids_[i % tids_.size()]; }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<int> tids_;
  std::vector<std::thread> threads_;
  int ready_ = 0;
  bool quit_ = false;
};

struct World {
  World(std::size_t n, const IdleThreads& threads, MonitorOptions options)
      : supervisor(registry, aggregator), monitor(aggregator, std::move(options)) {
    members.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      members.push_back(registry.join<kCapacity>("component_" + std::to_string(i)));
      task::TaskInfo info;
      info.name.assign("component_" + std::to_string(i));
      info.activity.assign("periodic");
      info.requested_policy = SchedPolicy::Fifo;
      info.policy = SchedPolicy::Fifo;
      info.threaded = true;
      info.priority = 80;
      info.tid = threads.tid(i);
      info.tasks_on_thread = 1;
      info.period_ns = kNanosPerMilli;
      info.port_capacity = kCapacity;
      (void)members.back().port()->try_push(task::Message{info});
      task::StateChange change{
          platform::now_ns(), TaskState::Stopped, TaskState::Running, Hook::Start, false, {}};
      (void)members.back().port()->try_push(task::Message{change});
    }
    cycles.assign(n, 0);
    feed();
  }

  /// 10 samples per component, drained by the supervisor (not timed).
  void feed() {
    Nanos t = platform::now_ns() - static_cast<Nanos>(kSamplesPerCycle) * kNanosPerMilli;
    for (std::size_t k = 0; k < kSamplesPerCycle; ++k, t += kNanosPerMilli) {
      for (std::size_t i = 0; i < members.size(); ++i) {
        task::CycleSample s;
        s.counters.cycles = ++cycles[i];
        s.release_ns = t;
        s.start_ns = t + 3'000;
        s.end_ns = s.start_ns + 40'000;
        s.overhead_ns = s.cycle() % 16 == 1 ? 150 : 0;
        (void)members[i].port()->try_push(task::Message{s});
      }
    }
    (void)supervisor.step();
  }

  Registry<task::Message> registry;
  supervisor::ComponentAggregator aggregator;
  supervisor::ComponentDrainLoop supervisor;
  Monitor monitor;
  std::vector<bus::Membership<task::Message, kCapacity>> members;
  std::vector<std::uint64_t> cycles;
};

void monitor_step(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const bool thread_stats = state.range(1) != 0;
  IdleThreads threads(kThreads);
  MonitorOptions options;
  options.read_thread_stats = thread_stats;
  World world(n, threads, options);
  (void)world.monitor.step();  // first observation of every component

  const Nanos clock_cost = cpu_clock_cost();
  std::vector<double> cycle_ns;
  for (auto _ : state) {
    world.feed();
    const Nanos c0 = thread_cpu_ns();
    const Nanos t0 = platform::now_ns();
    ReportSet set = world.monitor.step();
    const Nanos t1 = platform::now_ns();
    const Nanos c1 = thread_cpu_ns();
    benchmark::DoNotOptimize(set);
    // CPU time of the thread (the monitor runs on one): not charged for preemption.
    cycle_ns.push_back(static_cast<double>(std::max<Nanos>(c1 - c0 - clock_cost, 1)));
    state.SetIterationTime(static_cast<double>(t1 - t0) * 1e-9);
  }
  const double per_cycle = median(cycle_ns);
  report(state, "ns/component", per_cycle / static_cast<double>(n));
  state.counters["cycle_ms"] = per_cycle * 1e-6;
  state.counters["share_at_1Hz_pct"] = 100.0 * per_cycle / 1e9;
}

}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::monitor_step)
    ->Name("monitor/step")
    ->ArgNames({"components", "thread_stats"})
    ->ArgsProduct({{1, 100, 1'000, 10'000}, {0, 1}})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
