// Supervision across processes: what a shared-memory port costs a component per cycle, what the
// `vigil supervise` daemon costs for 100 processes x 10 components at 1 kHz, and how long it takes
// from a SIGKILL to the ERROR report.
//
// overhead: Task<Derived> with an empty on_update() stepped by a ManualActivity, its port in
// shared memory (subject) against the same Task with the in-process port (floor), measured in
// the same repetition as benches/task/overhead_bench.cpp does it: a consumer thread polls both
// every 10 ms (ShmReader::pop for the segment, Port::pop for the in-process port); each iteration
// waits for the next poll, then times a batch of 200 cycles of each (order alternating). Value:
// the shared-memory Task's median ns/cycle; ratio: shm / in-process (goal <= 1.05).
// overhead_cold: the same, one cycle at a time after a 1 ms sleep each (cold caches, as at 1 kHz);
// no goal, it says what a real component's overhead samples show.
//
// daemon_cpu: 100 forked processes with 10 segments each; every 10 ms each process pushes 10
// CycleSamples into each of its segments (what a 1 kHz component queues between two drains; the
// producers wake at 100 Hz to keep the machine usable, the daemon's work is the same). The daemon
// (the `vigil supervise` pipeline started: drain thread at 10 ms + monitor at 1 s) runs in this
// process, which does nothing else; value = this process's CPU time / wall time over 3 s, in % of
// one core. VIGIL_BENCH_DAEMON_SECONDS=N measures N s instead of 3 (to attach a profiler to the
// steady state: `perf record -g -p <pid> -- sleep 5`).
//
// daemon_vs_in_process: the daemon's CPU per message against the in-process supervisor's, in the
// same run, for the same components and messages (processes x components segments or ports, 10
// samples each every 10 ms: 1,000 components at 1 kHz). Each iteration measures both, 3 s each,
// order alternating, each a fresh SupervisionService (drain thread, monitor at 1 s, event hub):
// the daemon over the forked children's segments (the children stopped with SIGSTOP while the
// other phase runs), and one over this process's registry of as many ports, filled by a producer
// thread of this process whose CPU time is subtracted. Value: the daemon's CPU ns per message;
// floor: the in-process supervisor's; ratio: daemon / in-process, median of the iterations
// (goal <= 1.25, issue 49). processes:10/components:100 shows what the number of processes
// costs. VIGIL_BENCH_CHILDREN_RUN=1 keeps the children running during the in-process phase.
//
// drain_checks: the daemon's per-segment work on one segment, without the aggregator: the writer
// pushes 10 CycleSamples (what a 1 kHz component queues between two 10 ms drains), then the reader
// reads the state fields (live(): the index and counter checks of issue 49), pops the 10 records
// checking each (sequence, type, size, check_shm_message) and writes its heartbeat. Value: ns per
// drain (the pushes excluded). header_verify: one re-verification of a segment's header (the 768
// bytes copied, the constant part compared and hashed), done every 100 ms and at every report.
//
// sigkill_to_error: one forked process with a Task at 1 kHz; the daemon's thread runs; the
// process is killed with SIGKILL (and reaped at once, as a shell would); value = time from the
// kill() call to the daemon's Exited event, which it emits after building the ERROR reports.
// Goal: <= 2 supervisor periods (20 ms). 100 kills per repetition; p50, p99 and max reported.
#include <pthread.h>
#include <signal.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_session.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/task/default_registry.hpp"
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/task.hpp"

