#pragma once
/// @file
/// `ComponentAggregator`: the supervisor handler for component messages. It keeps one record per
/// component (identity, state, cumulative counters, statistics of user time, total time, wake-up
/// latency, period and supervision overhead) and hands consistent snapshots to readers.
///
/// Design: the supervisor thread is the only writer. Each record has its own mutex, held by the
/// supervisor while it applies one port's batch and by a reader while it copies one record, so a
/// reader never blocks the supervisor for longer than one record copy and never touches the RT
/// side. The record list has a separate mutex, taken exclusively only when components join or are
/// forgotten.

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/bus/registry.hpp"
#include "vigil/log/consumer.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/supervisor/supervisor.hpp"
#include "vigil/task/default_registry.hpp"
#include "vigil/task/messages.hpp"

namespace vigil {

/// Everything known about one component at one moment. Plain data: copy it freely.
struct ComponentSnapshot {
  std::uint32_t id = 0;
  std::string name;
  bool alive = true;      ///< false once the component left (kept for a while)
  bool has_info = false;  ///< a TaskInfo arrived (the component was configured)
  TaskInfo info;
  TaskState state = TaskState::PreOperational;
  bool has_sample = false;
  CycleSample last;  ///< latest cycle sample received
  std::uint64_t samples = 0;
  Counters counters;     ///< cumulative, exact even when samples were dropped
  StatsSummary user_ns;  ///< on_update() alone
  /// user + the latest measured supervision overhead: count, min, max, mean and EWMA exact;
  /// percentiles are user_ns's plus that overhead (capped at max).
  StatsSummary total_ns;
  StatsSummary latency_ns;   ///< wake-up latency: start - scheduled release
  StatsSummary period_ns;    ///< start-to-start of consecutive cycles
  StatsSummary overhead_ns;  ///< supervision's own time per cycle (sampled)
  bool has_exception = false;
  ExceptionReport last_exception;
  std::string last_exception_type;  ///< demangled
  /// The latest real-time loss reported (the cycle it happened in, its cause and count); the
  /// totals by cause are in `counters.losses`.
  bool has_loss = false;
  RealTimeLoss last_loss;
  Nanos last_loss_at = 0;  ///< supervisor clock when it arrived
  bool has_state_change = false;
  StateChange last_change;
  Nanos joined_at = 0;       ///< supervisor clock
  Nanos last_sample_at = 0;  ///< supervisor clock when the latest sample was drained; 0 if none
  Nanos left_at = 0;
  std::size_t port_capacity = 0;
  std::size_t port_high_water = 0;

  /// Overhead as a share of total time (mean overhead / mean total), 0 when unknown.
  [[nodiscard]] double overhead_share() const noexcept {
    return total_ns.mean > 0 ? overhead_ns.mean / total_ns.mean : 0.0;
  }
};

/// One component's distributions, lent to a `ComponentAggregator::visit_distributions` callback
/// for the duration of the call (the pointers are valid only then). For exporters that need the
/// histograms behind the percentiles (Prometheus buckets).
struct ComponentDistributions {
  std::uint32_t id = 0;
  std::string_view name;
  const RunningStats* user = nullptr;      ///< on_update() alone
  const RunningStats* latency = nullptr;   ///< wake-up latency
  const RunningStats* period = nullptr;    ///< start-to-start of consecutive cycles
  const RunningStats* overhead = nullptr;  ///< supervision's own time per cycle (sampled)
  /// Total time has no histogram of its own: it is user time plus this (the latest measured
  /// overhead), as for `ComponentSnapshot::total_ns`' percentiles.
  Nanos total_shift_ns = 0;
  StatsSummary total;  ///< total time's exact count, min, max, mean, EWMA
};

/// Options of the aggregator.
struct AggregatorOptions {
  /// Weight of the newest sample in the EWMAs (0 < w <= 1).
  double ewma_weight = kDefaultEwmaWeight;
  /// How long a component that left stays in snapshots.
  Nanos retain_left_ns = 60 * kNanosPerSecond;
  /// Supervisor-side clock used to stamp arrivals (for staleness checks).
  Clock clock = Clock::system();
};

/// The supervisor handler for `Message`. Not RT-safe (supervisor thread and readers only).
class ComponentAggregator {
 public:
  using Entry = RegistryEntry<Message>;

  explicit ComponentAggregator(AggregatorOptions options = {});
  ~ComponentAggregator();
  ComponentAggregator(const ComponentAggregator&) = delete;
  ComponentAggregator& operator=(const ComponentAggregator&) = delete;

  // --- SupervisorHandler (supervisor thread) ---
  void on_join(const Entry& e);
  void on_leave(const Entry& e);
  void begin(const Entry& e);
  void on(const Entry& e, const TaskInfo& m);
  void on(const Entry& e, const CycleSample& m);
  void on(const Entry& e, const RealTimeLoss& m);
  void on(const Entry& e, const ExceptionReport& m);
  void on(const Entry& e, const StateChange& m);
  void on(const Entry& e, const log::LogRecord& m);  // forwarded to the log consumer, if any
  /// Any other message type (one added to `Message` later): ignored until a handler cares.
  template <class M>
  void on(const Entry& /*e*/, const M& /*m*/) {}
  void end(const Entry& e, const PortDrain& d);
  void on_cycle(const SupervisorCycle& c);

  // --- readers (any thread) ---
  /// A consistent copy of every component's record, ordered by id.
  [[nodiscard]] std::vector<ComponentSnapshot> snapshot() const;
  /// The record of component `name` (the first alive one of that name), if any.
  [[nodiscard]] std::optional<ComponentSnapshot> find(std::string_view name) const;
  /// Calls `visit` for every record, in id order, holding that record's lock during the call:
  /// keep it short (no I/O), the supervisor waits for it. Any thread; not RT-safe. `visit` must
  /// not call back into the aggregator.
  void visit_distributions(const std::function<void(const ComponentDistributions&)>& visit) const;
  /// Number of records (alive and recently left).
  [[nodiscard]] std::size_t size() const;
  /// Changes the EWMA weight for every record (takes effect for new samples).
  void set_ewma_weight(double w);
  /// Where drained log records go (null: dropped). Any thread; the consumer must outlive the
  /// supervisor's cycles (set null before destroying it).
  void set_log_consumer(log::RecordConsumer* c) noexcept { log_consumer_.store(c); }

  struct Slot;

 private:
  Slot* slot_for(const Entry& e);
  AggregatorOptions options_;
  std::atomic<double> ewma_weight_;
  mutable std::shared_mutex list_mutex_;
  std::vector<std::unique_ptr<Slot>> slots_;  // ordered by id
  std::vector<std::uint32_t> ids_;            // slots_[i]'s id, contiguous for the searches
  std::size_t hint_ = 0;                      // where the next port's slot probably is
  std::size_t departed_ = 0;                  // records of components that left
  Slot* current_ = nullptr;                   // the slot between begin() and end()
  Nanos drain_time_ = 0;                      // supervisor clock at begin()
  std::atomic<log::RecordConsumer*> log_consumer_{nullptr};
};

static_assert(SupervisorHandler<ComponentAggregator, Message>);

/// The supervisor of tasks: one non-RT thread (or step()) that drains the port of every
/// component of a registry into a ComponentAggregator. Each component's own side is its
/// Task<Derived> or Instrumentation. (Was `ComponentSupervisorLoop`.)
using TaskSupervisor = Supervisor<Message, ComponentAggregator>;

}  // namespace vigil
