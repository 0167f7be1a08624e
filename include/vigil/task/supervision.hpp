#pragma once
/// @file
/// Supervision options, and `CycleRecorder`, the one implementation of per-cycle supervision
/// behind both front ends: `Task<Derived>` and `Instrumentation`.

#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/health/checkpoint.hpp"
#include "vigil/log/source.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/tsc.hpp"
#include "vigil/task/default_registry.hpp"
#include "vigil/task/messages.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::task {

/// Default capacity of a component's port: 256 messages of 128 bytes (32 KiB). At 1 kHz and a
/// supervisor period of 10 ms a component queues about 10 messages, so this absorbs a supervisor
/// stalled for a quarter of a second before any sample is dropped (counters stay exact even then).
inline constexpr std::size_t kDefaultPortCapacity = 256;

/// Compile-time options of a supervised task (a traits struct, as quill does).
struct DefaultTaskTraits {
  static constexpr std::size_t port_capacity = kDefaultPortCapacity;
};

/// Run-time options of supervision, per component.
struct SupervisionOptions {
  /// Real-time-loss detectors to run around on_update(). None by default: the cheapest.
  Detectors detectors = Detectors::None;
  /// Measure supervision's own overhead (two more clock reads) on one cycle in this many
  /// (any count: the first cycle, then one in this many); 1 = every cycle, 0 = never. User time
  /// is measured on every cycle.
  std::uint32_t overhead_sample_every = 64;
  /// While the safe state is requested (vigil/safe_state.hpp), stop the component (its
  /// on_stop(), in its own thread, at its next cycle) instead of running on_update(). A component
  /// that defines `on_safe_state()` runs that fallback instead and ignores this.
  bool stop_on_safe_state = false;
};

namespace detail {

/// Per-cycle supervision of one component: measures, counts, and pushes messages to the
/// component's port. Every member marked RT-safe is wait-free and allocation-free; it makes a
/// system call only when a detector that needs one (Blocking, PageFaults) is enabled.
///
/// Design: one producer, the component's thread (or, before the task runs, the thread calling its
/// commands; both are ordered by the activity's hand-over). Messages that could not be pushed
/// because the port was full are kept (the latest of each kind) and pushed again before the next
/// sample, so identity, exceptions and state changes are not lost to a full port; samples are
/// dropped and counted, and every sample carries exact cumulative counters.
template <std::size_t N>
class CycleRecorder {
 public:
  CycleRecorder(std::string name, SupervisionOptions options, Registry<Message>& registry)
      : name_(std::move(name)), options_(options), membership_(registry.join<N>(name_)) {
    set_options(options);
  }

  /// Leaves the registry with the final totals and anything still kept as "last words", so the
  /// supervisor's counts are exact even if the port was full at the end. Not RT-safe.
  ~CycleRecorder() {
    std::vector<Message> words;
    if ((pending_ & kInfo) != 0) words.emplace_back(info_);
    if ((pending_ & kException) != 0) words.emplace_back(exception_);
    if ((pending_ & kChange) != 0) words.emplace_back(change_);
    words.emplace_back(totals());
    membership_.leave(std::move(words));
  }
  CycleRecorder(const CycleRecorder&) = delete;
  CycleRecorder& operator=(const CycleRecorder&) = delete;

  /// Changes options; call before the component runs (not while it runs). Not RT-safe.
  void set_options(SupervisionOptions options) noexcept {
    options_ = options;
    const Detectors d = options.detectors;
    mode_ = static_cast<std::uint8_t>((mode_ & (kLookAtClock | kTscClock | kReplacedClock)) |
                                      (d == Detectors::None         ? 0
                                       : d == Detectors::Allocation ? kAllocationDetector
                                                                    : kOtherDetectors));
    // Cycles measured: the next one, then one in `every`, by number (a comparison per cycle, no
    // store). Never: cycle 0, which no cycle is.
    measure_every_ = options.overhead_sample_every;
    measured_cycle_ = measure_every_ == 0 ? 0 : counters().cycles + 1;
  }
  [[nodiscard]] const SupervisionOptions& options() const noexcept { return options_; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] Port<Message, N>* port() const noexcept { return membership_.port(); }