namespace vigil::bench {
namespace {

constexpr int kBatch = 200;
constexpr int kBatchesPerRep = 50;

std::string bench_name(const char* what) {
  return std::string("b") + std::to_string(::getpid()) + what;
}

void remove_segments(const std::string& name) {
  for (const auto& s : platform::list_shared_memory(bus::shm_segment_prefix(name))) {
    (void)platform::unlink_shared_memory(s);
  }
}

class EmptyTask : public Task<EmptyTask> {
 public:
  explicit EmptyTask(Registry<task::Message>& registry) : Task("bench_task", {}, registry) {}
  void on_update() { empty_update(); }
};

// One Task and how the consumer drains it: in-process, or through a segment.
struct TaskSubject {
  explicit TaskSubject(const std::string& shm) : shm_name(shm) {
    if (!shm.empty()) {
      bus::ShmOptions o;
      o.name = shm;
      if (!place_in_shared_memory(registry, o)) std::abort();
    }
    task = std::make_unique<EmptyTask>(registry);
    activity = std::make_unique<ManualActivity>(
        *task, ManualConfig{.name = "bench", .period_ns = kNanosPerMilli});
    (void)task->configure();
    (void)activity->start();
    if (!shm.empty()) {
      auto r = bus::ShmReader<task::Message>::open(bus::shm_segment_name(shm, ::getpid(), 0),
                                                   {task::kShmMessageSchema, shm},
                                                   platform::effective_uid(), false);
      if (!r) std::abort();
      reader.emplace(std::move(*r));
    }
  }
  ~TaskSubject() {
    (void)activity->stop();
    activity.reset();
    task.reset();
    reader.reset();
    remove_segments(shm_name);
  }
  [[gnu::noinline]] void cycle() noexcept { (void)activity->step(); }
  Poller::Drain drain() {
    if (reader) {
      return [this](task::Message* out, std::size_t n) {
        auto k = reader->pop(out, nullptr, n, nullptr);
        return k ? *k : std::size_t{0};
      };
    }
    return [p = task->port()](task::Message* out, std::size_t n) { return p->pop(out, n); };
  }

