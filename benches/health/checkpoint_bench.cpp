// The cost of checkpoints and health supervision, each next to its floor in the same run.
//
// 1. health/checkpoint/report: one checkpoint report on the real-time side
//    (Instrumentation::checkpoint: one clock read, the id's check, four stores and one push into
//    the component's port) against its floor: one read of vigil's clock and one push of a
//    CheckpointReport Message into the queue type behind every Port (goal <= 1.2x). Batches of
//    200 (below the port's 256: no push fails), a consumer polling every 10 ms, as in
//    task/overhead_bench.cpp.
// 2. health/checkpoint/cycle_with_3: a supervised Task cycle reporting three checkpoints against
//    the same cycle reporting none (no goal: it shows what three checkpoints add to a cycle);
//    and the same three reported at the cycle's start time (`checkpoint(id, time)`: no clock
//    read, a push each).
// 3. health/supervisor/per_checkpoint: the supervisor's cost per checkpoint report: a
//    ComponentDrainLoop step() draining 100 components x 200 reports, each checkpoint watched by a
//    logical, a deadline and an alive supervision, plus the judging of the drain (advance),
//    against the same step() draining as many cycle samples (the floor: the supervisor's cost
//    per ordinary message).
// 4. health/detection_latency: the time from a missed deadline (start + max) to the drain
//    thread's detection of it (the event's detected_ns - fault_ns), over many trials with a
//    random phase against the drain's 10 ms period; next to the wake-up latency of a plain timer
//    thread with the supervisor thread's policy and priority (SCHED_OTHER, nice 0) sleeping until
//    absolute times, in the same run (the floor). Rows for p50, p90, p99 and max (1,000 trials);
//    the p99 row has the goal p99 <= 1.2 x floor p99 + 100 us.
#include <algorithm>
#include <atomic>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/health/checkpoint.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

namespace vigil::bench {
namespace {

constexpr int kBatch = 200;
constexpr int kBatchesPerRep = 50;
constexpr Nanos kPeriod = kNanosPerMilli;

// --- 1. one report against one clock read and one push -----------------------------------------

class CheckpointFloor {
 public:
  CheckpointFloor() { report_.name.assign("frame_received"); }
  [[gnu::noinline]] void cycle() noexcept {
    report_.time_ns = platform::now_ns();
    ++report_.count;
    pushed_ += queue_.push(task::Message{report_}) ? 1 : 0;
  }
  [[nodiscard]] Poller::Drain drain() {
    return [this](task::Message* out, std::size_t n) { return queue_.pop(out, n); };
  }

 private:
  boost::lockfree::spsc_queue<task::Message, boost::lockfree::capacity<kDefaultPortCapacity>>
      queue_;
  health::CheckpointReport report_;
  std::uint64_t pushed_ = 0;
};

struct CheckpointSubject {
  CheckpointSubject() : instr("bench_checkpoint", {}, registry) {
    id = instr.declare_checkpoint("frame_received");
    instr.init(ManualInfo{.activity = "bench", .period_ns = kPeriod});
  }
  [[gnu::noinline]] void cycle() noexcept { instr.checkpoint(id); }
  Poller::Drain drain() {
    return [p = instr.port()](task::Message* out, std::size_t n) { return p->pop(out, n); };
  }
  Registry<task::Message> registry;
  Instrumentation instr;
  CheckpointId id;
};

// --- 2. a cycle with three checkpoints against the same cycle without ----------------------------

// What a cycle reports: nothing, three checkpoints (a clock read each), or three checkpoints at
// the cycle's own start time (no clock read).
enum class Reports { None, Now, CycleTime };

class StepsTask : public Task<StepsTask> {
 public:
  StepsTask(Registry<task::Message>& registry, Reports report)
      : Task("bench_steps", {}, registry), report_(report) {
    read_ = declare_checkpoint("read");
    compute_ = declare_checkpoint("compute");
    write_ = declare_checkpoint("write");
  }
  void on_update() {
    step(read_);
    empty_update();
    step(compute_);
    empty_update();
    step(write_);
  }

