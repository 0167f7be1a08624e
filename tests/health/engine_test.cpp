// The health engine as pure logic: inputs and times given by hand (a fake clock).
#include "vigil/health/engine.hpp"

#include <catch2/catch.hpp>
#include <stdexcept>
#include <string>

using namespace vigil;
using namespace vigil::health;

namespace {

constexpr Nanos kMs = kNanosPerMilli;
constexpr Nanos kT0 = 1'000 * kMs;  // the engine's origin in these tests
constexpr Nanos kSettle = 20 * kNanosPerMicro;

HealthConfig alive_config(std::uint32_t tolerance = 1, Nanos grace = 0) {
  HealthConfig c;
  c.alive.push_back({.name = "drive_alive",
                     .checkpoint = {"drive", "tick"},
                     .reference_cycle_ns = 10 * kMs,
                     .expected_indications = 10,
                     .min_margin = 1,
                     .max_margin = 1,
                     .failed_cycles_tolerance = tolerance,
                     .startup_grace_ns = grace});
  return c;
}

// Reports `n` ticks evenly over [from, from + 10 ms).
void ticks(HealthEngine& e, int cp, Nanos from, int n) {
  for (int i = 0; i < n; ++i) e.report(cp, from + i * (10 * kMs) / n + 1);
}

}  // namespace

TEST_CASE("Alive: correct reference cycles stay OK", "[health][alive]") {
  HealthEngine e(alive_config());
  const int tick = e.checkpoint("drive", "tick");
  REQUIRE(tick >= 0);
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  for (int w = 0; w < 5; ++w) ticks(e, tick, kT0 + w * 10 * kMs, 10);
  e.advance(kT0 + 50 * kMs + kSettle);
  CHECK(e.take_failures().empty());
  const auto r = e.reports().at(0);
  CHECK(r.status == SupervisionStatus::Ok);
  CHECK(r.evaluations == 5);
  CHECK(r.last_window_count == 10);
  CHECK(r.checkpoints == 50);
}

TEST_CASE("Alive: too rare fails, within the tolerance FAILED, beyond it EXPIRED",
          "[health][alive]") {
  HealthEngine e(alive_config(/*tolerance=*/1));
  const int tick = e.checkpoint("drive", "tick");
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  ticks(e, tick, kT0, 5);  // 5 < 10 - 1
  e.advance(kT0 + 10 * kMs + kSettle);
  auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::TooFewIndications);
  CHECK(f[0].status == SupervisionStatus::Failed);
  CHECK(f[0].fault_ns == kT0 + 10 * kMs);  // the window's end
  CHECK(f[0].detected_ns == kT0 + 10 * kMs + kSettle);
  CHECK(f[0].entity == "drive");
  CHECK(f[0].text.find("5 indications") != std::string::npos);
  CHECK(e.status("drive_alive") == SupervisionStatus::Failed);
  ticks(e, tick, kT0 + 10 * kMs, 3);
  e.advance(kT0 + 20 * kMs + kSettle);
  f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].status == SupervisionStatus::Expired);
  CHECK(e.status("drive_alive") == SupervisionStatus::Expired);
  // EXPIRED is latched: correct windows do not bring it back, and further failures are counted
  // without being raised again.
  ticks(e, tick, kT0 + 20 * kMs, 10);
  e.advance(kT0 + 40 * kMs + kSettle);
  CHECK(e.take_failures().empty());
  CHECK(e.status("drive_alive") == SupervisionStatus::Expired);
  CHECK(e.reports()[0].failures == 3);
  CHECK(e.reports()[0].expirations == 1);
}

TEST_CASE("Alive: correct windows take failures back (FAILED -> OK)", "[health][alive]") {
  HealthEngine e(alive_config(/*tolerance=*/2));
  const int tick = e.checkpoint("drive", "tick");
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  ticks(e, tick, kT0, 2);
  ticks(e, tick, kT0 + 10 * kMs, 2);
  e.advance(kT0 + 20 * kMs + kSettle);
  CHECK(e.take_failures().size() == 2);
  CHECK(e.reports()[0].failed_count == 2);
  ticks(e, tick, kT0 + 20 * kMs, 10);
  e.advance(kT0 + 30 * kMs + kSettle);
  CHECK(e.status("drive_alive") == SupervisionStatus::Failed);
  CHECK(e.reports()[0].failed_count == 1);
  ticks(e, tick, kT0 + 30 * kMs, 10);
  e.advance(kT0 + 40 * kMs + kSettle);
  CHECK(e.status("drive_alive") == SupervisionStatus::Ok);
}

