#include "vigil/exec/periodic_activity.hpp"

#include <array>
#include <atomic>
#include <cerrno>
#include <map>
#include <mutex>
#include <tuple>

#include "exec/spawn.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/wait.hpp"

namespace vigil::exec {
namespace detail {

// Design: a PeriodicThread runs the tasks of every activity with one key, in slot order. Slots
// are append-only while the thread lives (insertion order is execution order); a slot is emptied
// by the thread itself when its task is stopped, so the thread never dereferences a task that
// was handed back. Control threads talk to the loop through per-slot request words and wait on
// `done_` (a futex word): the loop never waits for them.
class PeriodicThread {
 public:
  static constexpr std::size_t kMaxTasks = 256;
  enum Request : std::uint32_t { kNone = 0, kStart = 1, kStop = 2 };

  explicit PeriodicThread(const PeriodicConfig& c)
      : config_(c), schedule_(c.period_ns, c.overrun_policy, c.overrun_limit) {}

  ~PeriodicThread() {
    quit_.store(true, std::memory_order_release);
    thread_.join();
  }

  expected<void, Error> spawn() {
    platform::ThreadConfig tc{.name = config_.name,
                              .policy = config_.policy,
                              .priority = config_.priority,
                              .cpu = config_.cpu,
                              .stack_bytes = config_.stack_bytes};
    auto t = spawn_activity_thread(
        tc, config_.fallback_to_other, [this] { run(); }, realtime_refused_);
    if (!t) return unexpected(t.error());
    policy_ = tc.policy;
    thread_ = std::move(*t);
    return {};
  }

  /// Appends a task and waits until the thread has started it. Control side, pool lock held.
  expected<std::size_t, Error> add(TaskCore& task, ActivityInfo& info) {
    const std::uint32_t n = count_.load(std::memory_order_relaxed);
    if (n >= kMaxTasks) {
      return unexpected(Error{ENOSPC, "periodic thread '" + config_.name + "' already runs " +
                                          std::to_string(kMaxTasks) + " tasks"});
    }
    info.name = config_.name;
    info.requested_policy = config_.policy;
    info.policy = policy_;
    info.realtime_refused = realtime_refused_;
    info.threaded = true;
    info.priority = policy_ == SchedPolicy::Fifo ? config_.priority : 0;
    info.cpu = config_.cpu;
    info.tid = thread_.tid();
    info.period_ns = config_.period_ns;
    info.overrun_policy = config_.overrun_policy;
    task.attach(&info);
    Slot& s = slots_[n];
    s.info = &info;
    s.request.store(kStart, std::memory_order_relaxed);
    s.task.store(&task, std::memory_order_relaxed);
    count_.store(n + 1, std::memory_order_release);  // publishes the slot to the loop
    ++live_;
    update_sharing();
    wait_done(s);
    return std::size_t{n};
  }

  /// Stops the task of slot `i` in the thread and empties the slot. Control side.
  void remove(std::size_t i) {
    Slot& s = slots_[i];
    if (s.task.load(std::memory_order_acquire) == nullptr) return;
    s.request.store(kStop, std::memory_order_release);
    wait_done(s);
    --live_;
    update_sharing();
  }

  [[nodiscard]] std::size_t live() const noexcept { return live_; }
  /// Stack of the thread, in bytes, as created (0: the system default).
  [[nodiscard]] std::size_t stack_bytes() const noexcept { return config_.stack_bytes; }
  [[nodiscard]] bool started_ok(std::size_t i) const noexcept {
    return slots_[i].result.load(std::memory_order_acquire);
  }

 private:
  struct Slot {
    std::atomic<TaskCore*> task{nullptr};
    std::atomic<std::uint32_t> request{kNone};
    std::atomic<std::uint32_t> done{0};
    std::atomic<bool> result{false};
    ActivityInfo* info = nullptr;
  };

  void wait_done(Slot& s) {
    for (;;) {
      const std::uint32_t d = s.done.load(std::memory_order_acquire);
      if (s.request.load(std::memory_order_acquire) == kNone) return;
      platform::wait_on(s.done, d, platform::now_ns() + 10 * kNanosPerMilli);
    }
  }

  void update_sharing() {
    const std::uint32_t n = count_.load(std::memory_order_relaxed);
    for (std::uint32_t i = 0; i < n; ++i) {
      if (slots_[i].info != nullptr && slots_[i].task.load() != nullptr) {
        slots_[i].info->tasks_on_thread.store(static_cast<std::uint16_t>(live_),
                                              std::memory_order_relaxed);
      }
    }
  }

  void handle(Slot& s, TaskCore& t, std::uint32_t r) noexcept {
    bool ok = false;
    if (r == kStart) {
      ok = t.start();
    } else if (r == kStop) {
      if (t.state() == TaskState::Running) t.stop();
      ok = true;
      s.task.store(nullptr, std::memory_order_release);
    }
    s.result.store(ok, std::memory_order_release);
    s.request.store(kNone, std::memory_order_release);
    s.done.fetch_add(1, std::memory_order_release);
    platform::wake_one(s.done);
  }

