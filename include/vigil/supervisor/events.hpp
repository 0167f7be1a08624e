#pragma once
/// @file
/// Events: discrete faults detected at the supervisor's pace (10 ms by default), not the
/// monitor's (1 s). The aggregator raises them while it drains the ports (an exception, a task
/// entering Exception or FatalError, the overrun limit, overruns, a real-time loss, a state
/// change) and its watchdog raises them at each supervisor cycle (a component silent past its
/// deadline, and its recovery). `EventHub` hands them to subscribers (the robot's state
/// machine, a JSON-lines file, the HTTP stream) without ever delaying the supervisor.
///
/// Design: `publish()` (the supervisor thread, or a thread clearing a latch) copies the event
/// into a bounded ring per subscriber under a mutex held only for that copy, and wakes the
/// subscriber's own dispatcher thread, which calls the callback outside any lock. When a ring is
/// full the event is dropped for that subscriber and counted (`SubscriberStats::lost`): a slow
/// subscriber loses events, never delays detection. The hub also keeps the latest events, in
/// order, for readers that poll (`since()`, `wait()`: the HTTP `/events` endpoint).
///
/// Nothing here is RT-safe: the real-time side never sees events.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"

namespace vigil::supervisor {

/// What happened.
enum class EventKind : std::uint8_t {
  Exception,     ///< a hook threw (ExceptionReport)
  OverrunLimit,  ///< the activity's overrun limit was reached (the task goes to Exception)
  FaultState,    ///< the task entered Exception or FatalError
  StateChange,   ///< any other lifecycle transition (or a refused one)
  Overrun,       ///< cycles ended after their next release (coalesced per supervisor drain)
  RealTimeLoss,  ///< a real-time loss (allocation, blocking call, page fault, mode switch)
  Deadline,      ///< the watchdog: no cycle arrived before the component's deadline
  Recovered,     ///< cycles arrive again after a Deadline event
  Cleared,       ///< a latched fault was cleared (API, auto-clear, HTTP)
  // What `vigil supervise` (a SegmentSource) sees of other processes:
  Joined,            ///< a component of another process appeared (its segment)
  Left,              ///< a component of another process left normally (segment closed, drained)
  ProcessExited,     ///< a supervised process ended; `detail` says how
  SegmentRejected,   ///< a segment failed validation; `detail` names the field and why
  ProcessStopped,    ///< a supervised process was stopped (by a signal or a tracer); Warn
  ProcessContinued,  ///< a stopped process runs again; `detail` says for how long it was stopped
  // What the units of a contributor report (CAN nodes):
  NotResponding,  ///< a unit (a CAN node) sent nothing within its silence limit
  Responding,     ///< a unit that was not responding sends again
  // Health supervision (vigil/health; `HealthSupervision`): `detail` names the supervision first.
  // Warn while the supervision is FAILED (within its tolerance), Error when it becomes EXPIRED.
  AliveSupervision,     ///< too few or too many indications in a reference cycle, or never started
  DeadlineSupervision,  ///< an end too early, missed (found when max passed), or a second start
  LogicalSupervision,   ///< a checkpoint the graph does not allow after the previous one
  CheckpointMisuse,     ///< a component reported a checkpoint id it did not declare (Warn)
  // What CAN frames say (vigil/can/protocol.hpp): the component is "can0/<node>" or "can bus 0";
  // `fault_ns` is the frame's time.
  NmtState,      ///< a CANopen node's NMT state changed (heartbeat); Warn when leaving operational
  NodeReset,     ///< a CANopen node that was running booted again (Warn)
  Emergency,     ///< a CANopen emergency message; `detail` decodes it (Warn; Info for a reset)
  NmtCommand,    ///< an NMT command on the bus (Info; Warn for reset node / communication)
  ErrorWarning,  ///< a CAN controller reached error warning (Info)
  ErrorPassive,  ///< a CAN controller went error passive (Warn)
  BusOff,        ///< a CAN controller went bus off (Error)
  ErrorActive,   ///< a CAN controller is error active again (Info)
  NodeHealth,    ///< a DroneCAN node's NodeStatus health changed (by the new health)
  // `vigil supervise` again (appended: the values above keep their numbers):
  SegmentCorrupted,  ///< a segment being read was found corrupt; `detail` names the field (Error)
  SupervisorRestarted,  ///< this daemon took over from one that was killed; `detail`: the outage
  // SAE J1939 (vigil/can/protocol.hpp), appended:
  DtcActive,     ///< a J1939 DM1 trouble code became active (Warn; Error with the red stop lamp)
  DtcCleared,    ///< a J1939 DM1 trouble code is no longer active (Info)
  AddressClaim,  ///< a J1939 address claim: first (Info), another NAME or cannot claim (Warn)
  // Reactions (vigil/service/reactions.hpp): `component` is "reaction <name>", `detail` the
  // action and its outcome; `fault_ns` the trigger's fault, `detected_ns` when the action was
  // taken (a handler: when it started). Info when done, Warn when it failed or the safe state
  // was requested.
  Reaction,
  // The pipeline's own threads (the supervisor, the monitor, the reaction thread): one stopped
  // making progress (Error), or runs again (Info). `component` is its unit ("vigil.supervisor").
  ThreadStalled,
  ThreadResumed,
};
/// Lower-case name of a kind ("exception", "overrun_limit", ...), as written in JSON.
[[nodiscard]] const char* to_string(EventKind k) noexcept;
/// The kind named `name` (to_string's spelling), or none.
[[nodiscard]] std::optional<EventKind> parse_event_kind(std::string_view name) noexcept;
/// Every kind's name, in order (for error messages and suggestions).
[[nodiscard]] std::vector<std::string_view> event_kind_names();

/// How bad it is. An Error event latches the component's fault (see `LatchedFault`).
enum class EventSeverity : std::uint8_t { Info, Warn, Error };
/// "info", "warn" or "error".
[[nodiscard]] const char* to_string(EventSeverity s) noexcept;

/// One event. Plain data.
struct Event {
  std::uint64_t seq = 0;  ///< 1-based, in publication order, per hub
  EventKind kind = EventKind::StateChange;
  EventSeverity severity = EventSeverity::Info;
  std::uint32_t component_id = 0;  ///< registry id (0 for the hub's own events)
  std::string component;
  /// The process an event of another process is about (`vigil supervise`: joined, left,
  /// process_exited, segment_rejected); 0 for this process's own components.
  std::int32_t pid = 0;
  /// The component's cycle number of the fault (the faulting cycle; for Deadline the latest
  /// cycle received; 0 when not known).
  std::uint64_t cycle = 0;
  /// Monotonic time of the fault: the faulting cycle's end, the transition's time, or for
  /// Deadline the deadline that passed. Nanoseconds, the same clock as `detected_ns`.
  Nanos fault_ns = 0;
  /// Monotonic time the supervisor detected it (supervisor clock).
  Nanos detected_ns = 0;
  /// How many faults this event stands for (overruns coalesced in one drain, losses in one
  /// cycle); 1 for the others.
  std::uint64_t count = 1;
  bool latched = false;  ///< this event raised the component's latch (first Error since clear)
  bool traced = false;   ///< a flight record was frozen for it (`FlightRecord`)
  std::string detail;    ///< human-readable: the exception's type and message, the cause, ...
  /// Detection latency (detected - fault), 0 when the fault time is unknown.
  [[nodiscard]] Nanos latency_ns() const noexcept {
    return fault_ns > 0 && detected_ns >= fault_ns ? detected_ns - fault_ns : 0;
  }
};

/// One line of text for an event: "ERROR encoder: exception: std::runtime_error: ... (cycle
/// 4001, detected 3.2 ms after the fault)". Not RT-safe (allocates).
[[nodiscard]] std::string format_event(const Event& e);

/// A subscriber's callback, called on its own dispatcher thread, one event at a time, in order.
/// It may block or be slow: only its own events are lost then. Exceptions it throws are
/// swallowed.
using EventCallback = std::function<void(const Event&)>;

/// Delivery statistics of one subscriber.
struct SubscriberStats {
  std::uint64_t delivered = 0;  ///< callbacks completed
  std::uint64_t lost = 0;       ///< events dropped because its queue was full
  std::size_t capacity = 0;
};

/// Options of a hub.
struct EventHubOptions {
  /// Events queued per subscriber before new ones are dropped and counted.
  std::size_t queue_capacity = 1024;
  /// Latest events kept for `since()` / `wait()`.
  std::size_t recent = 512;
};

/// Distributes events to subscribers. Every member is thread-safe; nothing is RT-safe.
class EventHub {
 public:
  explicit EventHub(EventHubOptions options = {});
  /// Stops every dispatcher thread (events still queued are not delivered).
  ~EventHub();
  EventHub(const EventHub&) = delete;
  EventHub& operator=(const EventHub&) = delete;

