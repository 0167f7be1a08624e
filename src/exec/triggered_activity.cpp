#include "vigil/exec/triggered_activity.hpp"

#include <cerrno>

#include "exec/spawn.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/wait.hpp"

namespace vigil::exec {

namespace {
constexpr std::uint32_t kStart = 1;
constexpr std::uint32_t kStopQuit = 2;
}  // namespace

TriggeredActivity::TriggeredActivity(TaskCore& task, TriggeredConfig config)
    : task_(task), config_(std::move(config)) {}

TriggeredActivity::~TriggeredActivity() { stop(); }

expected<void, Error> TriggeredActivity::start() {
  if (thread_.joinable()) return {};
  if (task_.state() != TaskState::Stopped) {
    return unexpected(Error{EINVAL, "task '" + task_.name() + "' is " + to_string(task_.state()) +
                                        ", not Stopped: configure it before starting"});
  }
  platform::ThreadConfig tc{.name = config_.name,
                            .policy = config_.policy,
                            .priority = config_.priority,
                            .cpu = config_.cpu,
                            .stack_bytes = config_.stack_bytes};
  auto t = detail::spawn_activity_thread(
      tc, config_.fallback_to_other, [this] { run(); }, info_.realtime_refused);
  if (!t) return unexpected(t.error());
  thread_ = std::move(*t);
  info_.name = config_.name;
  info_.requested_policy = config_.policy;
  info_.policy = tc.policy;
  info_.priority = tc.priority;
  info_.cpu = config_.cpu;
  info_.tid = thread_.tid();
  info_.threaded = true;
  task_.attach(&info_);
  if (!command(kStart)) {
    command(kStopQuit);
    thread_.join();
    task_.attach(nullptr);
    return unexpected(Error{ECANCELED, "task '" + task_.name() + "' refused to start (state " +
                                           to_string(task_.state()) + ")"});
  }
  return {};
}

void TriggeredActivity::stop() {
  if (!thread_.joinable()) return;
  command(kStopQuit);
  thread_.join();
  task_.attach(nullptr);
}

bool TriggeredActivity::command(std::uint32_t request) {
  const std::uint32_t before = done_.load(std::memory_order_acquire);
  request_.store(request, std::memory_order_release);
  word_.fetch_add(1, std::memory_order_seq_cst);
  platform::wake_one(word_);
  while (done_.load(std::memory_order_acquire) == before) {
    platform::wait_on(done_, before, platform::now_ns() + 10 * kNanosPerMilli);
  }
  return result_.load(std::memory_order_acquire);
}

void TriggeredActivity::trigger() noexcept {
  last_trigger_.store(platform::now_ns(), std::memory_order_relaxed);
  word_.fetch_add(1, std::memory_order_seq_cst);
  // Dekker with run(): either the thread sees the new word before sleeping, or we see it asleep.
  if (sleeping_.load(std::memory_order_seq_cst)) platform::wake_one(word_);
}

void TriggeredActivity::run() {
  platform::arm_mode_switch_detection();
  const Clock clock = Clock::system();
  std::uint32_t handled = word_.load(std::memory_order_acquire);
  for (;;) {
    const std::uint32_t seq = word_.load(std::memory_order_acquire);
    if (const std::uint32_t r = request_.exchange(0, std::memory_order_acq_rel); r != 0) {
      bool ok = true;
      if (r == kStart) ok = task_.start();
      if (r == kStopQuit && task_.state() == TaskState::Running) task_.stop();
      result_.store(ok, std::memory_order_release);
      done_.fetch_add(1, std::memory_order_release);
      platform::wake_one(done_);
      if (r == kStopQuit) return;
      handled = seq;
      continue;
    }
    if (seq != handled) {
      handled = seq;
      if (task_.state() == TaskState::Running) {
        CycleContext c;
        c.release_ns = last_trigger_.load(std::memory_order_relaxed);
        c.clock = &clock;
        task_.update_running(c);
        cycles_.fetch_add(1, std::memory_order_relaxed);
      }
      continue;
    }
    sleeping_.store(true, std::memory_order_seq_cst);
    if (word_.load(std::memory_order_seq_cst) == seq) platform::wait_on(word_, seq);
    sleeping_.store(false, std::memory_order_relaxed);
  }
}

}  // namespace vigil::exec
