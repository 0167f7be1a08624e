// Shared-memory ports carrying vigil::Message: placement by the registry (one call, the
// environment), what a daemon receives, a daemon attaching late or restarted (exact counters),
// and the daemon-side check of decoded messages.
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "shm_support.hpp"
#include "support/fake_clock.hpp"
#include "support/segment_daemon.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/supervisor/health_supervision.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::bus;

namespace {

class Ctl : public Task<Ctl> {
 public:
  Ctl(std::string name, Registry<task::Message>& registry) : Task(std::move(name), {}, registry) {}
  void on_update() {}
};

struct Placed {
  Placed() : name(test::unique_supervisor_name()), cleanup(name) {
    bus::ShmOptions o;
    o.name = name;
    REQUIRE(place_in_shared_memory(registry, o).has_value());
  }
  [[nodiscard]] std::string segment(std::uint32_t index) const {
    return bus::shm_segment_name(name, platform::self_identity().pid, index);
  }
  [[nodiscard]] bus::ShmReader<task::Message> reader(std::uint32_t index) const {
    auto r = bus::ShmReader<task::Message>::open(segment(index), {task::kShmMessageSchema, name},
                                                 platform::effective_uid(), false);
    REQUIRE(r.has_value());
    return std::move(*r);
  }
  [[nodiscard]] std::unique_ptr<test::Daemon> daemon() const {
    test::DaemonOptions o;
    o.name = name;
    o.monitor.read_thread_stats = false;
    auto d = test::Daemon::create(o);
    REQUIRE(d.has_value());
    return std::move(*d);
  }

  std::string name;
  test::ShmCleanup cleanup;
  Registry<task::Message> registry;
};

struct Running {
  Running(std::string name, Registry<task::Message>& reg)
      : task(std::move(name), reg), activity(task, {.name = "ctl", .period_ns = kNanosPerMilli}) {
    REQUIRE(task.configure());
    REQUIRE(activity.start());
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) activity.step();
  }
  Ctl task;
  ManualActivity activity;
};

std::vector<task::Message> drain_all(bus::ShmReader<task::Message>& r) {
  std::vector<task::Message> out(1024);
  auto n = r.pop(out.data(), nullptr, out.size(), &task::check_shm_message);
  REQUIRE(n.has_value());
  out.resize(*n);
  return out;
}

}  // namespace

TEST_CASE("A registry placed in shared memory gives each component its own segment",
          "[shm][port]") {
  Placed p;
  {
    Ctl a("a", p.registry);
    Ctl b("b", p.registry);
    CHECK(p.cleanup.count() == 2);
    CHECK(a.port()->shm() != nullptr);
    CHECK(p.registry.size() == 0);  // not this process's supervisor's business
    task::Message m;
    CHECK(a.port()->pop(&m, 1) == 0);
  }
  // No daemon drained them: the leaving components removed their segments themselves.
  CHECK(p.cleanup.count() == 0);
}

