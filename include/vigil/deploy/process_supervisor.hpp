#pragma once
/// @file
/// `ProcessSupervisor`: the daemon behind `vigil supervise`. It supervises the components of
/// other processes whose ports live in shared memory (VIGIL_SUPERVISOR=<name>, see
/// vigil/task/shm_messages.hpp), exactly as a process's own supervisor and monitor do in-process.
///
/// A cycle (every `period_ns`, 10 ms by default, or at once when a watched process dies):
/// (1) discover segments /dev/shm/vigil.<name>.<pid>.<index> (inotify, plus a full listing every
/// `rescan_ns`), check each one's file (owner, mode) and header (magic, ABI version, schema,
/// sizes, strings, indices) and reject bad ones with a message naming the field; (2) drain every
/// segment into a ComponentAggregator (sticky mailboxes first for a segment seen for the first
/// time, so a daemon started after its processes still gets their identity and exact counters);
/// (3) watch every process with a pidfd: a process that ends has its segments drained one last
/// time, its components turned into ERROR reports "process 1234 (ctl) exited: killed by signal 9
/// (SIGKILL)" that keep their last counters, and its segments removed; (4) remove the segments
/// of components that left, once drained. A restarted process whose components have the same
/// names replaces the dead reports; each component's incarnation is counted.
///
/// A Monitor (its own thread when started, `MonitorOptions::period_ns`) runs the usual checks on
/// the aggregated components; `reports()` adds the dead processes' components, each component's
/// process (pid, command line, start time, incarnation) as key/values, and a "vigil.supervise"
/// report of the daemon itself.
///
/// Thread safety: every public member is thread-safe. Nothing here is RT-safe.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::deploy {

/// Options of the daemon.
struct ProcessSupervisorOptions {
  /// The supervisor name processes were given (VIGIL_SUPERVISOR): 1..31 of [A-Za-z0-9_-].
  std::string name = "vigil";
  /// How often every segment is drained (the in-process supervisor's default).
  Nanos period_ns = 10 * kNanosPerMilli;
  /// How often /dev/shm is listed in full (new segments are normally noticed through inotify).
  Nanos rescan_ns = kNanosPerSecond;
  /// Notice new segments at once through an inotify watch of /dev/shm (one inotify instance per
  /// daemon). false: only at the full listings, every `rescan_ns` (and at the first step), for
  /// systems where inotify instances are scarce (fs.inotify.max_user_instances) and for
  /// daemons made and destroyed often (closing an inotify instance waits for the kernel,
  /// milliseconds: the shm_segment fuzzer makes one daemon per input).
  bool watch_directory = true;
  /// Accept segments readable by this group (mode 0660); empty: owner-only segments (0600).
  std::string group;
  /// Remove the segments of dead processes and of components that left, once drained.
  bool reclaim = true;
  /// Options of the monitor (its period is the live view's pace).
  MonitorOptions monitor;
  /// Options of the aggregator (the clock must be the monitor's).
  supervisor::AggregatorOptions aggregator;
  /// Thread name of the drain loop.
  std::string thread_name = "vigil-supervise";
};

/// One supervised process, as the daemon knows it.
struct ProcessInfo {
  std::int32_t pid = 0;
  std::uint64_t start_ticks = 0;
  std::string name;          ///< the kernel's name for it (comm)
  std::string command_line;  ///< arguments separated by spaces (truncated to 255 bytes)
  std::int64_t started_unix_ns = 0;
  /// 1 for the first process with this command line the daemon saw, 2 for the next...
  std::uint32_t incarnation = 1;
  bool alive = true;
  /// How it ended ("killed by signal 9 (SIGKILL)"), once it did.
  std::string exit;
  /// Where that came from: "pidfd" (the kernel, Linux >= 6.15), "self" (the process recorded
  /// it), "zombie" (/proc before the parent reaped it), or "unknown".
  std::string exit_source;
  Nanos ended_at = 0;                   ///< monitor clock when the death was detected
  std::vector<std::string> components;  ///< its components (alive ones, or those it had)
};

