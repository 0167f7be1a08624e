// The source of `vigil supervise`: segment discovery, draining, process death, reclaiming.
#include "vigil/service/segment_source.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <unordered_map>
#include <utility>

#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/platform/ready_set.hpp"
#include "vigil/platform/shm.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/shm_messages.hpp"

namespace vigil::service {

namespace {

// The aggregator asks an entry's port for its capacity; a remote port has nothing to pop here.
class RemotePort final : public PortReader<task::Message> {
 public:
  explicit RemotePort(std::size_t capacity) : capacity_(capacity) {}
  std::size_t pop(task::Message* /*out*/, std::size_t /*max*/) noexcept override { return 0; }
  [[nodiscard]] std::size_t read_available() const noexcept override { return 0; }
  [[nodiscard]] std::size_t capacity() const noexcept override { return capacity_; }

 private:
  std::size_t capacity_;
};

using Entry = bus::RegistryEntry<task::Message>;

struct Process;

constexpr std::uint64_t kNoProgress = std::numeric_limits<std::uint64_t>::max() - 1;

struct Segment {
  std::string name;
  bus::ShmReader<task::Message> reader;
  std::shared_ptr<Entry> entry;
  Process* process = nullptr;
  std::uint32_t incarnation = 1;
  bus::ShmLiveState last_live;
  // The cycle whose drain last received records from it (next to last_live, which every drain
  // writes): its process ran then (see check_run_states).
  std::uint64_t progress_cycle = kNoProgress;
};

struct Process {
  ProcessInfo info;
  platform::ProcessWatch watch;
  bool watched = false;       // watch holds a pidfd or /proc fallback for this process
  std::uint64_t set_tag = 0;  // its tag in the source's ReadySet while its pidfd is there; 0: not
  std::vector<Segment*> segments;
  std::vector<Report> dead_reports;           // its components at its death, or corrupted, ERROR
  std::vector<std::string> corrupt_segments;  // its segments found corrupt (removed at its end)
};

// What reports() adds to a component's report: where it runs.
struct Placement {
  std::int32_t pid = 0;
  std::string process;
  std::string command_line;
  std::int64_t started_unix_ns = 0;
  std::uint32_t incarnation = 1;
  bool dead = false;
  Nanos forget_at = 0;  // 0: still a member
};

// The name of a process's unit: "process <name> (pid <pid>)".
std::string process_unit_name(const std::string& name, std::int32_t pid) {
  return fmt::format("process {} (pid {})", name, pid);
}

std::optional<std::int32_t> pid_of_segment(const std::string& name) {
  // "/vigil.<name>.<pid>.<index>"
  const auto last = name.rfind('.');
  if (last == std::string::npos || last == 0) return std::nullopt;
  const auto prev = name.rfind('.', last - 1);
  if (prev == std::string::npos) return std::nullopt;
  const std::string pid = name.substr(prev + 1, last - prev - 1);
  if (pid.empty() || pid.size() > 9 ||
      !std::all_of(pid.begin(), pid.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return std::nullopt;
  }
  return static_cast<std::int32_t>(std::stol(pid));
}

}  // namespace

struct SegmentSource::Impl {
  Impl(SegmentSourceOptions o, supervisor::ComponentAggregator& a)
      : options(std::move(o)), aggregator(a) {
    expectation.schema = task::kShmMessageSchema;
    expectation.supervisor_name = options.name;
    segment_prefix = bus::shm_segment_prefix(options.name);
    uid = platform::effective_uid();
    self_pid = platform::self_identity().pid;
    buffer.resize(kShmMaxBatch);
    seqs.resize(kShmMaxBatch);
    if (auto r = platform::ReadySet::open()) ready_set.emplace(std::move(*r));
  }

  static constexpr std::size_t kShmMaxBatch = 256;

  SegmentSourceOptions options;
  supervisor::ComponentAggregator& aggregator;
  bus::ShmExpectation expectation;
  std::uint32_t uid = 0;
  std::int32_t self_pid = 0;

  // Cycle state, guarded by `mutex` (held for a whole cycle, and by readers for a copy).
  mutable std::mutex mutex;
  std::map<std::string, std::unique_ptr<Segment>> segments;  // by segment name
  std::map<std::pair<std::int32_t, std::uint64_t>, std::unique_ptr<Process>> processes;
  std::map<std::string, std::string> rejected;  // segment name -> why (while it exists)
  std::map<std::string, Nanos> pending;         // segments being created: first seen
  static constexpr Nanos kCreationGrace = 2 * kNanosPerSecond;
  std::string segment_prefix;  // "vigil.<name>.": our segments' file names
  // step()'s scratch vectors, kept between cycles.
  std::vector<int> step_fds;
  std::vector<Process*> step_owners;
  std::vector<char> step_ready;
  std::vector<Segment*> step_segments;  // the segments in id order, while !order_stale
  bool order_stale = true;              // segments came or went since step_segments was built
  // What the drain's hints need of step_segments[k], contiguous (no load of the segment itself).
  struct DrainRef {
    const void* base;  // the mapping
    const Entry* entry;
  };
  std::vector<DrainRef> step_refs;
  static constexpr std::size_t kPrefetchRecordLines = 16;   // 7 records of 136 bytes
  std::unordered_map<std::uint32_t, Placement> placements;  // by aggregator id
  // The earliest forget_at among placements: the step walks them only once it has passed (a
  // walk of a thousand scattered nodes every cycle was about a tenth of the daemon's time).
  Nanos next_forget = std::numeric_limits<Nanos>::max();
  std::map<std::string, std::uint32_t> incarnations;  // by component name
  std::map<std::string, std::uint32_t> process_runs;  // by command line
  std::optional<platform::ShmDirectoryWatch> dir_watch;
  // The live processes' pidfds (tags 1, 2...) and the directory watch (tag 0), waited on
  // with epoll: a wait costs what is ready, not the number of processes (two ppoll calls over
  // 100 pidfds per cycle were about 9 % of the daemon's CPU). Empty where epoll is unavailable:
  // then every descriptor is polled as before.
  std::optional<platform::ReadySet> ready_set;
  std::unordered_map<std::uint64_t, Process*> in_set;  // the processes in the set, by tag
  std::uint64_t next_tag = 1;
  bool dir_in_set = false;
  std::size_t outside_set = 0;  // live processes whose death the ready set does not report
  bool scanned = false;
  bool dir_changed = false;  // the drain thread saw our segments' names change while it slept
  Nanos next_scan = 0;
  Nanos next_state_check = 0;
  Nanos next_header_check = 0;
  std::uint32_t next_id = 1;
  // Daemons that drained segments before this one and stopped without detaching (killed), by
  // pid: found in the segments' daemon fields at open, announced once after the scan.
  struct Outage {
    Nanos last_beat = 0;  // the latest heartbeat it left (monotonic, system-wide)
    std::size_t segments = 0;
    std::set<std::int32_t> processes;
    bool announced = false;
  };
  std::map<std::int32_t, Outage> outages;
  std::vector<task::Message> buffer;
  std::vector<std::uint64_t> seqs;
  // Statistics.
  std::uint64_t cycles = 0;
  std::uint64_t messages = 0;
  std::uint64_t rejected_total = 0;
  std::uint64_t corrupted_total = 0;
  std::uint64_t header_checks = 0;
  std::uint64_t adopted_total = 0;
  std::uint64_t reclaimed = 0;
  supervisor::RunningStats cycle_time;