TEST_CASE("A component's messages arrive through its segment", "[shm][port]") {
  Placed p;
  Running r("motor", p.registry);
  r.cycles(10);
  auto reader = p.reader(0);
  const auto msgs = drain_all(reader);
  REQUIRE_FALSE(msgs.empty());
  CHECK(std::holds_alternative<task::TaskInfo>(msgs.front()));
  CHECK(std::get<task::TaskInfo>(msgs.front()).name.view() == "motor");
  std::vector<std::uint64_t> cycles;
  for (const auto& m : msgs) {
    if (const auto* s = std::get_if<task::CycleSample>(&m)) cycles.push_back(s->cycle());
  }
  CHECK(cycles == std::vector<std::uint64_t>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  CHECK(reader.info().component_name == "motor");
  CHECK(reader.info().pid == platform::self_identity().pid);
}

TEST_CASE("A daemon started after the process gets its identity and exact counters",
          "[shm][port]") {
  Placed p;
  Running r("late", p.registry);
  r.cycles(1000);  // the 256-record ring overflowed long ago
  REQUIRE(r.activity.stop());
  auto d = p.daemon();
  d->step();
  const auto s = d->aggregator().find("late");
  REQUIRE(s.has_value());
  CHECK(s->has_info);
  CHECK(s->counters.cycles == 1000);
  CHECK(s->state == TaskState::Stopped);
  CHECK(s->counters.dropped > 0);
}

TEST_CASE("A daemon without the inotify watch finds new segments at its full listings",
          "[shm][port]") {
  Placed p;
  test::DaemonOptions o;
  o.name = p.name;
  o.monitor.read_thread_stats = false;
  o.watch_directory = false;
  o.rescan_ns = 3600 * kNanosPerSecond;
  auto d = test::Daemon::create(o);
  REQUIRE(d.has_value());
  Running first("first", p.registry);
  first.cycles(10);
  (*d)->step();  // the first step lists the directory
  REQUIRE((*d)->aggregator().find("first").has_value());
  Running second("second", p.registry);
  second.cycles(10);
  for (int i = 0; i < 5; ++i) (*d)->step();
  CHECK_FALSE((*d)->aggregator().find("second").has_value());  // no listing due, no watch

  o.rescan_ns = 0;  // a listing at every step
  auto e = test::Daemon::create(o);
  REQUIRE(e.has_value());
  (*e)->step();
  Running third("third", p.registry);
  third.cycles(10);
  (*e)->step();
  CHECK((*e)->aggregator().find("third").has_value());
  CHECK((*e)->aggregator().find("second").has_value());
}

TEST_CASE("A daemon restarted while the component runs keeps its counters exact", "[shm][port]") {
  Placed p;
  Running r("restarted", p.registry);
  {
    auto a = p.daemon();
    r.cycles(100);
    a->step();
    REQUIRE(a->aggregator().find("restarted")->counters.cycles == 100);
  }
  r.cycles(5000);  // no daemon: the ring fills, samples are dropped
  auto b = p.daemon();
  b->step();
  auto s = b->aggregator().find("restarted");
  REQUIRE(s.has_value());
  CHECK(s->has_info);  // its identity went to the first daemon; the mailbox kept it
  CHECK(s->counters.cycles == 5100);
  r.cycles(10);
  b->step();
  CHECK(b->aggregator().find("restarted")->counters.cycles == 5110);
  // The daemon reports where the component runs.
  const ReportSet reports = b->step_monitor();
  const Report* rep = reports.find("restarted");
  REQUIRE(rep != nullptr);
  REQUIRE(rep->value("pid") != nullptr);
  CHECK(*rep->value("pid") == std::to_string(platform::self_identity().pid));
  CHECK(rep->value("command") != nullptr);
  CHECK(reports.find("vigil.supervise") != nullptr);
}

TEST_CASE("A component that leaves is drained, reported as left, and its segment removed",
          "[shm][port]") {
  Placed p;
  auto d = p.daemon();
  {
    Running r("leaver", p.registry);
    d->step();
    r.cycles(7);
    REQUIRE(r.activity.stop());
  }
  d->step();
  const auto s = d->aggregator().find("leaver");
  REQUIRE(s.has_value());
  CHECK_FALSE(s->alive);
  CHECK(s->counters.cycles == 7);
  CHECK(p.cleanup.count() == 0);
  // What happened to the segment reaches the one event stream, with the process named.
  std::vector<Event> events = d->take_events();
  std::erase_if(events, [](const Event& e) { return e.kind == EventKind::StateChange; });
  REQUIRE(events.size() == 2);
  CHECK(events[0].kind == EventKind::Joined);
  CHECK(events[1].kind == EventKind::Left);
  CHECK(events[1].component == "leaver");
  CHECK(events[1].pid == platform::self_identity().pid);
}

TEST_CASE("Components that come and go between a daemon's cycles are each drained exactly",
          "[shm][port]") {
  // The daemon drains segments in the order they joined, a list it rebuilds only when segments
  // come or go. Segment names end in an index, so that ".10" sorts before ".2": this mixes the
  // order of names with the order of joining, and every cycle below changes the set.
  Placed p;
  auto d = p.daemon();
  std::vector<std::unique_ptr<Running>> comps;
  std::vector<int> expected;
  const auto add = [&](int count) {
    for (int i = 0; i < count; ++i) {
      comps.push_back(std::make_unique<Running>("c" + std::to_string(comps.size()), p.registry));
      expected.push_back(0);
    }
  };
  const auto run_all = [&](int cycles) {
    for (std::size_t i = 0; i < comps.size(); ++i) {
      if (!comps[i]) continue;
      const int n = cycles + static_cast<int>(i);  // a different count for each
      comps[i]->cycles(n);
      expected[i] += n;
    }
  };
  const auto check_all = [&] {
    for (std::size_t i = 0; i < comps.size(); ++i) {
      const auto s = d->aggregator().find("c" + std::to_string(i));
      REQUIRE(s.has_value());
      CHECK(s->alive == (comps[i] != nullptr));
      CHECK(s->counters.cycles == static_cast<std::uint64_t>(expected[i]));
    }
  };
  add(3);
  run_all(5);
  d->step();
  check_all();
  add(10);  // indices 3..12
  run_all(7);
  d->step();
  check_all();
  REQUIRE(comps[1]->activity.stop());
  comps[1].reset();  // leaves: its segment is drained, then forgotten
  REQUIRE(comps[11]->activity.stop());
  comps[11].reset();
  add(2);
  run_all(3);
  d->step();
  check_all();
  run_all(4);
  d->step();
  d->step();
  check_all();
}

TEST_CASE("The daemon keeps where a component that left ran until its own retention ends",
          "[shm][port]") {
  Placed p;
  test::FakeClock clock;
  test::DaemonOptions o;
  o.name = p.name;
  o.monitor.read_thread_stats = false;
  o.monitor.clock = clock.clock();
  o.aggregator.retain_left_ns = kNanosPerSecond;
  auto created = test::Daemon::create(o);
  REQUIRE(created.has_value());
  auto& d = *created;
  auto a = std::make_unique<Running>("first_out", p.registry);
  auto b = std::make_unique<Running>("second_out", p.registry);
  a->cycles(3);
  b->cycles(3);
  d->step();
  const auto pid_of = [&](const char* name) -> std::string {
    const ReportSet reports = d->step_monitor();
    const Report* r = reports.find(name);
    if (r == nullptr) return "(no report)";
    const std::string* pid = r->value("pid");
    return pid != nullptr ? *pid : "(no pid)";
  };
  const std::string self = std::to_string(platform::self_identity().pid);
  REQUIRE(a->activity.stop());
  a.reset();
  d->step();  // first_out left at 1 s: kept until 2 s
  clock.advance(kNanosPerSecond / 2);
  REQUIRE(b->activity.stop());
  b.reset();
  d->step();  // second_out left at 1.5 s: kept until 2.5 s
  CHECK(pid_of("first_out") == self);
  CHECK(pid_of("second_out") == self);
  clock.advance(kNanosPerSecond * 7 / 10);  // 2.2 s
  d->step();
  CHECK(pid_of("first_out") == "(no report)");
  CHECK(pid_of("second_out") == self);  // its own retention has not ended
  clock.advance(kNanosPerSecond / 2);   // 2.7 s
  d->step();
  CHECK(pid_of("second_out") == "(no report)");
}

TEST_CASE("VIGIL_SUPERVISOR selects shared memory, and a bad name is refused with a message",
          "[shm][port]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  SECTION("valid") {
    ::setenv("VIGIL_SUPERVISOR", name.c_str(), 1);
    Registry<task::Message> reg;
    CHECK(bus::place_from_environment(reg, task::kShmMessageSchema, task::kShmStickyMessages));
    CHECK(reg.shared_memory() != nullptr);
    Ctl c("env", reg);
    CHECK(cleanup.count() == 1);
  }
  SECTION("invalid") {
    ::setenv("VIGIL_SUPERVISOR", "no/slashes", 1);
    auto o = bus::shm_options_from_environment();
    REQUIRE_FALSE(o.has_value());
    CHECK_THAT(o.error().message, Catch::Contains("VIGIL_SUPERVISOR='no/slashes'"));
    Registry<task::Message> reg;
    CHECK_FALSE(
        bus::place_from_environment(reg, task::kShmMessageSchema, task::kShmStickyMessages));
    CHECK(reg.shared_memory() == nullptr);
  }
  SECTION("unset") {
    ::unsetenv("VIGIL_SUPERVISOR");
    Registry<task::Message> reg;
    CHECK(bus::place_from_environment(reg, task::kShmMessageSchema, task::kShmStickyMessages));
    CHECK(reg.shared_memory() == nullptr);
  }
  ::unsetenv("VIGIL_SUPERVISOR");
}

