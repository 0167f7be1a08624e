#include "vigil/monitor/monitor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <optional>
#include <unordered_map>

#include "vigil/monitor/checks/builtin.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/supervisor/running_stats.hpp"

namespace vigil::monitor {

namespace {

// The counters of a component at an earlier monitor cycle: the start of a window.
struct Baseline {
  Nanos time = 0;
  task::Counters counters;
};

// What the monitor remembers about one component between cycles.
struct Memory {
  std::deque<Baseline> history;  // oldest first; the front is the oldest possible window start
  Nanos running_since = 0;       // monitor time it was seen entering Running (0: not needed)
  TaskState last_state = TaskState::PreOperational;
  std::uint64_t seen_cycle = 0;  // the last monitor cycle that saw it (0: never)
};

std::uint64_t minus(std::uint64_t a, std::uint64_t b) noexcept { return a >= b ? a - b : 0; }

Window delta(const task::Counters& now, const task::Counters& then) noexcept {
  Window w;
  static_cast<task::Counters&>(w) = now.since(then);
  return w;
}

// The window ending now: from the newest baseline at least `window_ns` old (the previous cycle
// when window_ns is 0), or from the oldest one kept; from the counters' origin the first time.
// Never from before the end of the component's warm-up: what it counted then stays out of every
// window (it stays in the totals).
Window window_of(const Memory& m, const task::Counters& now_counters, const task::Counters& warmup,
                 Nanos now, Nanos window_ns) {
  if (m.history.empty()) {
    Window w = delta(now_counters, warmup);
    w.first = true;
    return w;
  }
  const Baseline* base = &m.history.front();
  for (auto it = m.history.rbegin(); it != m.history.rend(); ++it) {
    if (it->time <= now - window_ns) {
      base = &*it;
      break;
    }
  }
  task::Counters from = base->counters;
  from.merge(warmup);
  Window w = delta(now_counters, from);
  w.first = false;
  w.duration_ns = now - base->time;
  return w;
}

void remember(Memory& m, const task::Counters& counters, Nanos now, Nanos window_ns) {
  m.history.push_back(Baseline{now, counters});
  // A baseline older than the newest one that is already window_ns old can never be chosen again.
  while (m.history.size() >= 2 && m.history[1].time <= now - window_ns) m.history.pop_front();
}

}  // namespace

struct Monitor::Impl {
  Impl(Monitor& self, const supervisor::ComponentAggregator& a, MonitorOptions o)
      : owner(self),
        aggregator(a),
        options(std::move(o)),
        thresholds(std::make_shared<const ThresholdSet>()) {
    if (options.builtin_checks) checks::add_builtin_checks(checks);
  }

  Monitor& owner;
  const supervisor::ComponentAggregator& aggregator;
  const MonitorOptions options;

  // The monitor's locks. Three threads meet here: the monitor's own thread (run(): a cycle every
  // period), the callers of step() (a control thread, the service's stop()), and readers of any
  // thread (latest(), thresholds(), subscribe(), ...).
  //
  // step_mutex orders whole cycles: the monitor's thread and step()'s callers, one cycle at a
  // time, and the changes to what a cycle uses (checks, hooks, the supervisor) against them.
  // Held for a whole cycle, subscribers' calls included.
  mutable std::mutex step_mutex;
  CheckList checks;
  std::unordered_map<std::uint32_t, Memory> memory;
  const supervisor::ComponentDrainLoop* supervisor = nullptr;
  std::uint64_t supervisor_cycles = 0;
  Nanos supervisor_changed_at = 0;
  bool supervisor_seen = false;
  std::uint64_t cycle = 0;
  supervisor::RunningStats step_time;
  std::vector<std::pair<std::uint64_t, CycleHook>> hooks;

  // state_mutex orders the readers and writers of any thread against the cycle that copies or
  // swaps the values below: the thresholds and their errors, the latest reports, the
  // subscribers. Held only for a copy or a swap, never during a call out, so a reader never
  // waits for a cycle.
  mutable std::mutex state_mutex;
  std::shared_ptr<const ThresholdSet> thresholds;
  std::uint64_t generation = 0;
  config::ConfigErrors errors;
  ReportSet latest;
  std::vector<std::pair<std::uint64_t, Callback>> subscribers;
  std::atomic<std::uint64_t> next_id{1};  // ids of subscribers and cycle hooks

  // thread_mutex orders start() and stop() of the monitor's thread against each other (a
  // control thread and a destructor); wake_mutex orders the thread's sleep against stop()'s
  // wake-up (quit). Two, because stop() joins the thread while holding thread_mutex and the
  // thread needs wake_mutex to see quit.
  std::mutex thread_mutex;
  std::mutex wake_mutex;
  std::condition_variable wake;
  bool quit = false;
  platform::Thread thread;
  std::atomic<bool> running{false};
  std::atomic<int> thread_tid{0};

