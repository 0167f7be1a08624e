#pragma once
/// @file
/// `ComponentAggregator`: the supervisor handler for component messages. It keeps one record per
/// component (identity, state, cumulative counters, statistics of execution time, total time,
/// wake-up latency, measured period and supervision overhead) and hands consistent snapshots to
/// readers.
///
/// Design: the supervisor thread is the only writer. Each record has its own mutex, held by the
/// supervisor while it applies one port's batch and by a reader while it copies one record, so a
/// reader never blocks the supervisor for longer than one record copy and never touches the RT
/// side. The record list has a separate mutex, taken exclusively only when components join or are
/// forgotten.
///
/// Scale: a record's hot part (what the per-message work touches: ~14 cache lines) comes before
/// its cold part, and its four distributions are `CompactRunningStats` (the buckets of the seen
/// range only), so that thousands of records stay cheap to drain (docs/design/supervision.md).

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/bus/registry.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/health/config.hpp"
#include "vigil/health/report.hpp"
#include "vigil/log/consumer.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#include "vigil/supervisor/events.hpp"
#include "vigil/supervisor/flight_recorder.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/default_registry.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::supervisor {

class HealthSupervision;

/// A component's latched fault: the first Error event since the latch was last cleared raised
/// it; later Error events only count and move `last_*`. It stays until cleared
/// (`ComponentAggregator::clear`, auto-clear, the HTTP clear endpoint).
struct LatchedFault {
  bool active = false;
  EventKind first_kind = EventKind::Exception;
  EventKind last_kind = EventKind::Exception;
  Nanos first_ns = 0;       ///< detection time of the first event (supervisor clock)
  Nanos last_ns = 0;        ///< detection time of the latest event
  std::uint64_t count = 0;  ///< Error events since it was raised
  std::string first_detail;
  std::string last_detail;
  std::uint64_t raised = 0;   ///< times it was raised since the component joined
  std::uint64_t cleared = 0;  ///< times it was cleared
};

/// Everything known about one component at one moment. Plain data: copy it freely.
struct ComponentSnapshot {
  std::uint32_t id = 0;
  std::string name;
  bool alive = true;      ///< false once the component left (kept for a while)
  bool has_info = false;  ///< a TaskInfo arrived (the component was configured)
  task::TaskInfo info;
  TaskState state = TaskState::PreOperational;
  bool has_sample = false;
  task::CycleSample last;  ///< latest cycle sample received
  std::uint64_t samples = 0;
  task::Counters counters;    ///< cumulative, exact even when samples were dropped
  StatsSummary execution_ns;  ///< on_update() alone
  /// execution + the latest measured supervision overhead: count, min, max, mean and EWMA exact;
  /// percentiles are execution_ns's plus that overhead (capped at max).
  StatsSummary total_ns;
  StatsSummary latency_ns;          ///< wake-up latency: start - scheduled release
  StatsSummary measured_period_ns;  ///< start-to-start of consecutive cycles
  StatsSummary overhead_ns;         ///< supervision's own time per cycle (sampled)
  bool has_exception = false;
  task::ExceptionReport last_exception;
  std::string last_exception_type;  ///< demangled
  /// The latest real-time loss reported (the cycle it happened in, its cause and count); the
  /// totals by cause are in `counters.losses`.
  bool has_loss = false;
  task::RealTimeLoss last_loss;
  Nanos last_loss_at = 0;  ///< supervisor clock when it arrived
  bool has_state_change = false;
  task::StateChange last_change;
  Nanos joined_at = 0;  ///< supervisor clock
  /// Supervisor clock when the latest sample was drained (read once per 16 port drains, so
  /// within microseconds of it); 0 if none.
  Nanos last_sample_at = 0;
  Nanos left_at = 0;
  std::size_t port_capacity = 0;
  std::size_t port_high_water = 0;
  /// Warm-up: the first cycles after the component started running (AggregatorOptions::
  /// warmup_ns) are counted in `counters` but kept out of every timing statistic above; the
  /// monitor's windows start after them too.
  bool warming_up = false;
  std::uint64_t warmup_cycles = 0;  ///< samples kept out of the statistics
  /// The counters when the latest warm-up ended (zeros before): overruns etc. of the warm-up.
  task::Counters warmup_counters;
  LatchedFault latch;
  /// Watchdog: the silence after which a Deadline event is raised (0: not watched).
  Nanos deadline_ns = 0;
  bool silent = false;                ///< the deadline passed and no cycle arrived since
  std::uint64_t deadline_misses = 0;  ///< Deadline events so far
  std::uint64_t events = 0;           ///< events raised for it so far