  /// Sends the component's identity (from its activity if it has one). RT-safe.
  void send_info(const ActivityInfo* a, bool threaded) noexcept {
    TaskInfo& i = info_;
    i.name.assign(name_);
    i.detectors = options_.detectors;
    i.port_capacity = static_cast<std::uint32_t>(N);
    if (a != nullptr) {
      i.activity.assign(a->name);
      i.requested_policy = a->requested_policy;
      i.policy = a->policy;
      i.realtime_refused = a->realtime_refused;
      i.priority = a->priority;
      i.cpu = a->cpu;
      i.tid = a->tid;
      i.period_ns = a->period_ns;
      i.overrun_policy = a->overrun_policy;
      i.tasks_on_thread = a->tasks_on_thread.load(std::memory_order_relaxed);
    }
    i.threaded = threaded;
    if (threaded && i.tid == 0) i.tid = platform::current_tid();
    pending_ |= kInfo;
    flush();
  }
  /// Sends identity for code without an activity (Instrumentation::init). RT-safe.
  void send_info(const TaskInfo& info) noexcept {
    info_ = info;
    info_.name.assign(name_);
    info_.detectors = options_.detectors;
    info_.port_capacity = static_cast<std::uint32_t>(N);
    pending_ |= kInfo;
    flush();
  }

  /// Reports a transition. RT-safe.
  void on_transition(TaskState from, TaskState to, Hook hook, bool refused, std::string_view reason,
                     Nanos now) noexcept {
    change_ = StateChange{now, from, to, hook, refused, {}};
    change_.reason.assign(reason);
    state_ = refused ? from : to;
    // (Re)started: the first cycle looks at the clock again (an activity passes the same Clock
    // on every cycle of a run).
    if (state_ == TaskState::Running) mode_ |= kLookAtClock;
    pending_ |= kChange;
    // Leaving Running: send the totals again, in case the latest samples were dropped.
    if (!refused && from == TaskState::Running && counters().cycles > 0) pending_ |= kTotals;
    flush();
  }

  /// Reports an exception caught at a hook boundary. RT-safe.
  void on_exception(Hook hook, std::string_view type, std::string_view what) noexcept {
    ++counters().exceptions;
    exception_.cycle = counters().cycles;
    exception_.hook = hook;
    exception_.count = static_cast<std::uint32_t>(counters().exceptions);
    exception_.type.assign(type);
    exception_.message.assign(what);
    pending_ |= kException;
    flush();
  }

  /// Before on_update(). RT-safe.
  [[gnu::always_inline]] void pre(CycleContext& c) noexcept {
    // The common case (the process's monotonic clock, read directly; no detector) tests one
    // byte; the rest is in pre_special().
    if (mode_ != 0) [[unlikely]] {
      pre_special(c);
      return;
    }
    const std::uint64_t cycle = counters().cycles + 1;
    if (cycle == measured_cycle_) [[unlikely]]
      pre_begin_ = platform::now_ns();
    const Nanos start = platform::now_ns();
    c.start_ns = start;
    log_.enter(cycle, start);
  }