  /// Adds a subscriber with its own dispatcher thread and a queue of `capacity` events
  /// (0: the hub's default). Returns its id (never 0). Throws std::system_error if the thread
  /// cannot be created.
  std::uint64_t subscribe(EventCallback callback, std::size_t capacity = 0);
  /// The same, the dispatcher thread on `policy` (SCHED_FIFO with `priority` 1..99: the
  /// reactions' subscriber, woken at once on a loaded host); a refused SCHED_FIFO falls back to
  /// SCHED_OTHER.
  std::uint64_t subscribe(EventCallback callback, std::size_t capacity,
                          platform::SchedPolicy policy, int priority);
  /// Removes a subscriber: waits for the callback under way, joins its thread; events still
  /// queued are dropped. Unknown ids are ignored. Must not be called from that callback.
  void unsubscribe(std::uint64_t id);
  /// Waits (at most `timeout_ns`) until every subscriber's queue is empty and its callback
  /// returned. True when they all drained.
  bool flush(Nanos timeout_ns = kNanosPerSecond);
  /// Delivery statistics of subscriber `id` (zeros for an unknown id).
  [[nodiscard]] SubscriberStats stats(std::uint64_t id) const;

  /// Publishes `e` (its `seq` is assigned here): never blocks for longer than copying it into
  /// each subscriber's queue. Returns the sequence number given.
  std::uint64_t publish(Event e);