  // The drain thread.
  std::mutex thread_mutex;
  platform::Thread thread;
  std::atomic<bool> quit{false};
  std::atomic<bool> running{false};

  [[nodiscard]] Nanos now() const { return aggregator.options().clock.now(); }

  // An event of the aggregator's hub, as the supervisor's own. No fault time: a process's death
  // or a segment's arrival has no earlier stamp the source could trust (0: unknown).
  void event(EventKind k, std::int32_t pid, std::string component, std::string message) {
    Event e;
    e.kind = k;
    e.severity = k == EventKind::ProcessExited || k == EventKind::SegmentCorrupted
                     ? EventSeverity::Error
                 : k == EventKind::SegmentRejected || k == EventKind::ProcessStopped ||
                         k == EventKind::SupervisorRestarted
                     ? EventSeverity::Warn
                     : EventSeverity::Info;
    e.component = component.empty() ? fmt::format("pid {}", pid) : std::move(component);
    e.pid = pid;
    e.detected_ns = now();
    e.detail = std::move(message);
    (void)aggregator.events().publish(std::move(e));
  }

  // --- messages into the aggregator -------------------------------------------------------------

  void visit(Segment& s, const task::Message* msgs, std::size_t n, std::size_t occupancy,
             std::uint64_t dropped) {
    Entry& e = *s.entry;
    aggregator.begin(e);
    // As the in-process supervisor: the whole batch at once (cycle samples without a variant
    // dispatch, packed into the flight ring, the statistics taken in bulk later).
    aggregator.on_batch(e, msgs, n);
    supervisor::PortDrain d;
    d.messages = n;
    d.occupancy = occupancy;
    d.capacity = s.reader.info().geometry.capacity;
    d.dropped = dropped;
    aggregator.end(e, d);
    messages += n;
  }

  // Drains up to the ring's capacity (everything when `all`), then marks the segment drained at
  // `beat` (monotonic ns). False when the segment turned out corrupt (it is then rejected by the
  // caller).
  bool drain(Segment& s, bool all, Nanos beat) {
    auto live = s.reader.live();
    if (!live) return false;
    s.last_live = *live;
    const std::size_t occupancy =
        static_cast<std::size_t>(live->write_index - s.reader.read_index());
    std::size_t budget = all ? occupancy : s.reader.info().geometry.capacity;
    std::size_t total = 0;
    bool first = true;
    while (budget > 0 || first) {
      first = false;
      const std::size_t want = std::min(budget, buffer.size());
      if (want == 0) break;
      auto n = s.reader.pop(buffer.data(), seqs.data(), want, &task::check_shm_message);
      if (!n) return false;
      if (*n == 0) break;
      visit(s, buffer.data(), *n, occupancy, live->dropped);
      total += *n;
      budget -= *n;
    }
    if (total == 0) {
      visit(s, buffer.data(), 0, occupancy, live->dropped);
    } else {
      s.progress_cycle = cycles;
    }
    // Emptied, but newer messages were offered than received: they were dropped (or are kept
    // for a retry) and wait in the mailboxes.
    if (s.reader.read_index() == live->write_index && live->offered > s.reader.last_seq()) {
      std::vector<task::Message> late;
      auto m = s.reader.settle(late, &task::check_shm_message);
      if (!m) return false;
      if (!late.empty()) visit(s, late.data(), late.size(), 0, live->dropped);
    }
    // A bad record after good ones: those were counted, the segment is corrupt.
    if (s.reader.error()) return false;
    s.reader.heartbeat(beat, self_pid);
    return true;
  }

  // A segment seen for the first time: what its mailboxes hold that the ring no longer does
  // (identity, state, exception, dropped samples), in order, then the ring.
  bool attach(Segment& s) {
    auto live = s.reader.live();
    if (!live) return false;
    s.last_live = *live;
    const std::size_t occupancy =
        static_cast<std::size_t>(live->write_index - s.reader.read_index());
    const std::size_t n0 = std::min(occupancy, buffer.size());
    auto n = s.reader.pop(buffer.data(), seqs.data(), n0, &task::check_shm_message);
    if (!n) return false;
    if (s.reader.error()) {  // good records, then a bad one: keep what was good
      visit(s, buffer.data(), *n, occupancy, live->dropped);
      return false;
    }
    const std::uint64_t first_seq = *n > 0 ? seqs[0] : ~std::uint64_t{0};
    std::vector<task::Message> early;
    auto m = s.reader.mailboxes(early, 0, first_seq, &task::check_shm_message);
    if (!m) return false;
    visit(s, early.data(), early.size(), occupancy, live->dropped);
    visit(s, buffer.data(), *n, occupancy, live->dropped);
    return drain(s, false, platform::now_ns());
  }