TEST_CASE("Alive: too often fails at the indication beyond the max margin", "[health][alive]") {
  HealthEngine e(alive_config(/*tolerance=*/0));
  const int tick = e.checkpoint("drive", "tick");
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  for (int i = 0; i < 12; ++i) e.report(tick, kT0 + (i + 1) * 100'000);  // 12 in 1.2 ms
  e.advance(kT0 + 2 * kMs);  // long before the window ends
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::TooManyIndications);
  CHECK(f[0].fault_ns == kT0 + 1'200'000);  // the 12th: 12 > 10 + 1
  CHECK(f[0].status == SupervisionStatus::Expired);
  // The window is judged once.
  e.advance(kT0 + 10 * kMs + kSettle);
  CHECK(e.take_failures().empty());
  CHECK(e.reports()[0].failures == 1);
}

TEST_CASE("Alive: reports dropped by a full port are counted from the gaps", "[health][alive]") {
  HealthEngine e(alive_config());
  const int tick = e.checkpoint("drive", "tick");
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  // Counts 1, 2, then 10: seven were dropped, the window still had ten.
  e.report(tick, kT0 + 1 * kMs, 1);
  e.report(tick, kT0 + 2 * kMs, 2);
  e.report(tick, kT0 + 9 * kMs, 10);
  e.advance(kT0 + 10 * kMs + kSettle);
  CHECK(e.take_failures().empty());
  CHECK(e.reports()[0].lost == 7);
  CHECK(e.reports()[0].last_window_count == 10);
}

TEST_CASE("Alive: an entity that never starts is EXPIRED when its grace period ends",
          "[health][alive]") {
  HealthEngine e(alive_config(1, /*grace=*/500 * kMs));
  e.start(kT0);
  CHECK(e.next_deadline() == kT0 + 500 * kMs + kSettle);
  e.advance(kT0 + 499 * kMs);
  CHECK(e.take_failures().empty());
  CHECK(e.status("drive_alive") == SupervisionStatus::Deactivated);
  e.advance(kT0 + 500 * kMs + kSettle);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::NeverStarted);
  CHECK(f[0].status == SupervisionStatus::Expired);  // whatever the tolerance
  CHECK(f[0].fault_ns == kT0 + 500 * kMs);
  // A late start is a fresh activation.
  const int tick = e.checkpoint("drive", "tick");
  ticks(e, tick, kT0 + 600 * kMs, 10);
  e.advance(kT0 + 605 * kMs);
  CHECK(e.status("drive_alive") == SupervisionStatus::Ok);
}

TEST_CASE("Alive: an entity deactivated on purpose is not a fault", "[health][alive]") {
  HealthEngine e(alive_config(0, /*grace=*/500 * kMs));
  const int drive = e.entity("drive");
  const int tick = e.checkpoint("drive", "tick");
  SECTION("before it starts: it need not start") {
    e.start(kT0);
    e.deactivate(drive, kT0 + kMs);
    e.advance(kT0 + 2 * kT0);
    CHECK(e.take_failures().empty());
    CHECK(e.status("drive_alive") == SupervisionStatus::Deactivated);
    CHECK(e.next_deadline() == kNever);
  }
  SECTION("stopped while running: silent windows do not fail; restarted: windows from then") {
    e.start(kT0);
    e.activate(drive, kT0);
    ticks(e, tick, kT0, 10);
    e.deactivate(drive, kT0 + 10 * kMs + 1);
    e.advance(kT0 + 200 * kMs);
    CHECK(e.take_failures().empty());
    CHECK(e.status("drive_alive") == SupervisionStatus::Deactivated);
    // Reports while deactivated are ignored (a last cycle while stopping).
    e.report(tick, kT0 + 201 * kMs);
    e.activate(drive, kT0 + 205 * kMs);
    ticks(e, tick, kT0 + 205 * kMs, 10);
    e.advance(kT0 + 215 * kMs + kSettle);
    CHECK(e.take_failures().empty());
    CHECK(e.status("drive_alive") == SupervisionStatus::Ok);
    CHECK(e.reports()[0].last_window_count == 10);
  }
}