  std::string shm_name;
  Registry<task::Message> registry;
  std::unique_ptr<EmptyTask> task;
  std::unique_ptr<ManualActivity> activity;
  std::optional<bus::ShmReader<task::Message>> reader;
};

template <class S>
Nanos run_batch(S& s) {
  const Nanos t0 = platform::now_ns();
  for (int i = 0; i < kBatch; ++i) s.cycle();
  return platform::now_ns() - t0;
}

void overhead(benchmark::State& state) {
  TaskSubject floor("");
  TaskSubject subject(bench_name("o"));
  Poller poller({floor.drain(), subject.drain()});
  for (int i = 0; i < 3; ++i) {
    poller.wait_next_poll();
    (void)run_batch(floor);
    (void)run_batch(subject);
  }
  measure_pair(
      state, "ns/cycle", kBatch, [&] { poller.wait_next_poll(); }, [&] { return run_batch(floor); },
      [&] { return run_batch(subject); });
  state.counters["goal_ratio_max"] = 1.05;
  state.counters["dropped"] = static_cast<double>(subject.task->port()->dropped());
}

// The same pair one cycle at a time, each after a 1 ms sleep: what a 1 kHz component meets (its
// caches and TLB entries cooled down while it slept), and what the overhead samples of a real
// component report (the multi-process example's ~300 ns, against ~75 ns for hot batches).
void overhead_cold(benchmark::State& state) {
  TaskSubject floor("");
  TaskSubject subject(bench_name("c"));
  Poller poller({floor.drain(), subject.drain()});
  auto one = [](TaskSubject& s) {
    platform::sleep_until(platform::now_ns() + kNanosPerMilli);
    const Nanos t0 = platform::now_ns();
    s.cycle();
    return platform::now_ns() - t0;
  };
  for (int i = 0; i < 20; ++i) {
    (void)one(floor);
    (void)one(subject);
  }
  measure_pair(
      state, "ns/cycle", 1.0, [&] {}, [&] { return one(floor); }, [&] { return one(subject); });
  state.counters["dropped"] = static_cast<double>(subject.task->port()->dropped());
}

// A forked child runs on any CPU (the measuring thread it was forked from is pinned).
void unpin() {
  cpu_set_t all;
  CPU_ZERO(&all);
  for (int i = 0; i < CPU_SETSIZE; ++i) CPU_SET(i, &all);
  (void)sched_setaffinity(0, sizeof all, &all);
}

// --- forked producers --------------------------------------------------------------------------

struct Children {
  std::vector<pid_t> pids;
  ~Children() { kill_all(); }
  void kill_all() {
    for (pid_t p : pids) ::kill(p, SIGKILL);
    for (pid_t p : pids) ::waitpid(p, nullptr, 0);
    pids.clear();
  }
};

// A child: `components` segments, 10 samples into each every 10 ms, until killed.
[[noreturn]] void producer_child(const std::string& name, int components, int ready_fd) {
  unpin();
  bus::ShmOptions o;
  o.name = name;
  o.sticky_types = task::kShmStickyMessages;
  auto session = bus::ShmSession::open(o, task::kShmMessageSchema);
  if (!session) ::_exit(2);
  std::vector<std::unique_ptr<bus::ShmPort<task::Message>>> ports;
  for (int c = 0; c < components; ++c) {
    auto seg = (*session)->create("p" + std::to_string(::getpid()) + ".c" + std::to_string(c), 256);
    if (!seg) ::_exit(3);
    ports.push_back(
        std::make_unique<bus::ShmPort<task::Message>>(std::move(*seg), task::kShmStickyMessages));
    task::TaskInfo info;
    info.name.assign("c" + std::to_string(c));
    info.period_ns = kNanosPerMilli;
    info.threaded = true;
    (void)ports.back()->producer().push(task::Message{info});
  }
  const char c = 'r';
  (void)!::write(ready_fd, &c, 1);
  std::uint64_t cycle = 0;
  Nanos next = platform::now_ns();
  std::vector<std::uint64_t> dropped(ports.size(), 0);  // each port counts its own drops
  for (;;) {
    next += 10 * kNanosPerMilli;
    platform::sleep_until(next);
    const Nanos now = platform::now_ns();
    // Continued after a stop (daemon_vs_in_process stops the children while the in-process
    // supervisor is measured): resume the 10 ms rhythm from now, not a burst of missed rounds.
    if (now - next > 10 * kNanosPerMilli) next = now;
    for (int k = 0; k < 10; ++k) {
      ++cycle;
      for (std::size_t i = 0; i < ports.size(); ++i) {
        auto& p = ports[i];
        task::CycleSample s;
        s.counters.cycles = cycle;
        s.release_ns = now - (10 - k) * kNanosPerMilli;
        s.start_ns = s.release_ns + 2'000;
        s.end_ns = s.start_ns + 20'000 + static_cast<Nanos>(cycle % 13) * 1'000;
        s.overhead_ns = cycle % 64 == 1 ? 150 : 0;
        s.state = TaskState::Running;
        const task::Message m{s};
        if (!p->producer().push(m)) p->producer().drop(m, ++dropped[i]);
      }
    }
  }
}

Nanos process_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

// The `vigil supervise` pipeline for `name`, not started (thread stats not read: the benchmark
// measures the daemon, not /proc).
std::unique_ptr<service::SupervisionService> make_daemon(const std::string& name) {
  service::SupervisionServiceOptions o;
  o.segments = service::SegmentSourceOptions{.name = name};
  o.monitor.read_thread_stats = false;
  o.summary_file = nullptr;
  return std::make_unique<service::SupervisionService>(std::move(o));
}

void daemon_cpu(benchmark::State& state) {
  const int processes = static_cast<int>(state.range(0));
  const int components = static_cast<int>(state.range(1));
  const std::string name = bench_name("d");
  remove_segments(name);
  Children children;
  int fds[2];
  if (::pipe(fds) != 0) std::abort();
  for (int i = 0; i < processes; ++i) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::close(fds[0]);
      producer_child(name, components, fds[1]);
    }
    children.pids.push_back(pid);
  }
  ::close(fds[1]);
  for (int i = 0; i < processes; ++i) {
    char c = 0;
    if (::read(fds[0], &c, 1) != 1) std::abort();
  }
  ::close(fds[0]);