  /// After on_update(). `state` is what the sample reports. RT-safe.
  [[gnu::always_inline]] void post(CycleContext& c, TaskState state) noexcept {
    log_.leave();
    const Nanos end = mode_ == 0 ? platform::now_ns() : post_special();
    c.end_ns = end;
    // The sample is built in place inside a Message, and it holds the counters themselves: the
    // push is the cycle's only copy.
    CycleSample& s = sample();
    const Nanos start = c.start_ns;
    const Nanos release = c.release_ns != 0 ? c.release_ns : start;
    const bool overrun = c.period_ns > 0 && end > release + c.period_ns;
    const std::uint64_t cycles = counters().cycles + 1;
    // What rarely changes is stored only when it does.
    if (overrun) [[unlikely]]
      ++counters().overruns;
    const std::uint32_t missed = c.missed_before;
    if (missed != 0) [[unlikely]]
      counters().missed_cycles += missed;
    auto* port = membership_.port();
    if (const std::uint64_t d = port->dropped(); d != counters().dropped) [[unlikely]] {
      counters().dropped = d;
    }
    // What changes every cycle is stored in 16-byte pieces that match the 16-byte loads of the
    // push's copy: a narrower store under a wider load is not forwarded, and the load would wait
    // for the store to reach the cache (~10 ns a cycle on the machine measured).
    auto* bytes = reinterpret_cast<unsigned char*>(&s);
    store_pair(bytes + offsetof(CycleSample, release_ns), release, start);
    // The overhead measured on an earlier cycle, or 0.
    store_pair(bytes + offsetof(CycleSample, end_ns), end, overhead_);
    std::uint64_t flags = 0;  // missed_before .. state, as their bytes lie in the sample
    if constexpr (std::endian::native == std::endian::little) {  // in registers
      flags = missed | (std::uint64_t{overrun} << 32U) |
              (std::uint64_t{static_cast<std::uint8_t>(state)} << 48U);
    } else {
      const Head h{missed, overrun, false, state, 0, cycles};
      std::memcpy(&flags, &h, sizeof flags);
    }
    store_pair(bytes + offsetof(CycleSample, missed_before), static_cast<std::int64_t>(flags),
               static_cast<std::int64_t>(cycles));
    if (pending_ != 0) [[unlikely]]
      flush();
    (void)port->try_push(sample_);
    published_cycles_.store(cycles, std::memory_order_relaxed);
    // A measured overhead travels with the next cycle's sample, once. (Stores only when
    // something changes: a store costs as much as several other instructions here.)
    if (cycles == measured_cycle_) [[unlikely]] {
      overhead_ = (start - pre_begin_) + (now() - end);
      measured_cycle_ += measure_every_;
    } else if (overhead_ != 0) [[unlikely]] {
      overhead_ = 0;
    }
  }

  /// Declares checkpoint `name` and returns its id; the same name again returns the same id.
  /// Not RT-safe (allocates one report, 128 bytes); call it before the component runs (its
  /// configuration, or before Instrumentation::init), from the thread that configures it.
  /// Throws std::invalid_argument for an empty name or one longer than kMaxCheckpointName bytes,
  /// std::length_error beyond kMaxCheckpoints, std::logic_error while the component runs (a
  /// report may be reading the list).
  health::CheckpointId declare_checkpoint(std::string_view name) {
    if (name.empty() || name.size() > health::kMaxCheckpointName) {
      throw std::invalid_argument("checkpoint name '" + std::string(name) + "' of " + name_ +
                                  " must be 1 to 63 bytes");
    }
    for (std::uint16_t i = 0; i < checkpoint_count_; ++i) {
      if (report(i).name.view() == name) return health::detail::make_checkpoint_id(owner_, i);
    }
    if (state_ == TaskState::Running) {
      throw std::logic_error(name_ + ": checkpoint '" + std::string(name) +
                             "' declared while running; declare checkpoints when configuring");
    }
    if (checkpoint_count_ == health::kMaxCheckpoints) {
      throw std::length_error(name_ + ": more than 256 checkpoints");
    }
    checkpoints_.emplace_back(std::in_place_type<health::CheckpointReport>);
    health::CheckpointReport& r = report(checkpoint_count_);
    r.index = checkpoint_count_;
    r.name.assign(name);
    return health::detail::make_checkpoint_id(owner_, checkpoint_count_++);
  }

