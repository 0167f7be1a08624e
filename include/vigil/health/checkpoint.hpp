#pragma once
/// @file
/// Checkpoints: the points in a component's code whose passage health supervision watches
/// (AUTOSAR PHM: a *supervised entity* reports *checkpoints*). This header holds what the
/// real-time side needs: `CheckpointId`, the handle a component gets when it declares a
/// checkpoint, and `CheckpointReport`, the message one report sends through the component's
/// port (an alternative of `vigil::task::Message`, like `log::LogRecord`).
///
/// A component declares its checkpoints by name when it is configured, never on the real-time
/// path (`Task::declare_checkpoint`, `Instrumentation::declare_checkpoint`), and reports one from
/// its cycle with `checkpoint(id)`: one clock read (or a time it already has) and one push of a
/// report built in place at declaration, so a report never allocates, locks, makes a system call
/// or throws. Each report carries the checkpoint's name, so the supervisor, in this process or in
/// `vigil supervise` (shared-memory ports), resolves it without any other message.
///
/// A `CheckpointId` is made only by a declaration and remembers the component that declared it:
/// an integer cannot be passed where a checkpoint is expected (a compile error), and an id that
/// is default-constructed or declared by another component is a *misuse*, counted and reported
/// (a `CheckpointReport` with index `kMisuseIndex`), never undefined behaviour.

#include <cstdint>
#include <type_traits>

#include "vigil/bus/fixed_string.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::health {

/// Longest checkpoint name kept (bytes); longer names are refused at declaration.
inline constexpr std::size_t kMaxCheckpointName = 63;
/// Checkpoints one component may declare.
inline constexpr std::uint16_t kMaxCheckpoints = 256;
/// `CheckpointReport::index` of a misuse report (an unknown or foreign `CheckpointId`).
inline constexpr std::uint16_t kMisuseIndex = 0xFFFF;

class CheckpointId;
namespace detail {
/// Makes the id of checkpoint `index` of the component tagged `owner` (the task module's
/// declaration does; nothing else should).
[[nodiscard]] constexpr CheckpointId make_checkpoint_id(std::uint32_t owner,
                                                        std::uint16_t index) noexcept;
}  // namespace detail

/// The handle of one declared checkpoint of one component. Trivially copyable; compare, copy
/// and keep it freely. Only a declaration makes a valid one; a default-constructed id is
/// invalid, and reporting it (or an id another component declared) is a counted misuse.
class CheckpointId {
 public:
  constexpr CheckpointId() noexcept = default;
  /// The checkpoint's index among its component's declarations (0-based).
  [[nodiscard]] constexpr std::uint16_t index() const noexcept { return index_; }
  /// The tag of the component that declared it (0: none, an invalid id).
  [[nodiscard]] constexpr std::uint32_t owner() const noexcept { return owner_; }
  /// False for a default-constructed id.
  [[nodiscard]] constexpr bool valid() const noexcept { return owner_ != 0; }
  friend constexpr bool operator==(CheckpointId, CheckpointId) noexcept = default;

 private:
  friend constexpr CheckpointId detail::make_checkpoint_id(std::uint32_t, std::uint16_t) noexcept;
  constexpr CheckpointId(std::uint32_t owner, std::uint16_t index) noexcept
      : owner_(owner), index_(index) {}
  std::uint32_t owner_ = 0;
  std::uint16_t index_ = kMisuseIndex;
};

namespace detail {
constexpr CheckpointId make_checkpoint_id(std::uint32_t owner, std::uint16_t index) noexcept {
  return CheckpointId(owner, index);
}
}  // namespace detail

/// One checkpoint report, as it travels through the component's port. Trivially copyable,
/// 96 bytes. Built in place when the checkpoint is declared; a report writes `time_ns`,
/// `cycle`, `count` and `misuses` and pushes it.
struct CheckpointReport {
  Nanos time_ns = 0;        ///< when the checkpoint was passed (the component's clock)
  std::uint64_t cycle = 0;  ///< the component's cycle it was passed in (1-based; 0: before any)
  /// Reports of this checkpoint so far, this one included: a supervisor that sees a gap knows
  /// how many reports the full port dropped (alive supervision counts them exactly).
  std::uint64_t count = 0;
  /// Misuses of this component so far (reports of an unknown or foreign id).
  std::uint32_t misuses = 0;
  /// The checkpoint's index among its component's declarations, or `kMisuseIndex`.
  std::uint16_t index = kMisuseIndex;
  std::uint16_t reserved = 0;
  FixedString<kMaxCheckpointName + 1> name;  ///< the declared name ("" for a misuse report)
};
static_assert(std::is_trivially_copyable_v<CheckpointReport>);
static_assert(sizeof(CheckpointReport) == 96, "CheckpointReport must stay 96 bytes");

}  // namespace vigil::health

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using health::CheckpointId;
}  // namespace vigil