  auto d = make_daemon(name);
  const Nanos period_ns = d->options().supervisor_period_ns;
  int shown = 0;
  const std::uint64_t sub = d->events().subscribe([&](const Event& e) {
    if (e.kind == EventKind::SegmentRejected && shown++ < 3) {
      std::fprintf(stderr, "daemon_cpu: %s\n", e.detail.c_str());
    }
  });
  if (!d->start()) std::abort();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // discovery, first monitor cycle
  // VIGIL_BENCH_DAEMON_SECONDS: a longer window, to attach a profiler to the steady state.
  const char* env_seconds = std::getenv("VIGIL_BENCH_DAEMON_SECONDS");
  const int seconds = env_seconds != nullptr ? std::max(1, std::atoi(env_seconds)) : 3;
  std::vector<double> shares;
  for (auto _ : state) {
    const Nanos c0 = process_cpu_ns();
    const Nanos t0 = platform::now_ns();
    std::this_thread::sleep_for(std::chrono::seconds(seconds));
    const double share = 100.0 * static_cast<double>(process_cpu_ns() - c0) /
                         static_cast<double>(platform::now_ns() - t0);
    shares.push_back(share);
    state.SetIterationTime(static_cast<double>(seconds));
  }
  const auto st = d->segments()->stats();
  (void)d->stop();
  d->events().unsubscribe(sub);
  children.kill_all();
  // The deaths of all 100 processes at once (a robot's stack that crashes): drained, judged
  // (ERROR reports of their 1,000 components) and reclaimed in one cycle.
  const Nanos deaths_t0 = platform::now_ns();
  (void)d->segments()->step();
  const Nanos deaths_ns = platform::now_ns() - deaths_t0;
  const auto after = d->segments()->stats();
  d.reset();
  remove_segments(name);
  report(state, "% of a core", median(shares));
  state.counters["segments"] = static_cast<double>(st.segments);
  state.counters["processes"] = static_cast<double>(st.processes);
  state.counters["dead_processes"] = static_cast<double>(st.dead_processes);
  state.counters["rejected"] = static_cast<double>(st.rejected);
  state.counters["msg_per_s"] =
      static_cast<double>(st.messages) /
      (static_cast<double>(st.cycles) * static_cast<double>(period_ns) / 1e9);
  state.counters["cycle_ns_p50"] = static_cast<double>(st.cycle_ns.p50);
  state.counters["deaths_step_ms"] = static_cast<double>(deaths_ns) / 1e6;
  state.counters["deaths_seen"] = static_cast<double>(after.dead_processes);
  state.counters["goal_value_max"] = 10.0;
}

// --- the daemon against the in-process supervisor ----------------------------------------------

// 1,000 in-process ports of a Task's capacity and a thread that pushes into them what the children
// push into their segments: 10 CycleSamples per port every 10 ms, while `active` (first each
// port's TaskInfo, as a joining Task sends it).
class InProcessLoad {
 public:
  explicit InProcessLoad(int n) {
    members_.reserve(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      members_.push_back(registry_.join<kDefaultPortCapacity>("c" + std::to_string(i)));
    }
    thread_ = std::thread([this] { run(); });
  }
  ~InProcessLoad() {
    quit_.store(true, std::memory_order_release);
    thread_.join();
  }
  InProcessLoad(const InProcessLoad&) = delete;
  InProcessLoad& operator=(const InProcessLoad&) = delete;

  void set_active(bool on) { active_.store(on, std::memory_order_release); }
  /// CPU time of the producer thread: not the supervisor's, subtracted from the process's.
  Nanos cpu_ns() {
    clockid_t id{};
    if (pthread_getcpuclockid(thread_.native_handle(), &id) != 0) return 0;
    timespec ts{};
    clock_gettime(id, &ts);
    return static_cast<Nanos>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
  }
  ComponentRegistry& registry() { return registry_; }
  [[nodiscard]] std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  void run() {
    std::uint64_t cycle = 0;
    bool was_active = false;
    Nanos next = platform::now_ns();
    while (!quit_.load(std::memory_order_acquire)) {
      next += 10 * kNanosPerMilli;
      platform::sleep_until(next);
      const Nanos now = platform::now_ns();
      if (now - next > 10 * kNanosPerMilli) next = now;
      const bool active = active_.load(std::memory_order_acquire);
      if (active && !was_active) {
        for (std::size_t i = 0; i < members_.size(); ++i) {
          task::TaskInfo info;
          info.name.assign("c" + std::to_string(i));
          info.period_ns = kNanosPerMilli;
          info.threaded = true;
          (void)members_[i].port()->try_push(task::Message{info});
        }
      }
      was_active = active;
      if (!active) continue;
      for (int k = 0; k < 10; ++k) {
        ++cycle;
        for (auto& m : members_) {
          task::CycleSample s;
          s.counters.cycles = cycle;
          s.release_ns = now - (10 - k) * kNanosPerMilli;
          s.start_ns = s.release_ns + 2'000;
          s.end_ns = s.start_ns + 20'000 + static_cast<Nanos>(cycle % 13) * 1'000;
          s.overhead_ns = cycle % 64 == 1 ? 150 : 0;
          s.state = TaskState::Running;
          if (!m.port()->try_push(task::Message{s}))
            dropped_.fetch_add(1, std::memory_order_relaxed);
        }
      }
    }
  }

