// Supervision across processes, end to end: child processes (fork) whose components are placed
// in shared memory, and the `vigil supervise` pipeline (a SupervisionService on a SegmentSource) in
// the test process. Processes killed with SIGKILL, exiting with a code, dying of a signal,
// restarted, started before the daemon, and a daemon restarted while they run. Timing goals are not
// asserted here (see benches/bus/shm_bench.cpp); only that what must happen happens, with generous
// time limits.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdlib>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "../bus/shm_support.hpp"
#include "children.hpp"
#include "support/segment_daemon.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/supervisor/health_supervision.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace std::chrono_literals;
using vigil::test::Child;
using vigil::test::ChildLink;
using vigil::test::Ctl;
using vigil::test::spawn;

namespace {

// Child body: `names` at 1 kHz on one periodic thread, in shared memory under `sup`; says ready
// once every component ran, then waits for "go" and does `then` (by default: runs until killed).
void run_components(const ChildLink& link, const std::string& sup,
                    const std::vector<std::string>& names, const std::function<void()>& then = {}) {
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = sup;
  if (!place_in_shared_memory(reg, o)) ::_exit(90);
  std::vector<std::unique_ptr<Ctl>> tasks;
  std::vector<std::unique_ptr<PeriodicActivity>> acts;
  for (const auto& n : names) {
    tasks.push_back(std::make_unique<Ctl>(n, reg));
    tasks.back()->configure();
    acts.push_back(std::make_unique<PeriodicActivity>(
        *tasks.back(), PeriodicConfig{.name = "ctl", .period_ns = kNanosPerMilli}));
    if (!acts.back()->start()) ::_exit(91);
  }
  for (auto& t : tasks) {
    while (t->cycles() < 20) std::this_thread::sleep_for(1ms);
  }
  link.ready();
  link.wait_go();
  if (then) then();
  for (;;) ::pause();
}

struct Daemon {
  explicit Daemon(const std::string& name, bool thread = true) : threaded(thread) {
    test::DaemonOptions o;
    o.name = name;
    o.monitor.read_thread_stats = false;
    auto d = test::Daemon::create(o);
    REQUIRE(d.has_value());
    sup = std::move(*d);
    if (thread) REQUIRE(sup->start().has_value());
  }
  // The daemon first: its thread calls the subscriber, which uses the members below.
  ~Daemon() { sup.reset(); }
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;
  // Waits until an event of kind `k` (about `pid` if not 0) arrived; returns it.
  std::optional<Event> wait_event(EventKind k, int pid = 0,
                                  std::chrono::milliseconds timeout = 10s) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      if (!threaded) sup->step();
      poll_events();
      {
        std::lock_guard lock(mutex);
        for (const auto& e : events) {
          if (e.kind == k && (pid == 0 || e.pid == pid)) return e;
        }
      }
      std::this_thread::sleep_for(2ms);
    }
    return std::nullopt;
  }
  std::size_t count(EventKind k) {
    poll_events();
    std::lock_guard lock(mutex);
    return static_cast<std::size_t>(
        std::count_if(events.begin(), events.end(), [&](const auto& e) { return e.kind == k; }));
  }
  // Waits until `n` components have joined.
  void wait_joined(std::size_t n) {
    const auto end = std::chrono::steady_clock::now() + 10s;
    while (count(EventKind::Joined) < n && std::chrono::steady_clock::now() < end) {
      if (!threaded) sup->step();
      std::this_thread::sleep_for(2ms);
    }
    REQUIRE(count(EventKind::Joined) >= n);
  }

  bool threaded;  // false: the test steps the daemon (wait_event and wait_joined do)
  // The events so far, read from the hub (no subscriber: a subscriber is a thread, and some
  // tests fork after the daemon was made).
  void poll_events() {
    std::vector<Event> more = sup->take_events();
    std::lock_guard lock(mutex);
    events.insert(events.end(), more.begin(), more.end());
  }

  std::unique_ptr<test::Daemon> sup;
  std::mutex mutex;
  std::vector<Event> events;
};

