#pragma once
/// @file
/// The safe-state request: one process-wide flag that a reaction raises (vigil/service/
/// reactions.hpp, a deployment's `reactions:` with `safe_state: true`, or a program's own call)
/// and that real-time code reads with one relaxed atomic load per cycle.
///
/// ```cpp
/// class Motor : public vigil::Task<Motor> {
///  public:
///   void on_update() { torque_ = control_law(); }
///   void on_safe_state() { torque_ = hold(); }   // runs instead of on_update() while requested
/// };
/// // or, in any real-time loop:
/// if (vigil::safe_state_requested()) hold(); else control();
/// ```
///
/// A `Task` that defines `on_safe_state()` runs it instead of `on_update()` while the request
/// stands (its fallback); a `Task` without it goes on with `on_update()`, which may read
/// `safe_state_requested()` itself. Only `clear_safe_state()` (a program's or an operator's
/// decision, `POST /api/v1/clear?safe_state=1`) ends the request: vigil never clears it on its
/// own. docs/guide/reactions.md.

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/platform/clock.hpp"

namespace vigil {

namespace detail {
/// The request's generation: 0 while none stands, else the number of the request (1, 2, ...).
extern std::atomic<std::uint64_t> safe_state_generation;
}  // namespace detail

/// Whether the safe state is requested: one relaxed atomic load. RT-safe (wait-free; no
/// allocation, lock, system call or exception); any thread.
[[nodiscard]] inline bool safe_state_requested() noexcept {
  return detail::safe_state_generation.load(std::memory_order_relaxed) != 0;
}

/// The standing request's number (0: none). Each new request after a clear gets a higher one, so
/// a loop can tell a second request from the first. RT-safe; any thread.
[[nodiscard]] inline std::uint64_t safe_state_generation() noexcept {
  return detail::safe_state_generation.load(std::memory_order_relaxed);
}

/// What the standing request says.
struct SafeStateRequest {
  std::uint64_t generation = 0;  ///< 0: no request stands
  Nanos requested_ns = 0;        ///< monotonic time it was raised (platform::now_ns())
  std::string reason{};          ///< who asked and why ("reaction encoder_fault: exception ...")
};

/// Raises the request (the first one stands: a second while it stands changes nothing and
/// returns false). Not RT-safe (copies `reason` under a lock); never blocks for longer than
/// that copy. Any thread.
bool request_safe_state(std::string_view reason);
/// Ends the request; false when none stood. Not RT-safe. Any thread.
bool clear_safe_state();
/// The standing request (generation 0 when none). Not RT-safe. Any thread.
[[nodiscard]] SafeStateRequest safe_state();

}  // namespace vigil
