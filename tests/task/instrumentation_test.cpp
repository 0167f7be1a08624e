#include "vigil/task/instrumentation.hpp"

#include <catch2/catch.hpp>
#include <stdexcept>

#include "support/drain.hpp"
#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"

using namespace vigil;
using namespace vigil::task;
using vigil::test::drain;
using vigil::test::only;

TEST_CASE("Instrumentation produces the same samples as Task<Derived>", "[task][instrumentation]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  constexpr Nanos kPeriod = 1000;
  // Front end 1: Task<Derived> on a manual activity.
  vigil::test::Probe task("task", {}, reg);
  task.work = [&] { fc.advance(300); };
  ManualActivity act(task, {.name = "m", .period_ns = kPeriod, .clock = fc.clock()});
  REQUIRE(task.configure());
  REQUIRE(act.start(fc.now()));
  std::vector<Nanos> releases;
  for (int i = 0; i < 10; ++i) {
    releases.push_back(act.next_release());
    fc.set(act.next_release() + 7 * i);
    REQUIRE(act.step());
  }
  // Front end 2: Instrumentation with the same clock, releases and work.
  Instrumentation sup("manual", {}, reg);
  sup.init({.activity = "m", .period_ns = kPeriod}, fc.clock());
  for (int i = 0; i < 10; ++i) {
    fc.set(releases[static_cast<std::size_t>(i)] + 7 * i);
    UpdateGuard guard(sup, releases[static_cast<std::size_t>(i)]);
    fc.advance(300);
  }
  const auto a = vigil::test::cycles_of(drain(*task.port()));
  const auto b = vigil::test::cycles_of(drain(*sup.port()));
  REQUIRE(a.size() == 10);
  REQUIRE(b.size() == 10);
  for (std::size_t i = 0; i < a.size(); ++i) {
    CHECK(a[i].cycle() == b[i].cycle());
    CHECK(a[i].release_ns == b[i].release_ns);
    CHECK(a[i].start_ns == b[i].start_ns);
    CHECK(a[i].end_ns == b[i].end_ns);
    CHECK(a[i].execution_ns() == 300);
    CHECK(a[i].overrun == b[i].overrun);

    CHECK(a[i].counters.overruns == b[i].counters.overruns);
  }
}

TEST_CASE("Missed releases given to pre_update are in that cycle's sample only",
          "[task][instrumentation]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  Instrumentation sup("manual", {}, reg);
  sup.init({.activity = "m", .period_ns = 1000}, fc.clock());
  const std::uint32_t missed[] = {0, 3, 0, 0, 2, 2, 0};
  for (const std::uint32_t m : missed) {
    sup.pre_update(fc.now(), m);
    fc.advance(100);
    sup.post_update();
  }
  const auto samples = vigil::test::cycles_of(drain(*sup.port()));
  REQUIRE(samples.size() == std::size(missed));
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    INFO("cycle " << samples[i].cycle());
    total += missed[i];
    CHECK(samples[i].missed_before == missed[i]);
    CHECK(samples[i].counters.missed_cycles == total);
  }
}

TEST_CASE("Instrumentation reads its thread's identity in init", "[task][instrumentation]") {
  Registry<Message> reg;
  Instrumentation sup("legacy", {}, reg);
  sup.init(
      {.activity = "vendor-loop", .period_ns = 2'000'000, .requested_policy = SchedPolicy::Fifo});
  const auto ms = drain(*sup.port());
  const auto info = only<TaskInfo>(ms);
  REQUIRE(info.size() == 1);
  CHECK(info[0].name == std::string_view("legacy"));
  CHECK(info[0].activity == std::string_view("vendor-loop"));
  CHECK(info[0].tid == platform::current_tid());
  CHECK(info[0].period_ns == 2'000'000);
  CHECK(info[0].policy == SchedPolicy::Other);  // the test thread is not real-time
  CHECK(info[0].realtime_refused);
  CHECK(sup.state() == TaskState::Running);
}

TEST_CASE("Instrumentation::run catches and reports exceptions exactly",
          "[task][instrumentation]") {
  Registry<Message> reg;
  Instrumentation sup("legacy", {}, reg);
  sup.init();
  (void)drain(*sup.port());
  CHECK(sup.run([] {}));
  CHECK_FALSE(sup.run([] { throw std::invalid_argument("bad setpoint"); }));
  CHECK(sup.state() == TaskState::Exception);
  const auto ms = drain(*sup.port());
  const auto ex = only<ExceptionReport>(ms);
  REQUIRE(ex.size() == 1);
  CHECK(ex[0].message == std::string_view("bad setpoint"));
  CHECK(vigil::test::cycles_of(ms).back().counters.exceptions == 1);
  sup.recover();
  CHECK(sup.state() == TaskState::Running);
}

TEST_CASE("An exception leaving an UpdateGuard is counted", "[task][instrumentation]") {
  Registry<Message> reg;
  Instrumentation sup("legacy", {}, reg);
  sup.init();
  (void)drain(*sup.port());
  try {
    UpdateGuard g(sup);
    throw std::runtime_error("escaped");
  } catch (const std::exception&) {
  }
  const auto ms = drain(*sup.port());
  REQUIRE(only<ExceptionReport>(ms).size() == 1);
  REQUIRE(vigil::test::cycles_of(ms).size() == 1);
  CHECK(vigil::test::cycles_of(ms)[0].counters.exceptions == 1);
}
