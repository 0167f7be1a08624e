#pragma once
/// @file
/// The messages a supervised task sends to the supervisor, and `vigil::Message`, the static
/// variant that carries them through one Port per component. They belong to the task module (the
/// bus below it is a generic transport that knows no message type).
///
/// Every message is trivially copyable and fixed-size (names are FixedStrings), so pushing one
/// never allocates. Each CycleSample repeats the component's cumulative counters: when a port is
/// full and samples are dropped, the totals stay exact and only timing detail is downsampled.
///
/// Adding a message type: define the struct here (trivially copyable, with a static_assert),
/// append it to `Message`, and add an overload in the handlers that care. Handlers that do not
/// care already accept any message through their generic catch-all (see ComponentAggregator).

#include <array>
#include <cstdint>
#include <type_traits>
#include <variant>

#include "vigil/bus/fixed_string.hpp"
#include "vigil/health/checkpoint.hpp"
#include "vigil/log/record.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/task/counters.hpp"
#include "vigil/task/state.hpp"

namespace vigil::task {

using platform::LossCause;
using platform::SchedPolicy;

/// What happens when a cycle ends after the next release.
enum class OverrunPolicy : std::uint8_t {
  CatchUp,   ///< run the missed releases back to back (none is skipped)
  Skip,      ///< skip to the next release in the future, counting the skipped ones (default)
  Reanchor,  ///< next release = end of the late cycle + period, counting the releases passed
};
[[nodiscard]] constexpr const char* to_string(OverrunPolicy p) noexcept {
  switch (p) {
    case OverrunPolicy::CatchUp:
      return "CatchUp";
    case OverrunPolicy::Skip:
      return "Skip";
    case OverrunPolicy::Reanchor:
      return "Reanchor";
  }
  return "?";
}

/// Real-time-loss detectors, selectable per component (bit mask).
enum class Detectors : std::uint8_t {
  None = 0,
  Allocation = 1U << 0,  ///< needs vigil::alloc_guard linked; one thread-local read per edge
  Blocking = 1U << 1,    ///< voluntary context switches; getrusage per edge (system call)
  PageFaults = 1U << 2,  ///< minor + major faults; getrusage per edge (shared with Blocking)
  ModeSwitch = 1U << 3,  ///< Cobalt only: SIGDEBUG counts; one thread-local read per edge
  All = 0x0F,
};
[[nodiscard]] constexpr Detectors operator|(Detectors a, Detectors b) noexcept {
  return static_cast<Detectors>(static_cast<std::uint8_t>(a) | static_cast<std::uint8_t>(b));
}
[[nodiscard]] constexpr bool has(Detectors set, Detectors d) noexcept {
  return (static_cast<std::uint8_t>(set) & static_cast<std::uint8_t>(d)) != 0;
}

/// Who a component is and where it runs. Sent on configure and again from the component's
/// thread when it starts (and when the set of tasks sharing its thread changes).
struct TaskInfo {
  FixedString<32> name;  ///< truncated to 31 bytes; the registry keeps the full name
  FixedString<32> activity;
  SchedPolicy requested_policy = SchedPolicy::Other;
  SchedPolicy policy = SchedPolicy::Other;  ///< what the thread actually got
  bool realtime_refused = false;            ///< asked for FIFO, the system refused it
  bool threaded = false;                    ///< false until the task runs on a thread
  OverrunPolicy overrun_policy = OverrunPolicy::Skip;
  Detectors detectors = Detectors::None;
  std::int32_t priority = 0;
  std::int32_t cpu = -1;
  std::int32_t tid = 0;
  std::uint16_t tasks_on_thread = 0;
  Nanos period_ns = 0;  ///< 0 for non-periodic (triggered, manual without period)
  std::uint32_t port_capacity = 0;
};

/// One cycle of a component's update, with its cumulative counters.
struct CycleSample {
  Nanos release_ns = 0;  ///< scheduled release (= start when there is no schedule)
  Nanos start_ns = 0;    ///< on_update() began
  Nanos end_ns = 0;      ///< on_update() ended
  /// Supervision's own time (pre + post, including the push) measured on an earlier sampled
  /// cycle; 0 when no new measurement is available. See SupervisionOptions.
  Nanos overhead_ns = 0;
  std::uint32_t missed_before = 0;  ///< releases skipped just before this cycle
  bool overrun = false;             ///< this cycle ended after its next release
  /// Not a new cycle: the latest cycle's counters again (sent when the component stops or
  /// leaves, so that totals are exact even if the latest samples were dropped).
  bool totals_only = false;
  TaskState state = TaskState::Running;
  /// Cumulative since the component joined; exact even when earlier samples were dropped.
  /// `counters.cycles` is the 1-based number of this cycle; `counters.dropped` counts the
  /// messages this component's port dropped before this one.
  Counters counters;

  /// The 1-based number of this cycle (`counters.cycles`).
  [[nodiscard]] std::uint64_t cycle() const noexcept { return counters.cycles; }
  [[nodiscard]] Nanos execution_ns() const noexcept { return end_ns - start_ns; }
};

/// Real-time losses detected in one cycle, by cause (sent only when there were some).
struct RealTimeLoss {
  std::uint64_t cycle = 0;
  LossCause cause = LossCause::Allocation;
  std::uint32_t count = 0;
};

/// An exception caught at a hook boundary.
struct ExceptionReport {
  std::uint64_t cycle = 0;
  std::uint32_t count = 0;  ///< cumulative number of exceptions of this component
  Hook hook = Hook::None;
  FixedString<35> type;     ///< mangled type name (the supervisor demangles it), truncated
  FixedString<72> message;  ///< what(), truncated to 71 bytes
};

/// A lifecycle transition or a refused one.
struct StateChange {
  Nanos time_ns = 0;
  TaskState from = TaskState::PreOperational;
  TaskState to = TaskState::PreOperational;
  Hook hook = Hook::None;
  bool refused = false;    ///< the hook returned false (or an error): `to` == `from`
  FixedString<96> reason;  ///< why it was refused, or why it failed
};

/// Everything a component's port carries. `health::CheckpointReport` is one checkpoint passed
/// (vigil/health/checkpoint.hpp).
using Message = std::variant<TaskInfo, CycleSample, RealTimeLoss, ExceptionReport, StateChange,
                             log::LogRecord, health::CheckpointReport>;

namespace detail {
template <class... T>
constexpr bool all_trivially_copyable(std::variant<T...>*) {
  return (std::is_trivially_copyable_v<T> && ...);
}
}  // namespace detail

static_assert(detail::all_trivially_copyable(static_cast<Message*>(nullptr)),
              "every message type must be trivially copyable: no std::string, no pointers owning "
              "memory; use FixedString");
static_assert(std::is_trivially_copyable_v<Message>, "Message must be trivially copyable");
// Every cycle copies one Message into the port: 128 bytes are two cache lines. Keep it there.
static_assert(sizeof(Message) <= 128, "keep Message within 128 bytes: it is copied every cycle");

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using platform::SchedPolicy;
using task::Detectors;
using task::has;
using task::OverrunPolicy;
using task::to_string;
}  // namespace vigil