std::size_t segments_of(const std::string& sup, pid_t pid) {
  const std::string prefix = bus::shm_segment_prefix(sup) + std::to_string(pid) + ".";
  return platform::list_shared_memory(prefix).size();
}

}  // namespace

TEST_CASE("A process killed with SIGKILL: ERROR with pid and signal, others stay, segments gone",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  auto a = spawn([&](const ChildLink& l) { run_components(l, name, {"a.x", "a.y"}); });
  auto b = spawn([&](const ChildLink& l) { run_components(l, name, {"b.x"}); });
  REQUIRE(a->wait_ready());
  REQUIRE(b->wait_ready());
  Daemon d(name);
  d.wait_joined(3);
  std::this_thread::sleep_for(100ms);
  REQUIRE(segments_of(name, a->pid) == 2);
  a->kill_and_reap(SIGKILL);
  const auto e = d.wait_event(EventKind::ProcessExited, a->pid);
  REQUIRE(e.has_value());
  INFO(e->detail);
  CHECK_THAT(e->detail, Catch::StartsWith("process " + std::to_string(a->pid) + " ("));
  // Linux >= 6.15 tells a pidfd holder the signal; older kernels cannot (docs/design).
  CHECK((e->detail.find("killed by signal 9 (SIGKILL)") != std::string::npos ||
         e->detail.find("vanished without recording an exit") != std::string::npos));
  const ReportSet r = d.sup->step_monitor();  // a monitor cycle that saw b.x for sure
  for (const char* n : {"a.x", "a.y"}) {
    const Report* rep = r.find(n);
    REQUIRE(rep != nullptr);
    CHECK(rep->status.level() == StatusLevel::Error);
    CHECK_FALSE(rep->alive);
    CHECK(rep->counters.cycles >= 20);  // its last counters are kept
    REQUIRE_FALSE(rep->status.messages().empty());
    CHECK(rep->status.messages().front().text == e->detail);
    REQUIRE(rep->value("pid") != nullptr);
    CHECK(*rep->value("pid") == std::to_string(a->pid));
  }
  const Report* other = r.find("b.x");
  REQUIRE(other != nullptr);
  // Still a live member, untouched by its neighbour's death (its own checks may still find
  // overruns on a loaded test machine: not asserted here).
  CHECK(other->alive);
  CHECK(other->status.summary().find("exited") == std::string::npos);
  CHECK(segments_of(name, a->pid) == 0);  // reclaimed
  CHECK(segments_of(name, b->pid) == 1);
  const auto procs = d.sup->processes();
  REQUIRE(procs.size() == 2);
  CHECK(procs.back().pid == a->pid);
  CHECK_FALSE(procs.back().alive);
}

TEST_CASE("A stopped process is named stopped, its stop and its continue are events",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  auto a = spawn([&](const ChildLink& l) { run_components(l, name, {"s.x"}); });
  REQUIRE(a->wait_ready());
  Daemon d(name);
  d.wait_joined(1);
  ::kill(a->pid, SIGSTOP);
  const auto stopped = d.wait_event(EventKind::ProcessStopped, a->pid);
  REQUIRE(stopped.has_value());
  CHECK(stopped->severity == EventSeverity::Warn);
  CHECK(stopped->detail.find("stopped") != std::string::npos);
  auto procs = d.sup->processes();
  REQUIRE(procs.size() == 1);
  CHECK(procs[0].alive);
  CHECK(procs[0].run_state == platform::RunState::Stopped);
  CHECK(service::format_processes(procs, procs[0].run_state_since + kNanosPerSecond)
            .find("stopped 1.00s, 1 component") != std::string::npos);
  // Its component's report names the stop as the cause of its silence.
  std::this_thread::sleep_for(200ms);
  const ReportSet r = d.sup->step_monitor();
  const Report* x = r.find("s.x");
  REQUIRE(x != nullptr);
  INFO(x->status.summary());
  CHECK(x->status.summary().find("is stopped for") != std::string::npos);
  // The process is a unit of the diagnosis graph: ERROR while stopped, the cause of its
  // component's status, named once as the root cause.
  const std::string unit = "process " + procs[0].name + " (pid " + std::to_string(a->pid) + ")";
  const Report* p = r.find(unit);
  REQUIRE(p != nullptr);
  CHECK(p->is_unit("process"));
  CHECK(p->status.level() == StatusLevel::Error);
  CHECK(p->state_label == "stopped");
  CHECK(x->caused_by == std::vector<std::string>{unit});
  CHECK(std::find(r.root_causes.begin(), r.root_causes.end(), unit) != r.root_causes.end());
  CHECK(std::find(r.root_causes.begin(), r.root_causes.end(), "s.x") == r.root_causes.end());
  ::kill(a->pid, SIGCONT);
  const auto resumed = d.wait_event(EventKind::ProcessContinued, a->pid);
  REQUIRE(resumed.has_value());
  CHECK(resumed->severity == EventSeverity::Info);
  CHECK(resumed->detail.find("runs again after") != std::string::npos);
  procs = d.sup->processes();
  CHECK(procs[0].run_state == platform::RunState::Running);
  CHECK(d.count(EventKind::ProcessExited) == 0);
}