TEST_CASE("Alive: a silent entity fails every window, judged in bulk after a long gap",
          "[health][alive]") {
  HealthEngine e(alive_config(/*tolerance=*/3));
  const int tick = e.checkpoint("drive", "tick");
  e.start(kT0);
  e.activate(e.entity("drive"), kT0);
  ticks(e, tick, kT0, 10);
  e.advance(kT0 + 100'000 * kMs);  // 10^4 windows at once
  const auto f = e.take_failures();
  REQUIRE(f.size() == 4);  // three FAILED, then EXPIRED; the rest is counted
  CHECK(f.back().status == SupervisionStatus::Expired);
  CHECK(f[0].fault_ns == kT0 + 20 * kMs);
  CHECK(e.reports()[0].evaluations == 9'999);
  CHECK(e.reports()[0].failures == 9'998);
}

namespace {
HealthConfig deadline_config() {
  HealthConfig c;
  c.deadline.push_back({.name = "sense_to_act",
                        .start = {"camera", "frame"},
                        .end = {"drive", "sent"},
                        .min_ns = 1 * kMs,
                        .max_ns = 5 * kMs});
  return c;
}
struct Chain {
  HealthEngine e{deadline_config()};
  int frame = e.checkpoint("camera", "frame");
  int sent = e.checkpoint("drive", "sent");
  Chain() {
    e.start(kT0);
    e.activate(e.entity("camera"), kT0);
    e.activate(e.entity("drive"), kT0);
  }
};
}  // namespace

TEST_CASE("Deadline: an end within [min, max] passes, across entities", "[health][deadline]") {
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.report(c.sent, kT0 + 13 * kMs);
  c.e.report(c.frame, kT0 + 20 * kMs);
  c.e.report(c.sent, kT0 + 25 * kMs);  // exactly max
  c.e.advance(kT0 + 30 * kMs);
  CHECK(c.e.take_failures().empty());
  const auto r = c.e.reports().at(0);
  CHECK(r.status == SupervisionStatus::Ok);
  CHECK(r.evaluations == 2);
  CHECK(r.min_duration_ns == 3 * kMs);
  CHECK(r.max_duration_ns == 5 * kMs);
  CHECK(r.entities == std::vector<std::string>{"camera", "drive"});
}

TEST_CASE("Deadline: inputs wait until every port is drained up to their time",
          "[health][deadline]") {
  // Ports are drained one after the other: the camera's port was drained after its second frame,
  // the drive's before its (earlier) end. Judged up to when the drain began, nothing is wrong.
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.report(c.frame, kT0 + 12 * kMs);  // drained; the end at 11 ms still in the drive's port
  c.e.advance(kT0 + 12 * kMs + kSettle, /*drained_to=*/kT0 + 10 * kMs + kSettle);
  CHECK(c.e.take_failures().empty());
  c.e.report(c.sent, kT0 + 11 * kMs + 500'000);  // the next drain brings it
  c.e.report(c.sent, kT0 + 14 * kMs);
  c.e.advance(kT0 + 20 * kMs, kT0 + 20 * kMs);
  CHECK(c.e.take_failures().empty());
  CHECK(c.e.reports().at(0).evaluations == 2);
  // Without the drain's time, the same inputs would pair the second frame with no end yet.
  Chain naive;
  naive.e.report(naive.frame, kT0 + 10 * kMs);
  naive.e.report(naive.frame, kT0 + 12 * kMs);
  naive.e.advance(kT0 + 12 * kMs + kSettle);
  const auto f = naive.e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::DeadlineRestarted);
}

TEST_CASE("Deadline: the latest pairs are kept as spans for traces, failures marked",
          "[health][deadline]") {
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.report(c.sent, kT0 + 13 * kMs);   // ok
  c.e.report(c.frame, kT0 + 20 * kMs);  // missed (no end by 25 ms)
  c.e.report(c.frame, kT0 + 40 * kMs);
  c.e.report(c.frame, kT0 + 42 * kMs);  // restarted
  c.e.report(c.sent, kT0 + 44 * kMs);
  c.e.advance(kT0 + 60 * kMs);
  const auto spans = c.e.deadline_spans("drive");
  REQUIRE(spans.size() == 4);
  CHECK(spans[0].supervision == "sense_to_act");
  CHECK(spans[0].start == "camera.frame");
  CHECK(spans[0].end == "drive.sent");
  CHECK(spans[0].failure == FailureKind::None);
  CHECK(spans[0].end_ns - spans[0].start_ns == 3 * kMs);
  CHECK(spans[1].failure == FailureKind::DeadlineMissed);
  CHECK(spans[1].end_ns == kT0 + 25 * kMs);  // ends at its max
  CHECK(spans[2].failure == FailureKind::DeadlineRestarted);
  CHECK(spans[2].end_ns == kT0 + 42 * kMs);  // ends at the second start
  CHECK(spans[3].failure == FailureKind::None);
  CHECK(c.e.deadline_spans("camera").size() == 4);  // the start's entity too
  CHECK(c.e.deadline_spans("drive", kT0 + 30 * kMs).size() == 2);
  CHECK(c.e.deadline_spans("elsewhere").empty());
  // Bounded: only the latest kKeptSpans.
  for (int i = 0; i < 100; ++i) {
    c.e.report(c.frame, kT0 + (100 + 10 * i) * kMs);
    c.e.report(c.sent, kT0 + (101 + 10 * i) * kMs);
  }
  c.e.advance(kT0 + 2000 * kMs);
  CHECK(c.e.deadline_spans("drive").size() == HealthEngine::kKeptSpans);
}

TEST_CASE("Deadline: inputs are paired in time order whatever their arrival order",
          "[health][deadline]") {
  Chain c;
  // The drive's port is drained before the camera's: its end arrives first.
  c.e.report(c.sent, kT0 + 13 * kMs);
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.advance(kT0 + 30 * kMs);
  CHECK(c.e.take_failures().empty());
  CHECK(c.e.reports()[0].last_duration_ns == 3 * kMs);
}

TEST_CASE("Deadline: too early fails when the end arrives", "[health][deadline]") {
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.report(c.sent, kT0 + 10 * kMs + 500'000);
  c.e.advance(kT0 + 11 * kMs);
  const auto f = c.e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::DeadlineTooEarly);
  CHECK(f[0].fault_ns == kT0 + 10 * kMs + 500'000);
  CHECK(f[0].entity == "drive");
  CHECK(f[0].status == SupervisionStatus::Expired);  // no tolerance: AUTOSAR's deadline
}

TEST_CASE("Deadline: a missing end is found when max passes, not when the end arrives",
          "[health][deadline]") {
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.advance(kT0 + 11 * kMs);
  // The engine asks to be woken just after start + max.
  CHECK(c.e.next_deadline() == kT0 + 15 * kMs + 1 + kSettle);
  c.e.advance(kT0 + 15 * kMs);  // at max: not yet late
  CHECK(c.e.take_failures().empty());
  c.e.advance(c.e.next_deadline());
  const auto f = c.e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::DeadlineMissed);
  CHECK(f[0].fault_ns == kT0 + 15 * kMs);
  CHECK(f[0].latency_ns() == 1 + kSettle);
  CHECK(f[0].text.find("drive.sent") != std::string::npos);
  // The late end is not judged again.
  c.e.report(c.sent, kT0 + 40 * kMs);
  c.e.advance(kT0 + 50 * kMs);
  CHECK(c.e.take_failures().empty());
}

TEST_CASE("Deadline: a second start before the end fails", "[health][deadline]") {
  HealthConfig cfg = deadline_config();
  cfg.deadline[0].failed_tolerance = 5;
  HealthEngine e(cfg);
  const int frame = e.checkpoint("camera", "frame");
  const int sent = e.checkpoint("drive", "sent");
  e.start(kT0);
  e.activate(e.entity("camera"), kT0);
  e.activate(e.entity("drive"), kT0);
  e.report(frame, kT0 + 10 * kMs);
  e.report(frame, kT0 + 12 * kMs);
  e.report(sent, kT0 + 14 * kMs);  // 2 ms after the second start: passes
  e.advance(kT0 + 30 * kMs);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::DeadlineRestarted);
  CHECK(f[0].status == SupervisionStatus::Failed);
  CHECK(f[0].fault_ns == kT0 + 12 * kMs);
  CHECK(e.reports()[0].last_duration_ns == 2 * kMs);
  CHECK(e.status("sense_to_act") == SupervisionStatus::Ok);  // the pair took it back
}

TEST_CASE("Deadline: deactivated while one of its entities is stopped", "[health][deadline]") {
  Chain c;
  c.e.report(c.frame, kT0 + 10 * kMs);
  c.e.deactivate(c.e.entity("drive"), kT0 + 11 * kMs);
  c.e.advance(kT0 + 100 * kMs);
  CHECK(c.e.take_failures().empty());
  CHECK(c.e.status("sense_to_act") == SupervisionStatus::Deactivated);
}

namespace {
HealthConfig logical_config() {
  HealthConfig c;
  c.logical.push_back({.name = "sequence",
                       .initial = {{"drive", "read"}},
                       .final = {{"drive", "write"}},
                       .transitions = {{{"drive", "read"}, {"drive", "compute"}},
                                       {{"drive", "compute"}, {"drive", "write"}},
                                       {{"drive", "compute"}, {"drive", "compute"}}}});
  return c;
}
}  // namespace

TEST_CASE("Logical: sequences along the graph pass", "[health][logical]") {
  HealthEngine e(logical_config());
  const int read = e.checkpoint("drive", "read");
  const int compute = e.checkpoint("drive", "compute");
  const int write = e.checkpoint("drive", "write");
  e.start(kT0);
  Nanos t = kT0;
  for (int i = 0; i < 3; ++i) {
    e.report(read, ++t);
    e.report(compute, ++t);
    e.report(compute, ++t);
    e.report(write, ++t);
  }
  e.advance(kT0 + kMs);
  CHECK(e.take_failures().empty());
  const auto r = e.reports()[0];
  CHECK(r.status == SupervisionStatus::Ok);
  CHECK(r.evaluations == 12);
  CHECK(r.current.empty());  // between two sequences
}

TEST_CASE("Logical: an invalid transition names the checkpoint, the allowed and the last ones",
          "[health][logical]") {
  HealthEngine e(logical_config());
  const int read = e.checkpoint("drive", "read");
  const int compute = e.checkpoint("drive", "compute");
  const int write = e.checkpoint("drive", "write");
  e.start(kT0);
  e.report(read, kT0 + 1);
  e.report(compute, kT0 + 2);
  e.report(write, kT0 + 3);
  e.report(read, kT0 + 4);
  e.report(write, kT0 + 5);  // skips compute
  e.advance(kT0 + kMs);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].failure == FailureKind::InvalidTransition);
  CHECK(f[0].fault_ns == kT0 + 5);
  CHECK(f[0].status == SupervisionStatus::Expired);
  CHECK(f[0].text ==
        "drive.write after drive.read; allowed: drive.compute; last: drive.read -> "
        "drive.compute -> drive.write -> drive.read");
}

