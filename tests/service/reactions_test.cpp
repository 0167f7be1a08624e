// Reactions with real threads: the event stream's dispatcher, the reaction thread, the monitor.
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "vigil/exec/periodic_activity.hpp"
#include "vigil/safe_state.hpp"
#include "vigil/service/reactions.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::service;
using supervisor::Event;
using supervisor::EventHub;
using supervisor::EventKind;

namespace {

// Collects the hub's reaction events.
struct Recorder {
  explicit Recorder(EventHub& h) : hub(h) {
    id = hub.subscribe([this](const Event& e) {
      if (e.kind != EventKind::Reaction) return;
      const std::lock_guard lock(mutex);
      events.push_back(e);
    });
  }
  ~Recorder() { hub.unsubscribe(id); }
  std::vector<Event> wait_for(std::size_t n, int ms = 3000) {
    for (int i = 0; i < ms; ++i) {
      {
        const std::lock_guard lock(mutex);
        if (events.size() >= n) return events;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const std::lock_guard lock(mutex);
    return events;
  }
  EventHub& hub;
  std::uint64_t id = 0;
  std::mutex mutex;
  std::vector<Event> events;
};

Event fault(EventKind kind, std::string component) {
  Event e;
  e.kind = kind;
  e.severity = supervisor::EventSeverity::Error;
  e.component = std::move(component);
  e.fault_ns = platform::now_ns();
  e.detected_ns = e.fault_ns;
  e.detail = "test fault";
  return e;
}

class Ticker : public Task<Ticker> {
 public:
  Ticker(std::string name, Registry<task::Message>& reg) : Task(std::move(name), {}, reg) {}
  void on_update() {}
};

struct SafeStateCleared {
  SafeStateCleared() { (void)clear_safe_state(); }
  ~SafeStateCleared() { (void)clear_safe_state(); }
};

}  // namespace

TEST_CASE("An event raises the safe state, real-time code sees it, the action is an event",
          "[service][reactions]") {
  SafeStateCleared guard;
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  REQUIRE(r.add({.name = "encoder_fault",
                 .on = {.event = EventKind::Exception, .component = "encoder"},
                 .safe_state = true})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  std::atomic<Nanos> seen{0};
  std::atomic<bool> quit{false};
  std::thread rt([&] {  // a "real-time" loop reading the flag each cycle
    while (!quit.load()) {
      if (safe_state_requested()) {
        seen.store(platform::now_ns());
        return;
      }
    }
  });
  CHECK_FALSE(safe_state_requested());
  hub.publish(fault(EventKind::Exception, "motor"));  // another component: nothing
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  CHECK_FALSE(safe_state_requested());
  const Event e = fault(EventKind::Exception, "encoder");
  hub.publish(e);
  const auto events = rec.wait_for(1);
  quit.store(true);
  rt.join();
  REQUIRE(events.size() == 1);
  CHECK(safe_state_requested());
  CHECK(seen.load() >= e.fault_ns);
  CHECK(events[0].component == "reaction encoder_fault");
  CHECK(events[0].detail.find("request the safe state") != std::string::npos);
  CHECK(events[0].fault_ns == e.fault_ns);
  CHECK(events[0].detected_ns >= e.fault_ns);
  const SafeStateRequest s = safe_state();
  CHECK(s.generation == safe_state_generation());
  CHECK(s.reason.find("encoder_fault") != std::string::npos);
  r.stop();
  CHECK(r.stats().fired == 1);
  CHECK(r.stats().actions == 1);
}

TEST_CASE("A reaction is rate-limited: one firing per interval, the rest counted",
          "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  std::atomic<int> calls{0};
  r.add_handler("count", [&](const ReactionContext&) { ++calls; });
  REQUIRE(r.add({.name = "limited",
                 .on = {.event = EventKind::Overrun},
                 .handlers = {"count"},
                 .min_interval_ns = 10 * kNanosPerSecond})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  for (int i = 0; i < 5; ++i) hub.publish(fault(EventKind::Overrun, "motor"));
  const auto events = rec.wait_for(2);
  REQUIRE(hub.flush());
  r.stop();
  CHECK(calls.load() == 1);
  CHECK(r.stats().fired == 1);
  CHECK(r.stats().rate_limited == 4);
  // One event for the handler's call, one (only) saying it was rate-limited.
  int limited = 0;
  for (const Event& e : rec.wait_for(2)) {
    if (e.detail.find("rate-limited") != std::string::npos) ++limited;
  }
  CHECK(limited == 1);
}

TEST_CASE("Dry run logs every action and takes none", "[service][reactions]") {
  SafeStateCleared guard;
  EventHub hub;
  Recorder rec(hub);
  Reactions r({.dry_run = true});
  std::atomic<int> calls{0};
  std::atomic<int> frames{0};
  r.add_handler("h", [&](const ReactionContext&) { ++calls; });
  r.add_can_writer("bus", [&](const can::Frame&) { return ++frames > 0; });
  REQUIRE(r.add({.name = "all",
                 .on = {.event = EventKind::Deadline},
                 .safe_state = true,
                 .can = {{.writer = "bus", .frame = can::Frame::classic(0x000, {0x02, 0x05})}},
                 .watchdog = true,
                 .handlers = {"h"}})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  hub.publish(fault(EventKind::Deadline, "gripper"));
  const auto events = rec.wait_for(4);
  r.stop();
  REQUIRE(events.size() == 4);
  for (const Event& e : events) {
    INFO(e.detail);
    CHECK(e.detail.find("dry run: would") != std::string::npos);
  }
  CHECK(events[1].detail.find("000 [2] 02 05") != std::string::npos);
  CHECK_FALSE(safe_state_requested());
  CHECK(calls.load() == 0);
  CHECK(frames.load() == 0);
}

TEST_CASE("A handler that throws is reported and the next one runs", "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  std::atomic<int> after{0};
  std::atomic<int> thread_id{0};
  r.add_handler("throws", [](const ReactionContext&) { throw std::runtime_error("no motor"); });
  r.add_handler("after", [&](const ReactionContext& c) {
    CHECK(c.reaction == "two");
    CHECK(c.unit == "motor");
    CHECK(c.event.has_value());
    thread_id = platform::current_tid();
    ++after;
  });
  REQUIRE(
      r.add({.name = "two", .on = {.event = EventKind::Exception}, .handlers = {"throws", "after"}})
          .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  hub.publish(fault(EventKind::Exception, "motor"));
  const auto events = rec.wait_for(2);
  r.stop();
  REQUIRE(events.size() == 2);
  CHECK(events[0].severity == supervisor::EventSeverity::Warn);
  CHECK(events[0].detail.find("no motor") != std::string::npos);
  CHECK(events[1].severity == supervisor::EventSeverity::Info);
  CHECK(after.load() == 1);
  CHECK(thread_id.load() != platform::current_tid());  // the reaction thread
  CHECK(r.stats().failed == 1);
  CHECK(r.stats().handler_calls == 2);
}

TEST_CASE("A handler over its budget is reported while it runs and when it returns",
          "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  std::atomic<bool> release{false};
  r.add_handler(
      "slow",
      [&](const ReactionContext&) {
        while (!release.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      },
      kNanosPerMilli);
  REQUIRE(r.add({.name = "slow", .on = {.event = EventKind::Exception}, .handlers = {"slow"}})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  CHECK(r.unit(platform::now_ns()).status.level() == monitor::StatusLevel::Ok);
  hub.publish(fault(EventKind::Exception, "motor"));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const monitor::Report busy = r.unit(platform::now_ns());
  CHECK(busy.status.level() == monitor::StatusLevel::Error);
  CHECK(busy.status.summary().find("handler slow has run for") != std::string::npos);
  release = true;
  const auto events = rec.wait_for(1);
  r.stop();
  REQUIRE(events.size() == 1);
  CHECK(events[0].severity == supervisor::EventSeverity::Warn);
  CHECK(events[0].detail.find("over its 1.00ms budget") != std::string::npos);
  CHECK(r.stats().over_budget == 1);
  CHECK(r.unit(platform::now_ns()).status.level() == monitor::StatusLevel::Ok);
}

TEST_CASE("A CAN writer gets the frames and a refusal is a failed action", "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  std::vector<can::Frame> sent;
  std::mutex m;
  r.add_can_writer("ok", [&](const can::Frame& f) {
    const std::lock_guard lock(m);
    sent.push_back(f);
    return true;
  });
  r.add_can_writer("full", [](const can::Frame&) { return false; });
  REQUIRE(r.add({.name = "nmt",
                 .on = {.event = EventKind::NotResponding, .component = "can0/drive_5"},
                 .can = {{.writer = "ok", .frame = can::Frame::classic(0x000, {0x02, 0x06})},
                         {.writer = "full", .frame = can::Frame::classic(0x000, {0x02, 0x07})}}})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  hub.publish(fault(EventKind::NotResponding, "can0/drive_5"));
  const auto events = rec.wait_for(2);
  r.stop();
  REQUIRE(events.size() == 2);
  const std::lock_guard lock(m);
  REQUIRE(sent.size() == 1);
  CHECK(sent[0].data[1] == 0x06);
  CHECK(events[1].severity == supervisor::EventSeverity::Warn);
  CHECK(events[1].detail.find("refused") != std::string::npos);
  CHECK(r.stats().failed == 1);
}

TEST_CASE("The outer watchdog action without systemd fails and says why", "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  REQUIRE(r.add({.name = "escalate", .on = {.event = EventKind::BusOff}, .watchdog = true})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  hub.publish(fault(EventKind::BusOff, "can bus 0"));
  const auto events = rec.wait_for(1);
  r.stop();
  REQUIRE(events.size() == 1);
  CHECK(events[0].detail.find("NOTIFY_SOCKET is not set") != std::string::npos);
}

TEST_CASE("A status trigger fires when its unit reaches the status, once per change",
          "[service][reactions]") {
  EventHub hub;
  Recorder rec(hub);
  Reactions r;
  std::atomic<int> calls{0};
  std::string cause;
  std::mutex m;
  r.add_handler("h", [&](const ReactionContext& c) {
    const std::lock_guard lock(m);
    cause = c.cause;
    ++calls;
  });
  REQUIRE(r.add({.name = "arm",
                 .on = {.unit = "can group right_arm", .status = monitor::StatusLevel::Error},
                 .handlers = {"h"},
                 .min_interval_ns = 0})
              .has_value());
  REQUIRE(r.start(hub, nullptr).has_value());
  auto cycle = [&](monitor::StatusLevel level) {
    monitor::ReportSet s;
    s.time_ns = platform::now_ns();
    monitor::Report rep;
    rep.name = "can group right_arm";
    if (level != monitor::StatusLevel::Ok) rep.merge(level, "1 of 4 nodes not responding");
    rep.caused_by = {"can0/drive_5"};
    s.components.push_back(rep);
    r.on_reports(s);
  };
  cycle(monitor::StatusLevel::Ok);
  cycle(monitor::StatusLevel::Warn);
  cycle(monitor::StatusLevel::Error);  // fires
  cycle(monitor::StatusLevel::Error);  // still ERROR: no new firing
  cycle(monitor::StatusLevel::Stale);  // worse, but already past the trigger
  cycle(monitor::StatusLevel::Ok);
  cycle(monitor::StatusLevel::Error);  // fires again
  (void)rec.wait_for(2);
  r.stop();
  CHECK(calls.load() == 2);
  const std::lock_guard lock(m);
  CHECK(cause == "can group right_arm ERROR: 1 of 4 nodes not responding (caused by can0/drive_5)");
}

TEST_CASE("Reactions refuse what cannot work, naming it", "[service][reactions]") {
  Reactions r;
  r.add_handler("h", [](const ReactionContext&) {});
  auto err = [&](Reaction x) {
    auto a = r.add(std::move(x));
    return a ? std::string() : a.error().message;
  };
  CHECK(err({.name = "x", .on = {.event = EventKind::Exception}, .handlers = {"nobody"}}) ==
        "reaction 'x': no handler named 'nobody' is registered");
  CHECK(err({.name = "x",
             .on = {.event = EventKind::Exception},
             .can = {{.writer = "can9", .frame = {}}}}) ==
        "reaction 'x': no CAN writer named 'can9' is registered");
  CHECK(err({.name = "x", .on = {.event = EventKind::Exception}}) ==
        "reaction 'x': no action (safe_state, can, watchdog or handlers)");
  CHECK(err({.name = "x", .on = {}, .safe_state = true}) ==
        "reaction 'x': name one trigger: a unit and its status, or an event kind");
  CHECK(err({.name = "x", .on = {.event = EventKind::Reaction}, .safe_state = true}) ==
        "reaction 'x': a reaction cannot fire on reaction events");
  CHECK(err({.name = "", .on = {.event = EventKind::Exception}, .safe_state = true}) ==
        "a reaction needs a name");
  CHECK(err({.name = "ok", .on = {.event = EventKind::Exception}, .safe_state = true}).empty());
  CHECK(err({.name = "ok", .on = {.event = EventKind::Exception}, .safe_state = true}) ==
        "reaction 'ok': a reaction of that name exists");
}

TEST_CASE("The service runs reactions, adds their unit and watches its monitor thread",
          "[service][reactions]") {
  SafeStateCleared guard;
  Registry<task::Message> reg;
  SupervisionService s({.registry = &reg,
                        .supervisor_period_ns = 5 * kNanosPerMilli,
                        .monitor_period_ns = 50 * kNanosPerMilli,
                        .summary_file = nullptr,
                        .systemd_notify = false});
  REQUIRE(
      s.reactions()
          .add({.name = "on_stall", .on = {.event = EventKind::ThreadStalled}, .safe_state = true})
          .has_value());
  std::vector<Event> seen;
  std::mutex m;
  const auto id = s.events().subscribe([&](const Event& e) {
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  // The monitor's cycle stalls for 2.5 s once (its limit: 3 periods, at least 2 s).
  std::atomic<int> cycles{0};
  (void)s.monitor().add_cycle_hook([&] {
    if (++cycles == 3) std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  });
  REQUIRE(s.start().has_value());
  for (int i = 0; i < 400 && cycles.load() < 6; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const ReportSet last = s.reports();
  (void)s.stop();
  s.events().unsubscribe(id);
  const monitor::Report* unit = last.find("vigil.reactions");
  REQUIRE(unit != nullptr);
  CHECK(unit->is_unit("reactions"));
  const std::lock_guard lock(m);
  int stalled = 0, resumed = 0, reactions = 0;
  for (const Event& e : seen) {
    if (e.kind == EventKind::ThreadStalled) {
      ++stalled;
      INFO(e.component << ": " << e.detail);
      CHECK(e.component == "vigil.monitor");
      CHECK(e.detail.find("the monitor thread has ended no cycle for") != std::string::npos);
    }
    if (e.kind == EventKind::ThreadResumed) ++resumed;
    if (e.kind == EventKind::Reaction) ++reactions;
  }
  CHECK(stalled == 1);
  CHECK(resumed == 1);
  CHECK(reactions == 1);
  CHECK(safe_state_requested());
}

TEST_CASE("The monitor reports a supervisor thread that stalls, and its return",
          "[service][reactions]") {
  Registry<task::Message> reg;
  SupervisionService s({.registry = &reg,
                        .supervisor_period_ns = 5 * kNanosPerMilli,
                        .monitor_period_ns = 50 * kNanosPerMilli,
                        .summary_file = nullptr,
                        .systemd_notify = false});
  std::vector<Event> seen;
  std::mutex m;
  const auto id = s.events().subscribe([&](const Event& e) {
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  // The supervisor's drain stalls for 1 s once (its limit: 10 periods, at least 100 ms).
  std::atomic<int> drains{0};
  s.aggregator().set_cycle_hook([&](Nanos) {
    if (++drains == 20) std::this_thread::sleep_for(std::chrono::seconds(1));
  });
  Ticker ticker("ticker", reg);
  PeriodicActivity act(ticker, {.name = "ticker", .period_ns = kNanosPerMilli});
  REQUIRE(ticker.configure());
  REQUIRE(act.start().has_value());
  REQUIRE(s.start().has_value());
  bool explained = false;  // the component's staleness named as the supervisor's
  for (int i = 0; i < 300 && drains.load() < 60; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    const ReportSet r = s.reports();
    const Report* t = r.find("ticker");
    if (t != nullptr && !t->status.ok() && !t->caused_by.empty()) {
      explained = explained || (t->caused_by == std::vector<std::string>{"vigil.supervisor"} &&
                                r.root_causes == std::vector<std::string>{"vigil.supervisor"});
    }
  }
  act.stop();
  CHECK(explained);
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  (void)s.stop();
  s.events().unsubscribe(id);
  const std::lock_guard lock(m);
  int stalled = 0, resumed = 0;
  for (const Event& e : seen) {
    if (e.kind == EventKind::ThreadStalled) {
      ++stalled;
      CHECK(e.component == "vigil.supervisor");
      CHECK(e.severity == supervisor::EventSeverity::Error);
      CHECK(e.detail.find("not draining") != std::string::npos);
    }
    if (e.kind == EventKind::ThreadResumed) ++resumed;
  }
  CHECK(stalled == 1);
  CHECK(resumed == 1);
}
