#pragma once
/// @file
/// What every vigil benchmark shares: CPU pinning, a consumer thread that polls queues at the
/// supervisor's default period, the floor (two clock reads around an empty call and one push of
/// a `Message` into the same queue type a Port uses), and the counters that benches/run turns
/// into its table.
///
/// Conventions read by benches/run (one row per benchmark, from its "_median" aggregate):
///   label            unit of `value` ("ns/cycle", "msg/s", "% of a core", "lines/s"...)
///   value            the measurement
///   floor            the floor or the peer, measured in the same repetition (optional)
///   ratio            per repetition: value / floor, or peer time / our time for "x faster"
///   goal_ratio_max   pass when ratio <= this      goal_ratio_min   pass when ratio >= this
///   goal_value_max   pass when value <= this      goal_value_min   pass when value >= this
/// Google Benchmark takes the median of every counter over the repetitions, so `ratio` in the
/// table is the median of per-repetition ratios, not a ratio of medians.

#include <benchmark/benchmark.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstdint>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#include "vigil/task/messages.hpp"
#include "vigil/task/supervision.hpp"

namespace vigil::bench {

/// CPU of the measuring thread (VIGIL_BENCH_CPU, default 1) and of the consumer
/// (VIGIL_BENCH_CONSUMER_CPU, default 0). On a one-CPU machine both are 0.
inline int env_cpu(const char* var, int fallback) {
  const int n = static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN));
  int cpu = fallback;
  if (const char* v = std::getenv(var)) cpu = std::atoi(v);
  return n > 0 ? cpu % n : 0;
}
inline int measure_cpu() { return env_cpu("VIGIL_BENCH_CPU", 1); }
inline int consumer_cpu() { return env_cpu("VIGIL_BENCH_CONSUMER_CPU", 0); }

/// Pins the calling thread to `cpu`; returns false when the system refuses.
inline bool pin_to_cpu(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0;
}

/// Thread CPU time of the caller, in ns.
inline Nanos thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

