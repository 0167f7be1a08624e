#pragma once
/// @file
/// `Schedule`: release times of a periodic activity, overrun policies and the overrun limit.
/// Shared by PeriodicActivity and ManualActivity so both behave identically.

#include <cstdint>
#include <vector>

#include "vigil/platform/clock.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::exec {

/// Optional escalation: after `max_overruns` overruns within the last `window_cycles` cycles,
/// the thread's tasks are moved to Exception. Off when max_overruns == 0 (the default).
struct OverrunLimit {
  std::uint32_t max_overruns = 0;
  std::uint32_t window_cycles = 0;
};

/// The release schedule of a periodic activity. advance() is RT-safe (no allocation; the window
/// is allocated by the constructor).
class Schedule {
 public:
  /// What one cycle's end means for the schedule.
  struct Outcome {
    bool overrun = false;      ///< the cycle ended after the next release
    std::uint32_t missed = 0;  ///< releases skipped before the next cycle
    bool limit_reached = false;
  };

  Schedule(Nanos period_ns, OverrunPolicy policy, OverrunLimit limit = {});

  /// Sets the first release. RT-safe.
  void start(Nanos first_release) noexcept {
    release_ = first_release;
    cycle_ = 0;
  }
  /// The current release (the one the next cycle belongs to).
  [[nodiscard]] Nanos release() const noexcept { return release_; }
  [[nodiscard]] Nanos period() const noexcept { return period_; }
  [[nodiscard]] OverrunPolicy policy() const noexcept { return policy_; }

  /// Advances past a cycle released at release() that ended at `end`. RT-safe, O(1).
  ///
  /// No overrun: next release = release + period. Overrun (end > release + period):
  /// CatchUp: next = release + period (runs at once, late; nothing missed);
  /// Skip: next = the first release at or after `end`, the ones before it are missed;
  /// Reanchor: next = end + period, the releases that passed are missed.
  Outcome advance(Nanos end) noexcept {
    if (advance_on_time(end)) [[likely]]
      return {};
    return advance_slow(end);
  }
  /// The common case of advance(), for a caller that handles the rest apart: when the cycle
  /// ended on time and no overrun limit is kept, advances (nothing missed) and returns true;
  /// otherwise changes nothing and returns false (call advance()). RT-safe, inline.
  [[nodiscard]] bool advance_on_time(Nanos end) noexcept {
    // The common case inline: on time, no overrun limit to keep (one flag, not the window's
    // two pointers: this runs on every cycle of every periodic task).
    if (end <= release_ + period_ && !limited_) [[likely]] {
      release_ += period_;  // (cycle_ numbers the overrun window's bits: not needed here)
      return true;
    }
    return false;
  }

  [[nodiscard]] std::uint64_t overruns() const noexcept { return overruns_; }
  [[nodiscard]] std::uint64_t missed() const noexcept { return missed_; }

 private:
  Outcome advance_slow(Nanos end) noexcept;

  Nanos period_;
  OverrunPolicy policy_;
  OverrunLimit limit_;
  Nanos release_ = 0;
  bool limited_ = false;  // an overrun limit is kept: window_ is not empty
  std::uint64_t cycle_ = 0;
  std::uint64_t overruns_ = 0;
  std::uint64_t missed_ = 0;
  std::vector<std::uint64_t> window_;  // one bit per cycle of the window, a ring
  std::uint32_t in_window_ = 0;
};

}  // namespace vigil::exec

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exec::OverrunLimit;
using exec::Schedule;
}  // namespace vigil