TEST_CASE("The run state of a state letter", "[integration][multi_process]") {
  CHECK(platform::run_state_of('R') == platform::RunState::Running);
  CHECK(platform::run_state_of('S') == platform::RunState::Running);
  CHECK(platform::run_state_of('D') == platform::RunState::Running);
  CHECK(platform::run_state_of('T') == platform::RunState::Stopped);
  CHECK(platform::run_state_of('t') == platform::RunState::Traced);
  CHECK(platform::run_state_of('Z') == platform::RunState::Zombie);
  CHECK(platform::run_state_of('X') == platform::RunState::Gone);
  CHECK(platform::process_run_state(platform::self_identity()) == platform::RunState::Running);
  CHECK(platform::process_run_state({platform::self_identity().pid, 1}) ==
        platform::RunState::Gone);  // another start time: another process
}

TEST_CASE("A process that exits with a code or dies of a signal is reported so",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  auto a =
      spawn([&](const ChildLink& l) { run_components(l, name, {"e.code"}, [] { std::exit(3); }); });
  auto b = spawn(
      [&](const ChildLink& l) { run_components(l, name, {"e.signal"}, [] { ::raise(SIGUSR1); }); });
  REQUIRE(a->wait_ready());
  REQUIRE(b->wait_ready());
  Daemon d(name);
  d.wait_joined(2);
  a->go();
  b->go();
  const auto ea = d.wait_event(EventKind::ProcessExited, a->pid);
  const auto eb = d.wait_event(EventKind::ProcessExited, b->pid);
  REQUIRE(ea.has_value());
  REQUIRE(eb.has_value());
  CHECK(ea->detail == "process " + std::to_string(a->pid) + " (" + d.sup->processes().back().name +
                          ") exited with code 3");
  CHECK_THAT(eb->detail, Catch::Contains("killed by signal 10 (SIGUSR1)"));
  CHECK(d.sup->reports().find("e.code")->status.level() == StatusLevel::Error);
  a->reap();
  b->reap();
}

TEST_CASE("A process records its own end in its segments (for a daemon that comes later)",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  auto a = spawn(
      [&](const ChildLink& l) { run_components(l, name, {"self.rec"}, [] { ::raise(SIGUSR1); }); });
  REQUIRE(a->wait_ready());
  a->go();
  const int status = a->reap();
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGUSR1);
  // No daemon ever drained it: a death by a signal keeps the segment, with the signal in it.
  const auto names = platform::list_shared_memory(bus::shm_segment_prefix(name));
  REQUIRE(names.size() == 1);
  auto r = bus::ShmReader<task::Message>::open(names[0], {task::kShmMessageSchema, name},
                                               platform::effective_uid(), false);
  REQUIRE(r.has_value());
  const auto live = r->live();
  REQUIRE(live.has_value());
  CHECK(live->exit_kind == bus::ShmExit::Signaled);
  CHECK(live->exit_code == SIGUSR1);
  // A daemon started now reports it, then removes the segment.
  Daemon d(name, false);
  d.sup->step();
  const auto e = d.wait_event(EventKind::ProcessExited, a->pid, 100ms);
  REQUIRE(e.has_value());
  CHECK_THAT(e->detail, Catch::Contains("killed by signal 10 (SIGUSR1)"));
  const ReportSet reports = d.sup->reports();
  const Report* rep = reports.find("self.rec");
  REQUIRE(rep != nullptr);
  CHECK(rep->status.level() == StatusLevel::Error);
  CHECK(rep->counters.cycles >= 20);
  CHECK(cleanup.count() == 0);
}

