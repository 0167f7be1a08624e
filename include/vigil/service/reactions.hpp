#pragma once
/// @file
/// Reactions: what the pipeline *does* about a fault. A reaction fires on a unit reaching a
/// status (a component, a CAN node or group, a health supervision, an aggregate of the diagnosis
/// graph: any report of the monitor's cycle), or on an event kind (within milliseconds of the
/// fault, from the event stream), and runs its actions:
///
///  - **safe state**: raises the process-wide request that real-time code reads with one relaxed
///    load (vigil/safe_state.hpp; a `Task` with `on_safe_state()` switches to it);
///  - **CAN frames** through a `CanWriter` the program registered (a CANopen NMT stop, say);
///  - **watchdog**: `WATCHDOG=trigger` to systemd, the process's outer watchdog;
///  - **handlers** the program registered, called on the reaction thread (never the supervisor's,
///    the monitor's or a real-time thread), their run time measured against a budget.
///
/// ```cpp
/// auto& r = service.reactions();
/// r.add_handler("log_fault", [](const vigil::ReactionContext& c) { ... });
/// (void)r.add({.name = "encoder_fault",
///              .on = {.event = vigil::EventKind::Exception, .component = "encoder"},
///              .safe_state = true, .handlers = {"log_fault"}});
/// ```
///
/// The safe state, the CAN frames and the watchdog are taken at once by the thread that saw the
/// trigger (the event stream's dispatcher, or the monitor's thread for a status); they never
/// block (a `CanWriter` must not). Handlers are queued to the reaction thread. Every action is an
/// event of kind `reaction` with its outcome, and its latency from the fault (`fault_ns` is the
/// trigger's fault time, `detected_ns` when the action was taken). A reaction fires at most
/// once per `min_interval_ns`; what it would have done meanwhile is counted (one `reaction`
/// event says it was rate-limited). In dry-run mode every action is logged as an event
/// ("dry run: would ...") and none is taken. No shell command is ever run.
///
/// A handler that throws is reported (a `reaction` event, warn) and the next one runs; one that
/// runs over its budget is reported when it returns, and while it runs the reaction thread's
/// unit (`vigil.reactions`) says so; supervision never waits for a handler.
///
/// Threads: add*, start() and stop() from the control thread before start() / after stop();
/// `on_event()` from the event stream's dispatcher, `on_reports()` from the monitor's thread;
/// stats() and unit() from any thread. Nothing here is RT-safe.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/supervisor/events.hpp"

namespace vigil::exporter {
class SystemdNotifyOutput;
}

namespace vigil::service {

/// What fired a reaction, handed to its handlers.
struct ReactionContext {
  std::string reaction{};  ///< the reaction's name
  std::string unit{};      ///< the unit (report) or component it fired for
  std::string cause{};     ///< the event's line, or the status and its first message
  /// When the fault happened: the event's fault time, or the monitor cycle that showed the
  /// status. Monotonic ns.
  Nanos fault_ns = 0;
  Nanos triggered_ns = 0;  ///< when the reaction matched
  bool dry_run = false;    ///< the handler is not called in dry-run mode; kept for symmetry
  /// The event that fired it (event triggers), else none.
  std::optional<supervisor::Event> event{};
  /// The status reached (status triggers), else Ok.
  monitor::StatusLevel status = monitor::StatusLevel::Ok;
};

/// A program's handler, called on the reaction thread, one at a time, in order.
using ReactionHandler = std::function<void(const ReactionContext&)>;

/// Sends one CAN frame for a reaction. Must not block: queue it for the program's CAN thread
/// (a lock-free queue its real-time loop empties) or write it to a non-blocking socket. Returns
/// false when the frame could not be sent or queued.
using CanWriter = std::function<bool(const can::Frame&)>;

/// When a reaction fires: set `unit` (a status trigger) or `event` (an event trigger).
struct ReactionTrigger {
  /// A report of the monitor's cycle, by name (a component, "can0/drive_5", "can group
  /// right_arm", "supervision <name>", an aggregate): fires when its shown status reaches
  /// `status` or worse, coming from better.
  std::string unit{};
  monitor::StatusLevel status = monitor::StatusLevel::Error;
  /// An event kind: fires on every event of that kind (of `component`, when set).
  std::optional<supervisor::EventKind> event{};
  std::string component{};
};

/// One CAN frame to send, and through which writer.
struct CanAction {
  std::string writer{};
  can::Frame frame{};
};

/// A reaction: a trigger and its actions.
struct Reaction {
  std::string name{};
  ReactionTrigger on{};
  bool safe_state = false;              ///< raise the safe-state request
  std::vector<CanAction> can{};         ///< frames to send
  bool watchdog = false;                ///< WATCHDOG=trigger (systemd)
  std::vector<std::string> handlers{};  ///< registered handlers to call, in order
  /// Fires at most once per interval; 0: every time.
  Nanos min_interval_ns = kNanosPerSecond;
};

/// Options of the reactions.
struct ReactionsOptions {
  /// Log every action as an event ("dry run: would ...") and take none.
  bool dry_run = false;
  /// Handler calls waiting for the reaction thread; more are dropped and counted.
  std::size_t queue_capacity = 64;
  /// A handler's budget unless it was registered with its own.
  Nanos default_budget_ns = 10 * kNanosPerMilli;
  /// The reaction thread's stack.
  std::size_t stack_bytes = std::size_t{256} * 1024;
  /// The scheduling of the reaction thread and of the event dispatcher that takes the immediate
  /// actions: SCHED_OTHER by default; SCHED_FIFO (with `priority` 1..99, below the real-time
  /// components') wakes them at once on a loaded host. When FIFO
  /// is refused (no privilege) the thread runs SCHED_OTHER and start() says nothing: the
  /// `vigil.reactions` unit shows the policy it got.
  platform::SchedPolicy policy = platform::SchedPolicy::Other;
  int priority = 0;
};

/// Counters, exact. Any thread.
struct ReactionStats {
  std::uint64_t fired = 0;          ///< firings (each may take several actions)
  std::uint64_t actions = 0;        ///< actions taken (or logged in dry run)
  std::uint64_t rate_limited = 0;   ///< firings suppressed by `min_interval_ns`
  std::uint64_t failed = 0;         ///< actions that failed (writer refused, handler threw, ...)
  std::uint64_t over_budget = 0;    ///< handler calls that ran over their budget
  std::uint64_t dropped = 0;        ///< handler calls dropped (queue full)
  std::uint64_t handler_calls = 0;  ///< handler calls completed
};

/// The reactions of one pipeline (`SupervisionService::reactions()`).
class Reactions {
 public:
  explicit Reactions(ReactionsOptions options = {});
  /// Stops the reaction thread (as stop()).
  ~Reactions();
  Reactions(const Reactions&) = delete;
  Reactions& operator=(const Reactions&) = delete;