  /// Overhead as a share of total time (mean overhead / mean total), 0 when unknown.
  [[nodiscard]] double overhead_share() const noexcept {
    return total_ns.mean > 0 ? overhead_ns.mean / total_ns.mean : 0.0;
  }
};

/// One cycle that was the worst of a distribution over a window (an exemplar's candidate:
/// vigil/export/exemplars.hpp).
struct WorstCycle {
  std::uint64_t cycle = 0;  ///< the component's cycle number (0: none in that window)
  Nanos value_ns = 0;       ///< its value in that distribution
  Nanos start_ns = 0;       ///< when on_update() began (the component's clock)
};

/// The worst cycles of one distribution: of the latest complete window and of the current one
/// (`AggregatorOptions::worst_window_ns`, on the component's clock; the warm-up's cycles are
/// not in them, as in the statistics).
struct WorstCycles {
  WorstCycle previous;  ///< the latest complete window (cycle 0: no cycle in it)
  WorstCycle current;   ///< the window under way so far
};

/// One component's distributions, lent to a `ComponentAggregator::visit_distributions` callback
/// for the duration of the call (the pointers are valid only then). For exporters that need the
/// histograms behind the percentiles (Prometheus buckets).
struct ComponentDistributions {
  std::uint32_t id = 0;
  std::string_view name;
  const CompactRunningStats* execution = nullptr;        ///< on_update() alone
  const CompactRunningStats* latency = nullptr;          ///< wake-up latency
  const CompactRunningStats* measured_period = nullptr;  ///< start-to-start of consecutive cycles
  const CompactRunningStats* overhead = nullptr;  ///< supervision's own time per cycle (sampled)
  /// Total time has no histogram of its own: it is execution time plus this (the latest measured
  /// overhead), as for `ComponentSnapshot::total_ns`' percentiles.
  Nanos total_shift_ns = 0;
  StatsSummary total;  ///< total time's exact count, min, max, mean, EWMA
  /// The worst cycles of each distribution, by window (none when
  /// `AggregatorOptions::worst_window_ns` is 0).
  WorstCycles execution_worst, total_worst, latency_worst, measured_period_worst;
};

/// Options of the watchdog (part of `AggregatorOptions`).
struct WatchdogOptions {
  bool enabled = true;
  /// A periodic component is silent when no cycle arrived for max(periods x period, floor).
  double periods = 10;
  Nanos floor_ns = 30 * kNanosPerMilli;
  /// Limit for components without a period (0: they are not watched).
  Nanos aperiodic_ns = 0;
  /// The limit for a component of period `period_ns` (0: not watched).
  [[nodiscard]] Nanos limit(Nanos period_ns) const noexcept {
    if (!enabled) return 0;
    if (period_ns <= 0) return aperiodic_ns;
    // A period read from a hostile shared-memory segment can be huge: saturate, never overflow
    // (found by fuzzing, tests/fuzz/regressions/shm_segment/watchdog_period_overflow.bin).
    const double by = periods * static_cast<double>(period_ns);
    const Nanos by_periods =
        by < 9.0e18 ? static_cast<Nanos>(by) : Nanos{9'000'000'000'000'000'000};
    return by_periods > floor_ns ? by_periods : floor_ns;
  }
};

