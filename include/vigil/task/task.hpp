#pragma once
/// @file
/// `Task<Derived>`: the CRTP base a component author inherits. One line instruments a component:
///
/// ```cpp
/// class Motor : public vigil::Task<Motor> {
///  public:
///   Motor() : Task("motor") {}
///   void on_update() { /* the control law */ }   // required
///   bool on_configure() { return true; }           // optional: on_start, on_stop, on_cleanup
///   void on_safe_state() { /* hold */ }            // optional: the fallback (safe_state.hpp)
/// };
/// ```
///
/// Task<Derived> overrides every framework hook of TaskCore as `final` and wraps the author's
/// `on_*` functions with supervision: timing, counters, real-time-loss detectors, and exceptions
/// caught at the boundary (reported with component, hook, type and what(); the task moves to
/// Exception and its thread keeps running). What the author writes is checked at compile time,
/// with messages that say what to change.

#include <concepts>
#include <exception>
#include <string>
#include <string_view>
#include <type_traits>
#include <typeinfo>
#include <utility>
#include <vector>

#include "vigil/expected.hpp"
#include "vigil/safe_state.hpp"
#include "vigil/task/supervision.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::task {

namespace detail {
template <class T>
struct is_expected_void : std::false_type {};
template <class E>
struct is_expected_void<vigil::expected<void, E>> : std::true_type {};

/// What an optional hook may return: bool, or vigil::expected<void, E>.
template <class R>
concept HookResult = std::same_as<R, bool> || is_expected_void<std::remove_cvref_t<R>>::value;

/// True when D declares (or inherits) a member named like an optional hook, whatever its kind,
/// signature or access: the name is then ambiguous in HookNameScan<D>. A final class cannot be
/// scanned (nothing may derive from it), so for it this is always false.
struct HookNames {
  int on_configure, on_start, on_stop, on_cleanup;
};
template <class D>
struct HookNameScan : D, HookNames {};
template <class D>
concept declares_on_configure = !std::is_final_v<D> && !requires {
  &HookNameScan<D>::on_configure;
};
template <class D>
concept declares_on_start = !std::is_final_v<D> && !requires {
  &HookNameScan<D>::on_start;
};
template <class D>
concept declares_on_stop = !std::is_final_v<D> && !requires {
  &HookNameScan<D>::on_stop;
};
template <class D>
concept declares_on_cleanup = !std::is_final_v<D> && !requires {
  &HookNameScan<D>::on_cleanup;
};

template <class E>
std::string_view error_text(const E& e) noexcept {
  if constexpr (std::is_convertible_v<const E&, std::string_view>) {
    return std::string_view(e);
  } else if constexpr (requires { std::string_view(e.message); }) {
    return std::string_view(e.message);
  } else {
    return "error";
  }
}
}  // namespace detail

template <class Derived, class Traits = DefaultTaskTraits>
class Task : public TaskCore {
 public:
  /// Creates the component and registers its port with `registry`. Not RT-safe (allocates).
  explicit Task(std::string name, SupervisionOptions options = {},
                Registry<Message>& registry = default_registry())
      : TaskCore(name), recorder_(std::move(name), options, registry) {}

  /// Supervision options (detectors, overhead sampling). Change them only while not running.
  void set_supervision(SupervisionOptions options) noexcept { recorder_.set_options(options); }
  [[nodiscard]] const SupervisionOptions& supervision() const noexcept {
    return recorder_.options();
  }
  /// The component's port (for tests and tools).
  [[nodiscard]] Port<Message, Traits::port_capacity>* port() const noexcept {
    return recorder_.port();
  }
  /// Cycles run so far. Any thread.
  [[nodiscard]] std::uint64_t cycles() const noexcept { return recorder_.cycles(); }