  /// Registers handler `name` (replacing one of that name) with its budget (0: the default).
  void add_handler(std::string name, ReactionHandler handler, Nanos budget_ns = 0);
  /// Registers CAN writer `name` (replacing one of that name).
  void add_can_writer(std::string name, CanWriter writer);
  [[nodiscard]] bool has_handler(std::string_view name) const;
  [[nodiscard]] bool has_can_writer(std::string_view name) const;
  /// Adds a reaction. Errors: no name, a name used twice, no trigger or both, an event trigger
  /// on `reaction` (a reaction never fires on reactions), no action, an unregistered handler or
  /// writer (each named).
  expected<void, Error> add(Reaction reaction);
  [[nodiscard]] const std::vector<Reaction>& reactions() const noexcept { return reactions_; }
  void set_dry_run(bool dry_run) noexcept { dry_run_.store(dry_run, std::memory_order_relaxed); }
  /// The reaction thread's scheduling (before start()).
  void set_scheduling(platform::SchedPolicy policy, int priority) noexcept {
    options_.policy = policy;
    options_.priority = priority;
  }
  [[nodiscard]] bool dry_run() const noexcept { return dry_run_.load(std::memory_order_relaxed); }

  /// Starts the reaction thread and subscribes to `events` (when any reaction needs it).
  /// `systemd` (may be null) is the outer watchdog. Nothing to do without reactions.
  expected<void, Error> start(supervisor::EventHub& events, exporter::SystemdNotifyOutput* systemd);
  /// Unsubscribes, lets the reaction thread finish the calls queued, joins it. Waits for a
  /// handler under way.
  void stop();

  /// An event of the stream: fires the event triggers it matches. The hub's dispatcher thread.
  void on_event(const supervisor::Event& e);
  /// A monitor cycle's reports (after the diagnosis graph): fires the status triggers whose unit
  /// reached its status since the previous cycle. The monitor's thread.
  void on_reports(const monitor::ReportSet& reports);

  [[nodiscard]] ReactionStats stats() const;
  /// The reaction thread's unit (`vigil.reactions`, kind `reactions`): OK while idle or within
  /// budget, ERROR while a handler runs over its budget (naming it and for how long), WARN when
  /// calls were dropped or failed in the latest window; its counters as fields. Monitor time
  /// `now`. Any thread.
  [[nodiscard]] monitor::Report unit(Nanos now) const;
  /// The name of the reaction thread's unit.
  static constexpr std::string_view kUnitName = "vigil.reactions";

 private:
  struct Call {
    std::string handler;
    ReactionHandler fn;
    Nanos budget_ns = 0;
    ReactionContext context;
  };
  struct PerReaction {
    Nanos last_fired = -1;
    bool limited_reported = false;  // a rate-limited event was published since the last firing
    monitor::StatusLevel shown = monitor::StatusLevel::Ok;  // status triggers: the latest seen
  };
  void fire(std::size_t index, ReactionContext context);
  void publish(const ReactionContext& c, supervisor::EventSeverity severity, std::string detail,
               Nanos action_ns);
  void run();

  ReactionsOptions options_;
  std::atomic<bool> dry_run_;
  std::vector<Reaction> reactions_;
  std::map<std::string, std::pair<ReactionHandler, Nanos>, std::less<>> handlers_;
  std::map<std::string, CanWriter, std::less<>> writers_;
  supervisor::EventHub* events_ = nullptr;
  exporter::SystemdNotifyOutput* systemd_ = nullptr;
  std::uint64_t subscription_ = 0;

  mutable std::mutex mutex_;  // per_, queue_, stats_, busy state, stopping_
  std::condition_variable wake_;
  std::vector<PerReaction> per_;
  std::deque<Call> queue_;
  ReactionStats stats_;
  std::string running_handler_;  // the handler under way ("" : idle)
  Nanos running_since_ = 0;
  Nanos running_budget_ = 0;
  bool stopping_ = false;
  bool realtime_ = false;  // the thread got SCHED_FIFO
  platform::Thread thread_;
};

}  // namespace vigil::service

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using service::CanAction;
using service::CanWriter;
using service::Reaction;
using service::ReactionContext;
using service::ReactionHandler;
using service::Reactions;
using service::ReactionTrigger;
}  // namespace vigil