  // The end of a segment (closed, or its process died): drain all, then what was dropped after
  // the last record.
  bool finish(Segment& s) {
    if (!drain(s, true, platform::now_ns())) return false;
    std::vector<task::Message> late;
    auto m =
        s.reader.mailboxes(late, s.reader.last_seq(), ~std::uint64_t{0}, &task::check_shm_message);
    if (!m) return false;
    if (!late.empty()) visit(s, late.data(), late.size(), 0, s.last_live.dropped);
    return true;
  }

  // --- discovery
  // -----------------------------------------------------------------------------------

  void scan() {
    const std::vector<std::string> names = platform::list_shared_memory(segment_prefix);
    // Forget rejections of files that are gone.
    for (auto it = rejected.begin(); it != rejected.end();) {
      it = std::binary_search(names.begin(), names.end(), it->first) ? std::next(it)
                                                                     : rejected.erase(it);
    }
    for (const std::string& name : names) {
      if (segments.count(name) != 0 || rejected.count(name) != 0) continue;
      open_segment(name);
    }
  }

  void reject(const std::string& name, std::int32_t pid, const bus::ShmError& e) {
    const std::string why = e.to_string();
    rejected[name] = why;
    ++rejected_total;
    event(EventKind::SegmentRejected, pid, name, fmt::format("segment {} rejected: {}", name, why));
  }

  void open_segment(const std::string& name) {
    auto r = bus::ShmReader<task::Message>::open(name, expectation, uid, !options.group.empty());
    const std::int32_t name_pid = pid_of_segment(name).value_or(0);
    if (!r) {
      const bus::ShmError& e = r.error();
      // Created but not sized or initialised yet (shm_open, then ftruncate, then the header):
      // retried for a while as long as its process runs.
      const bool young =
          e.field == "state" ||
          (e.field == "file" && (e.message.find("empty") != std::string::npos ||
                                 e.message.find("shorter than the header") != std::string::npos));
      if (young) {
        const Nanos t = now();
        auto [it, inserted] = pending.try_emplace(name, t);
        if (t - it->second < kCreationGrace) {
          if (!platform::process_start_ticks(name_pid)) {
            // Its process is gone: it never will be complete.
            if (options.reclaim) (void)platform::unlink_shared_memory(name);
            pending.erase(it);
          }
          return;
        }
        pending.erase(it);
        reject(name, name_pid, e);
        return;
      }
      if (e.field == "file" && e.message.find("No such file") != std::string::npos) return;
      reject(name, name_pid, e);
      return;
    }
    pending.erase(name);
    auto seg = std::make_unique<Segment>(
        Segment{name, std::move(*r), nullptr, nullptr, 1, {}, kNoProgress});
    const bus::ShmSegmentInfo& info = seg->reader.info();
    note_previous_daemon(seg->reader.header_at_open(), info.pid);
    Process& p = process_for(info);
    seg->process = &p;
    seg->entry = std::make_shared<Entry>();
    seg->entry->id = next_id++;
    seg->entry->name = info.component_name;
    seg->entry->port = std::make_shared<RemotePort>(info.geometry.capacity);
    // A name seen before is a new incarnation; it replaces the reports of a dead one.
    auto [it, first] = incarnations.try_emplace(info.component_name, 1);
    if (!first) ++it->second;
    seg->incarnation = it->second;
    // (In a live process, only corrupted components have such reports.)
    for (auto& [key, other] : processes) {
      std::erase_if(other->dead_reports,
                    [&](const Report& rep) { return rep.name == info.component_name; });
    }
    aggregator.on_join(*seg->entry);
    placements[seg->entry->id] = Placement{p.info.pid,
                                           p.info.name,
                                           p.info.command_line,
                                           p.info.started_unix_ns,
                                           seg->incarnation,
                                           false,
                                           0};
    if (std::find(p.info.components.begin(), p.info.components.end(), info.component_name) ==
        p.info.components.end()) {
      p.info.components.push_back(info.component_name);
    }
    Segment& s = *seg;
    p.segments.push_back(seg.get());
    segments.emplace(name, std::move(seg));
    order_stale = true;
    event(EventKind::Joined, p.info.pid, info.component_name,
          fmt::format("component {} of process {} ({}) joined{}", info.component_name, p.info.pid,
                      p.info.name,
                      s.incarnation > 1 ? fmt::format(", incarnation {}", s.incarnation) : ""));
    if (!attach(s)) {
      corrupt(s);
      return;
    }
    // A process found dead at discovery (it ended before the daemon watched it).
    if (!p.info.alive) end_segment_of_dead(s);
  }

  // A segment drained by another daemon that did not detach (a daemon detaches when it stops):
  // if that daemon is gone, it was killed, and this one takes over from it.
  void note_previous_daemon(const bus::ShmSegmentHeader& h, std::int32_t writer) {
    const std::int32_t prev = h.daemon_pid;
    if (h.daemon_heartbeat_ns == 0 || prev <= 0 || prev == self_pid) return;
    if (platform::process_start_ticks(prev)) return;  // still there: not an outage of ours
    Outage& o = outages[prev];
    o.last_beat = std::max(o.last_beat, h.daemon_heartbeat_ns);
    ++o.segments;
    o.processes.insert(writer);
    ++adopted_total;
  }

  // One event per daemon this one took over from, once the scan found its segments.
  void announce_outages() {
    for (auto& [pid, o] : outages) {
      if (o.announced) continue;
      o.announced = true;
      const Nanos mono = platform::now_ns();
      const std::int64_t wall = platform::unix_now_ns();
      const Nanos down = mono > o.last_beat ? mono - o.last_beat : 0;
      Event e;
      e.kind = EventKind::SupervisorRestarted;
      e.severity = EventSeverity::Warn;
      e.component = options.report_name;
      e.pid = pid;
      e.detected_ns = now();
      e.fault_ns = e.detected_ns > down ? e.detected_ns - down : 0;
      e.detail = fmt::format(
          "the daemon was down from {} to {} ({}): daemon {} stopped draining without detaching "
          "(killed), daemon {} took over its {} segment{} of {} process{}; totals continue from "
          "the segments, messages the full rings dropped meanwhile are counted as dropped",
          platform::format_unix_time(wall - down), platform::format_unix_time(wall),
          format_nanos(static_cast<double>(down)), pid, self_pid, o.segments,
          o.segments == 1 ? "" : "s", o.processes.size(), o.processes.size() == 1 ? "" : "es");
      (void)aggregator.events().publish(std::move(e));
    }
  }

