#pragma once
/// @file
/// `HealthEngine`: the evaluation of alive, deadline and logical supervision (AUTOSAR PHM), as
/// pure logic. It is driven by inputs, each a (checkpoint or entity event, time) pair, and by
/// `advance(now)`, which judges everything due until `now`; it reads no clock, starts no thread
/// and takes no lock, so a test drives it with a fake clock, and the supervisor
/// (`supervisor::HealthSupervision`) drives it from its drain thread with the real one.
///
/// ```cpp
/// health::HealthEngine engine(config);                 // validates; throws on a bad config
/// const int frame = engine.checkpoint("camera", "frame");
/// const int sent = engine.checkpoint("drive", "command_sent");
/// engine.activate(engine.entity("camera"), t0);
/// engine.activate(engine.entity("drive"), t0);
/// engine.report(frame, t1);
/// engine.report(sent, t2);
/// engine.advance(now);                                  // judges what is due before now
/// for (const auto& f : engine.take_failures()) { ... }  // kind, fault and detection times, text
/// const Nanos wake = engine.next_deadline();            // when to call advance() next
/// ```
///
/// Design: inputs are queued as they arrive (ports are drained one after the other, so they do
/// not arrive in time order) and `advance(now)` applies those time-stamped before
/// `now - settle_ns` in time order, interleaved with the due times they pass (alive reference
/// cycle ends, deadline maxima, start-up grace ends); later ones wait for a later `advance`.
/// `next_deadline()` is the earliest time at which `advance` has something to judge.
///
/// Vocabulary (AUTOSAR PHM): a *supervised entity* is a component (by name); it reports
/// *checkpoints*; each supervision is *activated* when its entities are (entered Running) and
/// *deactivated* when one of them is stopped on purpose. Not RT-safe, not thread-safe: one
/// thread drives it (the supervisor's), readers copy `reports()` under their own lock.

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "vigil/health/config.hpp"
#include "vigil/health/report.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::health {

/// "Nothing due": the value of `next_deadline()` when nothing waits.
inline constexpr Nanos kNever = INT64_MAX;

class HealthEngine {
 public:
  /// Builds the engine for `config`. Throws std::invalid_argument with `validate()`'s message
  /// when the configuration is wrong.
  explicit HealthEngine(HealthConfig config);
  ~HealthEngine();
  HealthEngine(HealthEngine&&) noexcept;
  HealthEngine& operator=(HealthEngine&&) noexcept;
  HealthEngine(const HealthEngine&) = delete;
  HealthEngine& operator=(const HealthEngine&) = delete;

  // --- names to handles (resolve once, report by handle) -------------------------------------
  /// The handle of supervised entity `name`, or -1 when no supervision names it.
  [[nodiscard]] int entity(std::string_view name) const;
  /// The handle of checkpoint `name` of entity `entity`, or -1 when no supervision watches it.
  [[nodiscard]] int checkpoint(std::string_view entity, std::string_view name) const;
  /// The handle of entity `entity`'s cycles as a checkpoint (alive supervision of its cycles),
  /// or -1 when no supervision watches them.
  [[nodiscard]] int cycles(std::string_view entity) const { return checkpoint(entity, {}); }
  /// The entity checkpoint handle `checkpoint` belongs to.
  [[nodiscard]] int entity_of(int checkpoint) const;
  /// Number of entities (handles are 0 .. entities() - 1).
  [[nodiscard]] std::size_t entities() const noexcept;
  /// The name of entity handle `entity`.
  [[nodiscard]] const std::string& entity_name(int entity) const;

  // --- inputs (queued, applied in time order by advance) --------------------------------------
  /// The time origin of the start-up grace periods (default: the first advance()'s `now`).
  void start(Nanos now);
  /// Entity `entity` became active at `time` (entered Running, or is expected to run again):
  /// its supervisions start (alive reference cycles begin at `time`). Unknown handles are
  /// ignored.
  void activate(int entity, Nanos time);
  /// Entity `entity` was stopped on purpose at `time`, or need not run: its supervisions are
  /// DEACTIVATED (not a fault), and an entity deactivated before its start-up grace period
  /// ended is not expected to start. Unknown handles are ignored.
  void deactivate(int entity, Nanos time);
  /// Checkpoint `checkpoint` was passed at `time`. `count`: the checkpoint's cumulative count
  /// of reports (`CheckpointReport::count`, a cycle's number), from which reports lost between
  /// two are counted; 0 when not known (one report). An entity that reports before it was
  /// activated is activated then. Unknown handles are ignored.
  void report(int checkpoint, Nanos time, std::uint64_t count = 0);

  // --- judging -------------------------------------------------------------------------------
  /// Applies the inputs time-stamped before `now - settle_ns` and judges everything due by
  /// then; failures found are stamped `detected_ns = now` and queued for take_failures().
  void advance(Nanos now);
  /// As advance(now), when the inputs are known complete only up to `drained_to` (the time the
  /// drain that brought them began: ports drained one after the other): inputs and due times
  /// after `drained_to - settle_ns` wait for the next call; what is found is stamped `now`.
  void advance(Nanos now, Nanos drained_to);
  /// The earliest time at which advance() has something to judge: a due time or a waiting
  /// input, plus `settle_ns`; kNever when nothing waits. Call advance() then. An active deadline
  /// supervision waiting for its start also asks for an advance (a drain) at least every max_ns
  /// after the latest one: its start is known only once drained, and must be before its
  /// deadline passes for the missing end to be found when it does.
  [[nodiscard]] Nanos next_deadline() const noexcept;
  /// The failures found since the last call, in the order found.
  [[nodiscard]] std::vector<Failure> take_failures();
  /// Failures found and not taken yet.
  [[nodiscard]] std::size_t pending_failures() const noexcept;

  // --- results -------------------------------------------------------------------------------
  /// One report per supervision, alive ones first, then deadline, then logical, each in the
  /// configuration's order.
  [[nodiscard]] std::vector<SupervisionReport> reports() const;
  /// The status of supervision `name` (Deactivated for an unknown name).
  [[nodiscard]] SupervisionStatus status(std::string_view name) const;
  /// The latest start/end pairs (at most kKeptSpans per deadline supervision) of the deadline
  /// supervisions whose start or end is on entity `entity`, that end at or after `from`, oldest
  /// first within each supervision.
  [[nodiscard]] std::vector<DeadlineSpan> deadline_spans(std::string_view entity,
                                                         Nanos from = 0) const;
  /// Start/end pairs kept per deadline supervision for deadline_spans().
  static constexpr std::size_t kKeptSpans = 64;
  /// The configuration (validated).
  [[nodiscard]] const HealthConfig& config() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vigil::health