TEST_CASE("A restarted process rejoins as a new incarnation", "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  // Stepped by the test, no thread: the second child is forked while the daemon runs, and a
  // child forked from a multi-threaded process may not start threads (POSIX; TSan enforces it).
  Daemon d(name, false);
  auto first = spawn([&](const ChildLink& l) { run_components(l, name, {"r.x"}); });
  REQUIRE(first->wait_ready());
  d.wait_joined(1);
  first->kill_and_reap(SIGKILL);
  REQUIRE(d.wait_event(EventKind::ProcessExited, first->pid).has_value());
  CHECK(d.sup->reports().find("r.x")->status.level() == StatusLevel::Error);
  auto second = spawn([&](const ChildLink& l) { run_components(l, name, {"r.x"}); });
  REQUIRE(second->wait_ready());
  d.wait_joined(2);
  const ReportSet r = d.sup->step_monitor();
  int seen = 0;
  for (const Report& rep : r.components) {
    if (rep.name != "r.x") continue;
    ++seen;
    CHECK(rep.alive);
    REQUIRE(rep.value("incarnation") != nullptr);
    CHECK(*rep.value("incarnation") == "2");
    CHECK(*rep.value("pid") == std::to_string(second->pid));
  }
  CHECK(seen == 1);  // the dead incarnation's report is replaced
}

TEST_CASE("Counters stay exact for a process started before the daemon and across a restart",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  // The child steps its component by hand: exactly 500 cycles, then 2500 more, then stops it.
  auto c = spawn([&](const ChildLink& l) {
    Registry<task::Message> reg;
    bus::ShmOptions o;
    o.name = name;
    if (!place_in_shared_memory(reg, o)) ::_exit(90);
    Ctl t("exact", reg);
    ManualActivity act(t, {.name = "m", .period_ns = kNanosPerMilli});
    t.configure();
    act.start();
    for (int i = 0; i < 500; ++i) act.step();
    l.ready();
    l.wait_go();
    for (int i = 0; i < 2500; ++i) act.step();
    act.stop();
    l.ready();
    for (;;) ::pause();
  });
  REQUIRE(c->wait_ready());
  {
    Daemon first(name, false);  // started after the process
    first.sup->step();
    const auto s = first.sup->aggregator().find("exact");
    REQUIRE(s.has_value());
    CHECK(s->has_info);
    CHECK(s->counters.cycles == 500);
  }  // the daemon goes away (restart)
  c->go();
  REQUIRE(c->wait_ready());
  Daemon second(name, false);
  second.sup->step();
  const auto s = second.sup->aggregator().find("exact");
  REQUIRE(s.has_value());
  CHECK(s->has_info);
  CHECK(s->counters.cycles == 3000);
  CHECK(s->state == TaskState::Stopped);
}

