#pragma once
/// @file
/// The lifecycle of a supervised task: states, hooks and the transition table.
///
/// States follow Orocos RTT's TaskCore. A command calls a hook; a hook that returns false refuses
/// the transition and the task stays where it was; a hook that throws moves the task to
/// Exception (the exception is caught and reported, never propagated).
///
// clang-format off
/// | command     | allowed from            | hook             | hook true      | hook false     | throws    |
/// |-------------|-------------------------|------------------|----------------|----------------|-----------|
/// | configure() | PreOperational, Stopped | configure_hook() | Stopped        | PreOperational | Exception |
/// | start()     | Stopped                 | start_hook()     | Running        | Stopped        | Exception |
/// | update()    | Running                 | update_hook()    | Running        | (void hook)    | Exception |
/// | stop()      | Running                 | stop_hook()      | Stopped        | Running        | Exception |
/// | cleanup()   | Stopped                 | cleanup_hook()   | PreOperational | Stopped        | Exception |
/// | recover()   | Exception               | (none)           | PreOperational |                |           |
/// | fatal()     | any                     | (none)           | FatalError     |                |           |
// clang-format on
///
/// A command called in any other state does nothing and returns false. FatalError is final:
/// only destroying the task leaves it. Every transition, refused or not, is reported to the
/// supervisor as a StateChange message.

#include <cstdint>

namespace vigil::task {

/// Lifecycle state of a task.
enum class TaskState : std::uint8_t {
  PreOperational,  ///< constructed, or cleaned up: needs configure()
  Stopped,         ///< configured, not running
  Running,         ///< update() runs the update hook
  Exception,       ///< a hook threw (or the overrun limit stopped it); recover() leaves it
  FatalError,      ///< unrecoverable; final
};

/// The framework hooks, named in reports.
enum class Hook : std::uint8_t { None, Configure, Start, Update, Stop, Cleanup };

/// "PreOperational", "Stopped", "Running", "Exception", "FatalError".
[[nodiscard]] constexpr const char* to_string(TaskState s) noexcept {
  switch (s) {
    case TaskState::PreOperational:
      return "PreOperational";
    case TaskState::Stopped:
      return "Stopped";
    case TaskState::Running:
      return "Running";
    case TaskState::Exception:
      return "Exception";
    case TaskState::FatalError:
      return "FatalError";
  }
  return "?";
}

/// "none", "configure", "start", "update", "stop", "cleanup".
[[nodiscard]] constexpr const char* to_string(Hook h) noexcept {
  switch (h) {
    case Hook::None:
      return "none";
    case Hook::Configure:
      return "configure";
    case Hook::Start:
      return "start";
    case Hook::Update:
      return "update";
    case Hook::Stop:
      return "stop";
    case Hook::Cleanup:
      return "cleanup";
  }
  return "?";
}

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::Hook;
using task::TaskState;
using task::to_string;
}  // namespace vigil