  /// Declares checkpoint `name` of this component (AUTOSAR PHM: a checkpoint of the supervised
  /// entity) and returns its id; the same name again returns the same id. Call it from the
  /// constructor or on_configure(), never while the component runs (std::logic_error). Not
  /// RT-safe (allocates a report). Throws std::invalid_argument for an empty name or one longer
  /// than 63 bytes (from on_configure(): the configuration fails with that reason).
  health::CheckpointId declare_checkpoint(std::string_view name) {
    return recorder_.declare_checkpoint(name);
  }
  /// The checkpoints declared so far, in declaration order. Not RT-safe.
  [[nodiscard]] std::vector<std::string> declared_checkpoints() const override {
    std::vector<std::string> names;
    names.reserve(recorder_.checkpoints());
    for (std::uint16_t i = 0; i < recorder_.checkpoints(); ++i) {
      names.emplace_back(recorder_.checkpoint_name(i));
    }
    return names;
  }
  /// Reports that the cycle passed checkpoint `id` now: one clock read and one push. RT-safe
  /// (wait-free; no allocation, lock, system call or exception); from on_update() (the
  /// component's thread). An id this component did not declare is a counted, reported misuse.
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id) noexcept {
    recorder_.checkpoint(id);
  }
  /// The same, at `time_ns` (e.g. `cycle().start_ns`, a frame's time stamp): no clock read.
  [[gnu::always_inline]] void checkpoint(health::CheckpointId id, Nanos time_ns) noexcept {
    recorder_.checkpoint(id, time_ns);
  }
  /// Reports of ids this component did not declare, so far. The component's thread.
  [[nodiscard]] std::uint32_t checkpoint_misuses() const noexcept {
    return recorder_.checkpoint_misuses();
  }

  /// TaskCore::update_running() without its virtual call, for an activity that knows the task's
  /// type (TypedManualActivity): the cycle is then inlined into the caller. The same behaviour.
  [[gnu::always_inline]] bool update_running(CycleContext& context) noexcept {
    run_cycle(context);
    return state() == TaskState::Running;
  }

 private:
  friend Derived;

  [[nodiscard]] Derived& derived() noexcept { return static_cast<Derived&>(*this); }

  // The framework hooks. `final`: a component cannot override them, and check_author() rejects
  // a member that would hide them.
  bool configure_hook() final {
    check_author();
    recorder_.send_info(activity(), false);
    if constexpr (requires(Derived & d) { d.on_configure(); }) {
      return result_of(Hook::Configure, derived().on_configure());
    }
    return true;
  }
  bool start_hook() final {
    recorder_.send_info(activity(), activity() != nullptr && activity()->threaded);
    if constexpr (requires(Derived & d) { d.on_start(); }) {
      return result_of(Hook::Start, derived().on_start());
    }
    return true;
  }
  // Not called by the framework: activities run a cycle through cycle_hook() (TaskCore's
  // update()/update_running()) or Task::update_running(). Required by TaskCore; a direct call
  // runs a cycle with the task's own context.
  void update_hook() noexcept final { run_cycle(cycle()); }
  void cycle_hook(CycleContext& c) noexcept final { run_cycle(c); }
  /// One supervised cycle: the body of cycle_hook() and of update_running().
  [[gnu::always_inline]] void run_cycle(CycleContext& c) noexcept {
    check_author();
    if constexpr (!requires(Derived & d) { d.on_safe_state(); }) {
      if (recorder_.options().stop_on_safe_state && safe_state_requested()) [[unlikely]] {
        (void)stop();  // in the component's own thread, as an activity's stop command does
        return;
      }
    }
    enter_cycle(c);  // for cycle() in on_update() and in the transition below
    recorder_.pre(c);
    bool threw = false;
    try {
      // Guarded so that a missing or inaccessible on_update() is reported by check_author() alone.
      if constexpr (requires(Derived & d) { d.on_safe_state(); }) {
        // The component's fallback while the safe state is requested (vigil/safe_state.hpp):
        // one relaxed load per cycle, only in components that define one.
        if (safe_state_requested()) {
          derived().on_safe_state();
        } else if constexpr (requires(Derived & d) { d.on_update(); }) {
          derived().on_update();
        }
      } else if constexpr (requires(Derived & d) { d.on_update(); }) {
        derived().on_update();
      }
    } catch (const std::exception& e) {
      recorder_.on_exception(Hook::Update, typeid(e).name(), e.what());
      threw = true;
    } catch (...) {
      recorder_.on_exception(Hook::Update, "unknown", "");
      threw = true;
    }
    recorder_.post(c, threw ? TaskState::Exception : TaskState::Running);
    // After the sample: whoever sees Exception also sees every message of this cycle.
    if (threw) transition(TaskState::Exception, Hook::Update, "exception");
    leave_cycle();
  }
  bool stop_hook() final {
    if constexpr (requires(Derived & d) { d.on_stop(); }) {
      return result_of(Hook::Stop, derived().on_stop());
    }
    return true;
  }
  bool cleanup_hook() final {
    if constexpr (requires(Derived & d) { d.on_cleanup(); }) {
      return result_of(Hook::Cleanup, derived().on_cleanup());
    }
    return true;
  }

  void on_transition(TaskState from, TaskState to, Hook hook, bool refused,
                     std::string_view reason) noexcept final {
    const Clock* clock = cycle().clock;
    recorder_.on_transition(from, to, hook, refused, reason,
                            clock != nullptr ? clock->now() : Clock::system().now());
  }
  void on_exception(Hook hook, std::string_view type, std::string_view what) noexcept final {
    recorder_.on_exception(hook, type, what);
  }

  template <class R>
  bool result_of(Hook hook, R&& r) {
    if constexpr (std::same_as<std::remove_cvref_t<R>, bool>) {
      return r;
    } else {
      (void)hook;
      if (r.has_value()) return true;
      set_refusal_reason(detail::error_text(r.error()));
      return false;
    }
  }

  /// Compile-time checks of what the author wrote, with messages that say what to do. Kept in a
  /// member so that private on_* functions (with `friend vigil::Task<Derived>`) are accepted.
  static constexpr void check_author() {
    static_assert(std::is_base_of_v<Task, Derived>,
                  "vigil::Task<Derived>: Derived must inherit vigil::Task<Derived> (CRTP)");
    static_assert(!std::is_base_of_v<Task, Derived> || std::is_convertible_v<Derived*, Task*>,
                  "vigil::Task<Derived>: inherit vigil::Task<Derived> publicly, e.g. "
                  "`class Motor : public vigil::Task<Motor>` (a class's bases are private by "
                  "default)");
    static_assert(
        requires(Derived & d) { d.on_update(); },
        "vigil::Task<Derived>: define `void on_update()` in your component (public, or "
        "private with `friend class vigil::Task<Derived>;`): it is the cycle's work");
    if constexpr (requires(Derived & d) { d.on_safe_state(); }) {
      static_assert(std::is_void_v<decltype(std::declval<Derived&>().on_safe_state())>,
                    "vigil::Task<Derived>: on_safe_state() must return void (it runs instead of "
                    "on_update() while the safe state is requested)");
    }
    if constexpr (requires(Derived & d) { d.on_update(); }) {
      static_assert(std::is_void_v<decltype(std::declval<Derived&>().on_update())>,
                    "vigil::Task<Derived>: on_update() must return void; report problems by "
                    "throwing (the task moves to Exception) or through your own outputs");
    }
    if constexpr (requires(Derived & d) { d.on_configure(); }) {
      static_assert(detail::HookResult<decltype(std::declval<Derived&>().on_configure())>,
                    "vigil::Task<Derived>: on_configure() must return bool or "
                    "vigil::expected<void, E> (false or an error refuses the transition)");
    } else {
      static_assert(!detail::declares_on_configure<Derived>,
                    "vigil::Task<Derived>: your class declares `on_configure` but Task cannot call "
                    "it as `on_configure()`, so it would never run; make it take no arguments, and "
                    "public or private with `friend class vigil::Task<Derived>;`");
    }
    if constexpr (requires(Derived & d) { d.on_start(); }) {
      static_assert(detail::HookResult<decltype(std::declval<Derived&>().on_start())>,
                    "vigil::Task<Derived>: on_start() must return bool or "
                    "vigil::expected<void, E> (false or an error refuses the transition)");
    } else {
      static_assert(!detail::declares_on_start<Derived>,
                    "vigil::Task<Derived>: your class declares `on_start` but Task cannot call "
                    "it as `on_start()`, so it would never run; make it take no arguments, and "
                    "public or private with `friend class vigil::Task<Derived>;`");
    }
    if constexpr (requires(Derived & d) { d.on_stop(); }) {
      static_assert(detail::HookResult<decltype(std::declval<Derived&>().on_stop())>,
                    "vigil::Task<Derived>: on_stop() must return bool or "
                    "vigil::expected<void, E> (false or an error refuses the transition)");
    } else {
      static_assert(!detail::declares_on_stop<Derived>,
                    "vigil::Task<Derived>: your class declares `on_stop` but Task cannot call "
                    "it as `on_stop()`, so it would never run; make it take no arguments, and "
                    "public or private with `friend class vigil::Task<Derived>;`");
    }
    if constexpr (requires(Derived & d) { d.on_cleanup(); }) {
      static_assert(detail::HookResult<decltype(std::declval<Derived&>().on_cleanup())>,
                    "vigil::Task<Derived>: on_cleanup() must return bool or "
                    "vigil::expected<void, E> (false or an error refuses the transition)");
    } else {
      static_assert(!detail::declares_on_cleanup<Derived>,
                    "vigil::Task<Derived>: your class declares `on_cleanup` but Task cannot call "
                    "it as `on_cleanup()`, so it would never run; make it take no arguments, and "
                    "public or private with `friend class vigil::Task<Derived>;`");
    }
    // Skipped for a non-public base, already reported: every &Derived::x would be inaccessible.
    if constexpr (std::is_convertible_v<Derived*, Task*>) check_hook_names();
  }
  static constexpr void check_hook_names() {
    // A member named like a framework hook hides it (or would override it, which `final`
    // forbids): &Derived::x then names Derived's member instead of Task's.
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::configure_hook),
                                decltype(&Task::configure_hook)>;
        },
        "vigil::Task<Derived>: your class declares `configure_hook`, a framework hook "
        "name; rename it: write `on_configure()` for configuration work");
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::start_hook), decltype(&Task::start_hook)>;
        },
        "vigil::Task<Derived>: your class declares `start_hook`, a framework hook "
        "name; rename it: write `on_start()` for start-up work");
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::update_hook), decltype(&Task::update_hook)>;
        },
        "vigil::Task<Derived>: your class declares `update_hook`, a framework hook "
        "name; rename it: write `on_update()` for the cycle's work");
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::cycle_hook), decltype(&Task::cycle_hook)>;
        },
        "vigil::Task<Derived>: your class declares `cycle_hook`, a framework hook "
        "name; rename it: write `on_update()` for the cycle's work");
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::stop_hook), decltype(&Task::stop_hook)>;
        },
        "vigil::Task<Derived>: your class declares `stop_hook`, a framework hook "
        "name; rename it: write `on_stop()` for stopping work");
    static_assert(
        requires {
          requires std::same_as<decltype(&Derived::cleanup_hook), decltype(&Task::cleanup_hook)>;
        },
        "vigil::Task<Derived>: your class declares `cleanup_hook`, a framework hook "
        "name; rename it: write `on_cleanup()` for clean-up work");
  }

  detail::CycleRecorder<Traits::port_capacity> recorder_;
};

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::Task;
}  // namespace vigil
