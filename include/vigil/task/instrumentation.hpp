#pragma once
/// @file
/// `Instrumentation`: the same supervision as Task<Derived>, as a member object, for code
/// that cannot change its base class. Same implementation (CycleRecorder), same data.
///
/// It instruments one component on the component's own thread (it times cycles and pushes
/// messages to the component's port); it does not supervise anything. The supervisor, which
/// drains every component's port on its own thread, is `ComponentDrainLoop`
/// (vigil/supervisor/component_aggregator.hpp), and a program gets it inside a
/// `SupervisionService`. (Before issue 13 these were `ComponentSupervisor` and
/// `ComponentSupervisorLoop`.)
///
/// ```cpp
/// class LegacyDrive : public SomeVendorBase {
///   vigil::Instrumentation instr_{"legacy_drive"};
///  public:
///   void thread_start() { instr_.init({.activity = "drive", .period_ns = 1'000'000}); }
///   void cycle() {
///     vigil::UpdateGuard guard(instr_);  // pre on construction, post on destruction
///     compute();
///   }
/// };
/// ```

#include <exception>
#include <string>
#include <typeinfo>

#include "vigil/platform/thread.hpp"
#include "vigil/task/supervision.hpp"

namespace vigil::task {

/// Identity of a manually instrumented component (what an activity would otherwise say).
struct ManualInfo {
  std::string activity = "manual";
  /// Period of the component's loop, for overrun detection; 0 = not periodic.
  Nanos period_ns = 0;
  /// The policy the component asked for; the one it got is read from the thread in init().
  SchedPolicy requested_policy = SchedPolicy::Other;
};

template <std::size_t N = kDefaultPortCapacity>
class BasicInstrumentation {
 public:
  /// Registers the component's port. Not RT-safe.
  explicit BasicInstrumentation(std::string name, SupervisionOptions options = {},
                                Registry<Message>& registry = default_registry())
      : recorder_(std::move(name), options, registry) {}

  /// Call once from the component's own thread before its loop: reads the thread's policy,
  /// priority, CPU and tid, sends the identity and enters Running. Not RT-safe.
  void init(const ManualInfo& info = {}, Clock clock = Clock::system()) {
    clock_ = clock;
    context_.clock = &clock_;
    context_.period_ns = info.period_ns;
    TaskInfo ti;
    ti.activity.assign(info.activity);
    ti.requested_policy = info.requested_policy;
    ti.period_ns = info.period_ns;
    ti.threaded = true;
    ti.tid = platform::current_tid();
    ti.tasks_on_thread = 1;
    if (const auto s = platform::current_sched_info()) {
      ti.policy = s->policy;
      ti.priority = s->priority;
      ti.cpu = s->pinned_cpu;
    }
    ti.realtime_refused =
        info.requested_policy == SchedPolicy::Fifo && ti.policy != SchedPolicy::Fifo;
    recorder_.send_info(ti);
    recorder_.on_transition(state_, TaskState::Running, Hook::Start, false, {}, clock_.now());
    state_ = TaskState::Running;
  }

  /// Before the component's update. `release_ns`: the scheduled release, if the loop has one
  /// (0: the cycle starts when released). RT-safe.
  /// Inline (as post_update()): a call and its return cost as much as ~40 instructions before
  /// the cycle's clock read (docs/design/performance-history.md).
  [[gnu::always_inline]] void pre_update(Nanos release_ns = 0,
                                         std::uint32_t missed_before = 0) noexcept {
    context_.release_ns = release_ns;
    if (context_.missed_before != missed_before) [[unlikely]]  // no store in the common case
      context_.missed_before = missed_before;
    recorder_.pre(context_);
  }
  /// After the component's update. RT-safe.
  [[gnu::always_inline]] void post_update() noexcept { recorder_.post(context_, state_); }

  /// Reports an exception the component caught (or let through an UpdateGuard) and enters
  /// Exception, as Task<Derived> does. RT-safe.
  void report_exception(std::string_view type, std::string_view what) noexcept {
    recorder_.on_exception(Hook::Update, type, what);
    if (state_ != TaskState::Exception) {
      recorder_.on_transition(state_, TaskState::Exception, Hook::Update, false, "exception",
                              clock_.now());
      state_ = TaskState::Exception;
    }
  }
  /// Leaves Exception (back to Running). Not RT-safe.
  void recover() {
    if (state_ != TaskState::Exception) return;
    recorder_.on_transition(state_, TaskState::Running, Hook::None, false, "recovered",
                            clock_.now());
    state_ = TaskState::Running;
  }