/// Median of `v` (reorders it); 0 when empty.
inline double median(std::vector<double>& v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

/// What reading the thread CPU clock twice costs (a system call each, ~0.3 us): subtracted from
/// CPU times measured with thread_cpu_ns().
inline Nanos cpu_clock_cost() {
  static const Nanos cost = [] {
    std::vector<double> d;
    for (int i = 0; i < 1001; ++i) {
      const Nanos a = thread_cpu_ns();
      d.push_back(static_cast<double>(thread_cpu_ns() - a));
    }
    return static_cast<Nanos>(median(d));
  }();
  return cost;
}

/// The component's empty update: one real call, identical in the floor and in every subject.
[[gnu::noinline]] inline void empty_update() noexcept { benchmark::ClobberMemory(); }

/// The period the consumer polls at: the supervisor's default (10 ms).
inline Nanos consumer_period_ns() { return supervisor::DrainOptions{}.period_ns; }

/// A consumer thread, pinned, that pops every queue it was given once per period (never spins),
/// as the supervisor does, and counts its polls so that a producer can wait for the next one.
class Poller {
 public:
  using Drain = std::function<std::size_t(task::Message*, std::size_t)>;

  explicit Poller(std::vector<Drain> drains, Nanos period_ns = consumer_period_ns())
      : drains_(std::move(drains)), period_ns_(period_ns), buffer_(64) {
    thread_ = std::thread([this] { run(); });
  }
  Poller(const Poller&) = delete;
  Poller& operator=(const Poller&) = delete;
  ~Poller() {
    quit_.store(true, std::memory_order_release);
    thread_.join();
  }

  /// Polls completed so far.
  [[nodiscard]] std::uint64_t polls() const noexcept {
    return completed_.load(std::memory_order_acquire);
  }
  /// Blocks (futex, no spinning) until a poll that began after this call has completed: every
  /// message pushed before the call has then been popped.
  void wait_next_poll() const noexcept {
    // Store-load ordering between our pushes and the read of `started_` (the consumer's
    // increment is a locked RMW followed by its own fence): the Dekker pattern needs both.
    std::atomic_thread_fence(std::memory_order_seq_cst);
    const std::uint64_t target = started_.load(std::memory_order_seq_cst) + 1;
    for (std::uint64_t done = completed_.load(std::memory_order_acquire); done < target;
         done = completed_.load(std::memory_order_acquire)) {
      completed_.wait(done, std::memory_order_acquire);
    }
  }
  /// Messages popped so far.
  [[nodiscard]] std::uint64_t popped() const noexcept {
    return popped_.load(std::memory_order_relaxed);
  }

 private:
  void run() {
    pin_to_cpu(consumer_cpu());
    Nanos next = platform::now_ns();
    while (!quit_.load(std::memory_order_acquire)) {
      started_.fetch_add(1, std::memory_order_seq_cst);
      std::atomic_thread_fence(std::memory_order_seq_cst);
      std::uint64_t n = 0;
      for (auto& d : drains_) {
        for (;;) {
          const std::size_t k = d(buffer_.data(), buffer_.size());
          benchmark::DoNotOptimize(buffer_.data());
          n += k;
          if (k < buffer_.size()) break;
        }
      }
      popped_.fetch_add(n, std::memory_order_relaxed);
      completed_.fetch_add(1, std::memory_order_release);
      completed_.notify_all();
      next += period_ns_;
      const Nanos now = platform::now_ns();
      if (next < now) next = now;
      platform::sleep_until(next);
    }
  }

  std::vector<Drain> drains_;
  Nanos period_ns_;
  std::vector<task::Message> buffer_;
  std::atomic<bool> quit_{false};
  std::atomic<std::uint64_t> started_{0};
  std::atomic<std::uint64_t> completed_{0};
  std::atomic<std::uint64_t> popped_{0};
  std::thread thread_;
};

/// The floor of per-cycle supervision: two reads of vigil's clock around the empty update and
/// one push of a CycleSample `Message` into a boost spsc_queue of the default port capacity,
/// the queue type behind every Port.
class Floor {
 public:
  [[gnu::noinline]] void cycle() noexcept {
    const Nanos t0 = platform::now_ns();
    empty_update();
    const Nanos t1 = platform::now_ns();
    task::CycleSample s;
    s.counters.cycles = ++cycles_;
    s.start_ns = t0;
    s.end_ns = t1;
    pushed_ += queue_.push(task::Message{s}) ? 1 : 0;
  }
  [[nodiscard]] Poller::Drain drain() {
    return [this](task::Message* out, std::size_t n) { return queue_.pop(out, n); };
  }
  [[nodiscard]] std::uint64_t pushed() const noexcept { return pushed_; }

 private:
  boost::lockfree::spsc_queue<task::Message, boost::lockfree::capacity<kDefaultPortCapacity>>
      queue_;
  std::uint64_t cycles_ = 0;
  std::uint64_t pushed_ = 0;
};

/// An experiment, not a floor: the same cycle pushing a 128-byte, cache-line-aligned element
/// (a CycleSample alone) instead of the 128-byte Message in its unaligned ring, to show what
/// alignment costs.
class Floor128 {
 public:
  struct alignas(64) Slot {
    task::CycleSample sample;
  };
  static_assert(sizeof(Slot) == 128);

  [[gnu::noinline]] void cycle() noexcept {
    const Nanos t0 = platform::now_ns();
    empty_update();
    const Nanos t1 = platform::now_ns();
    Slot s;
    s.sample.counters.cycles = ++cycles_;
    s.sample.start_ns = t0;
    s.sample.end_ns = t1;
    pushed_ += queue_.push(s) ? 1 : 0;
  }
  [[nodiscard]] Poller::Drain drain() {
    return [this](task::Message*, std::size_t) {
      return queue_.consume_all(
          [](const Slot& s) { benchmark::DoNotOptimize(s.sample.counters.cycles); });
    };
  }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return cycles_ - pushed_; }

 private:
  boost::lockfree::spsc_queue<Slot, boost::lockfree::capacity<kDefaultPortCapacity>> queue_;
  std::uint64_t cycles_ = 0;
  std::uint64_t pushed_ = 0;
};