  ComponentRegistry registry_;
  std::vector<bus::Membership<task::Message, kDefaultPortCapacity>> members_;
  std::atomic<bool> active_{false};
  std::atomic<bool> quit_{false};
  std::atomic<std::uint64_t> dropped_{0};
  std::thread thread_;
};

struct Phase {
  double cpu_ns = 0;  // the supervisor's threads
  double wall_ns = 0;
  double messages = 0;  // visited
};

// Starts `s`, lets it find its components and run its first monitor cycle (1.5 s), then measures
// 3 s: this process's CPU time minus `other_cpu` (a producer thread of this process), and the
// messages visited (`messages()`).
template <class Messages, class OtherCpu>
Phase measure_service(service::SupervisionService& s, Messages messages, OtherCpu other_cpu) {
  if (!s.start()) std::abort();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const Nanos c0 = process_cpu_ns() - other_cpu();
  const std::uint64_t m0 = messages();
  const Nanos t0 = platform::now_ns();
  std::this_thread::sleep_for(std::chrono::seconds(3));
  const Nanos c1 = process_cpu_ns() - other_cpu();
  const std::uint64_t m1 = messages();
  const Nanos t1 = platform::now_ns();
  (void)s.stop();
  return Phase{static_cast<double>(c1 - c0), static_cast<double>(t1 - t0),
               static_cast<double>(m1 - m0)};
}

// The `vigil supervise` daemon (its whole process: drain thread, monitor, event hub) against the
// in-process supervisor (a SupervisionService over this process's registry, the same threads),
// for the same components and messages, in the same run: per iteration one 3 s phase of each
// (order alternating), each service fresh; the children are stopped (SIGSTOP) while the
// in-process one runs and its producer thread idles while the daemon runs, so that each phase has
// the machine to itself but for its own producers. Value: the daemon's CPU ns per message; floor:
// the in-process supervisor's; ratio: daemon / in-process (median of the iterations' ratios).
void daemon_vs_in_process(benchmark::State& state) {
  const int processes = static_cast<int>(state.range(0));
  const int components = static_cast<int>(state.range(1));
  const std::string name = bench_name("v");
  remove_segments(name);
  Children children;
  int fds[2];
  if (::pipe(fds) != 0) std::abort();
  for (int i = 0; i < processes; ++i) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::close(fds[0]);
      producer_child(name, components, fds[1]);
    }
    children.pids.push_back(pid);
  }
  ::close(fds[1]);
  for (int i = 0; i < processes; ++i) {
    char c = 0;
    if (::read(fds[0], &c, 1) != 1) std::abort();
  }
  ::close(fds[0]);
  auto signal_children = [&](int sig) {
    for (pid_t p : children.pids) ::kill(p, sig);
  };
  signal_children(SIGSTOP);
  InProcessLoad load(processes * components);

  auto daemon_phase = [&] {
    signal_children(SIGCONT);
    auto d = make_daemon(name);
    const Phase p = measure_service(
        *d, [&] { return d->segments()->stats().messages; }, [] { return Nanos{0}; });
    d.reset();
    signal_children(SIGSTOP);
    return p;
  };
  // VIGIL_BENCH_CHILDREN_RUN=1: the children keep running (into full rings) while the in-process
  // supervisor is measured: the machine as busy with processes as in the daemon's phase.
  const bool children_run = std::getenv("VIGIL_BENCH_CHILDREN_RUN") != nullptr;
  auto in_process_phase = [&] {
    if (children_run) signal_children(SIGCONT);
    load.set_active(true);
    service::SupervisionServiceOptions o;
    o.registry = &load.registry();
    o.monitor.read_thread_stats = false;
    o.summary_file = nullptr;
    service::SupervisionService s(std::move(o));
    const Phase p = measure_service(
        s, [&] { return s.supervisor()->stats().messages; }, [&] { return load.cpu_ns(); });
    load.set_active(false);
    if (children_run) signal_children(SIGSTOP);
    return p;
  };

  std::vector<double> daemon_ns;
  std::vector<double> in_process_ns;
  std::vector<double> ratios;
  std::vector<double> daemon_share;
  std::vector<double> in_process_share;
  std::vector<double> daemon_rate;
  std::vector<double> in_process_rate;
  bool daemon_first = true;
  for (auto _ : state) {
    Phase d;
    Phase in;
    if (daemon_first) {
      d = daemon_phase();
      in = in_process_phase();
    } else {
      in = in_process_phase();
      d = daemon_phase();
    }
    daemon_first = !daemon_first;
    const double dn = d.cpu_ns / std::max(d.messages, 1.0);
    const double in_ns = in.cpu_ns / std::max(in.messages, 1.0);
    daemon_ns.push_back(dn);
    in_process_ns.push_back(in_ns);
    ratios.push_back(dn / in_ns);
    daemon_share.push_back(100.0 * d.cpu_ns / d.wall_ns);
    in_process_share.push_back(100.0 * in.cpu_ns / in.wall_ns);
    daemon_rate.push_back(d.messages * 1e9 / d.wall_ns);
    in_process_rate.push_back(in.messages * 1e9 / in.wall_ns);
    state.SetIterationTime((d.wall_ns + in.wall_ns) * 1e-9);
  }
  children.kill_all();
  remove_segments(name);
  report_vs(state, "ns/msg", median(daemon_ns), median(in_process_ns), median(ratios));
  state.counters["daemon_share"] = median(daemon_share);
  state.counters["in_process_share"] = median(in_process_share);
  state.counters["daemon_msg_per_s"] = median(daemon_rate);
  state.counters["in_process_msg_per_s"] = median(in_process_rate);
  state.counters["in_process_dropped"] = static_cast<double>(load.dropped());
  state.counters["goal_ratio_max"] = 1.25;
}