  void run() noexcept {
    platform::arm_mode_switch_detection();
    const Clock clock = Clock::system();
    schedule_.start(clock.now() + config_.period_ns);
    std::uint32_t missed = 0;
    while (!quit_.load(std::memory_order_acquire)) {
      platform::sleep_until(schedule_.release());
      const Nanos release = schedule_.release();
      const std::uint32_t n = count_.load(std::memory_order_acquire);
      Nanos end = 0;
      for (std::uint32_t i = 0; i < n; ++i) {
        Slot& s = slots_[i];
        TaskCore* t = s.task.load(std::memory_order_acquire);
        if (t == nullptr) continue;
        if (const auto r = s.request.load(std::memory_order_acquire); r != kNone) {
          handle(s, *t, r);
          if (r == kStop) continue;
        }
        if (t->state() != TaskState::Running) continue;
        CycleContext c;
        c.release_ns = release;
        c.period_ns = config_.period_ns;
        c.missed_before = missed;
        c.clock = &clock;
        t->update_running(c);
        end = c.end_ns != 0 ? c.end_ns : clock.now();
      }
      if (end == 0) end = clock.now();
      if (schedule_.advance_on_time(end)) [[likely]] {
        missed = 0;
        continue;
      }
      const auto o = schedule_.advance(end);
      missed = o.missed;
      if (o.limit_reached) {
        for (std::uint32_t i = 0; i < n; ++i) {
          if (TaskCore* t = slots_[i].task.load(std::memory_order_acquire)) {
            t->raise_exception(Hook::Update, "vigil::OverrunLimit",
                               "overrun limit reached: too many overruns in the window");
          }
        }
      }
    }
  }

  PeriodicConfig config_;
  Schedule schedule_;
  platform::Thread thread_;
  SchedPolicy policy_ = SchedPolicy::Other;
  bool realtime_refused_ = false;
  std::array<Slot, kMaxTasks> slots_;
  std::atomic<std::uint32_t> count_{0};
  std::atomic<bool> quit_{false};
  std::size_t live_ = 0;
};

namespace {
using Key = std::tuple<int, Nanos, int, int, int>;

struct Pool {
  std::mutex mutex;
  std::map<Key, std::weak_ptr<PeriodicThread>> threads;
};
Pool& pool() {
  static Pool p;
  return p;
}
/// A shared thread of `have` bytes of stack (0: the system default, taken as large) serves an
/// activity asking for `want`.
bool stack_fits(std::size_t want, std::size_t have) {
  if (have == 0) return true;
  return want != 0 && want <= have;
}
Key key_of(const PeriodicConfig& c) {
  return {static_cast<int>(c.policy), c.period_ns, c.priority, c.cpu,
          static_cast<int>(c.overrun_policy)};
}
}  // namespace
}  // namespace detail

PeriodicActivity::PeriodicActivity(TaskCore& task, PeriodicConfig config)
    : task_(task), config_(std::move(config)) {}

PeriodicActivity::~PeriodicActivity() { stop(); }

expected<void, Error> PeriodicActivity::start() {
  if (thread_) return {};
  if (config_.period_ns <= 0) {
    return unexpected(
        Error{EINVAL, "periodic activity '" + config_.name + "': period_ns must be > 0"});
  }
  if (task_.state() != TaskState::Stopped) {
    return unexpected(Error{EINVAL, "task '" + task_.name() + "' is " + to_string(task_.state()) +
                                        ", not Stopped: configure it before starting"});
  }
  auto& pool = detail::pool();
  std::lock_guard lock(pool.mutex);
  std::shared_ptr<detail::PeriodicThread> thread;
  if (config_.share_thread) {
    auto& weak = pool.threads[detail::key_of(config_)];
    thread = weak.lock();
    if (thread && !detail::stack_fits(config_.stack_bytes, thread->stack_bytes())) {
      return unexpected(Error{
          EINVAL, "periodic activity '" + config_.name + "' asks for a " +
                      std::to_string(config_.stack_bytes) + "-byte stack but would share the " +
                      std::to_string(thread->stack_bytes()) +
                      "-byte stack of an equal activity's thread: give both the same stack, or "
                      "this one share_thread = false"});
    }
    if (!thread) {
      thread = std::make_shared<detail::PeriodicThread>(config_);
      if (auto r = thread->spawn(); !r) return unexpected(r.error());
      weak = thread;
    }
  } else {
    thread = std::make_shared<detail::PeriodicThread>(config_);
    if (auto r = thread->spawn(); !r) return unexpected(r.error());
  }
  auto slot = thread->add(task_, info_);
  if (!slot) return unexpected(slot.error());
  slot_ = *slot;
  thread_ = std::move(thread);
  if (!thread_->started_ok(slot_)) {
    thread_->remove(slot_);
    thread_.reset();
    task_.attach(nullptr);
    return unexpected(Error{ECANCELED, "task '" + task_.name() + "' refused to start (state " +
                                           to_string(task_.state()) + ")"});
  }
  return {};
}

void PeriodicActivity::stop() {
  if (!thread_) return;
  auto& pool = detail::pool();
  std::lock_guard lock(pool.mutex);
  thread_->remove(slot_);
  task_.attach(nullptr);
  if (thread_->live() == 0) {
    // The last task left: end the thread now (its destructor joins) so that a later activity
    // with the same key starts a fresh thread with a fresh schedule.
    for (auto it = pool.threads.begin(); it != pool.threads.end();) {
      it = it->second.lock() == thread_ ? pool.threads.erase(it) : std::next(it);
    }
  }
  thread_.reset();
}

}  // namespace vigil::exec