/// Options of the aggregator.
struct AggregatorOptions {
  /// Weight of the newest sample in the EWMAs (0 < w <= 1).
  double ewma_weight = kDefaultEwmaWeight;
  /// How long a component that left stays in snapshots.
  Nanos retain_left_ns = 60 * kNanosPerSecond;
  /// Supervisor-side clock used to stamp arrivals (for staleness checks) and events.
  Clock clock = Clock::system();
  /// The first cycles after a component starts running, measured on the component's clock from
  /// its first cycle, are kept out of the timing statistics and the monitor's windows (still
  /// counted). 0: no warm-up.
  Nanos warmup_ns = 100 * kNanosPerMilli;
  WatchdogOptions watchdog{};
  FlightRecorderOptions recorder{};
  EventHubOptions events{};
  /// A latched fault with no new Error event for this long is cleared (0: never).
  Nanos auto_clear_ns = 0;
  /// Raise an Info event for every lifecycle transition (Exception/FatalError are always
  /// raised, as Error).
  bool state_events = true;
  /// The worst cycle of each distribution is kept per window of this length, on the
  /// component's clock (`WorstCycles`: the exemplars of the OpenMetrics histograms name them).
  /// 0: not kept.
  Nanos worst_window_ns = kNanosPerSecond;
};

/// The supervisor handler for `Message`. Not RT-safe (supervisor thread and readers only).
class ComponentAggregator {
 public:
  using Entry = bus::RegistryEntry<task::Message>;

  explicit ComponentAggregator(AggregatorOptions options = {});
  ~ComponentAggregator();
  ComponentAggregator(const ComponentAggregator&) = delete;
  ComponentAggregator& operator=(const ComponentAggregator&) = delete;

  // --- SupervisorHandler (supervisor thread) ---
  void on_join(const Entry& e);
  void on_leave(const Entry& e);
  void begin(const Entry& e);
  void on(const Entry& e, const task::TaskInfo& m);
  void on(const Entry& e, const task::CycleSample& m);
  void on(const Entry& e, const task::RealTimeLoss& m);
  void on(const Entry& e, const task::ExceptionReport& m);
  void on(const Entry& e, const task::StateChange& m);
  void on(const Entry& e, const log::LogRecord& m);  // forwarded to the log consumer, if any
  void on(const Entry& e, const health::CheckpointReport& m);  // to health supervision, if any
  /// Any other message type (one added to `Message` later): ignored until a handler cares.
  template <class M>
  void on(const Entry& /*e*/, const M& /*m*/) {}
  /// A batch of `n` messages of the current port, in order: the same as `on()` for each, with
  /// cycle samples handled without a variant dispatch (the supervisor calls this when present).
  void on_batch(const Entry& e, const task::Message* messages, std::size_t n);
  void end(const Entry& e, const PortDrain& d);
  void on_cycle(const DrainCycle& c);
  /// When the supervisor must drain and judge next for health supervision (the earliest alive
  /// reference cycle end, deadline max or grace end, on this aggregator's clock); INT64_MAX
  /// when nothing waits, or when the clock is not the system's (a test steps it by hand).
  /// The supervisor's thread sleeps until the earlier of this and its next period.
  [[nodiscard]] Nanos next_deadline() const;

  // --- health supervision (vigil/health) ---
  /// Supervises `config`'s alive, deadline and logical supervisions from now on: checkpoint
  /// reports and cycles drained from then feed them, failures are raised as events
  /// (AliveSupervision, DeadlineSupervision, LogicalSupervision; Error when EXPIRED, latched on
  /// the component), and the drain thread wakes at their deadlines. Call it before the
  /// supervisor starts (or between step() calls); again, it replaces the previous one. Fails,
  /// with `health::validate()`'s message, for a bad configuration. Not RT-safe.
  expected<void, Error> supervise_health(health::HealthConfig config);
  /// The health supervision, or null when none was asked for (`supervise_health`): its
  /// reports, entity deactivation for modes, checkpoint statistics. Thread-safe.
  [[nodiscard]] HealthSupervision* health() const noexcept { return health_.get(); }
  /// A copy of every health supervision's report (empty when none). Any thread.
  [[nodiscard]] std::vector<health::SupervisionReport> health_reports() const;