  /// Events with seq > `after`, oldest first, at most `max` (the latest `recent` are kept:
  /// older ones are gone, see `first_seq`).
  [[nodiscard]] std::vector<Event> since(std::uint64_t after, std::size_t max = SIZE_MAX) const;
  /// Waits until an event with seq > `after` exists or `timeout_ns` passed, or `cancel()` was
  /// called; true when there is one. For long polls.
  bool wait(std::uint64_t after, Nanos timeout_ns) const;
  /// Wakes every `wait()` (a server stopping).
  void cancel_waits();
  /// Sequence number of the latest event published (0: none yet).
  [[nodiscard]] std::uint64_t last_seq() const;
  /// Events published since the hub was made.
  [[nodiscard]] std::uint64_t published() const { return last_seq(); }
  /// Events lost by every subscriber together.
  [[nodiscard]] std::uint64_t lost() const;

 private:
  struct Subscriber;
  EventHubOptions options_;
  mutable std::mutex mutex_;  // subscribers_, recent_, seq_
  mutable std::condition_variable published_cv_;
  std::vector<std::shared_ptr<Subscriber>> subscribers_;
  std::deque<Event> recent_;
  std::uint64_t seq_ = 0;
  std::uint64_t next_id_ = 1;
  std::uint64_t lost_gone_ = 0;  // lost by subscribers that left
  std::uint64_t cancel_gen_ = 0;
};

/// Turns events into text lines, at most one per component per `interval_ns` (default 1 s):
/// the events in between are counted and the next line says how many were folded into it.
/// Never loses a count: `folded()` is exact. For the log and the text view. Thread-safe.
class EventLineLimiter {
 public:
  explicit EventLineLimiter(Nanos interval_ns = kNanosPerSecond) : interval_ns_(interval_ns) {}
  /// The line to print for `e` (at its detection time), or an empty string when it is folded.
  std::string line(const Event& e);
  /// Events folded into later lines so far (all components).
  [[nodiscard]] std::uint64_t folded() const;

 private:
  struct PerComponent {
    Nanos last_line = 0;
    std::uint64_t pending = 0;  // folded since that line
  };
  Nanos interval_ns_;
  mutable std::mutex mutex_;
  std::vector<std::pair<std::string, PerComponent>> components_;
  std::uint64_t folded_ = 0;
};

}  // namespace vigil::supervisor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using supervisor::Event;
using supervisor::EventCallback;
using supervisor::EventKind;
using supervisor::EventSeverity;
using supervisor::format_event;
using supervisor::to_string;
}  // namespace vigil
