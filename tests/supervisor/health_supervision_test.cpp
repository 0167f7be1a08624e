// Health supervision driven by the supervisor: components' checkpoints and cycles through their
// ports, failures as events, the drain thread woken at the deadline.
#include "vigil/supervisor/health_supervision.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <functional>
#include <string>
#include <thread>

#include "support/fake_clock.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::supervisor;

namespace {

constexpr Nanos kMs = kNanosPerMilli;

// A component with two checkpoints; what it reports in each cycle is scripted.
class Stage : public vigil::Task<Stage> {
 public:
  Stage(std::string name, Registry<task::Message>& reg) : Task(std::move(name), {}, reg) {}
  CheckpointId begin, end;
  std::atomic<bool> report_begin{true};
  std::atomic<bool> report_end{true};
  std::atomic<bool> begin_once{false};  // one "begin", then nothing
  bool on_configure() {
    begin = declare_checkpoint("begin");
    end = declare_checkpoint("end");
    return true;
  }
  void on_update() {
    if (begin_once.exchange(false, std::memory_order_relaxed)) checkpoint(begin);
    if (report_begin.load(std::memory_order_relaxed)) checkpoint(begin);
    if (report_end.load(std::memory_order_relaxed)) checkpoint(end);
  }
};

std::vector<Event> events_of(const ComponentAggregator& agg, EventKind kind) {
  std::vector<Event> out;
  for (const auto& e : agg.events().since(0)) {
    if (e.kind == kind) out.push_back(e);
  }
  return out;
}

template <class F>
bool eventually(F done, std::chrono::milliseconds limit = std::chrono::seconds(10)) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (!done()) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace

TEST_CASE("Checkpoints and cycles drained from ports feed health supervision (fake clock)",
          "[supervisor][health]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.clock = fc.clock(), .state_events = false});
  health::HealthConfig cfg;
  cfg.alive.push_back({.name = "a_cycles",
                       .checkpoint = {"a"},
                       .reference_cycle_ns = 10 * kMs,
                       .expected_indications = 10,
                       .min_margin = 2,
                       .max_margin = 2,
                       .startup_grace_ns = 0});
  cfg.deadline.push_back(
      {.name = "a_to_b", .start = {"a", "begin"}, .end = {"b", "end"}, .max_ns = 3 * kMs});
  cfg.logical.push_back({.name = "b_order",
                         .initial = {{"b", "begin"}},
                         .final = {{"b", "end"}},
                         .transitions = {{{"b", "begin"}, {"b", "end"}}}});
  REQUIRE(agg.supervise_health(cfg).has_value());
  ComponentDrainLoop sup(reg, agg, {.clock = fc.clock()});
  Stage a("a", reg);
  Stage b("b", reg);
  a.report_end = false;
  b.report_begin = false;  // b's cycle: "end" only, until told otherwise
  ManualActivity act_a(a, {.name = "ma", .period_ns = kMs, .clock = fc.clock()});
  ManualActivity act_b(b, {.name = "mb", .period_ns = kMs, .clock = fc.clock()});
  REQUIRE(a.configure());
  REQUIRE(b.configure());
  REQUIRE(act_a.start(fc.now()));
  REQUIRE(act_b.start(fc.now()));
  b.report_begin = true;
  // 20 ms of a then b, 1 kHz: every deadline met, b's sequence begin -> end.
  for (int i = 0; i < 20; ++i) {
    fc.set(act_a.next_release());
    act_a.step();
    fc.advance(100'000);
    act_b.step();
    sup.step();
  }
  CHECK(agg.events().since(0).empty());
  auto reports = agg.health_reports();
  REQUIRE(reports.size() == 3);
  CHECK(reports[0].status == health::SupervisionStatus::Ok);
  CHECK(reports[0].evaluations >= 1);
  CHECK(reports[1].status == health::SupervisionStatus::Ok);
  CHECK(reports[1].evaluations >= 18);  // the latest end waits for the next drain
  CHECK(reports[2].status == health::SupervisionStatus::Ok);

  // b skips its "begin" once: an invalid transition; and its "end" is too late for a's start.
  b.report_begin = false;
  fc.set(act_a.next_release());
  act_a.step();
  fc.advance(4 * kMs);
  act_b.step();
  sup.step();
  fc.advance(100'000);
  sup.step();  // b's end, drained at its own time, is judged once settled
  const auto logical = events_of(agg, EventKind::LogicalSupervision);
  REQUIRE(logical.size() == 1);
  CHECK(logical[0].component == "b");
  CHECK(logical[0].component_id != 0);
  CHECK(logical[0].severity == EventSeverity::Error);
  CHECK(logical[0].detail.find("b.end at the start of a sequence; allowed: b.begin") !=
        std::string::npos);
  const auto deadline = events_of(agg, EventKind::DeadlineSupervision);
  REQUIRE(deadline.size() == 1);
  CHECK(deadline[0].component == "b");
  CHECK(deadline[0].detail.find("deadline_missed") != std::string::npos);
  CHECK(deadline[0].fault_ns < deadline[0].detected_ns);
  CHECK(deadline[0].latched);  // the first Error on b: its latch and a flight record
  // The flight record of that event holds b's checkpoints and the chain's pairs (traces).
  const auto record = agg.frozen_record(deadline[0].seq);
  REQUIRE(record != nullptr);
  REQUIRE_FALSE(record->checkpoints.empty());
  CHECK(record->checkpoints.back().name == "end");
  CHECK(record->checkpoints.front().time_ns >= record->cycles.front().release_ns);
  REQUIRE(record->deadlines.size() >= 19);
  CHECK(record->deadlines.front().supervision == "a_to_b");
  CHECK(record->deadlines.front().failure == health::FailureKind::None);
  CHECK(record->deadlines.back().failure == health::FailureKind::DeadlineMissed);
  // On demand too, for a component that only starts the chain.
  const auto of_a = agg.flight_record("a");
  REQUIRE(of_a.has_value());
  CHECK_FALSE(of_a->checkpoints.empty());
  CHECK(of_a->checkpoints.front().name == "begin");
  CHECK(of_a->deadlines.size() == record->deadlines.size());

  // a stops on purpose: its alive supervision is deactivated, not failed.
  REQUIRE(act_a.stop());
  fc.advance(100'000);
  sup.step();
  fc.advance(100 * kMs);
  sup.step();
  CHECK(events_of(agg, EventKind::AliveSupervision).empty());
  reports = agg.health_reports();
  CHECK(reports[0].status == health::SupervisionStatus::Deactivated);
  CHECK(reports[1].status == health::SupervisionStatus::Deactivated);
}

TEST_CASE("An entity that never starts is EXPIRED after its grace period, as an event",
          "[supervisor][health]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.clock = fc.clock()});
  health::HealthConfig cfg;
  cfg.alive.push_back({.name = "ghost_alive",
                       .checkpoint = {"ghost"},
                       .reference_cycle_ns = 10 * kMs,
                       .expected_indications = 10,
                       .startup_grace_ns = 500 * kMs});
  REQUIRE(agg.supervise_health(cfg).has_value());
  ComponentDrainLoop sup(reg, agg, {.clock = fc.clock()});
  sup.step();
  fc.advance(499 * kMs);
  sup.step();
  CHECK(events_of(agg, EventKind::AliveSupervision).empty());
  fc.advance(2 * kMs);
  sup.step();
  const auto ev = events_of(agg, EventKind::AliveSupervision);
  REQUIRE(ev.size() == 1);
  CHECK(ev[0].component == "ghost");
  CHECK(ev[0].component_id == 0);  // it never joined
  CHECK(ev[0].severity == EventSeverity::Error);
  CHECK(ev[0].detail.find("never_started") != std::string::npos);
  CHECK(agg.health_reports()[0].status == health::SupervisionStatus::Expired);
}

TEST_CASE("A program deactivates an entity that need not run", "[supervisor][health]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.clock = fc.clock()});
  health::HealthConfig cfg;
  cfg.alive.push_back({.name = "docking_alive",
                       .checkpoint = {"docking"},
                       .reference_cycle_ns = 10 * kMs,
                       .startup_grace_ns = 500 * kMs});
  REQUIRE(agg.supervise_health(cfg).has_value());
  ComponentDrainLoop sup(reg, agg, {.clock = fc.clock()});
  sup.step();
  REQUIRE(agg.health() != nullptr);
  CHECK(agg.health()->deactivate("docking"));
  CHECK_FALSE(agg.health()->deactivate("nobody"));
  fc.advance(kNanosPerSecond);
  sup.step();
  CHECK(agg.events().since(0).empty());
  CHECK(agg.health()->status("docking_alive") == health::SupervisionStatus::Deactivated);
}

TEST_CASE("Misused checkpoint ids are counted and raised once per drain", "[supervisor][health]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.clock = fc.clock()});
  health::HealthConfig cfg;  // no supervision: misuses are reported anyway
  REQUIRE(agg.supervise_health(cfg).has_value());
  ComponentDrainLoop sup(reg, agg, {.clock = fc.clock()});
  Instrumentation in("sloppy", {}, reg);
  in.init({}, fc.clock());
  for (int i = 0; i < 3; ++i) {
    UpdateGuard guard(in);
    in.checkpoint(CheckpointId{});
  }
  sup.step();
  const auto ev = events_of(agg, EventKind::CheckpointMisuse);
  REQUIRE(ev.size() == 1);
  CHECK(ev[0].component == "sloppy");
  CHECK(ev[0].count == 3);
  const auto use = agg.health()->checkpoint_use();
  REQUIRE(use.size() == 1);
  CHECK(use[0].misuses == 3);
}

TEST_CASE("A bad health configuration is refused", "[supervisor][health]") {
  ComponentAggregator agg;
  health::HealthConfig cfg;
  cfg.deadline.push_back({.name = "x", .start = {"a", "s"}, .end = {"a", "e"}, .max_ns = 0});
  const auto r = agg.supervise_health(cfg);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message.find("max_ns") != std::string::npos);
  CHECK(agg.health() == nullptr);
}

TEST_CASE("The drain thread wakes at a missed deadline, long before its next period",
          "[supervisor][health][threads]") {
  Registry<task::Message> reg;
  ComponentAggregator agg({.state_events = false});
  health::HealthConfig cfg;
  cfg.deadline.push_back({.name = "begin_to_end",
                          .start = {"stage", "begin"},
                          .end = {"stage", "end"},
                          .max_ns = 20 * kMs});
  REQUIRE(agg.supervise_health(cfg).has_value());
  // A drain period of 2 s: without the deadline's wake-up nothing would be found for seconds.
  ComponentDrainLoop sup(reg, agg, {.period_ns = 2 * kNanosPerSecond});
  Stage s("stage", reg);
  PeriodicActivity act(s, {.name = "stage", .period_ns = kMs});
  REQUIRE(s.configure());
  REQUIRE(act.start().has_value());
  REQUIRE(sup.start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  s.report_begin = false;
  s.report_end = false;
  s.begin_once = true;  // one more "begin", never followed by its "end"
  REQUIRE(eventually([&] { return !events_of(agg, EventKind::DeadlineSupervision).empty(); }));
  const auto ev = events_of(agg, EventKind::DeadlineSupervision).front();
  // Behaviour, not a timing goal: found within a fraction of the 2 s period, so by the wake-up.
  CHECK(ev.latency_ns() < kNanosPerSecond);
  CHECK(ev.latency_ns() > 0);
  CHECK(ev.detail.find("deadline_missed") != std::string::npos);
  act.stop();
  sup.stop();
}
