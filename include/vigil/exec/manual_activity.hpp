#pragma once
/// @file
/// `ManualActivity`: no thread; `step()` runs one cycle of its task in the caller's thread. For
/// tests (with a controllable clock) and for embedding a task in a loop you own (Orocos'
/// SlaveActivity).

#include <string>
#include <type_traits>
#include <utility>

#include "vigil/exec/schedule.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::exec {

/// Configuration of a ManualActivity.
struct ManualConfig {
  std::string name = "manual";
  /// Period used for release times and overrun detection; 0 = not periodic (each step is
  /// released when it is called).
  Nanos period_ns = 0;
  OverrunPolicy overrun_policy = OverrunPolicy::Skip;
  OverrunLimit overrun_limit{};
  /// The clock the task's supervision reads (replace it to control time in tests).
  Clock clock = Clock::system();
};

class ManualActivity {
 public:
  /// Takes `task` (which must outlive the activity). Not RT-safe.
  explicit ManualActivity(TaskCore& task, ManualConfig config = {});
  ~ManualActivity();
  ManualActivity(const ManualActivity&) = delete;
  ManualActivity& operator=(const ManualActivity&) = delete;

  /// Starts the task in the calling thread; the first release is `first_release_ns`, or now.
  bool start(Nanos first_release_ns = 0);
  /// Stops the task.
  bool stop();
  /// Runs one cycle (the release of the cycle is the schedule's, or now when not periodic).
  /// Returns false when the task is not Running. RT-safe when the task's hooks are.
  /// Inline: the per-cycle path is the task's own update and the schedule's on-time case.
  bool step() noexcept { return step_with(task_); }

  /// The release of the next cycle (periodic only).
  [[nodiscard]] Nanos next_release() const noexcept { return schedule_.release(); }
  [[nodiscard]] const Schedule& schedule() const noexcept { return schedule_; }
  [[nodiscard]] const ActivityInfo& info() const noexcept { return info_; }
  [[nodiscard]] TaskCore& task() const noexcept { return task_; }

 protected:
  /// step() on `task` (this activity's task) seen as a T: through TaskCore, a virtual call; as a
  /// Task<Derived>, a direct one (TypedManualActivity).
  template <class T>
  [[gnu::always_inline]] bool step_with(T& task) noexcept {
    if (task.state() != TaskState::Running) [[unlikely]]
      return false;
    CycleContext& c = context_;
    const bool periodic = c.period_ns > 0;
    if (periodic) {
      c.release_ns = schedule_.release();
      // Written only when it changes, as below (no store in the common case).
      if (c.missed_before != missed_carry_) [[unlikely]]
        c.missed_before = missed_carry_;
    }
    c.end_ns = 0;
    const bool ok = task.update_running(c);
    if (periodic) {
      const Nanos end = c.end_ns != 0 ? c.end_ns : config_.clock.now();
      if (schedule_.advance_on_time(end)) [[likely]] {
        if (missed_carry_ != 0) [[unlikely]]
          missed_carry_ = 0;
      } else {
        late(end);
      }
    }
    return ok;
  }

 private:
  // A cycle that ended late, or an overrun limit to keep: out of the per-cycle path.
  void late(Nanos end) noexcept;

  TaskCore& task_;
  ManualConfig config_;
  ActivityInfo info_;
  Schedule schedule_;
  std::uint32_t missed_carry_ = 0;
  // The cycle's context lives with the activity: its clock and period are set once, so a cycle
  // writes only what changes (release, missed releases, end).
  CycleContext context_;
};

/// A ManualActivity that knows its task's type, for a loop you own around one component:
/// `step()` calls the task's cycle directly instead of through TaskCore's virtual hook, so the
/// compiler inlines the whole supervised cycle into your loop. Everything else is
/// ManualActivity's. Write it like a ManualActivity; the type is deduced:
///
/// ```cpp
/// vigil::TypedManualActivity act(motor, {.name = "loop", .period_ns = 1'000'000});
/// ```
template <class T>
class TypedManualActivity final : public ManualActivity {
  static_assert(std::is_base_of_v<TaskCore, T>, "TypedManualActivity<T>: T must be a task");

 public:
  explicit TypedManualActivity(T& task, ManualConfig config = {})
      : ManualActivity(task, std::move(config)), typed_(task) {}

  /// ManualActivity::step(), without the virtual call for a Task<Derived>. RT-safe when the
  /// task's hooks are.
  bool step() noexcept { return step_with(typed_); }
  [[nodiscard]] T& task() const noexcept { return typed_; }

 private:
  T& typed_;
};

}  // namespace vigil::exec

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exec::ManualActivity;
using exec::ManualConfig;
using exec::TypedManualActivity;
}  // namespace vigil