/// Something that happened to a process or a segment.
struct ProcessEvent {
  enum class Kind : std::uint8_t {
    Joined,    ///< a component (segment) appeared
    Left,      ///< a component left normally (its segment was closed and drained)
    Exited,    ///< a process ended; `message` says how
    Rejected,  ///< a segment failed validation; `message` says which field and why
  };
  Kind kind = Kind::Joined;
  Nanos time_ns = 0;  ///< monitor clock when the daemon noticed it
  std::int32_t pid = 0;
  std::string component;  ///< for Joined, Left; the segment name for Rejected
  std::string message;
};

/// "joined", "left", "exited", "rejected".
[[nodiscard]] const char* to_string(ProcessEvent::Kind k) noexcept;

/// The daemon's own measurements.
struct ProcessSupervisorStats {
  std::uint64_t cycles = 0;
  std::uint64_t messages = 0;
  std::size_t segments = 0;        ///< segments drained now
  std::size_t processes = 0;       ///< processes alive now
  std::size_t dead_processes = 0;  ///< processes whose end is still reported
  std::uint64_t rejected = 0;      ///< segments rejected so far
  std::uint64_t reclaimed = 0;     ///< segments removed so far
  StatsSummary cycle_ns;           ///< time per cycle
};

class ProcessSupervisor {
 public:
  /// Called on the drain thread (or step()'s caller) for every event, after the cycle.
  using EventCallback = std::function<void(const ProcessEvent&)>;

  /// Prepares the daemon for `options.name` (nothing runs before step() or start()). Fails for
  /// an invalid name or group.
  static expected<std::unique_ptr<ProcessSupervisor>, Error> create(
      ProcessSupervisorOptions options);
  ~ProcessSupervisor();
  ProcessSupervisor(const ProcessSupervisor&) = delete;
  ProcessSupervisor& operator=(const ProcessSupervisor&) = delete;

  /// Runs one cycle in the calling thread (discover, drain, detect deaths, reclaim); returns the
  /// messages visited. Serialised with the drain thread's cycles.
  std::size_t step();

  /// Starts the drain thread (a cycle every period, or at once when a watched process ends or a
  /// segment appears) and the monitor's thread. Idempotent.
  expected<void, Error> start();
  /// Stops both threads. Idempotent. The segments stay as they are: a daemon started later
  /// continues where this one stopped.
  void stop();
  /// Tells the processes that no daemon drains their segments any more (done on destruction):
  /// a component that leaves, or a process that exits, then removes its segments itself.
  void detach();

  /// The latest monitor cycle's reports with the processes' information, the dead processes'
  /// components and the daemon's own report.
  [[nodiscard]] ReportSet reports() const;
  /// `base` (a monitor cycle's reports, e.g. what a monitor subscriber receives) with the
  /// processes' information, the dead processes' components and the daemon's own report, as
  /// reports() does for the latest cycle. Any thread.
  [[nodiscard]] ReportSet compose(const ReportSet& base) const;
  /// Runs a monitor cycle now and returns reports() as of then.
  ReportSet step_monitor();
  /// The processes: alive ones, then those whose end is still reported.
  [[nodiscard]] std::vector<ProcessInfo> processes() const;
  /// Adds an event subscriber; returns its id.
  std::uint64_t subscribe(EventCallback callback);
  /// Removes a subscriber.
  void unsubscribe(std::uint64_t id);

  [[nodiscard]] ProcessSupervisorStats stats() const;
  [[nodiscard]] const ProcessSupervisorOptions& options() const noexcept;
  [[nodiscard]] Monitor& monitor() noexcept;
  [[nodiscard]] const supervisor::ComponentAggregator& aggregator() const noexcept;

  struct Impl;

 private:
  explicit ProcessSupervisor(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vigil::deploy