  /// Reports checkpoint `id`, passed now (the component's clock: one read). RT-safe:
  /// wait-free, no allocation, lock, system call or exception. The component's thread only.
  /// An id this component did not declare is counted and reported as a misuse.
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id) noexcept {
    if (id.owner() != owner_ || id.index() >= checkpoint_count_) [[unlikely]] {
      misuse();
      return;
    }
    push_checkpoint(id.index(), now());
  }
  /// Reports checkpoint `id`, passed at `time_ns` (a time the caller has: its cycle's start,
  /// a frame's time stamp); no clock read. RT-safe, as checkpoint(id).
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id, Nanos time_ns) noexcept {
    if (id.owner() != owner_ || id.index() >= checkpoint_count_) [[unlikely]] {
      misuse();
      return;
    }
    push_checkpoint(id.index(), time_ns);
  }
  /// Misuses so far (reports of an id this component did not declare). Component's thread.
  [[nodiscard]] std::uint32_t checkpoint_misuses() const noexcept { return misuses_; }
  /// Checkpoints declared so far.
  [[nodiscard]] std::uint16_t checkpoints() const noexcept { return checkpoint_count_; }
  /// The name of declared checkpoint `i` (< checkpoints()). Not for the real-time path.
  [[nodiscard]] std::string_view checkpoint_name(std::uint16_t i) const noexcept {
    const auto* r = std::get_if<health::CheckpointReport>(&checkpoints_[i]);
    return r != nullptr ? r->name.view() : std::string_view{};
  }

  /// Cycles run so far. Any thread (relaxed atomic).
  [[nodiscard]] std::uint64_t cycles() const noexcept {
    return published_cycles_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t overruns() const noexcept { return counters().overruns; }
  [[nodiscard]] std::uint64_t exceptions() const noexcept { return counters().exceptions; }
  [[nodiscard]] std::uint64_t losses(LossCause c) const noexcept { return counters().loss(c); }

 private:
  static constexpr std::uint8_t kInfo = 1;
  static constexpr std::uint8_t kChange = 2;
  static constexpr std::uint8_t kException = 4;
  static constexpr std::uint8_t kTotals = 8;

  [[nodiscard]] health::CheckpointReport& report(std::uint16_t i) noexcept {
    auto* r = std::get_if<health::CheckpointReport>(&checkpoints_[i]);
    if (r == nullptr) __builtin_unreachable();
    return *r;
  }

  // The report was built when the checkpoint was declared: four stores and the push (its only
  // copy).
  [[gnu::always_inline]] void push_checkpoint(std::uint16_t i, Nanos time_ns) noexcept {
    health::CheckpointReport& r = report(i);
    r.time_ns = time_ns;
    r.cycle = counters().cycles + 1;
    ++r.count;
    r.misuses = misuses_;
    (void)membership_.port()->try_push(checkpoints_[i]);
  }

  [[gnu::noinline]] void misuse() noexcept {
    ++misuses_;
    health::CheckpointReport& r = *std::get_if<health::CheckpointReport>(&misuse_);
    r.time_ns = now();
    r.cycle = counters().cycles + 1;
    r.count = misuses_;
    r.misuses = misuses_;
    (void)membership_.port()->try_push(misuse_);
  }

  // A tag per recorder, so that an id declared by another component is told apart.
  static std::uint32_t next_owner() noexcept {
    static std::atomic<std::uint32_t> next{1};
    std::uint32_t o = next.fetch_add(1, std::memory_order_relaxed);
    if (o == 0) o = next.fetch_add(1, std::memory_order_relaxed);  // 0 is "no owner"
    return o;
  }

  [[nodiscard]] [[gnu::always_inline]] Nanos now() const noexcept {
    if ((mode_ & (kTscClock | kReplacedClock)) == 0) [[likely]]
      return platform::now_ns();
    if ((mode_ & kTscClock) != 0) return platform::tsc_now_ns();
    return clock_->now();
  }

  /// pre() beyond the common case: the first cycle of a run, another clock, a detector.
  /// Inline (the allocation detector's path stays without a call), out of the common path.
  [[gnu::always_inline]] void pre_special(CycleContext& c) noexcept {
    // The process's clock is read directly (monotonic, or the TSC when selected), not through
    // the Clock's function pointer; a replaced clock (tests, replay) through it. Looked at once
    // per start: a running task keeps the clock it started with (select_clock() is called
    // before tasks run).
    if ((mode_ & kLookAtClock) != 0) [[unlikely]]
      look_at_clock(c.clock);
    const std::uint64_t cycle = counters().cycles + 1;
    if (cycle == measured_cycle_) [[unlikely]]
      pre_begin_ = now();
    // The common detector inline (one thread-local load); the others out of line.
    if ((mode_ & kAllocationDetector) != 0) {
      alloc0_ = platform::thread_allocations();
    } else if ((mode_ & kOtherDetectors) != 0) {
      arm();
    }
    const Nanos start = now();
    c.start_ns = start;
    log_.enter(cycle, start);
  }

  /// post()'s clock read and detectors beyond the common case; returns the end of the cycle.
  [[gnu::always_inline]] Nanos post_special() noexcept {
    const Nanos end = now();
    if ((mode_ & kAllocationDetector) != 0) {
      if (const std::uint64_t n = platform::thread_allocations() - alloc0_; n != 0) [[unlikely]] {
        record_loss(LossCause::Allocation, n);
      }
    } else if ((mode_ & kOtherDetectors) != 0) {
      collect();
    }
    return end;
  }

  [[gnu::noinline]] void look_at_clock(const Clock* clock) noexcept {
    clock_ = clock;
    const bool direct = clock == nullptr || clock->fn == &Clock::system_now;
    const std::uint8_t source = !direct ? kReplacedClock
                                : platform::active_clock() == platform::ClockSource::Tsc ? kTscClock
                                                                                         : 0;
    mode_ = static_cast<std::uint8_t>((mode_ & (kAllocationDetector | kOtherDetectors)) | source);
  }

  // sample_ always holds a CycleSample: saying so spares the variant's index check.
  // The sample's bytes from `missed_before` to `counters.cycles` (checked below).
  struct Head {
    std::uint32_t missed_before;
    bool overrun;
    bool totals_only;
    TaskState state;
    std::uint8_t padding;
    std::uint64_t cycles;
  };
  static_assert(sizeof(Head) == 16 &&
                offsetof(CycleSample, counters) + offsetof(Counters, cycles) ==
                    offsetof(CycleSample, missed_before) + 8);
  static_assert(offsetof(CycleSample, overrun) == offsetof(CycleSample, missed_before) + 4 &&
                offsetof(CycleSample, totals_only) == offsetof(CycleSample, missed_before) + 5 &&
                offsetof(CycleSample, state) == offsetof(CycleSample, missed_before) + 6 &&
                sizeof(TaskState) == 1);
  static_assert(offsetof(CycleSample, start_ns) == offsetof(CycleSample, release_ns) + 8 &&
                offsetof(CycleSample, overhead_ns) == offsetof(CycleSample, end_ns) + 8);
  /// Two adjacent 64-bit fields written with one 16-byte store.
  static void store_pair(unsigned char* dst, Nanos a, Nanos b) noexcept {
    using Pair [[gnu::vector_size(16)]] = Nanos;
    const Pair p{a, b};
    std::memcpy(dst, &p, sizeof p);
  }

  [[nodiscard]] CycleSample& sample() noexcept {
    CycleSample* s = std::get_if<CycleSample>(&sample_);
    if (s == nullptr) __builtin_unreachable();
    return *s;
  }
  [[nodiscard]] const CycleSample& sample() const noexcept {
    const CycleSample* s = std::get_if<CycleSample>(&sample_);
    if (s == nullptr) __builtin_unreachable();
    return *s;
  }
  // The component's counters live in the sample: building a sample copies none of them.
  [[nodiscard]] Counters& counters() noexcept { return sample().counters; }
  [[nodiscard]] const Counters& counters() const noexcept { return sample().counters; }

  [[nodiscard]] CycleSample totals() const noexcept {
    CycleSample t = *std::get_if<CycleSample>(&sample_);
    t.totals_only = true;
    t.state = state_;
    t.counters.dropped = membership_.port() != nullptr ? membership_.port()->dropped() : 0;
    return t;
  }

  void flush() noexcept {
    auto* port = membership_.port();
    // Kept messages are retried, not dropped: a failed attempt is not counted as a drop.
    if ((pending_ & kInfo) != 0 && port->try_push_or_keep(Message{info_})) pending_ &= ~kInfo;
    if ((pending_ & kException) != 0 && port->try_push_or_keep(Message{exception_})) {
      pending_ &= ~kException;
    }
    if ((pending_ & kChange) != 0 && port->try_push_or_keep(Message{change_})) {
      pending_ &= ~kChange;
    }
    if ((pending_ & kTotals) != 0 && port->try_push_or_keep(Message{totals()})) {
      pending_ &= ~kTotals;
    }
  }

  [[gnu::noinline]] void arm() noexcept {
    const Detectors d = options_.detectors;
    if (has(d, Detectors::Allocation)) alloc0_ = platform::thread_allocations();
    if (has(d, Detectors::ModeSwitch)) modesw0_ = platform::thread_mode_switches();
    if (has(d, Detectors::Blocking) || has(d, Detectors::PageFaults)) {
      usage0_ = platform::thread_usage();
    }
  }

  [[gnu::noinline]] void collect() noexcept {
    const Detectors d = options_.detectors;
    std::uint64_t delta[kLossCauses] = {};
    if (has(d, Detectors::Allocation)) {
      delta[static_cast<int>(LossCause::Allocation)] = platform::thread_allocations() - alloc0_;
    }
    if (has(d, Detectors::ModeSwitch)) {
      delta[static_cast<int>(LossCause::ModeSwitch)] = platform::thread_mode_switches() - modesw0_;
    }
    if (has(d, Detectors::Blocking) || has(d, Detectors::PageFaults)) {
      const auto u = platform::thread_usage();
      if (has(d, Detectors::Blocking)) {
        delta[static_cast<int>(LossCause::Blocking)] =
            u.voluntary_switches - usage0_.voluntary_switches;
      }
      if (has(d, Detectors::PageFaults)) {
        delta[static_cast<int>(LossCause::MinorFault)] = u.minor_faults - usage0_.minor_faults;
        delta[static_cast<int>(LossCause::MajorFault)] = u.major_faults - usage0_.major_faults;
      }
    }
    for (int i = 0; i < kLossCauses; ++i) {
      if (delta[i] != 0) record_loss(static_cast<LossCause>(i), delta[i]);
    }
  }

  [[gnu::noinline]] void record_loss(LossCause cause, std::uint64_t n) noexcept {
    counters().losses[static_cast<std::size_t>(cause)] += n;
    const RealTimeLoss loss{counters().cycles + 1, cause, static_cast<std::uint32_t>(n)};
    (void)membership_.port()->try_push(Message{loss});
  }

  std::string name_;
  SupervisionOptions options_;
  bus::Membership<Message, N> membership_;
  log::PortSource<Message, N> log_{name_, membership_.port()};
  // What a cycle does beyond the common case (the process's monotonic clock read directly, no
  // detector), one bit each; 0 is the common case, which pre() and post() test with one load.
  static constexpr std::uint8_t kLookAtClock = 1;         // first cycle of a run
  static constexpr std::uint8_t kTscClock = 2;            // read the TSC directly
  static constexpr std::uint8_t kReplacedClock = 4;       // through the Clock's function pointer
  static constexpr std::uint8_t kAllocationDetector = 8;  // Detectors::Allocation alone
  static constexpr std::uint8_t kOtherDetectors = 16;     // any other set: arm() and collect()
  // The clock of the run (null: the process's), looked at on its first cycle.
  const Clock* clock_ = nullptr;
  std::uint8_t mode_ = kLookAtClock;
  std::uint64_t measure_every_ = 64;
  std::uint64_t measured_cycle_ = 1;  // the number of the next measured cycle (0: none)
  Nanos pre_begin_ = 0;
  Nanos overhead_ = 0;  // measured on the latest cycle, sent with the next sample
  std::atomic<std::uint64_t> published_cycles_{0};  // single writer: a plain store on x86
  std::uint64_t alloc0_ = 0;
  std::uint64_t modesw0_ = 0;
  platform::ThreadUsage usage0_{};
  TaskState state_ = TaskState::PreOperational;
  std::uint8_t pending_ = 0;
  TaskInfo info_;
  // The latest sample, pushed by copy; its counters are the component's (`dropped` is the
  // port's, read when a sample is built).
  Message sample_{std::in_place_type<CycleSample>};
  ExceptionReport exception_;
  StateChange change_;
  // Checkpoints: one report per declaration, built in place (the list grows only while the
  // component does not run), and the report of a misuse.
  std::vector<Message> checkpoints_;
  Message misuse_{std::in_place_type<health::CheckpointReport>};
  std::uint32_t owner_ = next_owner();
  std::uint32_t misuses_ = 0;
  std::uint16_t checkpoint_count_ = 0;
};

}  // namespace detail
}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::DefaultTaskTraits;
using task::kDefaultPortCapacity;
using task::SupervisionOptions;
}  // namespace vigil