  Process& process_for(const bus::ShmSegmentInfo& info) {
    const auto key = std::make_pair(info.pid, info.start_ticks);
    auto it = processes.find(key);
    if (it != processes.end()) return *it->second;
    auto p = std::make_unique<Process>();
    p->info.pid = info.pid;
    p->info.start_ticks = info.start_ticks;
    p->info.name = info.process_name;
    p->info.command_line = info.command_line;
    p->info.started_unix_ns = platform::start_time_unix_ns(info.start_ticks);
    p->info.incarnation = ++process_runs[info.command_line];
    // Older dead runs of the same command are replaced by this one.
    std::erase_if(processes, [&](const auto& kv) {
      return !kv.second->info.alive && kv.second->info.command_line == info.command_line &&
             kv.second->segments.empty();
    });
    auto w = platform::ProcessWatch::open({info.pid, info.start_ticks});
    if (w) {
      p->watch = std::move(*w);
      p->watched = true;
      if (ready_set && p->watch.fd() >= 0 && ready_set->add(p->watch.fd(), next_tag)) {
        p->set_tag = next_tag++;
        in_set.emplace(p->set_tag, p.get());
      } else {
        ++outside_set;
      }
    } else {
      p->info.alive = false;
      p->info.ended_at = now();
      p->info.exit_source = "unknown";
    }
    return *processes.emplace(key, std::move(p)).first->second;
  }

  // --- ends ------------------------------------------------------------------------------------

  void unlink(Segment& s) {
    if (!options.reclaim) return;
    if (platform::unlink_shared_memory(s.name)) ++reclaimed;
  }

  void forget(Segment& s, bool dead) {
    aggregator.on_leave(*s.entry);
    if (auto it = placements.find(s.entry->id); it != placements.end()) {
      it->second.dead = dead;
      it->second.forget_at = now() + aggregator.options().retain_left_ns;
      next_forget = std::min(next_forget, it->second.forget_at);
    }
    if (s.process != nullptr) std::erase(s.process->segments, &s);
    segments.erase(s.name);  // destroys s (unmaps)
    order_stale = true;
  }

  // A segment found corrupt while being read: never read again. Its component becomes an ERROR
  // report that keeps its counters up to the last good record (until its process ends, or a
  // component of that name joins again), and an event names the field.
  void corrupt(Segment& s) {
    const bus::ShmError e = s.reader.error().value_or(bus::ShmError{"segment", "unreadable"});
    if (!s.reader.error()) s.reader.set_corrupt(e);
    const std::int32_t pid = s.process != nullptr ? s.process->info.pid : 0;
    rejected[s.name] = e.to_string();
    ++rejected_total;
    ++corrupted_total;
    const std::string component = s.entry->name;
    event(EventKind::SegmentCorrupted, pid, component,
          fmt::format("segment {} of component {} (process {}) corrupted: {}; no longer read, "
                      "its counters are kept up to its last good record",
                      s.name, component, pid, e.to_string()));
    if (s.process != nullptr) {
      Report r = dead_report(s, corruption_message(e));
      r.state_label = "segment corrupted";
      s.process->dead_reports.push_back(std::move(r));
      s.process->corrupt_segments.push_back(s.name);
    }
    forget(s, true);
  }

  static std::string corruption_message(const bus::ShmError& e) {
    return fmt::format("segment corrupted: {} ({})", e.field, e.message);
  }

  std::string death_message(const Process& p) const {
    const ProcessInfo& i = p.info;
    if (i.exit_source == "unknown") {
      return fmt::format("process {} ({}) exited: {}", i.pid, i.name, i.exit);
    }
    return fmt::format("process {} ({}) {}", i.pid, i.name,
                       i.exit.rfind("exited", 0) == 0 ? i.exit : "exited: " + i.exit);
  }

  // Learns how `p` ended: the kernel (pidfd), the process's own record, the zombie, or nothing.
  void settle_exit(Process& p) {
    const char* source = nullptr;
    if (p.watched) {
      if (auto st = p.watch.exit_status(&source)) {
        p.info.exit = st->describe();
        p.info.exit_source = source != nullptr ? source : "pidfd";
        return;
      }
    }
    for (const Segment* s : p.segments) {
      if (auto live = s->reader.peek()) {
        if (live->exit_kind == bus::ShmExit::Exited) {
          p.info.exit =
              platform::ExitStatus{platform::ExitStatus::Kind::Exited, live->exit_code, false}
                  .describe();
          p.info.exit_source = "self";
          return;
        }
        if (live->exit_kind == bus::ShmExit::Signaled) {
          p.info.exit =
              platform::ExitStatus{platform::ExitStatus::Kind::Signaled, live->exit_code, false}
                  .describe();
          p.info.exit_source = "self";
          return;
        }
      }
    }
    p.info.exit =
        p.watched ? "vanished without recording an exit: killed by SIGKILL or by the kernel (e.g. "
                    "the OOM killer), or _exit(); this kernel does not tell a non-parent which "
                    "(Linux >= 6.15 does)"
                  : "ended before this daemon watched it, without recording how";
    p.info.exit_source = "unknown";
  }

  Report dead_report(const Segment& s, const std::string& message) {
    Report r;
    // This component's record only: a snapshot of all of them per dead segment made a death of
    // many processes quadratic in the components (seconds of the drain thread at 1,000).
    if (const auto snap = aggregator.find_id(s.entry->id)) fill_report(r, *snap);
    r.kind = ReportKind::Component;
    r.id = s.entry->id;
    r.name = s.entry->name;
    r.alive = false;
    r.state_label = "process ended";
    r.merge(StatusLevel::Error, message);
    add_placement(r, placements[s.entry->id]);
    return r;
  }

  void process_died(Process& p) {
    if (!p.info.alive) return;
    leave_set(p);
    p.info.alive = false;
    p.info.ended_at = now();
    // Last drain first (every record it pushed, then what it dropped), then the verdict.
    std::vector<Segment*> segs = p.segments;
    for (Segment* s : segs) {
      if (!finish(*s)) corrupt(*s);
    }
    settle_exit(p);
    end_all(p);
    reclaim_corrupt(p);
  }