  std::shared_ptr<const ThresholdSet> current_thresholds() const {
    std::lock_guard lock(state_mutex);
    return thresholds;
  }

  // `st` was read at `now`, the cycle's start (before its hooks): a cycle delayed after its start
  // (its hooks, a loaded host) must not judge statistics read later by an earlier time.
  Report supervisor_report(const supervisor::ComponentDrainLoop& sup,
                           const supervisor::DrainStats& st, const ThresholdSet& th, Nanos now) {
    const Thresholds& t = th.for_component(options.supervisor_name);
    Report r;
    r.kind = ReportKind::Supervisor;
    r.name = options.supervisor_name;
    r.configured = true;
    r.activity = sup.options().thread_name;
    r.period_ns = sup.options().period_ns;
    r.counters.cycles = st.cycles;
    r.samples = st.cycles;
    r.total_ns = st.drain_ns;
    r.port_high_water = st.max_occupancy;
    r.window.first = !supervisor_seen;
    r.window.cycles = supervisor_seen ? minus(st.cycles, supervisor_cycles) : st.cycles;
    if (!supervisor_seen || st.cycles != supervisor_cycles) supervisor_changed_at = now;
    supervisor_seen = true;
    supervisor_cycles = st.cycles;
    r.silence_ns = now - supervisor_changed_at;
    r.add("messages", std::to_string(st.messages));
    r.add("ports", std::to_string(st.ports));
    r.add("messages_per_cycle", fmt::format("{:.1f}", st.messages_per_cycle.mean));
    r.add("max_occupancy", std::to_string(st.max_occupancy));

    const Nanos limit = checks::starvation_limit(t, r.period_ns);
    // Whether its thread runs is not asked (DrainLoop::running() is not safe against a
    // concurrent start/stop): it runs if it cycles.
    const bool cycling = st.cycles > 0 && (limit <= 0 || r.silence_ns <= limit);
    r.state = cycling ? TaskState::Running : TaskState::Stopped;
    if (t.starvation.enabled && limit > 0 && r.silence_ns > limit) {
      if (st.cycles == 0) {
        r.merge(StatusLevel::Warn, fmt::format("not started: no cycle in {}",
                                               format_nanos(static_cast<double>(r.silence_ns))));
      } else {
        r.merge(StatusLevel::Stale,
                fmt::format("not draining: no cycle for {} (limit {}); component data is stale",
                            format_nanos(static_cast<double>(r.silence_ns)),
                            format_nanos(static_cast<double>(limit))));
      }
    }
    const double period = static_cast<double>(r.period_ns);
    if (t.overrun.enabled && t.overrun.near_fraction > 0 && st.drain_ns.count > 0 &&
        st.drain_ns.ewma > t.overrun.near_fraction * period) {
      r.merge(StatusLevel::Warn, fmt::format("busy: EWMA of drain time {} near its {} period",
                                             format_nanos(st.drain_ns.ewma), format_nanos(period)));
    }
    return r;
  }

  Report monitor_report(const ThresholdSet& th, std::size_t components) {
    Report r;
    r.kind = ReportKind::Monitor;
    r.name = options.monitor_name;
    r.configured = true;
    r.activity = options.thread_name;
    r.period_ns = options.period_ns;
    r.state = running.load(std::memory_order_relaxed) ? TaskState::Running : TaskState::Stopped;
    r.counters.cycles = cycle;
    r.samples = cycle;
    r.total_ns = step_time.summary();
    r.window.first = cycle == 1;
    r.window.cycles = 1;
    const int tid = thread_tid.load(std::memory_order_relaxed);
    if (tid != 0) {
      r.tid = tid;
      r.tasks_on_thread = 1;
      if (options.read_thread_stats) {
        if (auto s = platform::read_thread_stats(tid)) r.thread = std::move(*s);
      }
    }
    std::uint64_t gen = 0;
    config::ConfigErrors errs;
    {
      std::lock_guard lock(state_mutex);
      gen = generation;
      errs = errors;
    }
    r.add("components", std::to_string(components));
    r.add("checks", std::to_string(checks.size()));
    r.add("thresholds", th.source.empty() ? std::string("built-in") : th.source);
    r.add("thresholds_generation", std::to_string(gen));
    for (const auto& e : errs) {
      r.merge(StatusLevel::Warn, "thresholds not reloaded (previous ones kept): " + e.to_string());
    }
    if (r.total_ns.count > 0 && r.total_ns.ewma > static_cast<double>(options.period_ns)) {
      r.merge(StatusLevel::Warn,
              fmt::format("cycle time {} above its {} period", format_nanos(r.total_ns.ewma),
                          format_nanos(static_cast<double>(options.period_ns))));
    }
    return r;
  }