/// Sets the counters benches/run reads.
inline void report(benchmark::State& state, const char* unit, double value) {
  state.SetLabel(unit);
  state.counters["value"] = value;
}
inline void report_vs(benchmark::State& state, const char* unit, double value, double floor,
                      double ratio) {
  report(state, unit, value);
  state.counters["floor"] = floor;
  state.counters["ratio"] = ratio;
}

/// Times `floor` and `subject` alternately, once each per benchmark iteration, and reports the
/// medians of their ns per operation and of the per-iteration ratios (`report_vs`). Which of the
/// two runs first flips every iteration, so neither always meets the caches the other left.
/// `before()` runs untimed at the start of each iteration (e.g. `Poller::wait_next_poll`);
/// `time_floor()` and `time_subject()` return the nanoseconds of `ops` operations.
template <class Before, class TimeFloor, class TimeSubject>
void measure_pair(benchmark::State& state, const char* unit, double ops, Before&& before,
                  TimeFloor&& time_floor, TimeSubject&& time_subject) {
  std::vector<double> floor_ns;
  std::vector<double> subject_ns;
  std::vector<double> ratios;
  bool subject_first = false;
  for (auto _ : state) {
    before();
    Nanos tf = 0;
    Nanos ts = 0;
    if (subject_first) {
      ts = time_subject();
      tf = time_floor();
    } else {
      tf = time_floor();
      ts = time_subject();
    }
    subject_first = !subject_first;
    floor_ns.push_back(static_cast<double>(tf) / ops);
    subject_ns.push_back(static_cast<double>(ts) / ops);
    ratios.push_back(static_cast<double>(ts) / static_cast<double>(tf));
    state.SetIterationTime(static_cast<double>(ts) * 1e-9 / ops);
  }
  // Medians over the iterations: a batch the scheduler interrupted (the machine is shared)
  // moves a mean, not a median.
  report_vs(state, unit, median(subject_ns), median(floor_ns), median(ratios));
}

/// VIGIL_BENCH_FIFO=<priority>: runs the measuring thread (and the threads it creates, which
/// inherit it) SCHED_FIFO, so that other processes of a shared machine cannot preempt a timed
/// batch. Returns a description for the context.
inline std::string apply_fifo_from_env() {
  const char* v = std::getenv("VIGIL_BENCH_FIFO");
  if (v == nullptr || *v == '\0' || std::atoi(v) <= 0) return "no (SCHED_OTHER)";
  sched_param p{};
  p.sched_priority = std::atoi(v);
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
  return rc == 0 ? "SCHED_FIFO " + std::to_string(p.sched_priority)
                 : "refused (" + std::to_string(rc) + "), SCHED_OTHER";
}

/// Registers the context (CPUs used) and runs the benchmarks; the measuring thread is pinned.
/// `before` runs first, before the thread is pinned and made SCHED_FIFO (processes it starts
/// then inherit neither); `after` runs once the benchmarks have run.
inline int run_main(int argc, char** argv, const std::function<void()>& before = {},
                    const std::function<void()>& after = {}) {
  if (before) before();
  const int cpu = measure_cpu();
  const bool pinned = pin_to_cpu(cpu);
  benchmark::AddCustomContext("vigil.fifo", apply_fifo_from_env());
  benchmark::AddCustomContext("vigil.measure_cpu", pinned ? std::to_string(cpu) : "unpinned");
  benchmark::AddCustomContext("vigil.consumer_cpu", std::to_string(consumer_cpu()));
  benchmark::AddCustomContext("vigil.consumer_period_ns", std::to_string(consumer_period_ns()));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  if (after) after();
  benchmark::Shutdown();
  return 0;
}

}  // namespace vigil::bench