TEST_CASE("check_shm_message rejects what would be undefined to read", "[shm][port]") {
  std::string why;
  SECTION("valid messages pass") {
    task::Message m{task::CycleSample{
        .release_ns = 5, .start_ns = 10, .end_ns = 20, .counters = {.cycles = 1}}};
    CHECK(task::check_shm_message(m, why));
    task::Message i{task::TaskInfo{}};
    CHECK(task::check_shm_message(i, why));
  }
  SECTION("a bool byte of 2") {
    task::CycleSample s;
    std::memset(&s.overrun, 2, 1);
    task::Message m{s};
    CHECK_FALSE(task::check_shm_message(m, why));
    CHECK_THAT(why, Catch::Contains("bool"));
  }
  SECTION("a loss cause used as an index") {
    task::RealTimeLoss l;
    l.cause = static_cast<platform::LossCause>(200);
    task::Message m{l};
    CHECK_FALSE(task::check_shm_message(m, why));
  }
  SECTION("states and hooks out of range") {
    task::StateChange c;
    c.to = static_cast<TaskState>(9);
    task::Message m{c};
    CHECK_FALSE(task::check_shm_message(m, why));
    task::ExceptionReport e;
    e.hook = static_cast<Hook>(77);
    task::Message m2{e};
    CHECK_FALSE(task::check_shm_message(m2, why));
  }
  SECTION("times that would overflow arithmetic") {
    task::Message m{task::CycleSample{.start_ns = -1, .end_ns = 5, .counters = {.cycles = 1}}};
    CHECK_FALSE(task::check_shm_message(m, why));
    task::Message m2{task::CycleSample{.start_ns = 10, .end_ns = 5, .counters = {.cycles = 1}}};
    CHECK_FALSE(task::check_shm_message(m2, why));
  }
  SECTION("unterminated strings are terminated") {
    task::ExceptionReport e;
    std::memset(e.message.data_, 'x', sizeof e.message.data_);
    task::Message m{e};
    REQUIRE(task::check_shm_message(m, why));
    CHECK(std::get<task::ExceptionReport>(m).message.size() == sizeof e.message.data_ - 1);
  }
}

