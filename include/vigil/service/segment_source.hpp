#pragma once
/// @file
/// `SegmentSource`: the source of `vigil supervise` (vigil/service/source.hpp). It drains the
/// components of other processes whose ports live in shared memory (VIGIL_SUPERVISOR=<name>, see
/// vigil/task/shm_messages.hpp) into the pipeline's aggregator, exactly as the in-process
/// supervisor drains a registry, and it contributes (vigil/service/contributor.hpp) what only it
/// knows: each component's process, the components of dead processes, and its own report.
///
/// A cycle (every `period_ns`, 10 ms by default, or at once when a watched process dies):
/// (1) discover segments /dev/shm/vigil.<name>.<pid>.<index> (inotify, plus a full listing every
/// `rescan_ns`), check each one's file (owner, mode) and header (magic, ABI version, schema,
/// sizes, strings, indices) and reject bad ones with an event naming the field; (2) drain every
/// segment into the aggregator (sticky mailboxes first for a segment seen for the first time, so a
/// daemon started after its processes still gets their identity and exact counters); (3) watch
/// every process with a pidfd: a process that ends has its segments drained one last time, its
/// components turned into ERROR reports "process 1234 (ctl) exited: killed by signal 9
/// (SIGKILL)" that keep their last counters, and its segments removed; (4) remove the segments
/// of components that left, once drained. A restarted process whose components have the same
/// names replaces the dead reports; each component's incarnation is counted.
///
/// Corruption (docs/reference/shm-segment.md): every drain checks the state fields and indices
/// against each other and against what this daemon saw and wrote, and every record (sequence,
/// type, size, fields); the constant header under its checksum is verified every
/// `header_check_ns` and at every report. A segment found corrupt is never read again: its
/// component becomes an ERROR report "segment corrupted: <field> (...)" that keeps its counters
/// up to the last good record, and a `segment_corrupted` event names the field.
///
/// A daemon that restarts (the previous one killed): the segments keep their read index and the
/// components' cumulative counters, so the new daemon continues every total; it finds the
/// previous daemon's pid and last heartbeat in the segments and raises one
/// `supervisor_restarted` event naming the outage ("daemon 1234 was down from ... to ...").
///
/// What happens to processes and segments reaches subscribers as ordinary events of the
/// aggregator's hub (`joined`, `left`, `process_exited`, `segment_rejected`, `segment_corrupted`,
/// `supervisor_restarted`): one event stream.
///
/// Built by `SupervisionService` when its options name `segments`. Thread safety: every public
/// member is thread-safe. Nothing here is RT-safe.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/service/contributor.hpp"
#include "vigil/service/source.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::service {

/// Options of a segment source.
struct SegmentSourceOptions {
  /// The supervisor name processes were given (VIGIL_SUPERVISOR): 1..31 of [A-Za-z0-9_-].
  std::string name = "vigil";
  /// How often every segment is drained. The service sets it from its `supervisor_period_ns`.
  Nanos period_ns = 10 * kNanosPerMilli;
  /// How often /dev/shm is listed in full (new segments are normally noticed through inotify).
  Nanos rescan_ns = kNanosPerSecond;
  /// Notice new segments at once through an inotify watch of /dev/shm (one inotify instance per
  /// source). false: only at the full listings, every `rescan_ns` (and at the first step), for
  /// systems where inotify instances are scarce (fs.inotify.max_user_instances) and for
  /// sources made and destroyed often (closing an inotify instance waits for the kernel,
  /// milliseconds: the shm_segment fuzzer makes one per input).
  bool watch_directory = true;
  /// How often each live process's run state is read from /proc (running, stopped by a signal,
  /// stopped by a tracer): a stop and a continue are events found within this time (a process
  /// whose records arrived at the previous drain was running then and is not read: its stop is
  /// found within this time and two periods). 0: never.
  Nanos state_check_ns = 100 * kNanosPerMilli;
  /// How often what each writer set once in its segment's header (the constant part under its
  /// checksum, the reserved fields) is verified again; it is also verified at every report
  /// (contribute). 0: at every cycle. The state fields, indices and records are checked at every
  /// drain whatever this says.
  Nanos header_check_ns = 100 * kNanosPerMilli;
  /// Accept segments readable by this group (mode 0660); empty: owner-only segments (0600).
  std::string group{};
  /// Remove the segments of dead processes and of components that left, once drained.
  bool reclaim = true;
  /// Thread name of the drain loop.
  std::string thread_name = "vigil-supervise";
  /// The name of the source's own report.
  std::string report_name = "vigil.supervise";
};