  // `p` ended: its pidfd stays readable, so it leaves the ready set (or the count of the others).
  void leave_set(Process& p) {
    if (p.set_tag != 0) {
      ready_set->remove(p.watch.fd());
      in_set.erase(p.set_tag);
      p.set_tag = 0;
    } else if (p.info.alive && outside_set > 0) {
      --outside_set;
    }
  }

  // The files of a dead process's corrupted segments: nobody writes them any more.
  void reclaim_corrupt(Process& p) {
    for (const std::string& name : p.corrupt_segments) {
      if (options.reclaim && platform::unlink_shared_memory(name)) {
        ++reclaimed;
        rejected.erase(name);
      }
    }
    p.corrupt_segments.clear();
  }

  void end_segment_of_dead(Segment& s) {
    Process& p = *s.process;
    if (!finish(s)) {
      corrupt(s);
      return;
    }
    const bool first = p.info.exit.empty();
    if (first) settle_exit(p);
    const std::string msg = death_message(p);
    if (first) event(EventKind::ProcessExited, p.info.pid, "", msg);
    p.dead_reports.push_back(dead_report(s, msg));
    unlink(s);
    forget(s, true);
  }

  void end_all(Process& p) {
    const std::string msg = death_message(p);
    std::vector<Segment*> segs = p.segments;
    for (Segment* s : segs) p.dead_reports.push_back(dead_report(*s, msg));
    event(EventKind::ProcessExited, p.info.pid, "", msg);
    for (Segment* s : segs) {
      unlink(*s);
      forget(*s, true);
    }
  }

  // --- the cycle -------------------------------------------------------------------------------

  std::size_t step() {
    const Nanos t0 = now();
    const std::uint64_t m0 = messages;
    detect_deaths();
    check_run_states(t0);
    discover(t0);
    announce_outages();
    verify_headers(t0, false);
    drain_all();
    forget_placements(t0);
    const Nanos t1 = now();
    supervisor::DrainCycle c{cycles + 1,      t0, t1 - t0, static_cast<std::size_t>(messages - m0),
                             segments.size(), 0};
    aggregator.on_cycle(c);
    ++cycles;
    cycle_time.add(t1 - t0);
    return static_cast<std::size_t>(messages - m0);
  }

  // (1) Deaths: the ready set's pidfds that are readable (one epoll_wait that returns what is
  // ready), one poll over the pidfds outside it, /proc for processes without one.
  void detect_deaths() {
    if (ready_set) {
      std::uint64_t tags[64];
      for (;;) {
        const int n = ready_set->wait(0, tags, std::size(tags));
        bool died = false;
        for (int i = 0; i < n; ++i) {
          const auto it = tags[i] == 0 ? in_set.end() : in_set.find(tags[i]);
          if (it == in_set.end()) continue;  // the directory (discover() reads it), or gone
          Process& p = *it->second;
          if (p.info.alive) {
            process_died(p);
          } else {
            leave_set(p);
          }
          died = true;
        }
        if (!died || n < static_cast<int>(std::size(tags))) break;
      }
      if (outside_set == 0) return;
    }
    std::vector<int>& fds = step_fds;
    std::vector<Process*>& owners = step_owners;
    fds.clear();
    owners.clear();
    for (auto& [key, p] : processes) {
      if (!p->info.alive || p->set_tag != 0) continue;
      if (p->watch.fd() >= 0) {
        fds.push_back(p->watch.fd());
        owners.push_back(p.get());
      } else if (p->watch.exited()) {
        process_died(*p);
      }
    }
    if (!fds.empty()) {
      std::vector<char>& ready = step_ready;
      ready.assign(fds.size(), 0);
      auto* flags = reinterpret_cast<bool*>(ready.data());
      if (platform::wait_readable(fds.data(), fds.size(), 0, flags) > 0) {
        for (std::size_t i = 0; i < fds.size(); ++i) {
          if (flags[i]) process_died(*owners[i]);
        }
      }
    }
  }

  // (2b) What the writers set once: every `header_check_ns`, or now when `force` (a report).
  // Returns the segments found corrupt (marked; `corrupt()` handles them at the drain).
  std::size_t verify_headers(Nanos t0, bool force) {
    if (!force && t0 < next_header_check) return 0;
    if (!force) next_header_check = t0 + options.header_check_ns;
    std::size_t bad = 0;
    for (auto& [name, s] : segments) {
      if (s->reader.error()) continue;
      ++header_checks;
      if (!s->reader.verify()) ++bad;
    }
    return bad;
  }

  // (1b) Stops and continues: each live process's state in /proc, every `state_check_ns`.
  void check_run_states(Nanos t0) {
    if (options.state_check_ns <= 0 || t0 < next_state_check) return;
    next_state_check = t0 + options.state_check_ns;
    for (auto& [key, p] : processes) {
      if (!p->info.alive) continue;
      // Records arrived from it at the previous drain (one period ago): it was running then, as
      // it was at the last check. A stopped process pushes nothing, so it is read from /proc at
      // the next check: a stop is found within state_check_ns + two periods, and a process that
      // is not running (or sends nothing) is read every time. Reading /proc/<pid>/stat for 100
      // processes every 100 ms was about 6 % of the daemon's CPU.
      if (p->info.run_state == platform::RunState::Running &&
          std::any_of(p->segments.begin(), p->segments.end(),
                      [&](const Segment* sg) { return sg->progress_cycle + 1 == cycles; })) {
        continue;
      }
      const platform::RunState now_state =
          platform::process_run_state({p->info.pid, p->info.start_ticks});
      // A zombie or a gone process is a death: detect_deaths reports it, with how it ended.
      if (now_state == platform::RunState::Zombie || now_state == platform::RunState::Gone) {
        continue;
      }
      const platform::RunState was = p->info.run_state;
      if (now_state == was) continue;
      const Nanos since = p->info.run_state_since;
      p->info.run_state = now_state;
      p->info.run_state_since = t0;
      if (now_state == platform::RunState::Running) {
        event(EventKind::ProcessContinued, p->info.pid, p->info.name,
              fmt::format("{} runs again after {} {}", p->info.name,
                          format_nanos(static_cast<double>(t0 - since)), platform::to_string(was)));
      } else {
        event(EventKind::ProcessStopped, p->info.pid, p->info.name,
              fmt::format("{} {} ({})", p->info.name, platform::to_string(now_state),
                          now_state == platform::RunState::Traced
                              ? "stopped by a tracer"
                              : "stopped by a signal: SIGSTOP, SIGTSTP, SIGTTIN or SIGTTOU"));
      }
    }
  }

