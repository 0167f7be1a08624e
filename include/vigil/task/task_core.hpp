#pragma once
/// @file
/// `TaskCore`: the runtime interface an activity drives (configure, start, update, stop,
/// cleanup, recover) and the lifecycle state machine; see vigil/task/state.hpp for the table.

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/platform/clock.hpp"
#include "vigil/task/messages.hpp"
#include "vigil/task/state.hpp"

namespace vigil::task {

/// Timing of one cycle, written by the activity before update() and completed by supervision.
struct CycleContext {
  /// Scheduled release; 0 means "now" (the cycle starts when it is released).
  Nanos release_ns = 0;
  /// Period of the activity; 0 for non-periodic activities (no overrun is possible).
  Nanos period_ns = 0;
  /// Releases skipped just before this cycle (Skip / Reanchor policies).
  std::uint32_t missed_before = 0;
  /// The clock of the activity (null: the system clock).
  const Clock* clock = nullptr;
  /// Out: start and end of on_update() as supervision measured them; end_ns == 0 when the task
  /// is not supervised (the activity then reads the clock itself).
  Nanos start_ns = 0;
  Nanos end_ns = 0;
};

/// Where a task runs, as its activity describes it. Owned by the activity.
struct ActivityInfo {
  std::string name;
  SchedPolicy requested_policy = SchedPolicy::Other;
  SchedPolicy policy = SchedPolicy::Other;
  bool realtime_refused = false;
  bool threaded = false;
  int priority = 0;
  int cpu = -1;
  int tid = 0;
  Nanos period_ns = 0;
  OverrunPolicy overrun_policy = OverrunPolicy::Skip;
  std::atomic<std::uint16_t> tasks_on_thread{1};
};

/// The lifecycle state machine. Commands are not thread-safe with respect to each other or to
/// update(): call them from one thread at a time. A task on a running PeriodicActivity or
/// TriggeredActivity is started and stopped through the activity, which runs the commands in
/// the task's own thread (as Orocos does).
class TaskCore {
 public:
  explicit TaskCore(std::string name);
  virtual ~TaskCore();
  TaskCore(const TaskCore&) = delete;
  TaskCore& operator=(const TaskCore&) = delete;

  /// PreOperational|Stopped -> Stopped (or PreOperational when refused). Not RT-safe.
  bool configure();
  /// Stopped -> Running (or Stopped when refused).
  bool start();
  /// Runs one cycle when Running; returns false (doing nothing) in any other state, and when
  /// the cycle moved the task to Exception. RT-safe when the hooks are.
  bool update() noexcept;
  /// The same with the activity's timing (activities call this one). Inline: the per-cycle
  /// path is one state check and one virtual call (cycle_hook()).
  bool update(CycleContext& context) noexcept {
    if (state() != TaskState::Running) [[unlikely]]
      return false;
    return update_running(context);
  }
  /// The same for an activity that has just seen state() == TaskState::Running in this thread
  /// (as its loop must, to skip a stopped task): no second check.
  bool update_running(CycleContext& context) noexcept {
    cycle_hook(context);
    return state() == TaskState::Running;
  }
  /// Running -> Stopped (or Running when refused).
  bool stop();
  /// Stopped -> PreOperational (or Stopped when refused).
  bool cleanup();
  /// Exception -> PreOperational.
  bool recover();

  /// Current state. Any thread (atomic load).
  [[nodiscard]] TaskState state() const noexcept { return state_.load(std::memory_order_acquire); }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }

  /// Called by activities when they take the task (nullptr when they release it).
  void attach(ActivityInfo* info) noexcept { activity_ = info; }
  [[nodiscard]] ActivityInfo* activity() const noexcept { return activity_; }

  /// Moves a Running task to Exception with a report (e.g. the activity's overrun limit).
  /// The names of the checkpoints this task has declared so far (vigil/health/checkpoint.hpp),
  /// in declaration order; none for a task that cannot declare any. Not RT-safe.
  [[nodiscard]] virtual std::vector<std::string> declared_checkpoints() const { return {}; }
  /// RT-safe (no allocation): `reason` is copied into a fixed-size message.
  void raise_exception(Hook hook, std::string_view type, std::string_view reason) noexcept;
  /// Moves the task to FatalError, from any state. Final.
  void fatal(std::string_view reason) noexcept;

 protected:
  virtual bool configure_hook() { return true; }
  virtual bool start_hook() { return true; }
  /// The cycle's work. Pure: every task has one.
  virtual void update_hook() = 0;
  /// Runs one cycle with the activity's timing: what update(CycleContext&) calls. The default
  /// makes cycle() return `context` while update_hook() runs, and reports an exception that
  /// escapes it (update_threw()). Task<Derived> overrides it to hand `context` to supervision
  /// directly: the cycle then reads its timing from a register, not back through context_.
  virtual void cycle_hook(CycleContext& context) noexcept {
    context_ = &context;
    try {
      update_hook();
    } catch (...) {
      update_threw();
    }
    context_ = &own_context_;
  }
  virtual bool stop_hook() { return true; }
  virtual bool cleanup_hook() { return true; }

  /// Told about every transition, refused or not. Default: nothing. RT-safe implementations only.
  virtual void on_transition(TaskState from, TaskState to, Hook hook, bool refused,
                             std::string_view reason) noexcept;
  /// Told about every exception caught at a hook boundary. Default: prints to stderr.
  virtual void on_exception(Hook hook, std::string_view type, std::string_view what) noexcept;

  /// The timing of the cycle being run (valid inside update_hook()).
  [[nodiscard]] CycleContext& cycle() noexcept { return *context_; }
  /// For an override of cycle_hook(): what cycle() returns from now on (the cycle being run),
  /// and back to the task's own context once it is over.
  void enter_cycle(CycleContext& context) noexcept { context_ = &context; }
  void leave_cycle() noexcept { context_ = &own_context_; }
  /// Sets the state and reports the transition.
  void transition(TaskState to, Hook hook, std::string_view reason = {}) noexcept;
  /// Reports a refused transition (with the reason set by set_refusal_reason, if any).
  void refuse(Hook hook, std::string_view reason) noexcept;
  /// Why the running hook refuses its transition (e.g. the error of a vigil::expected).
  void set_refusal_reason(std::string_view reason) { refusal_.assign(reason); }

 private:
  template <class F>
  bool run_hook(Hook hook, F&& f) noexcept;
  /// The current exception escaped update_hook(): reports it and moves to Exception.
  void update_threw() noexcept;

  std::atomic<TaskState> state_{TaskState::PreOperational};
  std::string name_;
  CycleContext own_context_;
  CycleContext* context_ = &own_context_;
  ActivityInfo* activity_ = nullptr;
  std::string refusal_;
};

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::ActivityInfo;
using task::CycleContext;
using task::TaskCore;
}  // namespace vigil