  // --- readers (any thread) ---
  /// A consistent copy of every component's record, ordered by id.
  [[nodiscard]] std::vector<ComponentSnapshot> snapshot() const;
  /// The record of component `name` (the first alive one of that name), if any.
  [[nodiscard]] std::optional<ComponentSnapshot> find(std::string_view name) const;
  /// The record of component `id` (ids are never reused), if any: one copy, O(log n) to find it
  /// (snapshot() copies every record, with their percentiles).
  [[nodiscard]] std::optional<ComponentSnapshot> find_id(std::uint32_t id) const;
  /// Calls `visit` for every record, in id order, holding that record's lock during the call:
  /// keep it short (no I/O), the supervisor waits for it. Any thread; not RT-safe. `visit` must
  /// not call back into the aggregator.
  void visit_distributions(const std::function<void(const ComponentDistributions&)>& visit) const;
  /// Number of records (alive and recently left).
  [[nodiscard]] std::size_t size() const;
  /// Takes every drained cycle still waiting in the flight rings into the statistics now (a
  /// drain leaves up to three quarters of a ring waiting; every read catches its record up
  /// itself, so this changes no result: it moves the work, e.g. into a measurement). Any thread.
  void catch_up();
  /// Changes the EWMA weight for every record (takes effect for new samples).
  void set_ewma_weight(double w);
  /// Where drained log records go (null: dropped). Any thread; the consumer must outlive the
  /// supervisor's cycles (set null before destroying it).
  void set_log_consumer(log::RecordConsumer* c) noexcept { log_consumer_.store(c); }
  /// Called at the end of every supervisor cycle, on the supervisor's thread, with the
  /// aggregator's clock (the service's cross-check of its monitor). Set it before the supervisor
  /// starts; it must not block.
  void set_cycle_hook(std::function<void(Nanos)> hook) { cycle_hook_ = std::move(hook); }

  // --- events, latches, flight recorder (any thread) ---
  /// The events raised by this aggregator: subscribe there (thread-safe, hence usable through
  /// a const aggregator).
  [[nodiscard]] EventHub& events() const noexcept { return events_; }
  /// Clears the latched fault of every component named `name`; raises a Cleared event each.
  /// Returns how many were latched. Any thread.
  std::size_t clear(std::string_view name);
  /// Clears every latched fault. Returns how many were latched. Any thread.
  std::size_t clear_all();
  /// The flight record frozen with event `seq` (`Event::traced`), if still kept (the latest
  /// `recorder.max_records` are). Any thread.
  [[nodiscard]] std::shared_ptr<const FlightRecord> frozen_record(std::uint64_t seq) const;
  /// Every frozen record still kept, oldest first. Any thread.
  [[nodiscard]] std::vector<std::shared_ptr<const FlightRecord>> frozen_records() const;
  /// The flight recorder of component `name` now (on demand), if it exists. Any thread.
  [[nodiscard]] std::optional<FlightRecord> flight_record(std::string_view name) const;
  [[nodiscard]] const AggregatorOptions& options() const noexcept { return options_; }
  /// True while drains write the flight rings with streaming stores (`RingStores`; with Auto it
  /// changes as components join and are forgotten). Supervisor thread.
  [[nodiscard]] bool streams_rings() const noexcept { return stream_rings_; }
  /// The rule of `RingStores` (Auto and the others): whether the rings stream when the drains
  /// sweep through `drained_bytes` in all (every component's flight ring and port), on a CPU
  /// whose last-level cache holds `cache_bytes` (0: unknown, never streams). Auto: beyond four
  /// times the cache.
  [[nodiscard]] static bool streams_rings(RingStores mode, std::size_t drained_bytes,
                                          std::size_t cache_bytes) noexcept;

  /// Flight rings whose slots are on huge pages (`RingPages`), and the bytes of the 2 MiB
  /// regions mapped for them (counted in no malloc statistic). Supervisor thread.
  [[nodiscard]] std::size_t rings_on_huge_pages() const noexcept;
  [[nodiscard]] std::size_t ring_region_bytes() const noexcept;