  // (2) New segments: when the directory changed, at every rescan, and the pending ones.
  void discover(Nanos t0) {
    if (!dir_watch && options.watch_directory) {
      if (auto w = platform::ShmDirectoryWatch::open()) {
        dir_watch.emplace(std::move(*w));
        dir_in_set = ready_set && ready_set->add(dir_watch->fd(), 0).has_value();
      }
    }
    // Only our segments' names count: other programs' files in /dev/shm (other daemons', test
    // runs', tracers') must not make us list the directory every cycle.
    const bool changed =
        std::exchange(dir_changed, false) || (dir_watch && dir_watch->consume(segment_prefix));
    if (!scanned || changed || t0 >= next_scan) {
      scan();
      scanned = true;
      next_scan = t0 + options.rescan_ns;
    } else if (!pending.empty()) {
      std::vector<std::string> retry;
      retry.reserve(pending.size());
      for (const auto& [name, since] : pending) retry.push_back(name);
      for (const auto& name : retry) open_segment(name);
    }
  }

  // (3) Drain; (4) segments whose component left.
  void drain_all() {
    // In the aggregator's id order (the order segments were opened), so that its record lookups hit
    // their hint and bring in the next records ahead, as for the in-process supervisor; the list is
    // rebuilt only when segments come or go.
    std::vector<Segment*>& all = step_segments;  // reused: no allocation per cycle
    if (order_stale) {
      all.clear();
      for (auto& [name, s] : segments) all.push_back(s.get());
      std::sort(all.begin(), all.end(),
                [](const Segment* a, const Segment* b) { return a->entry->id < b->entry->id; });
      step_refs.clear();
      for (Segment* s : all) step_refs.push_back({s->reader.memory().data(), s->entry.get()});
      order_stale = false;
    }
    Nanos beat = 0;
    const std::size_t n = all.size();
    for (std::size_t k = 0; k < n; ++k) {
      // Staged hints, as DrainLoop::prefetch_ahead: the segment's reader four ahead, its
      // header's state lines and its entry three ahead, its waiting records one ahead (the
      // segments are other processes' memory, written since the last drain: every line is a
      // miss otherwise).
      if (k + 4 < n) all[k + 4]->reader.prefetch_self();
      if (k + 3 < n) {
        bus::ShmRingReader::prefetch_state(step_refs[k + 3].base);
        __builtin_prefetch(step_refs[k + 3].entry);
      }
      if (k + 1 < n) all[k + 1]->reader.prefetch_records(kPrefetchRecordLines);
      // The heartbeat's clock, read once per 16 segments (within microseconds of each drain).
      if (k % 16 == 0) beat = platform::now_ns();
      Segment* s = all[k];
      if (!s->process->info.alive) continue;
      if (!drain(*s, false, beat)) {
        corrupt(*s);
        continue;
      }
      if (s->last_live.state == bus::ShmState::Closed &&
          s->reader.read_index() == s->last_live.write_index) {
        if (!finish(*s)) {
          corrupt(*s);
          continue;
        }
        const std::int32_t pid = s->process->info.pid;
        const std::string component = s->entry->name;
        unlink(*s);
        forget(*s, false);
        event(EventKind::Left, pid, component,
              fmt::format("component {} of process {} left", component, pid));
      }
    }
  }

  // Placements of components the aggregator has forgotten.
  void forget_placements(Nanos t0) {
    if (t0 > next_forget) {
      std::erase_if(placements, [&](const auto& kv) {
        return kv.second.forget_at != 0 && t0 > kv.second.forget_at;
      });
      next_forget = std::numeric_limits<Nanos>::max();
      for (const auto& [id, pl] : placements) {
        if (pl.forget_at != 0) next_forget = std::min(next_forget, pl.forget_at);
      }
    }
  }

  // --- reports -------------------------------------------------------------------------------

  // A component of a stopped process: the stop is its cause (its silence, its deadline events).
  void name_a_stop(Report& r, std::int32_t pid, Nanos t) const {
    for (const auto& [key, p] : processes) {
      if (p->info.pid != pid || !p->info.alive) continue;
      if (p->info.run_state == platform::RunState::Stopped ||
          p->info.run_state == platform::RunState::Traced) {
        r.merge(StatusLevel::Warn,
                fmt::format(
                    "its process {} (pid {}) is {}{}", p->info.name, pid,
                    platform::to_string(p->info.run_state),
                    p->info.run_state_since > 0 && t > p->info.run_state_since
                        ? " for " + format_nanos(static_cast<double>(t - p->info.run_state_since))
                        : std::string()));
      }
      return;
    }
  }

  // A process of the daemon as a unit of the diagnosis graph (kind `process`): ERROR while it is
  // stopped, traced or a zombie, its components depending on it.
  static Report process_unit(const ProcessInfo& info, Nanos t) {
    Report r;
    r.kind = ReportKind::Unit;
    r.unit_kind = "process";
    r.name = process_unit_name(info.name, info.pid);
    r.configured = true;
    r.state_label = platform::to_string(info.run_state);
    if (info.run_state != platform::RunState::Running) {
      r.merge(
          StatusLevel::Error,
          fmt::format("{}{}: its components cannot run", platform::to_string(info.run_state),
                      info.run_state_since > 0 && t > info.run_state_since
                          ? " for " + format_nanos(static_cast<double>(t - info.run_state_since))
                          : std::string()));
    }
    r.add_field(monitor::Field::of_count("pid", static_cast<std::uint64_t>(info.pid)));
    r.add_field(monitor::Field::of_count("components", info.components.size()));
    r.add_field(monitor::Field::of_count("incarnation", info.incarnation));
    r.add_field(monitor::Field::of_text("command", info.command_line));
    return r;
  }

