#pragma once
/// @file
/// `PeriodicActivity`: runs a task periodically in a real-time thread.
///
/// Periodic activities with the same (policy, period, priority, CPU, overrun policy) share one
/// thread and their tasks run in the order the activities were started, as Orocos does. To give
/// a task a thread of its own, set `share_thread = false`.
///
/// Commands run in the task's thread: start() hands the task to the thread, which calls
/// task.start() before its next cycle; stop() has the thread call task.stop() and let go of it.
/// Both wait (off the RT path) until the thread has done it.

#include <memory>
#include <string>

#include "vigil/error.hpp"
#include "vigil/exec/schedule.hpp"
#include "vigil/exec/stack.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::exec {

/// Configuration of a PeriodicActivity.
struct PeriodicConfig {
  std::string name = "periodic";
  /// Period in nanoseconds (> 0).
  Nanos period_ns = kNanosPerMilli;
  SchedPolicy policy = SchedPolicy::Other;
  /// 1..99 for FIFO; ignored for OTHER.
  int priority = 0;
  /// CPU to pin the thread to; -1 = no affinity.
  int cpu = -1;
  OverrunPolicy overrun_policy = OverrunPolicy::Skip;
  OverrunLimit overrun_limit{};
  /// Share a thread with activities of equal (policy, period, priority, CPU, overrun policy).
  bool share_thread = true;
  /// When SCHED_FIFO is refused (no privilege): run SCHED_OTHER and report it (true), or fail
  /// start() (false).
  bool fallback_to_other = true;
  /// Stack of the thread, in bytes; 0 keeps the system default (`ulimit -s`, usually 8 MiB, all
  /// of it resident under mlockall). Activities that share a thread share its stack: one that
  /// asks for more than the running thread has fails start() (give it `share_thread = false` or
  /// the same size).
  std::size_t stack_bytes = kDefaultActivityStackBytes;
};

namespace detail {
class PeriodicThread;
}

class PeriodicActivity {
 public:
  /// Takes `task`, which must outlive the activity. Not RT-safe.
  PeriodicActivity(TaskCore& task, PeriodicConfig config);
  ~PeriodicActivity();
  PeriodicActivity(const PeriodicActivity&) = delete;
  PeriodicActivity& operator=(const PeriodicActivity&) = delete;

  /// Hands the task to its thread (created if needed) and starts it there. Fails when the thread
  /// cannot be created, or the task refuses to start (its state says why). Not RT-safe.
  expected<void, Error> start();
  /// Stops the task in its thread and releases it; the thread ends with its last task.
  void stop();
  [[nodiscard]] bool running() const noexcept { return thread_ != nullptr; }

  /// Where the task runs (valid after start()).
  [[nodiscard]] const ActivityInfo& info() const noexcept { return info_; }
  [[nodiscard]] const PeriodicConfig& config() const noexcept { return config_; }

 private:
  TaskCore& task_;
  PeriodicConfig config_;
  ActivityInfo info_;
  std::shared_ptr<detail::PeriodicThread> thread_;
  std::size_t slot_ = 0;
};

}  // namespace vigil::exec

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exec::PeriodicActivity;
using exec::PeriodicConfig;
}  // namespace vigil