/// Checks `options` (the name, the group, the periods): the error says which field is wrong.
[[nodiscard]] expected<void, Error> validate(const SegmentSourceOptions& options);

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
  /// While alive: running, stopped (by a signal: SIGSTOP, SIGTSTP...), traced (stopped by a
  /// debugger) or zombie, as /proc said at the latest check (`state_check_ns`).
  platform::RunState run_state = platform::RunState::Running;
  /// Monitor clock when it entered `run_state` (as found: within `state_check_ns`); 0 when it
  /// was so from the start.
  Nanos run_state_since = 0;
  /// How it ended ("killed by signal 9 (SIGKILL)"), once it did.
  std::string exit;
  /// Where that came from: "pidfd" (the kernel, Linux >= 6.15), "self" (the process recorded
  /// it), "zombie" (/proc before the parent reaped it), or "unknown".
  std::string exit_source;
  Nanos ended_at = 0;                   ///< monitor clock when the death was detected
  std::vector<std::string> components;  ///< its components (alive ones, or those it had)
};

/// The daemon's own measurements.
struct SegmentSourceStats {
  std::uint64_t cycles = 0;
  std::uint64_t messages = 0;
  std::size_t segments = 0;         ///< segments drained now
  std::size_t processes = 0;        ///< processes alive now
  std::size_t dead_processes = 0;   ///< processes whose end is still reported
  std::uint64_t rejected = 0;       ///< segments rejected so far (at open, or corrupted later)
  std::uint64_t corrupted = 0;      ///< segments found corrupt while being read, so far
  std::uint64_t header_checks = 0;  ///< header verifications (every segment counts one)
  /// Segments taken over from a daemon that stopped draining them without detaching (killed).
  std::uint64_t adopted = 0;
  std::uint64_t reclaimed = 0;  ///< segments removed so far
  StatsSummary cycle_ns;        ///< time per cycle
};

/// The process table, one line per process: name, pid, start time, incarnation, state (running,
/// stopped or traced with its components, or how it ended), command line; a header line first.
/// `now`: the monitor clock, for how long a process has been stopped (0: not said).
[[nodiscard]] std::string format_processes(const std::vector<ProcessInfo>& processes,
                                           Nanos now = 0);

class SegmentSource final : public Source, public Contributor, public exporter::TextPanel {
 public:
  /// Prepares a source for `options.name` draining into `aggregator` (which must outlive it;
  /// its clock stamps the source's events and reports). Nothing runs before step() or start().
  /// The options must be valid (`validate`): `SupervisionService::start()` checks them.
  SegmentSource(SegmentSourceOptions options, supervisor::ComponentAggregator& aggregator);
  /// Stops, then detaches.
  ~SegmentSource() override;
  SegmentSource(const SegmentSource&) = delete;
  SegmentSource& operator=(const SegmentSource&) = delete;

  /// Runs one cycle in the calling thread (discover, drain, detect deaths, reclaim); returns the
  /// messages visited. Serialised with the drain thread's cycles.
  std::size_t step() override;
  /// Starts the drain thread (a cycle every period, or at once when a watched process ends or a
  /// segment appears). Fails for invalid options. Idempotent.
  expected<void, Error> start() override;
  /// Stops the thread after a last drain. Idempotent. The segments stay as they are: a source
  /// started later continues where this one stopped.
  void stop() override;
  [[nodiscard]] bool running() const override;
  /// Tells the processes that no daemon drains their segments any more (done on destruction):
  /// a component that leaves, or a process that exits, then removes its segments itself.
  void detach();

  /// Adds to a monitor cycle's snapshot each component's process (pid, command line, start
  /// time, incarnation) as key/values, the dead processes' components (ERROR, replacing the
  /// monitor's reports of them), and the source's own report. Monitor's thread.
  void contribute(exporter::Snapshot& snapshot) override;

  /// The processes: alive ones, then those whose end is still reported.
  [[nodiscard]] std::vector<ProcessInfo> processes() const;
  /// The process table (`format_processes`) under a text view's summary.
  void append(std::string& out) const override;
  [[nodiscard]] SegmentSourceStats stats() const;
  [[nodiscard]] const SegmentSourceOptions& options() const noexcept;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace vigil::service