  /// Runs `f` as one supervised update: exceptions are caught and reported. RT-safe when f is.
  template <class F>
  bool run(F&& f, Nanos release_ns = 0) noexcept {
    pre_update(release_ns);
    bool ok = true;
    try {
      f();
    } catch (const std::exception& e) {
      recorder_.on_exception(Hook::Update, typeid(e).name(), e.what());
      ok = false;
    } catch (...) {
      recorder_.on_exception(Hook::Update, "unknown", "");
      ok = false;
    }
    if (!ok) state_ = TaskState::Exception;
    post_update();
    if (!ok) {
      recorder_.on_transition(TaskState::Running, TaskState::Exception, Hook::Update, false,
                              "exception", clock_.now());
    }
    return ok;
  }

  /// Declares checkpoint `name` and returns its id (the same name again: the same id). Before
  /// init() (std::logic_error once it runs). Not RT-safe; throws std::invalid_argument for an
  /// empty name or one longer than 63 bytes.
  health::CheckpointId declare_checkpoint(std::string_view name) {
    return recorder_.declare_checkpoint(name);
  }
  /// Reports that the component passed checkpoint `id` now (one clock read, one push). RT-safe;
  /// the component's thread only (inside or outside an UpdateGuard's scope). An id this
  /// component did not declare is a counted, reported misuse.
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id) noexcept {
    recorder_.checkpoint(id);
  }
  /// The same, at `time_ns` (a time the component already has): no clock read.
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id, Nanos time_ns) noexcept {
    recorder_.checkpoint(id, time_ns);
  }
  /// Reports of ids this component did not declare, so far. The component's thread.
  [[nodiscard]] std::uint32_t checkpoint_misuses() const noexcept {
    return recorder_.checkpoint_misuses();
  }

  [[nodiscard]] TaskState state() const noexcept { return state_; }
  [[nodiscard]] std::uint64_t cycles() const noexcept { return recorder_.cycles(); }
  [[nodiscard]] Port<Message, N>* port() const noexcept { return recorder_.port(); }
  [[nodiscard]] const std::string& name() const noexcept { return recorder_.name(); }

 private:
  detail::CycleRecorder<N> recorder_;
  Clock clock_ = Clock::system();
  CycleContext context_{0, 0, 0, nullptr, 0, 0};
  TaskState state_ = TaskState::PreOperational;
};

/// The instrumentation of one component, with the default port capacity.
using Instrumentation = BasicInstrumentation<>;

/// RAII: pre_update() on construction, post_update() on destruction. An exception that leaves
/// the guarded scope is counted and reported (its type cannot be known here: use
/// Instrumentation::run() to report it exactly). A guard destroyed while the stack unwinds
/// for another reason (a guard constructed inside a destructor during unwinding) would report
/// that unwinding too; cycles are not run from destructors in practice, and checking only here
/// keeps the guard at one std::uncaught_exceptions() call per cycle.
template <class Instr>
class [[nodiscard]] UpdateGuard {
 public:
  // Inline, with what they call: the cycle then makes no call of its own beyond the clock reads
  // and the one std::uncaught_exceptions().
  [[gnu::always_inline]] explicit UpdateGuard(Instr& s, Nanos release_ns = 0) noexcept : s_(s) {
    s_.pre_update(release_ns);
  }
  [[gnu::always_inline]] ~UpdateGuard() {
    if (std::uncaught_exceptions() > 0) [[unlikely]] {
      s_.report_exception("unknown", "exception propagated through UpdateGuard");
    }
    s_.post_update();
  }
  UpdateGuard(const UpdateGuard&) = delete;
  UpdateGuard& operator=(const UpdateGuard&) = delete;

 private:
  Instr& s_;
};

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::BasicInstrumentation;
using task::Instrumentation;
using task::ManualInfo;
using task::UpdateGuard;
}  // namespace vigil
