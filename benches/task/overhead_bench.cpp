// Per-cycle cost of supervision next to its floor, measured in the same repetition.
//
// Subjects: Task<Derived> with an empty on_update() stepped by a ManualActivity (through
// TaskCore's virtual hook, as every activity reaches a task whose type it does not know), for
// each real-time-loss detector setting (goals: none <= 1.2x, allocation <= 1.25x); the same
// stepped by a TypedManualActivity (`typed_activity`: no virtual call, the cycle inlined into the
// caller's loop; the same goals); the same on the TSC clock (vigil/platform/tsc.hpp; goal <= 1.0x,
// against the same vDSO floor; "not available" with the reason where the TSC cannot be used); the
// Instrumentation + UpdateGuard path; and, for scale, the same activity driving an unsupervised
// TaskCore. The floor (bench_support.hpp): two reads of vigil's clock around the same empty call
// and one push of the same Message into the queue type behind every Port, with the same capacity.
//
// Method. The measuring thread is pinned (VIGIL_BENCH_CPU, default 1); one consumer thread,
// pinned to another CPU, pops the floor's queue and the subject's port once every 10 ms (the
// supervisor's default period), and never spins. Each benchmark iteration waits for the next
// poll, then runs a batch of 200 floor cycles and a batch of 200 subject cycles (the order
// alternates), timing each batch with two clock reads; 200 < 256 so no push fails. The
// iteration time reported is the subject's mean cycle time; counters carry the floor's, and
// the ratio subject / floor of the repetition. The "port full" variants do not wait: the
// the queues stay full and every push fails (dropped and counted), the other case users meet.
//
// Against what users pick instead (when built with liblttng-ust-dev): the same empty cycle traced
// with two LTTng-UST tracepoints, a start and an end carrying the cycle number (LTTng timestamps
// every event itself), as a tracing user instruments a loop, under an active session this
// program starts and ends itself (benches/lttng/session.hpp): `lttng_ust_2_tracepoints` against
// the floor, and `supervised_vs_lttng`, the default supervised cycle (Task, no detector) with the
// traced cycle as its reference, in the same iteration (ratio < 1: supervision costs less than
// tracing the loop). When no session can be made the rows say why. VIGIL_BENCH_LTTNG=0 skips them
// without touching LTTng.
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/tsc.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

#ifdef VIGIL_BENCH_LTTNG
#include "lttng/session.hpp"
#include "lttng/vigil_bench_tp.h"
#endif

namespace vigil::bench {
namespace {

constexpr int kBatch = 200;         // cycles per batch: below the port's 256, so nothing drops
constexpr int kBatchesPerRep = 50;  // one per consumer poll: ~0.5 s per repetition
constexpr int kFullBatchesPerRep = 200;
constexpr Nanos kPeriod = kNanosPerMilli;

class EmptyTask : public Task<EmptyTask> {
 public:
  EmptyTask(Registry<task::Message>& registry, SupervisionOptions options)
      : Task("bench_task", options, registry) {}
  void on_update() { empty_update(); }
};

// TaskCore without supervision: what the activity costs by itself.
class BareTask : public TaskCore {
 public:
  BareTask() : TaskCore("bare_task") {}

 protected:
  void update_hook() override { empty_update(); }
};

template <class Activity>
struct BasicTaskSubject {
  BasicTaskSubject(Detectors d, Nanos period)
      : task(registry, SupervisionOptions{.detectors = d}),
        activity(task, ManualConfig{.name = "bench", .period_ns = period}) {
    (void)task.configure();
    (void)activity.start();
  }
  ~BasicTaskSubject() { (void)activity.stop(); }
  [[gnu::noinline]] void cycle() noexcept { (void)activity.step(); }
  Poller::Drain drain() {
    return [p = task.port()](task::Message* out, std::size_t n) { return p->pop(out, n); };
  }
  std::uint64_t dropped() const { return task.port()->dropped(); }

  Registry<task::Message> registry;
  EmptyTask task;
  Activity activity;
};
// Through TaskCore's virtual hook, as every activity reaches a task it does not know the type of.
using TaskSubject = BasicTaskSubject<ManualActivity>;
// Through TypedManualActivity: the cycle inlined into the caller's loop, no virtual call.
using TypedTaskSubject = BasicTaskSubject<TypedManualActivity<EmptyTask>>;

// The same Task on the TSC clock (vigil/platform/tsc.hpp), selected for the process while the
// subject lives; the floor keeps reading CLOCK_MONOTONIC (the vDSO), as before.
struct TscTaskSubject {
  explicit TscTaskSubject(Detectors d) : selection(select()), inner(d, kPeriod) {}
  ~TscTaskSubject() { (void)platform::select_clock(platform::ClockSource::Monotonic); }
  static platform::ClockSelection select() {
    return platform::select_clock(platform::ClockSource::Tsc);
  }
  [[gnu::noinline]] void cycle() noexcept { inner.cycle(); }
  Poller::Drain drain() { return inner.drain(); }
  std::uint64_t dropped() const { return inner.dropped(); }