TEST_CASE("Logical: a sequence must begin at an initial checkpoint", "[health][logical]") {
  HealthConfig cfg = logical_config();
  cfg.logical[0].failed_tolerance = 3;
  HealthEngine e(cfg);
  e.start(kT0);
  // Judged from the first initial checkpoint after the activation (a sequence may be under
  // way when it starts): this compute is not.
  e.report(e.checkpoint("drive", "compute"), kT0 + 1);
  e.report(e.checkpoint("drive", "read"), kT0 + 2);
  e.report(e.checkpoint("drive", "compute"), kT0 + 3);
  e.report(e.checkpoint("drive", "write"), kT0 + 4);
  e.advance(kT0 + kMs);
  CHECK(e.take_failures().empty());
  e.report(e.checkpoint("drive", "compute"), kT0 + kMs);
  e.advance(kT0 + 2 * kMs);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].status == SupervisionStatus::Failed);
  CHECK(f[0].text ==
        "drive.compute at the start of a sequence; allowed: drive.read; last: drive.compute "
        "-> drive.read -> drive.compute -> drive.write");
}

TEST_CASE("Logical: across entities", "[health][logical]") {
  HealthConfig c;
  c.logical.push_back(
      {.name = "handshake",
       .initial = {{"a", "request"}},
       .final = {{"a", "done"}},
       .transitions = {{{"a", "request"}, {"b", "reply"}}, {{"b", "reply"}, {"a", "done"}}}});
  HealthEngine e(c);
  e.start(kT0);
  e.activate(e.entity("a"), kT0);
  e.activate(e.entity("b"), kT0);
  e.report(e.checkpoint("a", "request"), kT0 + 1);
  e.report(e.checkpoint("a", "done"), kT0 + 3);  // arrives before b's reply, later in time
  e.report(e.checkpoint("b", "reply"), kT0 + 2);
  e.advance(kT0 + kMs);
  CHECK(e.take_failures().empty());
  e.report(e.checkpoint("a", "request"), kT0 + 4);
  e.report(e.checkpoint("a", "done"), kT0 + 5);
  e.advance(kT0 + 2 * kMs);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].entity == "a");
  CHECK(f[0].text.find("allowed: b.reply") != std::string::npos);
}