TEST_CASE("A segment's start ticks, however large, give a start time no later than now",
          "[shm][port]") {
  // Found by fuzzing (tests/fuzz/regressions/shm_segment/start_ticks_overflow.bin): the ticks
  // come from the segment header; ticks * ns-per-tick overflowed.
  const std::int64_t self = platform::start_time_unix_ns(
      platform::process_start_ticks(platform::current_pid()).value_or(0));
  const std::int64_t huge = platform::start_time_unix_ns(~std::uint64_t{0});
  const std::int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  // Each call reads the realtime and boot clocks anew: allow their jitter (a process started in
  // the current clock tick has the same ticks as `huge`).
  CHECK(huge + kNanosPerMilli >= self);
  CHECK(huge <= now + kNanosPerSecond);
  CHECK(std::llabs(platform::start_time_unix_ns(std::uint64_t{1} << 62) - huge) < kNanosPerSecond);
}

TEST_CASE("Checkpoints through shared memory: a cross-component deadline judged by the daemon",
          "[shm][port][health]") {
  Placed p;
  auto d = p.daemon();
  health::HealthConfig cfg;
  cfg.deadline.push_back({.name = "chain",
                          .start = {"cam", "frame"},
                          .end = {"act", "sent"},
                          .max_ns = 5 * kNanosPerMilli});
  REQUIRE(d->aggregator().supervise_health(cfg).has_value());
  Instrumentation cam("cam", {}, p.registry);
  Instrumentation act("act", {}, p.registry);
  const CheckpointId frame = cam.declare_checkpoint("frame");
  const CheckpointId sent = act.declare_checkpoint("sent");
  cam.init();
  act.init();
  const auto settle = [&] {
    d->step();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    d->step();
  };
  settle();
  {
    UpdateGuard g(cam);
    cam.checkpoint(frame);
  }
  {
    UpdateGuard g(act);
    act.checkpoint(sent);
  }
  settle();
  auto r = d->aggregator().health_reports();
  REQUIRE(r.size() == 1);
  CHECK(r[0].evaluations == 1);
  CHECK(r[0].status == health::SupervisionStatus::Ok);
  {
    UpdateGuard g(cam);
    cam.checkpoint(frame);  // never followed by act's "sent"
  }
  d->step();
  std::this_thread::sleep_for(std::chrono::milliseconds(10));
  d->step();
  std::vector<Event> missed;
  for (const auto& e : d->take_events()) {
    if (e.kind == EventKind::DeadlineSupervision) missed.push_back(e);
  }
  REQUIRE(missed.size() == 1);
  CHECK(missed[0].component == "act");
  CHECK(missed[0].detail.find("deadline_missed") != std::string::npos);
  CHECK(d->aggregator().health_reports()[0].status == health::SupervisionStatus::Expired);
}
