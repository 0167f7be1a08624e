#pragma once
/// @file
/// The configuration of health supervision in C++: which supervised entities (components) and
/// checkpoints are supervised, and how (AUTOSAR PHM's three kinds):
///
/// - **alive supervision**: a checkpoint (or the entity's cycles) must be reported a number of
///   times per *reference cycle* (a window), within a min and a max margin;
/// - **deadline supervision**: the time from a start checkpoint to an end checkpoint must be
///   within [min, max], in one entity, across entities or across processes;
/// - **logical supervision**: the checkpoints must follow a graph of allowed transitions, from
///   an initial checkpoint to a final one.
///
/// ```cpp
/// vigil::health::HealthConfig config;
/// config.alive.push_back({.name = "drive_alive", .checkpoint = {"drive"},  // its cycles
///                         .reference_cycle_ns = 10'000'000, .expected_indications = 10,
///                         .min_margin = 1, .max_margin = 1, .failed_cycles_tolerance = 2});
/// config.deadline.push_back({.name = "sense_to_act", .start = {"camera", "frame"},
///                            .end = {"drive", "command_sent"}, .max_ns = 2'000'000});
/// config.logical.push_back({.name = "control_sequence",
///                           .initial = {{"drive", "read"}}, .final = {{"drive", "write"}},
///                           .transitions = {{{"drive", "read"}, {"drive", "compute"}},
///                                           {{"drive", "compute"}, {"drive", "write"}}}});
/// ```
///
/// Plain aggregates: build them, then hand them to a `HealthEngine` (or the aggregator's
/// `supervise_health()`), which validates them. Not RT-safe.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::health {

/// One checkpoint of one supervised entity.
struct CheckpointRef {
  CheckpointRef() = default;
  /// `{"drive", "read"}`; `{"drive"}`: the entity's cycles. Implicit, for braced lists.
  CheckpointRef(std::string entity_name,  // NOLINT(google-explicit-constructor)
                std::string checkpoint_name = {})
      : entity(std::move(entity_name)), checkpoint(std::move(checkpoint_name)) {}
  CheckpointRef(const char* entity_name)  // NOLINT(google-explicit-constructor)
      : entity(entity_name) {}
  std::string entity;  ///< the supervised entity: the component's name
  /// The checkpoint's declared name; empty: the entity's cycles (every supervised cycle of the
  /// component is one indication, with no checkpoint to declare).
  std::string checkpoint;
  friend bool operator==(const CheckpointRef&, const CheckpointRef&) = default;
};
/// "entity.checkpoint", or "entity (cycles)".
[[nodiscard]] std::string to_string(const CheckpointRef& ref);

/// Alive supervision of one checkpoint (or of an entity's cycles).
struct AliveSupervisionConfig {
  std::string name;  ///< unique among every supervision
  CheckpointRef checkpoint;
  /// The reference cycle: the window over which indications are counted (> 0). Windows follow
  /// each other from the entity's activation.
  Nanos reference_cycle_ns = 0;
  /// Indications expected per reference cycle.
  std::uint32_t expected_indications = 1;
  /// A window with fewer than expected - min_margin indications fails (too rare).
  std::uint32_t min_margin = 0;
  /// A window with more than expected + max_margin indications fails (too often), detected
  /// when the indication that exceeds it arrives.
  std::uint32_t max_margin = 0;
  /// Failed reference cycles tolerated: while the failed windows (each correct window takes
  /// one back) are within it the supervision is FAILED, beyond it EXPIRED. 0: EXPIRED at once.
  std::uint32_t failed_cycles_tolerance = 0;
  /// The entity must run: an entity that has not become active (reported, or entered Running)
  /// this long after the engine started is EXPIRED. 0: no start-up check.
  Nanos startup_grace_ns = kNanosPerSecond;
};

/// Deadline supervision: the time from `start` to `end`.
struct DeadlineSupervisionConfig {
  std::string name;  ///< unique among every supervision
  CheckpointRef start;
  CheckpointRef end;  ///< another checkpoint than start; any entity (any process)
  Nanos min_ns = 0;   ///< an end sooner than this after its start fails (too early)
  /// An end later than this fails; no end by then is detected when it passes (> 0, >= min_ns).
  Nanos max_ns = 0;
  /// Failures tolerated before EXPIRED (each correct start/end pair takes one back); 0: EXPIRED
  /// at the first (AUTOSAR's deadline supervision has no FAILED state).
  std::uint32_t failed_tolerance = 0;
};

/// One allowed transition of a logical supervision's graph.
struct Transition {
  CheckpointRef from;
  CheckpointRef to;
};

/// Logical supervision: the checkpoints must follow the graph of `transitions`. A sequence
/// begins at an initial checkpoint and ends at a final one (after which an initial one must
/// come next); a graph without final checkpoints cycles for ever.
struct LogicalSupervisionConfig {
  std::string name;                    ///< unique among every supervision
  std::vector<CheckpointRef> initial;  ///< at least one
  std::vector<CheckpointRef> final;    ///< may be empty (a cyclic graph)
  std::vector<Transition> transitions;
  /// Invalid transitions tolerated before EXPIRED (each valid one takes one back); 0: EXPIRED
  /// at the first.
  std::uint32_t failed_tolerance = 0;
};

/// Every supervision of one engine.
struct HealthConfig {
  std::vector<AliveSupervisionConfig> alive;
  std::vector<DeadlineSupervisionConfig> deadline;
  std::vector<LogicalSupervisionConfig> logical;
  /// How long past a due time the engine waits before it judges it, so that a checkpoint
  /// time-stamped just before and pushed just after is counted. Detection latency includes it.
  Nanos settle_ns = 20 * kNanosPerMicro;
  /// Last transitions a logical supervision's failure text names.
  std::uint32_t history = 4;
};

/// Checks `config`: a name empty or used twice, an empty entity, a reference cycle or a max
/// that is not positive, min > max, margins beyond the expected count, a deadline from a
/// checkpoint to itself, a graph with no initial checkpoint, an initial or final checkpoint
/// that no transition names, a checkpoint unreachable from every initial one. The error names
/// the supervision and the field ("deadline 'x': min_ns (5 ms) > max_ns (2 ms)"). Not RT-safe.
[[nodiscard]] expected<void, Error> validate(const HealthConfig& config);

}  // namespace vigil::health