TEST_CASE("Inputs later than now - settle wait for a later advance", "[health]") {
  HealthEngine e(logical_config());
  e.start(kT0);
  e.report(e.checkpoint("drive", "read"), kT0 + 1);
  e.advance(kT0 + kMs);
  e.report(e.checkpoint("drive", "write"), kT0 + 10 * kMs);  // skips compute
  e.advance(kT0 + 10 * kMs + kSettle - 1);
  CHECK(e.take_failures().empty());
  CHECK(e.next_deadline() == kT0 + 10 * kMs + kSettle);
  e.advance(kT0 + 10 * kMs + kSettle);
  CHECK(e.take_failures().size() == 1);
  CHECK(e.next_deadline() == kNever);
}

TEST_CASE("A bad configuration is refused with a message naming the field", "[health][config]") {
  const auto error = [](const HealthConfig& c) {
    const auto r = validate(c);
    REQUIRE_FALSE(r.has_value());
    return r.error().message;
  };
  HealthConfig c = deadline_config();
  c.deadline[0].min_ns = 6 * kMs;
  CHECK(error(c).find("deadline 'sense_to_act': min_ns") != std::string::npos);
  CHECK_THROWS_AS(HealthEngine(c), std::invalid_argument);
  c = alive_config();
  c.alive[0].reference_cycle_ns = 0;
  CHECK(error(c).find("reference_cycle_ns") != std::string::npos);
  c = alive_config();
  c.alive.push_back(c.alive[0]);
  CHECK(error(c).find("used twice") != std::string::npos);
  c = logical_config();
  c.logical[0].initial.clear();
  CHECK(error(c).find("no initial checkpoint") != std::string::npos);
  c = logical_config();
  c.logical[0].transitions.push_back({{"drive", "orphan"}, {"drive", "write"}});
  CHECK(error(c).find("drive.orphan is unreachable") != std::string::npos);
  c = deadline_config();
  c.deadline[0].end = c.deadline[0].start;
  CHECK(error(c).find("same checkpoint") != std::string::npos);
  CHECK(validate(alive_config()).has_value());
  CHECK(validate(logical_config()).has_value());
}

