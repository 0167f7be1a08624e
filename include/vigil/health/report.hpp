#pragma once
/// @file
/// What health supervision says: the status of each supervision (AUTOSAR PHM's local
/// supervision status), its failures, and `SupervisionReport`, a plain value with everything
/// known about one supervision at one moment. Not RT-safe.
///
/// Status machine (every kind):
///
/// ```
///  DEACTIVATED --activation--> OK --failure, tolerance left--> FAILED --correct, last one--> OK
///       ^                       |                                 |
///       |                       +--failure, no tolerance left--+  +--failures beyond tolerance--+
///       |                                                      v                                v
///       +-------------------deactivation (any state)------- EXPIRED <---------------------------+
/// ```
///
/// EXPIRED is kept until the supervision is deactivated (its entity stopped on purpose, or told
/// it need not run) or its entity starts again. Mapped onto vigil's levels (monitor/health.hpp):
/// OK and DEACTIVATED are Ok, FAILED is Warn, EXPIRED is Error.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/platform/clock.hpp"

namespace vigil::health {

/// The unit kind (monitor::Report::unit_kind) of a supervision's report in the pipeline.
inline constexpr std::string_view kSupervisionUnit = "supervision";

/// The status of one supervision.
enum class SupervisionStatus : std::uint8_t {
  Ok,           ///< active, no failure (or every failure taken back by correct results)
  Failed,       ///< failures within the tolerance (shown as WARN)
  Expired,      ///< failures beyond the tolerance, or an entity that never started (ERROR)
  Deactivated,  ///< not supervised now: its entity is stopped, or has not started yet
};
/// "ok", "failed", "expired", "deactivated".
[[nodiscard]] const char* to_string(SupervisionStatus s) noexcept;

/// The kind of a supervision.
enum class SupervisionKind : std::uint8_t { Alive, Deadline, Logical };
/// "alive", "deadline", "logical".
[[nodiscard]] const char* to_string(SupervisionKind k) noexcept;

/// What went wrong.
enum class FailureKind : std::uint8_t {
  None,
  TooFewIndications,   ///< alive: a reference cycle ended with too few indications
  TooManyIndications,  ///< alive: more indications than expected + max_margin in one cycle
  NeverStarted,        ///< alive: the entity did not start within the start-up grace period
  DeadlineTooEarly,    ///< deadline: the end came sooner than min after the start
  DeadlineMissed,      ///< deadline: no end by max after the start (found when max passed)
  DeadlineRestarted,   ///< deadline: a second start before the end
  InvalidTransition,   ///< logical: a checkpoint the graph does not allow here
};
/// "too_few_indications", "too_many_indications", ...
[[nodiscard]] const char* to_string(FailureKind k) noexcept;

/// One failure of one supervision.
struct Failure {
  std::string supervision;  ///< its name
  SupervisionKind kind = SupervisionKind::Alive;
  FailureKind failure = FailureKind::None;
  SupervisionStatus status = SupervisionStatus::Failed;  ///< the status it led to
  /// The entity the failure is about: the alive checkpoint's, the deadline's end, the
  /// checkpoint seen by a logical supervision.
  std::string entity;
  Nanos fault_ns = 0;     ///< when it happened: the window's end, start + max, the checkpoint
  Nanos detected_ns = 0;  ///< when the engine found it (`HealthEngine::advance`'s `now`)
  std::string text;       ///< what happened, in words, naming checkpoints and times
  /// Detection latency (detected - fault), 0 when unknown.
  [[nodiscard]] Nanos latency_ns() const noexcept {
    return detected_ns >= fault_ns && fault_ns > 0 ? detected_ns - fault_ns : 0;
  }
};

/// One checkpoint a component passed, as a trace shows it (an instant).
struct CheckpointMark {
  std::string name;         ///< the declared name
  Nanos time_ns = 0;        ///< when it was passed (the component's clock)
  std::uint64_t cycle = 0;  ///< the component's cycle it was passed in
};

/// One start/end pair of a deadline supervision, as a trace shows it (a span from its start to
/// its end, or to its max when the end never came).
struct DeadlineSpan {
  std::string supervision;  ///< its name
  std::string start;        ///< the start checkpoint ("entity.checkpoint")
  std::string end;          ///< the end checkpoint
  Nanos start_ns = 0;
  /// When the end came; for a missed deadline, start + max; for a restarted one, the second
  /// start.
  Nanos end_ns = 0;
  FailureKind failure = FailureKind::None;  ///< None for a pair within [min, max]
};

/// Everything known about one supervision at one moment. Plain data: copy it freely.
struct SupervisionReport {
  std::string name;
  SupervisionKind kind = SupervisionKind::Alive;
  SupervisionStatus status = SupervisionStatus::Deactivated;
  std::vector<std::string> entities;  ///< the supervised entities it watches
  /// Checkpoints (or cycles) it has seen, counting those a full port dropped when known.
  std::uint64_t checkpoints = 0;
  /// Reports a full port dropped, found by gaps in the checkpoints' counts.
  std::uint64_t lost = 0;
  /// Results judged: reference cycles (alive), start/end pairs (deadline), transitions
  /// (logical).
  std::uint64_t evaluations = 0;
  std::uint64_t failures = 0;      ///< every failure so far
  std::uint32_t failed_count = 0;  ///< failures not yet taken back (FAILED/EXPIRED's counter)
  std::uint32_t tolerance = 0;     ///< failures tolerated before EXPIRED
  std::uint64_t expirations = 0;   ///< times it became EXPIRED
  // Alive:
  std::uint64_t last_window_count = 0;  ///< indications in the latest full reference cycle
  std::uint64_t window_count = 0;       ///< indications in the current one so far
  // Deadline (durations of start/end pairs, ns; 0 when none yet):
  Nanos last_duration_ns = 0;
  Nanos min_duration_ns = 0;
  Nanos max_duration_ns = 0;
  bool started = false;  ///< a start waits for its end
  // Logical:
  std::string current;  ///< the latest checkpoint of the sequence under way ("" between two)
  bool has_failure = false;
  Failure last_failure;  ///< the latest failure (when has_failure)
};

}  // namespace vigil::health