  static void add_placement(Report& r, const Placement& pl) {
    r.add("process", pl.process);
    r.add("pid", std::to_string(pl.pid));
    r.add("process_started", platform::format_unix_time(pl.started_unix_ns));
    r.add("command", pl.command_line);
    r.add("incarnation", std::to_string(pl.incarnation));
  }

  Report self_report(Nanos t) const {
    Report r;
    r.kind = ReportKind::Supervisor;
    r.name = options.report_name;
    r.configured = true;
    r.activity = options.thread_name;
    r.period_ns = options.period_ns;
    r.state = running.load(std::memory_order_relaxed) ? TaskState::Running : TaskState::Stopped;
    r.counters.cycles = cycles;
    r.samples = cycles;
    r.total_ns = cycle_time.summary();
    r.window.first = false;
    std::size_t alive = 0;
    std::size_t dead = 0;
    for (const auto& [key, p] : processes) (p->info.alive ? alive : dead) += 1;
    r.add("supervisor_name", options.name);
    r.add("processes", std::to_string(alive));
    r.add("dead_processes", std::to_string(dead));
    r.add("segments", std::to_string(segments.size()));
    r.add("messages", std::to_string(messages));
    r.add("rejected", std::to_string(rejected_total));
    r.add("corrupted", std::to_string(corrupted_total));
    r.add("adopted", std::to_string(adopted_total));
    r.add("reclaimed", std::to_string(reclaimed));
    for (const auto& [name, why] : rejected) {
      r.merge(StatusLevel::Warn, fmt::format("segment {} rejected: {}", name, why));
    }
    if (r.total_ns.count > 0 && r.total_ns.ewma > 0.9 * static_cast<double>(options.period_ns)) {
      r.merge(StatusLevel::Warn, fmt::format("busy: EWMA of cycle time {} near its {} period",
                                             format_nanos(r.total_ns.ewma),
                                             format_nanos(static_cast<double>(options.period_ns))));
    }
    (void)t;
    return r;
  }

  void contribute(ReportSet& set) {
    ReportSet out;
    out.cycle = set.cycle;
    out.time_ns = set.time_ns;
    const ReportSet& base = set;
    std::lock_guard lock(mutex);
    // Every report verifies the headers: a segment found corrupt now is an ERROR in this very
    // report (its event and its final report come with the next drain).
    std::unordered_map<std::uint32_t, std::string> corrupt_now;
    if (verify_headers(0, true) > 0) {
      for (const auto& [name, sg] : segments) {
        if (sg->reader.error()) {
          corrupt_now.emplace(sg->entry->id, corruption_message(*sg->reader.error()));
        }
      }
    }
    for (const Report& r : base.components) {
      if (r.kind != ReportKind::Component) continue;
      const auto it = placements.find(r.id);
      if (it != placements.end() && it->second.dead) continue;  // its dead report replaces it
      Report c = r;
      if (it != placements.end()) {
        add_placement(c, it->second);
        name_a_stop(c, it->second.pid, base.time_ns);
        // The diagnosis graph: a component needs its process (a stopped process explains its
        // components' silence).
        c.depends_on.push_back(process_unit_name(it->second.process, it->second.pid));
      }
      if (const auto bad = corrupt_now.find(r.id); bad != corrupt_now.end()) {
        c.alive = false;
        c.state_label = "segment corrupted";
        c.merge(StatusLevel::Error, bad->second);
      }
      out.components.push_back(std::move(c));
    }
    for (const auto& [key, p] : processes) {
      for (const Report& r : p->dead_reports) out.components.push_back(r);
    }
    for (const auto& [key, p] : processes) {
      if (p->info.alive) out.components.push_back(process_unit(p->info, base.time_ns));
    }
    out.components.push_back(self_report(base.time_ns));
    for (const Report& r : base.components) {
      if (r.kind != ReportKind::Component) out.components.push_back(r);
    }
    set = std::move(out);
  }

  // The daemon goes away: its processes must not count on it to remove their segments.
  void detach() {
    for (auto& [name, s] : segments) s->reader.heartbeat(0, 0);
  }

  void run() {
    Nanos next = platform::now_ns();
    std::vector<int> fds;
    std::vector<char> ready;
    while (!quit.load(std::memory_order_acquire)) {
      {
        std::lock_guard lock(mutex);
        step();
      }
      const Nanos t = platform::now_ns();
      // A regular cycle schedules the next one; an early one (a death, a new segment) leaves the
      // regular cycle where it was. (Advancing `next` on every wake-up had let a busy /dev/shm
      // push the deadline seconds ahead: thousands of early cycles per second while another
      // program churned files there, then none at all once it stopped.)
      if (t >= next) {
        next += options.period_ns;
        if (next < t) next = t;
      }
      // Health supervision's deadlines (a deadline's max, an alive reference cycle's end) are
      // judged when they pass, not at the next period (include/vigil/health/engine.hpp).
      sleep_until_next(std::min(next, aggregator.next_deadline()), fds, ready);
    }
  }