  void run() {
    thread_tid.store(platform::current_tid(), std::memory_order_relaxed);
    // The first cycle comes one period after the start, not at once: a cycle at the start sees
    // components that have not configured yet and nodes that could not have sent anything, and
    // a table of such findings is a false alarm (the status flips of issue 46).
    Nanos next = platform::now_ns() + options.period_ns;
    std::unique_lock lock(wake_mutex);
    wake.wait_for(lock, std::chrono::nanoseconds(options.period_ns), [this] { return quit; });
    while (!quit) {
      lock.unlock();
      owner.step();
      lock.lock();
      next += options.period_ns;
      const Nanos now = platform::now_ns();
      if (next < now)
        next = now;  // late: skip the missed cycles instead of running them back to back
      wake.wait_for(lock, std::chrono::nanoseconds(next - now), [this] { return quit; });
    }
  }
};

Monitor::Monitor(const supervisor::ComponentAggregator& aggregator, MonitorOptions options)
    : impl_(std::make_unique<Impl>(*this, aggregator, std::move(options))) {}

Monitor::~Monitor() { stop(); }

const MonitorOptions& Monitor::options() const noexcept { return impl_->options; }

std::unique_lock<std::mutex> Monitor::lock_checks_() const {
  return std::unique_lock<std::mutex>(impl_->step_mutex);
}

CheckList& Monitor::checks_() noexcept { return impl_->checks; }

void Monitor::set_supervisor(const supervisor::ComponentDrainLoop* supervisor) {
  std::lock_guard lock(impl_->step_mutex);
  impl_->supervisor = supervisor;
  impl_->supervisor_seen = false;
  impl_->supervisor_cycles = 0;
}

std::size_t Monitor::remove_check(std::string_view name) {
  std::lock_guard lock(impl_->step_mutex);
  return impl_->checks.remove(name);
}

std::vector<std::string> Monitor::check_names() const {
  std::lock_guard lock(impl_->step_mutex);
  return impl_->checks.names();
}

void Monitor::set_thresholds(ThresholdSet thresholds) {
  set_thresholds(std::make_shared<const ThresholdSet>(std::move(thresholds)), 0);
}

void Monitor::set_thresholds(std::shared_ptr<const ThresholdSet> thresholds,
                             std::uint64_t generation) {
  if (!thresholds) return;
  std::lock_guard lock(impl_->state_mutex);
  impl_->thresholds = std::move(thresholds);
  impl_->generation = generation;
  impl_->errors.clear();
}

std::shared_ptr<const ThresholdSet> Monitor::thresholds() const {
  return impl_->current_thresholds();
}

std::uint64_t Monitor::thresholds_generation() const {
  std::lock_guard lock(impl_->state_mutex);
  return impl_->generation;
}

void Monitor::set_threshold_errors(config::ConfigErrors errors) {
  std::lock_guard lock(impl_->state_mutex);
  impl_->errors = std::move(errors);
}

config::ConfigErrors Monitor::threshold_errors() const {
  std::lock_guard lock(impl_->state_mutex);
  return impl_->errors;
}

std::uint64_t Monitor::add_cycle_hook(CycleHook hook) {
  const std::uint64_t id = impl_->next_id.fetch_add(1);
  std::lock_guard lock(impl_->step_mutex);
  impl_->hooks.emplace_back(id, std::move(hook));
  return id;
}

void Monitor::remove_cycle_hook(std::uint64_t id) {
  std::lock_guard lock(impl_->step_mutex);
  std::erase_if(impl_->hooks, [&](const auto& h) { return h.first == id; });
}

ReportSet Monitor::step() {
  Impl& m = *impl_;
  std::lock_guard lock(m.step_mutex);
  const Nanos t0 = m.options.clock.now();
  std::optional<supervisor::DrainStats> supervisor_stats;
  if (m.supervisor != nullptr) supervisor_stats = m.supervisor->stats();
  for (auto& [id, hook] : m.hooks) {
    // A hook's failure must not stop the monitor or the other hooks.
    try {
      hook();
    } catch (...) {
    }
  }
  const std::shared_ptr<const ThresholdSet> th = m.current_thresholds();
  const std::vector<supervisor::ComponentSnapshot> snaps = m.aggregator.snapshot();

  ReportSet set;
  set.cycle = ++m.cycle;
  set.time_ns = t0;
  set.components.reserve(snaps.size() + 2);

  std::unordered_map<int, unsigned> per_tid;
  for (const auto& s : snaps) {
    if (s.alive && s.has_info && s.info.tid != 0) ++per_tid[s.info.tid];
  }
  // One OS reading per thread and cycle, however many components share the thread.
  std::unordered_map<int, std::optional<platform::ThreadStats>> os;
  const auto thread_stats = [&](int tid) -> const std::optional<platform::ThreadStats>& {
    auto [it, inserted] = os.try_emplace(tid);
    if (inserted) {
      if (auto r = platform::read_thread_stats(tid)) it->second = std::move(*r);
    }
    return it->second;
  };

  for (const supervisor::ComponentSnapshot& s : snaps) {
    Report r;
    fill_report(r, s);
    const Thresholds& t = th->for_component(s.name);
    Memory& mem = m.memory[s.id];
    const bool first = mem.seen_cycle == 0;
    mem.seen_cycle = set.cycle;
    r.window = window_of(mem, s.counters, s.warmup_counters, t0, t.window_ns);

    const bool running = s.alive && s.state == TaskState::Running;
    if (first) {
      // Seen for the first time: with samples, the silence runs from the latest one; without,
      // from now (it may just have started).
      mem.running_since = running && !s.has_sample ? t0 : 0;
    } else if (running && mem.last_state != TaskState::Running) {
      mem.running_since = t0;  // (re)started since the previous cycle
    }
    mem.last_state = s.alive ? s.state : TaskState::Stopped;
    if (running) r.silence_ns = t0 - std::max(s.last_sample_at, mem.running_since);

    if (s.alive && s.has_info && s.info.tid != 0) {
      r.tasks_on_thread = per_tid[s.info.tid];
      if (m.options.read_thread_stats && s.info.threaded) r.thread = thread_stats(s.info.tid);
    }

    m.checks.run(CheckInput{s, t, r.window, t0, r.silence_ns}, r);
    remember(mem, s.counters, t0, t.window_ns);
    set.components.push_back(std::move(r));
  }
  std::erase_if(m.memory, [&](const auto& kv) { return kv.second.seen_cycle != set.cycle; });

  if (m.supervisor != nullptr && supervisor_stats) {
    set.components.push_back(m.supervisor_report(*m.supervisor, *supervisor_stats, *th, t0));
  }
  m.step_time.add(m.options.clock.now() - t0);
  if (m.options.self_report) set.components.push_back(m.monitor_report(*th, snaps.size()));

  {
    std::lock_guard latest_lock(m.state_mutex);
    m.latest = set;
  }
  std::vector<std::pair<std::uint64_t, Callback>> subscribers;
  {
    std::lock_guard sub_lock(m.state_mutex);
    subscribers = m.subscribers;
  }
  for (auto& [id, callback] : subscribers) {
    // A subscriber's failure must not stop the monitor or the other subscribers.
    try {
      callback(set);
    } catch (...) {
    }
  }
  return set;
}

expected<void, Error> Monitor::start() {
  Impl& m = *impl_;
  std::lock_guard lock(m.thread_mutex);
  if (m.thread.joinable()) return {};
  {
    std::lock_guard wake_lock(m.wake_mutex);
    m.quit = false;
  }
  m.running.store(true, std::memory_order_relaxed);
  auto t = platform::Thread::spawn(
      {.name = m.options.thread_name, .stack_bytes = m.options.stack_bytes}, [&m] { m.run(); });
  if (!t) {
    m.running.store(false, std::memory_order_relaxed);
    return vigil::unexpected<Error>(t.error());
  }
  m.thread = std::move(*t);
  return {};
}

void Monitor::stop() {
  Impl& m = *impl_;
  std::lock_guard lock(m.thread_mutex);
  if (!m.thread.joinable()) return;
  {
    std::lock_guard wake_lock(m.wake_mutex);
    m.quit = true;
  }
  m.wake.notify_all();
  m.thread.join();
  m.thread = platform::Thread();
  m.running.store(false, std::memory_order_relaxed);
  m.thread_tid.store(0, std::memory_order_relaxed);
}

bool Monitor::running() const noexcept { return impl_->running.load(std::memory_order_relaxed); }

ReportSet Monitor::latest() const {
  std::lock_guard lock(impl_->state_mutex);
  return impl_->latest;
}

std::vector<Report> Monitor::reports() const {
  std::lock_guard lock(impl_->state_mutex);
  return impl_->latest.components;
}

std::uint64_t Monitor::subscribe(Callback callback) {
  const std::uint64_t id = impl_->next_id.fetch_add(1);
  std::lock_guard lock(impl_->state_mutex);
  impl_->subscribers.emplace_back(id, std::move(callback));
  return id;
}

void Monitor::unsubscribe(std::uint64_t id) {
  std::lock_guard lock(impl_->state_mutex);
  std::erase_if(impl_->subscribers, [&](const auto& s) { return s.first == id; });
}

}  // namespace vigil::monitor