// --- SIGKILL to ERROR ----------------------------------------------------------------------------

class Spin : public Task<Spin> {
 public:
  explicit Spin(Registry<task::Message>& r) : Task("victim", {}, r) {}
  void on_update() { empty_update(); }
};

[[noreturn]] void victim_child(const std::string& name, int ready_fd) {
  unpin();
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = name;
  if (!place_in_shared_memory(reg, o)) ::_exit(2);
  Spin t(reg);
  t.configure();
  PeriodicActivity act(t, {.name = "victim", .period_ns = kNanosPerMilli});
  if (!act.start()) ::_exit(3);
  while (t.cycles() < 10) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const char c = 'r';
  (void)!::write(ready_fd, &c, 1);
  for (;;) ::pause();
}

void sigkill_to_error(benchmark::State& state) {
  const std::string name = bench_name("k");
  remove_segments(name);
  auto d = make_daemon(name);
  const Nanos period_ns = d->options().supervisor_period_ns;
  std::mutex m;
  std::condition_variable cv;
  std::optional<Nanos> exited_at;
  std::string message;
  std::size_t joined = 0;
  const std::uint64_t sub = d->events().subscribe([&](const Event& e) {
    const Nanos t = platform::now_ns();
    std::lock_guard lock(m);
    if (e.kind == EventKind::ProcessExited) {
      exited_at = t;
      message = e.detail;
    }
    if (e.kind == EventKind::Joined) ++joined;
    if (e.kind == EventKind::SegmentRejected) {
      std::fprintf(stderr, "sigkill_to_error: %s\n", e.detail.c_str());
    }
    cv.notify_all();
  });
  if (!d->start()) std::abort();
  std::vector<double> latencies;
  int timeouts = 0;
  for (auto _ : state) {
    int fds[2];
    if (::pipe(fds) != 0) std::abort();
    const std::size_t before = joined;
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::close(fds[0]);
      victim_child(name, fds[1]);
    }
    ::close(fds[1]);
    char c = 0;
    if (::read(fds[0], &c, 1) != 1) std::abort();
    ::close(fds[0]);
    {
      std::unique_lock lock(m);
      cv.wait_for(lock, std::chrono::seconds(5), [&] { return joined > before; });
      exited_at.reset();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(30));  // a few drains
    const Nanos t0 = platform::now_ns();
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    Nanos t1 = 0;
    {
      std::unique_lock lock(m);
      cv.wait_for(lock, std::chrono::seconds(5), [&] { return exited_at.has_value(); });
      t1 = exited_at.value_or(t0 + 5 * kNanosPerSecond);
    }
    if (t1 - t0 >= 5 * kNanosPerSecond) {
      const auto st = d->segments()->stats();
      std::fprintf(stderr,
                   "sigkill_to_error: no Exited event for pid %d within 5 s (processes %zu, "
                   "dead %zu, segments %zu, rejected %llu)\n",
                   static_cast<int>(pid), st.processes, st.dead_processes, st.segments,
                   static_cast<unsigned long long>(st.rejected));
      ++timeouts;
    }
    latencies.push_back(static_cast<double>(t1 - t0) / 1e6);
    state.SetIterationTime(static_cast<double>(t1 - t0) * 1e-9);
  }
  (void)d->stop();
  d->events().unsubscribe(sub);
  d.reset();
  remove_segments(name);
  std::sort(latencies.begin(), latencies.end());
  report(state, "ms", median(latencies));
  state.counters["p99_ms"] =
      latencies.empty() ? 0.0 : latencies[(latencies.size() * 99 + 99) / 100 - 1];
  state.counters["max_ms"] = latencies.empty() ? 0.0 : latencies.back();
  state.counters["timeouts"] = timeouts;
  state.counters["goal_value_max"] = 2 * static_cast<double>(period_ns) / 1e6;
  benchmark::DoNotOptimize(message.data());
}