  // Sleeps until `next`, waking early only for a death (a pidfd) or a change among our own
  // segments' names: other programs' files in /dev/shm do not wake a cycle.
  void sleep_until_next(Nanos next, std::vector<int>& fds, std::vector<char>& ready) {
    bool use_set = false;
    {
      std::lock_guard lock(mutex);
      use_set = ready_set && outside_set == 0 && (dir_in_set || !dir_watch);
    }
    while (use_set && !quit.load(std::memory_order_acquire)) {
      std::uint64_t tags[64];
      const int n = ready_set->wait(next, tags, std::size(tags));
      if (n < 0) break;  // the poll below instead
      if (platform::now_ns() >= next) return;
      bool wake = false;
      for (int i = 0; i < n; ++i) {
        if (tags[i] != 0) {
          wake = true;  // a death
          continue;
        }
        std::lock_guard lock(mutex);
        if (dir_watch && dir_watch->consume(segment_prefix)) {
          dir_changed = true;
          wake = true;
        }
      }
      if (wake) return;
    }
    while (!quit.load(std::memory_order_acquire)) {
      fds.clear();
      bool has_dir = false;
      {
        std::lock_guard lock(mutex);
        if (dir_watch) {
          fds.push_back(dir_watch->fd());
          has_dir = true;
        }
        for (const auto& [key, p] : processes) {
          if (p->info.alive && p->watch.fd() >= 0) fds.push_back(p->watch.fd());
        }
      }
      ready.assign(fds.size(), 0);
      (void)platform::wait_readable(fds.data(), fds.size(), next,
                                    reinterpret_cast<bool*>(ready.data()));
      if (platform::now_ns() >= next) return;
      bool wake = false;
      std::size_t i = 0;
      if (has_dir) {
        if (ready[0] != 0) {
          std::lock_guard lock(mutex);
          if (dir_watch && dir_watch->consume(segment_prefix)) {
            dir_changed = true;
            wake = true;
          }
        }
        i = 1;
      }
      for (; i < fds.size(); ++i) wake = wake || ready[i] != 0;
      if (wake) return;
    }
  }
};

expected<void, Error> validate(const SegmentSourceOptions& options) {
  if (!bus::valid_supervisor_name(options.name)) {
    return unexpected<Error>(Error(EINVAL, fmt::format("supervisor name '{}' is not 1 to 31 of "
                                                       "A-Z a-z 0-9 _ -",
                                                       options.name)));
  }
  if (!options.group.empty() && !platform::group_id(options.group)) {
    return unexpected<Error>(
        Error(EINVAL, fmt::format("group '{}' does not exist", options.group)));
  }
  if (options.period_ns <= 0) return unexpected<Error>(Error(EINVAL, "period must be positive"));
  if (options.header_check_ns < 0) {
    return unexpected<Error>(Error(EINVAL, "header_check_ns must not be negative"));
  }
  return {};
}

SegmentSource::SegmentSource(SegmentSourceOptions options,
                             supervisor::ComponentAggregator& aggregator)
    : impl_(std::make_unique<Impl>(std::move(options), aggregator)) {}

SegmentSource::~SegmentSource() {
  // The last drain may allocate: out of memory there must not terminate the process.
  try {
    stop();
    detach();
  } catch (...) {  // NOLINT(bugprone-empty-catch): nothing left to report it to
  }
}

std::size_t SegmentSource::step() {
  std::lock_guard lock(impl_->mutex);
  return impl_->step();
}

expected<void, Error> SegmentSource::start() {
  Impl& m = *impl_;
  if (auto ok = validate(m.options); !ok) return ok;
  std::lock_guard lock(m.thread_mutex);
  if (m.thread.joinable()) return {};
  m.quit.store(false, std::memory_order_relaxed);
  m.running.store(true, std::memory_order_relaxed);
  auto t = platform::Thread::spawn({.name = m.options.thread_name}, [&m] { m.run(); });
  if (!t) {
    m.running.store(false, std::memory_order_relaxed);
    return unexpected<Error>(t.error());
  }
  m.thread = std::move(*t);
  return {};
}

void SegmentSource::stop() {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.thread_mutex);
    if (!m.thread.joinable()) return;
    m.quit.store(true, std::memory_order_release);
    m.thread.join();
    m.thread = platform::Thread();
    m.running.store(false, std::memory_order_relaxed);
  }
  step();  // a last drain: what the processes sent before the stop is reported
}

bool SegmentSource::running() const { return impl_->running.load(std::memory_order_relaxed); }

void SegmentSource::detach() {
  std::lock_guard lock(impl_->mutex);
  impl_->detach();
}

void SegmentSource::contribute(exporter::Snapshot& snapshot) {
  impl_->contribute(snapshot.reports);
}

std::vector<ProcessInfo> SegmentSource::processes() const {
  std::lock_guard lock(impl_->mutex);
  std::vector<ProcessInfo> alive;
  std::vector<ProcessInfo> dead;
  for (const auto& [key, p] : impl_->processes) {
    (p->info.alive ? alive : dead).push_back(p->info);
  }
  alive.insert(alive.end(), dead.begin(), dead.end());
  return alive;
}

SegmentSourceStats SegmentSource::stats() const {
  std::lock_guard lock(impl_->mutex);
  SegmentSourceStats s;
  s.cycles = impl_->cycles;
  s.messages = impl_->messages;
  s.segments = impl_->segments.size();
  for (const auto& [key, p] : impl_->processes)
    (p->info.alive ? s.processes : s.dead_processes) += 1;
  s.rejected = impl_->rejected_total;
  s.corrupted = impl_->corrupted_total;
  s.header_checks = impl_->header_checks;
  s.adopted = impl_->adopted_total;
  s.reclaimed = impl_->reclaimed;
  s.cycle_ns = impl_->cycle_time.summary();
  return s;
}

const SegmentSourceOptions& SegmentSource::options() const noexcept { return impl_->options; }

std::string format_processes(const std::vector<ProcessInfo>& processes, Nanos now) {
  std::string out = fmt::format("{:<16} {:>7} {:<19} {:>3} {:<40} {}\n", "PROCESS", "PID",
                                "STARTED", "RUN", "STATE", "COMMAND");
  for (const auto& p : processes) {
    const std::string how =
        p.run_state != platform::RunState::Running && now > p.run_state_since &&
                p.run_state_since > 0
            ? fmt::format("{} {}", platform::to_string(p.run_state),
                          format_nanos(static_cast<double>(now - p.run_state_since)))
            : std::string(platform::to_string(p.run_state));
    std::string state = p.alive ? fmt::format("{}, {} component{}", how, p.components.size(),
                                              p.components.size() == 1 ? "" : "s")
                                : p.exit + (p.exit_source.empty() || p.exit_source == "unknown"
                                                ? std::string()
                                                : " [" + p.exit_source + "]");
    out += fmt::format("{:<16} {:>7} {:<19} {:>3} {:<40} {}\n", p.name, p.pid,
                       platform::format_unix_time(p.started_unix_ns), p.incarnation, state,
                       p.command_line);
  }
  return out;
}

void SegmentSource::append(std::string& out) const {
  out += '\n';
  out += format_processes(processes(), impl_->now());
}

}  // namespace vigil::service
