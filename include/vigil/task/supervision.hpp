#pragma once
/// @file
/// Supervision options, and `CycleRecorder`, the one implementation of per-cycle supervision
/// behind both front ends: `Task<Derived>` and `Instrumentation`.

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/log/source.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/rt_loss.hpp"
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
  /// (a power of two); 1 = every cycle, 0 = never. User time is measured on every cycle.
  std::uint32_t overhead_sample_every = 64;
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
    const std::uint32_t every = options.overhead_sample_every;
    sample_mask_ = every == 0 ? ~std::uint64_t{0} : std::uint64_t{every} - 1;
    sample_never_ = every == 0;
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
    pending_ |= kChange;
    // Leaving Running: send the totals again, in case the latest samples were dropped.
    if (!refused && from == TaskState::Running && counters_.cycles > 0) pending_ |= kTotals;
    flush();
  }

  /// Reports an exception caught at a hook boundary. RT-safe.
  void on_exception(Hook hook, std::string_view type, std::string_view what) noexcept {
    ++counters_.exceptions;
    exception_.cycle = counters_.cycles;
    exception_.hook = hook;
    exception_.count = static_cast<std::uint32_t>(counters_.exceptions);
    exception_.type.assign(type);
    exception_.message.assign(what);
    pending_ |= kException;
    flush();
  }

  /// Before on_update(). RT-safe.
  void pre(CycleContext& c) noexcept {
    clock_ = c.clock != nullptr ? c.clock : &system_clock_;
    // The system clock is read directly, not through the Clock's function pointer.
    direct_clock_ = clock_->fn == &Clock::system_now;
    measure_ = !sample_never_ && (counters_.cycles & sample_mask_) == 0;
    if (measure_) pre_begin_ = now();
    if (options_.detectors != Detectors::None) arm();
    c.start_ns = now();
    log_.enter(counters_.cycles + 1, c.start_ns);
  }

  /// After on_update(). `state` is what the sample reports. RT-safe.
  void post(CycleContext& c, TaskState state) noexcept {
    log_.leave();
    const Nanos end = now();
    c.end_ns = end;
    if (options_.detectors != Detectors::None) collect();
    ++counters_.cycles;
    const Nanos release = c.release_ns != 0 ? c.release_ns : c.start_ns;
    const bool overrun = c.period_ns > 0 && end > release + c.period_ns;
    counters_.overruns += overrun ? 1 : 0;
    counters_.missed_cycles += c.missed_before;
    if (pending_ != 0) flush();
    auto* port = membership_.port();
    // The sample is built in place inside a Message: the push is its only copy.
    CycleSample& s = *std::get_if<CycleSample>(&sample_);
    s.release_ns = release;
    s.start_ns = c.start_ns;
    s.end_ns = end;
    s.overhead_ns = overhead_;
    s.missed_before = c.missed_before;
    s.overrun = overrun;
    s.state = state;
    s.counters = counters_;
    s.counters.dropped = port->dropped();
    (void)port->try_push(sample_);
    published_cycles_.store(counters_.cycles, std::memory_order_relaxed);
    overhead_ = 0;
    if (measure_) overhead_ = (c.start_ns - pre_begin_) + (now() - end);
  }

  /// Cycles run so far. Any thread (relaxed atomic).
  [[nodiscard]] std::uint64_t cycles() const noexcept {
    return published_cycles_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t overruns() const noexcept { return counters_.overruns; }
  [[nodiscard]] std::uint64_t exceptions() const noexcept { return counters_.exceptions; }
  [[nodiscard]] std::uint64_t losses(LossCause c) const noexcept { return counters_.loss(c); }

 private:
  static constexpr std::uint8_t kInfo = 1;
  static constexpr std::uint8_t kChange = 2;
  static constexpr std::uint8_t kException = 4;
  static constexpr std::uint8_t kTotals = 8;

  [[nodiscard]] Nanos now() const noexcept {
    return direct_clock_ ? platform::now_ns() : clock_->now();
  }

  [[nodiscard]] CycleSample totals() const noexcept {
    CycleSample t = *std::get_if<CycleSample>(&sample_);
    t.totals_only = true;
    t.state = state_;
    t.counters = counters_;
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

  void arm() noexcept {
    const Detectors d = options_.detectors;
    if (has(d, Detectors::Allocation)) alloc0_ = platform::thread_allocations();
    if (has(d, Detectors::ModeSwitch)) modesw0_ = platform::thread_mode_switches();
    if (has(d, Detectors::Blocking) || has(d, Detectors::PageFaults)) {
      usage0_ = platform::thread_usage();
    }
  }

  void collect() noexcept {
    const Detectors d = options_.detectors;
    if (d == Detectors::Allocation) {  // the common cheap case: one load, one compare
      const std::uint64_t n = platform::thread_allocations() - alloc0_;
      if (n != 0) record_loss(LossCause::Allocation, n);
      return;
    }
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

  void record_loss(LossCause cause, std::uint64_t n) noexcept {
    counters_.losses[static_cast<std::size_t>(cause)] += n;
    const RealTimeLoss loss{counters_.cycles + 1, cause, static_cast<std::uint32_t>(n)};
    (void)membership_.port()->try_push(Message{loss});
  }

  std::string name_;
  SupervisionOptions options_;
  bus::Membership<Message, N> membership_;
  log::PortSource<Message, N> log_{name_, membership_.port()};
  Clock system_clock_ = Clock::system();
  const Clock* clock_ = &system_clock_;
  bool direct_clock_ = true;
  std::uint64_t sample_mask_ = 63;
  bool sample_never_ = false;
  bool measure_ = false;
  Nanos pre_begin_ = 0;
  Nanos overhead_ = 0;
  Counters counters_;  // `dropped` is the port's, read when a sample is built
  std::atomic<std::uint64_t> published_cycles_{0};  // single writer: a plain store on x86
  std::uint64_t alloc0_ = 0;
  std::uint64_t modesw0_ = 0;
  platform::ThreadUsage usage0_{};
  TaskState state_ = TaskState::PreOperational;
  std::uint8_t pending_ = 0;
  TaskInfo info_;
  Message sample_{std::in_place_type<CycleSample>};  // the latest sample, pushed by copy
  ExceptionReport exception_;
  StateChange change_;
};

}  // namespace detail
}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::DefaultTaskTraits;
using task::kDefaultPortCapacity;
using task::SupervisionOptions;
}  // namespace vigil