// One segment of this process, its producer and the daemon's reader.
struct DrainSubject {
  DrainSubject() : name(bench_name("d")) {
    auto session = bus::ShmSession::open(bus::ShmOptions{name, "", 0, {}}, task::kShmMessageSchema);
    if (!session) std::abort();
    auto seg = (*session)->create("drain", 64);
    if (!seg) std::abort();
    segment = std::move(*seg);
    producer = bus::ShmProducer<task::Message>(segment->data(), segment->geometry(),
                                               task::kShmStickyMessages);
    auto r = bus::ShmReader<task::Message>::open(segment->name(), {task::kShmMessageSchema, name},
                                                 platform::effective_uid(), false);
    if (!r) std::abort();
    reader.emplace(std::move(*r));
  }
  ~DrainSubject() {
    reader.reset();
    segment.reset();
    remove_segments(name);
  }
  void push(int n) {
    for (int i = 0; i < n; ++i) {
      task::CycleSample c;
      c.counters.cycles = ++cycle;
      c.start_ns = static_cast<Nanos>(cycle) * 1000;
      c.end_ns = c.start_ns + 100;
      (void)producer.push(task::Message{c});
    }
  }
  std::string name;
  std::unique_ptr<bus::ShmSegment> segment;
  bus::ShmProducer<task::Message> producer;
  std::optional<bus::ShmReader<task::Message>> reader;
  std::uint64_t cycle = 0;
  task::Message out[16];
};

void drain_checks(benchmark::State& state) {
  DrainSubject s;
  for (auto _ : state) {
    s.push(10);
    const Nanos t0 = platform::now_ns();
    auto live = s.reader->live();
    auto n = s.reader->pop(s.out, nullptr, 16, &task::check_shm_message);
    s.reader->heartbeat(t0, 1);
    const Nanos t1 = platform::now_ns();
    if (!live || !n || *n != 10) std::abort();
    state.SetIterationTime(static_cast<double>(t1 - t0) / 1e9);
  }
}

void header_verify(benchmark::State& state) {
  DrainSubject s;
  for (auto _ : state) {
    if (!s.reader->verify()) std::abort();
  }
}

void register_all() {
  benchmark::RegisterBenchmark("bus/shm/drain_checks", drain_checks)
      ->Iterations(200000)
      ->UseManualTime()
      ->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("bus/shm/header_verify", header_verify)
      ->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("bus/shm/overhead:shm_vs_in_process", overhead)
      ->Iterations(kBatchesPerRep)
      ->UseManualTime()
      ->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("bus/shm/overhead_cold:shm_vs_in_process", overhead_cold)
      ->Iterations(500)
      ->UseManualTime()
      ->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("bus/shm/daemon_cpu", daemon_cpu)
      ->Args({100, 10})
      ->ArgNames({"processes", "components"})
      ->Iterations(1)
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("bus/shm/daemon_vs_in_process", daemon_vs_in_process)
      ->Args({100, 10})
      ->Args({10, 100})
      ->ArgNames({"processes", "components"})
      ->Iterations(3)
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("bus/shm/sigkill_to_error", sigkill_to_error)
      ->Iterations(100)
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond);
}

}  // namespace
}  // namespace vigil::bench

int main(int argc, char** argv) {
  vigil::bench::register_all();
  return vigil::bench::run_main(argc, argv);
}