 private:
  [[gnu::always_inline]] void step(CheckpointId id) noexcept {
    if (report_ == Reports::Now) {
      checkpoint(id);
    } else if (report_ == Reports::CycleTime) {
      checkpoint(id, cycle().start_ns);
    }
  }
  Reports report_;
  CheckpointId read_, compute_, write_;
};

struct StepsSubject {
  explicit StepsSubject(Reports report)
      : task(registry, report),
        activity(task, ManualConfig{.name = "bench", .period_ns = kPeriod}) {
    (void)task.configure();
    (void)activity.start();
  }
  ~StepsSubject() { (void)activity.stop(); }
  [[gnu::noinline]] void cycle() noexcept { (void)activity.step(); }
  Poller::Drain drain() {
    return [p = task.port()](task::Message* out, std::size_t n) { return p->pop(out, n); };
  }
  Registry<task::Message> registry;
  StepsTask task;
  TypedManualActivity<StepsTask> activity;
};

template <class S>
Nanos run_batch(S& s, int n = kBatch) {
  const Nanos t0 = platform::now_ns();
  for (int i = 0; i < n; ++i) s.cycle();
  return platform::now_ns() - t0;
}

void report_vs_floor(benchmark::State& state) {
  CheckpointFloor floor;
  CheckpointSubject subject;
  Poller poller({floor.drain(), subject.drain()});
  for (int i = 0; i < 3; ++i) {
    poller.wait_next_poll();
    (void)run_batch(floor);
    (void)run_batch(subject);
  }
  measure_pair(
      state, "ns/checkpoint", kBatch, [&] { poller.wait_next_poll(); },
      [&] { return run_batch(floor); }, [&] { return run_batch(subject); });
  state.counters["goal_ratio_max"] = 1.2;
}

void cycle_with_3(benchmark::State& state, Reports how) {
  StepsSubject without(Reports::None);
  StepsSubject with(how);
  Poller poller({without.drain(), with.drain()});
  // 3 checkpoints + 1 sample per cycle: 50 cycles fill 200 of the 256 slots.
  constexpr int kCycles = 50;
  for (int i = 0; i < 3; ++i) {
    poller.wait_next_poll();
    (void)run_batch(without, kCycles);
    (void)run_batch(with, kCycles);
  }
  measure_pair(
      state, "ns/cycle", kCycles, [&] { poller.wait_next_poll(); },
      [&] { return run_batch(without, kCycles); }, [&] { return run_batch(with, kCycles); });
}

// --- 3. the supervisor's cost per checkpoint ----------------------------------------------------

constexpr int kComponents = 100;
constexpr int kPerPort = 200;

health::HealthConfig supervised_config() {
  health::HealthConfig cfg;
  for (int c = 0; c < kComponents; ++c) {
    const std::string n = "c" + std::to_string(c);
    cfg.logical.push_back({.name = n + "_order",
                           .initial = {{n, "read"}},
                           .final = {{n, "write"}},
                           .transitions = {{{n, "read"}, {n, "write"}}}});
    cfg.deadline.push_back({.name = n + "_deadline",
                            .start = {n, "read"},
                            .end = {n, "write"},
                            .max_ns = kNanosPerSecond});
    cfg.alive.push_back({.name = n + "_alive",
                         .checkpoint = {n, "read"},
                         .reference_cycle_ns = 100 * kNanosPerSecond,
                         .expected_indications = 1,
                         .max_margin = 1'000'000'000,
                         .startup_grace_ns = 0});
  }
  return cfg;
}

void supervisor_per_checkpoint(benchmark::State& state) {
  // Subject: ports full of checkpoint reports, every one supervised three times.
  Registry<task::Message> reg_cp;
  supervisor::ComponentAggregator agg_cp({.state_events = false});
  if (!agg_cp.supervise_health(supervised_config())) {
    state.SkipWithError("bad configuration");
    return;
  }
  supervisor::ComponentDrainLoop sup_cp(reg_cp, agg_cp);
  std::vector<std::unique_ptr<Instrumentation>> cps;
  std::vector<std::pair<CheckpointId, CheckpointId>> ids;
  // Floor: ports full of cycle samples.
  Registry<task::Message> reg_s;
  supervisor::ComponentAggregator agg_s({.state_events = false});
  supervisor::ComponentDrainLoop sup_s(reg_s, agg_s);
  std::vector<std::unique_ptr<Instrumentation>> samples;
  for (int c = 0; c < kComponents; ++c) {
    const std::string n = "c" + std::to_string(c);
    cps.push_back(std::make_unique<Instrumentation>(n, SupervisionOptions{}, reg_cp));
    ids.emplace_back(cps.back()->declare_checkpoint("read"),
                     cps.back()->declare_checkpoint("write"));
    cps.back()->init(ManualInfo{.activity = "bench", .period_ns = kPeriod});
    samples.push_back(std::make_unique<Instrumentation>(n, SupervisionOptions{}, reg_s));
    samples.back()->init(ManualInfo{.activity = "bench", .period_ns = kPeriod});
  }
  (void)sup_cp.step();
  (void)sup_s.step();
  const auto fill = [&] {
    for (int c = 0; c < kComponents; ++c) {
      auto& in = *cps[static_cast<std::size_t>(c)];
      for (int k = 0; k < kPerPort / 2; ++k) {
        in.checkpoint(ids[static_cast<std::size_t>(c)].first);
        in.checkpoint(ids[static_cast<std::size_t>(c)].second);
      }
      auto& s = *samples[static_cast<std::size_t>(c)];
      for (int k = 0; k < kPerPort; ++k) {
        UpdateGuard g(s);
      }
    }
  };
  std::size_t n_cp = 0;
  std::size_t n_s = 0;
  measure_pair(
      state, "ns/checkpoint", 1.0, fill,
      [&] {
        const Nanos t0 = platform::now_ns();
        n_s = sup_s.step();
        return (platform::now_ns() - t0) / static_cast<Nanos>(std::max<std::size_t>(n_s, 1));
      },
      [&] {
        const Nanos t0 = platform::now_ns();
        n_cp = sup_cp.step();
        return (platform::now_ns() - t0) / static_cast<Nanos>(std::max<std::size_t>(n_cp, 1));
      });
  state.counters["messages_per_step"] = static_cast<double>(n_cp);
  const auto r = agg_cp.health_reports();
  state.counters["health_failures"] = static_cast<double>(
      std::count_if(r.begin(), r.end(), [](const auto& x) { return x.failures > 0; }));
}

// --- 4. detection latency after a deadline ------------------------------------------------------

constexpr int kTrials = 1000;
constexpr Nanos kMax = 2 * kNanosPerMilli;

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

struct Latencies {
  std::vector<double> detection;
  std::vector<double> timer;
};

Latencies measure_latencies() {
  Latencies out;
  Registry<task::Message> reg;
  supervisor::ComponentAggregator agg({.state_events = false});
  health::HealthConfig cfg;
  cfg.deadline.push_back({.name = "begin_to_end",
                          .start = {"stage", "begin"},
                          .end = {"stage", "end"},
                          .max_ns = kMax,
                          .failed_tolerance = 1'000'000'000});  // FAILED, raised every time
  (void)agg.supervise_health(cfg);
  supervisor::ComponentDrainLoop sup(reg, agg);  // SCHED_OTHER, the default 10 ms period
  Instrumentation stage("stage", {}, reg);
  const CheckpointId begin = stage.declare_checkpoint("begin");
  stage.init(ManualInfo{.activity = "bench"});
  if (!sup.start()) return out;
  std::mt19937 rng(45);
  std::uniform_int_distribution<Nanos> phase(0, 10 * kNanosPerMilli);
  // The floor: a plain thread of the same policy and priority, woken at absolute times.
  std::atomic<Nanos> target{0};
  std::atomic<Nanos> woke{0};
  std::uint64_t seen = agg.events().last_seq();
  for (int i = 0; i < kTrials; ++i) {
    // A deadline missed at a random phase of the drain period.
    platform::sleep_until(platform::now_ns() + phase(rng));
    stage.checkpoint(begin);
    for (int spins = 0; spins < 1000; ++spins) {
      if (agg.events().wait(seen, 50 * kNanosPerMilli)) break;
    }
    for (const auto& e : agg.events().since(seen)) {
      if (e.kind == supervisor::EventKind::DeadlineSupervision) {
        out.detection.push_back(static_cast<double>(e.latency_ns()));
      }
      seen = e.seq;
    }
    // The timer's trial, at another random phase.
    const Nanos t = platform::now_ns() + kMax + phase(rng) / 10;
    target.store(t);
    std::thread timer([&] {
      platform::sleep_until(target.load());
      woke.store(platform::now_ns());
    });
    timer.join();
    out.timer.push_back(static_cast<double>(woke.load() - t));
  }
  sup.stop();
  return out;
}

const Latencies& latencies() {
  static const Latencies l = measure_latencies();
  return l;
}

void detection_latency(benchmark::State& state, double p) {
  const Latencies& l = latencies();
  for (auto _ : state) {
  }
  if (l.detection.size() < kTrials / 2) {
    state.SkipWithError("not available: too few deadline events");
    return;
  }
  const double value = percentile(l.detection, p) / 1e3;
  const double floor = percentile(l.timer, p) / 1e3;
  report_vs(state, "us", value, floor, floor > 0 ? value / floor : 0);
  state.counters["trials"] = static_cast<double>(l.detection.size());
  if (p == 0.99) state.counters["goal_value_max"] = 1.2 * floor + 100.0;
}

void register_all() {
  auto add = [](const std::string& name, int iterations, auto fn) {
    benchmark::RegisterBenchmark(name.c_str(), fn)
        ->Iterations(iterations)
        ->UseManualTime()
        ->Unit(benchmark::kNanosecond);
  };
  add("health/checkpoint/report", kBatchesPerRep, report_vs_floor);
  add("health/checkpoint/cycle_with_3", kBatchesPerRep,
      [](benchmark::State& s) { cycle_with_3(s, Reports::Now); });
  add("health/checkpoint/cycle_with_3_at_cycle_start", kBatchesPerRep,
      [](benchmark::State& s) { cycle_with_3(s, Reports::CycleTime); });
  add("health/supervisor/per_checkpoint", 20, supervisor_per_checkpoint);
  add("health/detection_latency/p50", 1, [](benchmark::State& s) { detection_latency(s, 0.5); });
  add("health/detection_latency/p90", 1, [](benchmark::State& s) { detection_latency(s, 0.9); });
  add("health/detection_latency/p99", 1, [](benchmark::State& s) { detection_latency(s, 0.99); });
  add("health/detection_latency/max", 1, [](benchmark::State& s) { detection_latency(s, 1.0); });
}

}  // namespace
}  // namespace vigil::bench

int main(int argc, char** argv) {
  vigil::bench::register_all();
  return vigil::bench::run_main(argc, argv);
}
