#pragma once
/// @file
/// `TriggeredActivity`: runs a task in its own thread each time trigger() is called.
///
/// trigger() is RT-safe and makes a system call only when the activity's thread sleeps and must
/// be woken; triggers that arrive while a cycle runs are coalesced into one more cycle.

#include <atomic>
#include <cstdint>
#include <string>

#include "vigil/error.hpp"
#include "vigil/exec/stack.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::exec {

/// Configuration of a TriggeredActivity.
struct TriggeredConfig {
  std::string name = "triggered";
  SchedPolicy policy = SchedPolicy::Other;
  /// 1..99 for FIFO; ignored for OTHER.
  int priority = 0;
  /// CPU to pin the thread to; -1 = no affinity.
  int cpu = -1;
  /// When SCHED_FIFO is refused (no privilege): run SCHED_OTHER and report it (true), or fail
  /// start() (false).
  bool fallback_to_other = true;
  /// Stack of the thread, in bytes (kDefaultActivityStackBytes unless set); 0 keeps the system
  /// default (`ulimit -s`, usually 8 MiB, all of it resident under mlockall).
  std::size_t stack_bytes = kDefaultActivityStackBytes;
};

class TriggeredActivity {
 public:
  TriggeredActivity(TaskCore& task, TriggeredConfig config);
  ~TriggeredActivity();
  TriggeredActivity(const TriggeredActivity&) = delete;
  TriggeredActivity& operator=(const TriggeredActivity&) = delete;

  /// Creates the thread and starts the task there. Not RT-safe.
  expected<void, Error> start();
  /// Stops the task in its thread and joins the thread. Not RT-safe.
  void stop();

  /// Requests one cycle. RT-safe from any thread: one clock read, one atomic increment, and a
  /// futex wake only when the activity sleeps.
  void trigger() noexcept;

  /// Cycles run so far (any thread).
  [[nodiscard]] std::uint64_t cycles() const noexcept {
    return cycles_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] const ActivityInfo& info() const noexcept { return info_; }

 private:
  void run();
  bool command(std::uint32_t request);

  TaskCore& task_;
  TriggeredConfig config_;
  ActivityInfo info_;
  platform::Thread thread_;
  std::atomic<std::uint32_t> word_{0};  // bumped by every trigger and request
  std::atomic<bool> sleeping_{false};
  std::atomic<Nanos> last_trigger_{0};
  std::atomic<std::uint32_t> request_{0};  // 1 start, 2 stop + quit
  std::atomic<std::uint32_t> done_{0};     // bumped when a request is handled
  std::atomic<bool> result_{false};
  std::atomic<std::uint64_t> cycles_{0};
};

}  // namespace vigil::exec

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exec::TriggeredActivity;
using exec::TriggeredConfig;
}  // namespace vigil