  /// The instruction set the statistics' catch-up runs with (the bulk update of a component's
  /// statistics, every few hundred of its cycles; docs/design/supervision.md, "Instruction
  /// sets"). On x86-64 it is compiled twice, and the process picks `LzcntBmi2` when the CPU has
  /// LZCNT, BMI1 and BMI2 (every x86-64 core since about 2013), else `Base`. Both give the same
  /// results, bit for bit; only their speed differs. A build that targets those instructions
  /// already (`-march=haswell` or later) has only `LzcntBmi2`; other CPUs, only `Base`.
  enum class InstructionSet { Base, LzcntBmi2 };
  /// The catch-up's instruction set in this process. Any thread.
  [[nodiscard]] static InstructionSet instruction_set() noexcept;
  /// Makes every aggregator of the process use `set` from their next catch-up (to compare, or to
  /// rule the faster one out). False, and nothing changes, when this build or CPU has no such
  /// copy. Any thread.
  static bool set_instruction_set(InstructionSet set) noexcept;
  /// The name of `set`: "base", "lzcnt+bmi2".
  [[nodiscard]] static const char* name(InstructionSet set) noexcept;

  struct Slot;

 private:
  [[nodiscard]] platform::HugePageBlocks* ring_blocks_for_next() const noexcept;
  Slot* slot_for(const Entry& e);
  void take_sample(Slot& s, const task::CycleSample& m);  // all but the copy into data.last
  void raise(Slot& s, Event e);
  // Adds health supervision's checkpoints and deadline spans to a flight record.
  void add_health_trace(FlightRecord& r) const;  // the slot is locked by the caller
  void resolve_pending(Slot& s, const task::CycleSample* sample);
  void watch(Slot& s, Nanos now);
  std::size_t clear_slot(Slot& s, const char* why);
  AggregatorOptions options_;
  std::atomic<double> ewma_weight_;
  mutable std::shared_mutex list_mutex_;
  // Where rings come from (RingPages); before slots_: destroyed after the rings given back to it.
  std::unique_ptr<platform::HugePageBlocks> ring_blocks_;
  std::vector<std::unique_ptr<Slot>> slots_;  // ordered by id
  std::vector<std::uint32_t> ids_;            // slots_[i]'s id, contiguous for the searches
  std::size_t hint_ = 0;                      // where the next port's slot probably is
  std::size_t departed_ = 0;                  // records of components that left
  Slot* current_ = nullptr;                   // the slot between begin() and end()
  Nanos drain_time_ = 0;                      // supervisor clock at begin() (every 16th port)
  std::uint32_t clock_reads_ = 0;             // ports since the clock was read
  std::size_t drained_ = 0;                   // messages of the current port's drain so far
  std::atomic<log::RecordConsumer*> log_consumer_{nullptr};
  std::function<void(Nanos)> cycle_hook_;
  std::unique_ptr<HealthSupervision> health_;  // supervise_health(); set while not draining
  std::vector<Event> health_events_;           // advance()'s output, reused
  std::size_t raise_health(Nanos now, Nanos drained_to);  // advance() health, raise what it found
  mutable std::mutex frozen_mutex_;  // frozen_: taken before the hub's lock, never after
  std::deque<std::shared_ptr<const FlightRecord>> frozen_;
  std::size_t frozen_total_ = 0;
  std::size_t cache_bytes_ = 0;      // last-level cache (RingStores::Auto)
  std::size_t footprint_bytes_ = 0;  // every record's ring and port
  bool stream_rings_ = false;        // streams_rings()
  void choose_ring_stores() noexcept;
  mutable EventHub events_;  // last: destroyed first, its dispatchers may still read the above
};

static_assert(SupervisorHandler<ComponentAggregator, task::Message>);

/// The supervisor of tasks: one non-RT thread (or step()) that drains the port of every
/// component of a registry into a ComponentAggregator. Each component's own side is its
/// Task<Derived> or Instrumentation. (Was `ComponentSupervisorLoop`.)
using ComponentDrainLoop = DrainLoop<task::Message, ComponentAggregator>;

}  // namespace vigil::supervisor