  platform::ClockSelection selection;
  TaskSubject inner;
};

struct BareSubject {
  BareSubject() : activity(task, ManualConfig{.name = "bench", .period_ns = kPeriod}) {
    (void)task.configure();
    (void)activity.start();
  }
  ~BareSubject() { (void)activity.stop(); }
  [[gnu::noinline]] void cycle() noexcept { (void)activity.step(); }
  Poller::Drain drain() {
    return [](task::Message*, std::size_t) { return std::size_t{0}; };
  }
  std::uint64_t dropped() const { return 0; }

  BareTask task;
  ManualActivity activity;
};

struct GuardSubject {
  GuardSubject() : sup("bench_guard", {}, registry) {
    sup.init(ManualInfo{.activity = "bench", .period_ns = kPeriod});
  }
  [[gnu::noinline]] void cycle() noexcept {
    UpdateGuard guard(sup);
    empty_update();
  }
  Poller::Drain drain() {
    return [p = sup.port()](task::Message* out, std::size_t n) { return p->pop(out, n); };
  }
  std::uint64_t dropped() const { return sup.port()->dropped(); }

  Registry<task::Message> registry;
  Instrumentation sup;
};

#ifdef VIGIL_BENCH_LTTNG
LttngSession& lttng_session() {
  static LttngSession session;
  return session;
}
bool lttng_wanted() {
  const char* v = std::getenv("VIGIL_BENCH_LTTNG");
  return v == nullptr || std::string(v) != "0";
}

// The cycle a tracing user writes: a tracepoint at the start and one at the end of the body.
struct LttngSubject {
  [[gnu::noinline]] void cycle() noexcept {
    const unsigned long c = ++cycles;
    lttng_ust_tracepoint(vigil_bench, cycle_start, c);
    empty_update();
    lttng_ust_tracepoint(vigil_bench, cycle_end, c);
  }
  Poller::Drain drain() {
    return [](task::Message*, std::size_t) { return std::size_t{0}; };
  }
  std::uint64_t dropped() const { return 0; }
  unsigned long cycles = 0;
};
#endif

template <class S>
Nanos run_batch(S& s) {
  const Nanos t0 = platform::now_ns();
  for (int i = 0; i < kBatch; ++i) s.cycle();
  return platform::now_ns() - t0;
}

template <class S>
void fill_port(S& s) {
  for (int i = 0; i < static_cast<int>(kDefaultPortCapacity) + 8; ++i) s.cycle();
}

// Times `Subject` against `Reference` (the floor unless said otherwise) in alternating batches.
template <class Reference, class Subject, class... Args>
void paired_with(benchmark::State& state, bool full, double goal_ratio_max, Args... args) {
  Reference floor;
  Subject subject(args...);
  Poller poller({floor.drain(), subject.drain()});

  // Warm-up: touch both rings and every code path, outside the measurement.
  for (int i = 0; i < 3; ++i) {
    poller.wait_next_poll();
    (void)run_batch(floor);
    (void)run_batch(subject);
  }

  std::vector<double> floor_ns;
  std::vector<double> subject_ns;
  std::vector<double> ratios;
  std::uint64_t drops = 0;
  auto time_subject = [&] {
    const std::uint64_t d0 = subject.dropped();
    const Nanos t = run_batch(subject);
    drops += subject.dropped() - d0;
    return t;
  };
  bool subject_first = false;
  for (auto _ : state) {
    if (full) {
      fill_port(floor);  // untimed: from here on every push fails
      fill_port(subject);
    } else {
      poller.wait_next_poll();  // both queues are empty: every push succeeds
    }
    Nanos tf = 0;
    Nanos ts = 0;
    if (subject_first) {
      ts = time_subject();
      tf = run_batch(floor);
    } else {
      tf = run_batch(floor);
      ts = time_subject();
    }
    subject_first = !subject_first;
    floor_ns.push_back(static_cast<double>(tf) / kBatch);
    subject_ns.push_back(static_cast<double>(ts) / kBatch);
    ratios.push_back(static_cast<double>(ts) / static_cast<double>(tf));
    state.SetIterationTime(static_cast<double>(ts) * 1e-9 / kBatch);
  }
  const auto cycles = static_cast<double>(subject_ns.size()) * kBatch;
  // Medians over the batches of this repetition: a batch the scheduler interrupted (the
  // machine is shared) moves a mean, not a median.
  report_vs(state, "ns/cycle", median(subject_ns), median(floor_ns), median(ratios));
  if (goal_ratio_max > 0) state.counters["goal_ratio_max"] = goal_ratio_max;
  // Of the timed cycles: 0 in the normal variants, about 1 in the port-full ones.
  state.counters["dropped_per_cycle"] = static_cast<double>(drops) / cycles;
}

template <class Subject, class... Args>
void paired(benchmark::State& state, bool full, double goal_ratio_max, Args... args) {
  paired_with<Floor, Subject>(state, full, goal_ratio_max, args...);
}

void register_all() {
  struct Setting {
    const char* name;
    Detectors detectors;
    double goal;
  };
  const std::array<Setting, 5> settings{{
      {"none", Detectors::None, 1.2},
      {"allocation", Detectors::Allocation, 1.25},
      {"blocking", Detectors::Blocking, 0},
      {"page_faults", Detectors::PageFaults, 0},
      {"all", Detectors::All, 0},
  }};
  auto add = [](const std::string& name, int batches, auto fn) {
    benchmark::RegisterBenchmark(name.c_str(), fn)
        ->Iterations(batches)
        ->UseManualTime()
        ->Unit(benchmark::kNanosecond);
  };
  for (const auto& s : settings) {
    add(std::string("task/overhead/detectors:") + s.name, kBatchesPerRep,
        [s](benchmark::State& st) {
          paired<TaskSubject>(st, false, s.goal, s.detectors, kPeriod);
        });
  }
  // With the TSC clock: goal <= 1.0, the supervised cycle at most the vDSO floor.
  for (const auto& s : {settings[0], settings[1]}) {
    add(std::string("task/overhead/tsc_clock/detectors:") + s.name, kBatchesPerRep,
        [s](benchmark::State& st) {
          const platform::TscSupport support = platform::tsc_support();
          if (!support.usable) {
            const std::string why = "not available: TSC clock: " + support.reason;
            st.SkipWithError(why.c_str());
            return;
          }
          paired<TscTaskSubject>(st, false, s.detectors == Detectors::None ? 1.0 : 0, s.detectors);
        });
  }
  for (const auto& s : {settings[0], settings[1]}) {
    add(std::string("task/overhead/typed_activity/detectors:") + s.name, kBatchesPerRep,
        [s](benchmark::State& st) {
          paired<TypedTaskSubject>(st, false, s.goal, s.detectors, kPeriod);
        });
  }
  add("task/overhead/detectors:none/not_periodic", kBatchesPerRep,
      [](benchmark::State& st) { paired<TaskSubject>(st, false, 1.2, Detectors::None, Nanos{0}); });
  add("task/overhead/update_guard", kBatchesPerRep,
      [](benchmark::State& st) { paired<GuardSubject>(st, false, 1.5); });
  add("task/overhead/unsupervised_activity", kBatchesPerRep,
      [](benchmark::State& st) { paired<BareSubject>(st, false, 0); });
  add("task/overhead/experiment:floor_with_128B_message", kBatchesPerRep,
      [](benchmark::State& st) { paired<Floor128>(st, false, 0); });
  add("task/overhead/detectors:none/port_full", kFullBatchesPerRep,
      [](benchmark::State& st) { paired<TaskSubject>(st, true, 0, Detectors::None, kPeriod); });
  add("task/overhead/update_guard/port_full", kFullBatchesPerRep,
      [](benchmark::State& st) { paired<GuardSubject>(st, true, 0); });

  // Against LTTng-UST. The second row's value is the supervised cycle and its reference column
  // the traced one; goal: supervision costs no more than tracing the loop.
#ifdef VIGIL_BENCH_LTTNG
  auto lttng_or_skip = [](benchmark::State& st) {
    if (lttng_session().active()) return true;
    const std::string why = "not available: LTTng session: " + lttng_session().why();
    st.SkipWithError(why.c_str());
    return false;
  };
  add("task/overhead/lttng_ust_2_tracepoints", kBatchesPerRep, [=](benchmark::State& st) {
    if (lttng_or_skip(st)) paired<LttngSubject>(st, false, 0);
  });
  add("task/overhead/supervised_vs_lttng", kBatchesPerRep, [=](benchmark::State& st) {
    if (lttng_or_skip(st)) {
      paired_with<LttngSubject, TaskSubject>(st, false, 1.0, Detectors::None, kPeriod);
    }
  });
#else
  auto skip = [](benchmark::State& st) {
    st.SkipWithError("not available: built without liblttng-ust-dev (scripts/setup.sh)");
  };
  add("task/overhead/lttng_ust_2_tracepoints", kBatchesPerRep, skip);
  add("task/overhead/supervised_vs_lttng", kBatchesPerRep, skip);
#endif
}

}  // namespace
}  // namespace vigil::bench

int main(int argc, char** argv) {
  benchmark::AddCustomContext("vigil.alloc_guard", vigil::platform::allocation_counting_available()
                                                       ? "linked"
                                                       : "not linked");
  vigil::bench::register_all();
#ifdef VIGIL_BENCH_LTTNG
  using vigil::bench::lttng_session;
  auto before = [] {
    // Before the thread is pinned and made FIFO: a session daemon started here inherits neither.
    if (!vigil::bench::lttng_wanted()) {
      benchmark::AddCustomContext("vigil.lttng", "not available: VIGIL_BENCH_LTTNG=0");
      return;
    }
    (void)lttng_session().begin([] {
      return lttng_ust_tracepoint_enabled(vigil_bench, cycle_start) &&
             lttng_ust_tracepoint_enabled(vigil_bench, cycle_end);
    });
    benchmark::AddCustomContext("vigil.lttng", lttng_session().describe());
  };
  auto after = [] {
    const std::string said = lttng_session().end();
    if (!said.empty()) std::fprintf(stderr, "lttng stop: %s\n", said.c_str());
  };
  return vigil::bench::run_main(argc, argv, before, after);
#else
  return vigil::bench::run_main(argc, argv);
#endif
}