TEST_CASE("Deadlines of several supervisions are judged in time order among other inputs",
          "[health][deadline]") {
  HealthConfig cfg;
  cfg.deadline.push_back(
      {.name = "slow", .start = {"a", "s"}, .end = {"a", "e"}, .max_ns = 5 * kMs});
  cfg.deadline.push_back({.name = "fast",
                          .start = {"b", "s"},
                          .end = {"b", "e"},
                          .max_ns = 2 * kMs,
                          .failed_tolerance = 100});
  HealthEngine e(cfg);
  e.start(kT0);
  const int as = e.checkpoint("a", "s");
  const int bs = e.checkpoint("b", "s");
  const int be = e.checkpoint("b", "e");
  e.report(as, kT0 + 10 * kMs);  // never ended: missed at +15 ms
  for (int i = 0; i < 20; ++i) {
    e.report(bs, kT0 + 11 * kMs + i * kMs);
    // "fast" pairs of 0.5 and 0.9 ms, all within their max, judged between the "slow" start
    // and its missed deadline.
    e.report(be, kT0 + 11 * kMs + i * kMs + (i % 4 == 3 ? 900'000 : 500'000));
  }
  e.advance(kT0 + 40 * kMs);
  const auto f = e.take_failures();
  REQUIRE(f.size() == 1);
  CHECK(f[0].supervision == "slow");
  CHECK(f[0].fault_ns == kT0 + 15 * kMs);
  CHECK(e.reports()[1].evaluations == 20);
  CHECK(e.status("fast") == SupervisionStatus::Ok);
}