namespace {
class Plain : public Task<Plain> {
 public:
  explicit Plain(const deploy::ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};
deploy::ComponentFactory& plain_factory() {
  static deploy::ComponentFactory f;
  static const bool once = f.add<Plain>("test.plain");
  (void)once;
  return f;
}
}  // namespace

TEST_CASE("A deployment's supervision.shared_memory sends its components to the daemon",
          "[integration][multi_process]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  const std::string yaml =
      "activities: [{name: a, period: 1ms}]\n"
      "components: [{name: dep.x, type: test.plain, activity: a}]\n"
      "supervision: {shared_memory: " +
      name + ", lock_memory: false}\n";
  auto spec = deploy::load_deployment_string(yaml, "shm.yaml", plain_factory());
  REQUIRE(spec.has_value());
  CHECK(spec->supervision.shared_memory == name);
  auto sys = deploy::System::create(std::move(*spec), plain_factory());
  REQUIRE(sys.has_value());
  CHECK(cleanup.count() == 1);
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(50ms);
  Daemon d(name, false);
  d.sup->step();
  const auto s = d.sup->aggregator().find("dep.x");
  REQUIRE(s.has_value());
  CHECK(s->counters.cycles > 0);
  CHECK((*sys)->aggregator().find("dep.x") == std::nullopt);  // not the process's own business
  (*sys)->stop();
}

TEST_CASE("A bad shared_memory name in a deployment is an error at its line",
          "[integration][multi_process]") {
  const std::string yaml =
      "activities: [{name: a, period: 1ms}]\n"
      "components: [{name: x, type: test.plain, activity: a}]\n"
      "supervision: {shared_memory: no/slash}\n";
  auto spec = deploy::load_deployment_string(yaml, "bad.yaml", plain_factory());
  REQUIRE_FALSE(spec.has_value());
  CHECK_THAT(config::to_string(spec.error()),
             Catch::Contains("bad.yaml:3:") && Catch::Contains("not a supervisor name"));
}

namespace {
// Child body: one Instrumentation named `component` in shared memory under `sup`, with one
// checkpoint; each "go" from the parent is one cycle reporting it.
void report_on_go(const ChildLink& link, const std::string& sup, const std::string& component,
                  const std::string& checkpoint) {
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = sup;
  if (!place_in_shared_memory(reg, o)) ::_exit(90);
  Instrumentation in(component, {}, reg);
  const CheckpointId id = in.declare_checkpoint(checkpoint);
  in.init();
  link.ready();
  for (;;) {
    link.wait_go();
    UpdateGuard guard(in);
    in.checkpoint(id);
  }
}
}  // namespace

TEST_CASE("A deadline across two processes: met, then missed and found by the daemon",
          "[integration][multi_process][health]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  auto cam = spawn([&](const ChildLink& l) { report_on_go(l, name, "cam", "frame"); });
  auto act = spawn([&](const ChildLink& l) { report_on_go(l, name, "act", "sent"); });
  REQUIRE(cam->wait_ready());
  REQUIRE(act->wait_ready());
  Daemon d(name, /*thread=*/false);
  health::HealthConfig cfg;
  cfg.deadline.push_back({.name = "frame_to_command",
                          .start = {"cam", "frame"},
                          .end = {"act", "sent"},
                          .max_ns = 300 * kNanosPerMilli});
  REQUIRE(d.sup->aggregator().supervise_health(cfg).has_value());
  d.wait_joined(2);
  const auto evaluations = [&] { return d.sup->aggregator().health_reports().at(0).evaluations; };
  cam->go();
  // The start is drained (so the camera's child has time-stamped it) before the end is asked
  // for: a loaded machine may wake the two children in any order.
  const auto started_by = std::chrono::steady_clock::now() + 10s;
  while (!d.sup->aggregator().health_reports().at(0).started &&
         std::chrono::steady_clock::now() < started_by) {
    d.sup->step();
    std::this_thread::sleep_for(1ms);
  }
  std::this_thread::sleep_for(2ms);
  act->go();
  const auto end = std::chrono::steady_clock::now() + 10s;
  while (evaluations() < 1 && std::chrono::steady_clock::now() < end) {
    d.sup->step();
    std::this_thread::sleep_for(2ms);
  }
  auto r = d.sup->aggregator().health_reports().at(0);
  CHECK(r.evaluations == 1);
  CHECK(r.status == health::SupervisionStatus::Ok);
  CHECK(r.last_duration_ns >= 2 * kNanosPerMilli);
  CHECK(r.entities == std::vector<std::string>{"cam", "act"});
  cam->go();  // act never answers
  const auto e = d.wait_event(EventKind::DeadlineSupervision);
  REQUIRE(e.has_value());
  INFO(e->detail);
  CHECK(e->component == "act");
  CHECK(e->severity == EventSeverity::Error);
  CHECK(e->detail.find("deadline_missed: no act.sent within 300.000 ms of cam.frame") !=
        std::string::npos);
  CHECK(e->detected_ns > e->fault_ns);
}
