#pragma once
/// @file
/// `HealthSupervision`: health supervision (alive, deadline, logical; vigil/health) driven by
/// the supervisor's drain. The `ComponentAggregator` owns one when a program asks for it
/// (`ComponentAggregator::supervise_health`) and hands it, from the drain thread, what the
/// ports carry: components joining and leaving, their lifecycle (entering Running activates a
/// supervised entity, a stop deactivates it), their cycles and their checkpoint reports. After
/// each drain it judges what is due (`advance`) and the aggregator raises the failures as
/// events. The drain thread sleeps until the earlier of its next period and `next_deadline()`,
/// so a missed deadline is found when it passes, not at the next drain.
///
/// Design: the drain thread is the only one that feeds the engine; a mutex, held for one call,
/// lets readers (`reports()`) and a program (`deactivate()`, `activate()`) in from any thread.
/// Each component's checkpoint names are resolved once (its reports carry them), then a report
/// costs a lock, an index and a queue append. Not RT-safe.

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "vigil/health/checkpoint.hpp"
#include "vigil/health/config.hpp"
#include "vigil/health/engine.hpp"
#include "vigil/health/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/events.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::supervisor {

/// Per-component checkpoint statistics (a program's view of its checkpoints' health).
struct CheckpointUse {
  std::string component;
  std::uint64_t reports = 0;  ///< checkpoint reports drained (every checkpoint, supervised or not)
  std::uint32_t misuses = 0;  ///< reports of ids the component did not declare
};

class HealthSupervision {
 public:
  /// Builds the engine for `config` (validated: throws std::invalid_argument with the reason).
  /// `clock`: the supervisor's clock (time of detection, of program requests).
  explicit HealthSupervision(health::HealthConfig config, Clock clock = Clock::system());
  HealthSupervision(const HealthSupervision&) = delete;
  HealthSupervision& operator=(const HealthSupervision&) = delete;

  // --- the drain thread (the aggregator calls these) -------------------------------------------
  void join(std::uint32_t id, std::string_view name);
  void leave(std::uint32_t id);
  /// A lifecycle transition of component `id`: Running activates its entity, Stopped or
  /// PreOperational (a stop on purpose) deactivates it; Exception and FatalError do not (the
  /// supervisions then see the component fall silent).
  void state(std::uint32_t id, const task::StateChange& m);
  /// True when a supervision watches component `id`'s cycles (then call cycle() per sample).
  [[nodiscard]] bool watches_cycles(std::uint32_t id);
  void cycle(std::uint32_t id, const task::CycleSample& m);
  void checkpoint(std::uint32_t id, const health::CheckpointReport& m);
  /// Judges what is due at `now` and appends the failures (and misuses) as events to `out`,
  /// with the component's id when it is known (0 otherwise: an entity that never joined).
  void advance(Nanos now, std::vector<Event>& out);
  /// As above, the reports complete up to `drained_to` only (when the drain pass began).
  void advance(Nanos now, Nanos drained_to, std::vector<Event>& out);
  /// When advance() has something to judge next (kNever: nothing).
  [[nodiscard]] Nanos next_deadline() const;

  // --- any thread ------------------------------------------------------------------------------
  /// A copy of every supervision's report.
  [[nodiscard]] std::vector<health::SupervisionReport> reports() const;
  /// The status of supervision `name` (Deactivated for an unknown one).
  [[nodiscard]] health::SupervisionStatus status(std::string_view name) const;
  /// Entity `name` need not run (a mode where it is idle): its supervisions are DEACTIVATED,
  /// and one that has not started is not expected to. False for an entity no supervision names.
  bool deactivate(std::string_view entity);
  /// Entity `name` must run again (its supervisions restart now). False for an unknown entity.
  bool activate(std::string_view entity);
  /// What a flight record of component `id` shows besides its cycles: its latest checkpoints
  /// (at most kKeptCheckpoints) passed at or after `from`, oldest first, and the latest
  /// start/end pairs of the deadline supervisions that start or end on it.
  void trace(std::uint32_t id, Nanos from, std::vector<health::CheckpointMark>& marks,
             std::vector<health::DeadlineSpan>& spans) const;
  /// Checkpoint reports kept per component for trace().
  static constexpr std::size_t kKeptCheckpoints = 512;
  /// Checkpoint statistics per component that reported one.
  [[nodiscard]] std::vector<CheckpointUse> checkpoint_use() const;
  [[nodiscard]] const health::HealthConfig& config() const noexcept { return engine_.config(); }

 private:
  struct Binding {
    std::string name;
    int entity = -1;
    int cycles = -1;               // the engine's handle of its cycles, or -1
    std::vector<int> checkpoints;  // report index -> engine handle; -2: not resolved yet
    std::uint64_t reports = 0;
    std::uint32_t misuses = 0;
    std::uint32_t misuses_raised = 0;
    bool alive = true;
    // The latest checkpoint reports (a ring of kKeptCheckpoints, allocated at the first one).
    struct Mark {
      Nanos time = 0;
      std::uint64_t cycle = 0;
      std::uint16_t index = 0;
    };
    std::vector<Mark> recent;
    std::size_t next = 0;  // where the next one goes
    std::uint64_t kept = 0;
    std::vector<std::string> names;  // report index -> declared name
  };
  Binding* binding(std::uint32_t id);

  mutable std::mutex mutex_;
  health::HealthEngine engine_;
  Clock clock_;
  std::unordered_map<std::uint32_t, Binding> bindings_;
  std::map<std::string, std::uint32_t, std::less<>> ids_;  // entity name -> latest component id
  std::uint32_t cached_id_ = 0;
  Binding* cached_ = nullptr;
};

}  // namespace vigil::supervisor
