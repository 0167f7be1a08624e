#include "vigil/exec/manual_activity.hpp"

#include <catch2/catch.hpp>

#include "support/drain.hpp"
#include "support/fake_clock.hpp"
#include "support/probe.hpp"

using namespace vigil;
using vigil::test::drain;
using vigil::test::only;

TEST_CASE("ManualActivity counts overruns and missed cycles exactly (Skip)", "[exec][manual]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {}, reg);
  Nanos work = 100;
  p.work = [&] { fc.advance(work); };
  ManualActivity act(p, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  (void)drain(*p.port());
  int overruns = 0;
  std::uint64_t missed = 0;
  for (int i = 1; i <= 100; ++i) {
    fc.set(act.next_release());
    work = i % 10 == 0 ? 2500 : 100;  // every 10th cycle takes 2.5 periods
    REQUIRE(act.step());
    if (i % 10 == 0) {
      ++overruns;
      missed += 2;
    }
  }
  const auto samples = vigil::test::cycles_of(drain(*p.port()));
  REQUIRE(samples.size() == 100);
  CHECK(samples.back().counters.overruns == static_cast<std::uint64_t>(overruns));
  CHECK(samples.back().counters.missed_cycles ==
        missed - 2);  // the last 2 are carried to cycle 101
  CHECK(act.schedule().missed() == missed);
  for (const auto& s : samples) CHECK(s.overrun == (s.cycle() % 10 == 0));
}

TEST_CASE("ManualActivity CatchUp runs late cycles back to back", "[exec][manual]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {}, reg);
  ManualActivity act(p, {.name = "m",
                         .period_ns = 1000,
                         .overrun_policy = OverrunPolicy::CatchUp,
                         .clock = fc.clock()});
  REQUIRE(p.configure());
  const Nanos t0 = fc.now();
  REQUIRE(act.start(t0));
  p.work = [&] { fc.advance(3500); };
  REQUIRE(act.step());  // ends at +3500: releases +1000, +2000, +3000 are behind
  p.work = [&] { fc.advance(10); };
  for (Nanos expected : {1000, 2000, 3000}) {
    CHECK(act.next_release() == t0 + expected);
    REQUIRE(act.step());
  }
  CHECK(act.next_release() == t0 + 4000);
  const auto samples = vigil::test::cycles_of(drain(*p.port()));
  CHECK(samples.back().counters.missed_cycles == 0);
  CHECK(samples[1].start_ns - samples[1].release_ns == 2500);  // late, not skipped
}

TEST_CASE("The overrun limit moves the task to Exception with a report", "[exec][manual]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {}, reg);
  p.work = [&] { fc.advance(1500); };
  ManualActivity act(p, {.name = "m",
                         .period_ns = 1000,
                         .overrun_limit = {.max_overruns = 3, .window_cycles = 10},
                         .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  for (int i = 0; i < 3; ++i) {
    fc.set(act.next_release());
    act.step();
  }
  CHECK(p.state() == TaskState::Exception);
  const auto ex = only<task::ExceptionReport>(drain(*p.port()));
  REQUIRE(ex.size() == 1);
  CHECK(ex[0].type == std::string_view("vigil::OverrunLimit"));
}

namespace {
// Runs 40 cycles of a probe on activity type A with a fake clock: every 10th cycle overruns,
// cycle 35 throws. Returns everything the port received.
template <template <class> class A>
std::vector<task::Message> scripted_run() {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {.overhead_sample_every = 4}, reg);
  p.script.throw_update_at = 35;
  Nanos work = 100;
  p.work = [&] { fc.advance(work); };
  A<vigil::test::Probe> act(p, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  for (int i = 1; i <= 40; ++i) {
    fc.set(act.next_release() + 7);
    work = i % 10 == 0 ? 2500 : 100;
    CHECK(act.step() == (i < 35));
  }
  CHECK(p.state() == TaskState::Exception);
  return drain(*p.port());
}
template <class T>
using Erased = ManualActivity;
}  // namespace

TEST_CASE("TypedManualActivity sends what ManualActivity sends, message by message",
          "[exec][manual]") {
  const auto erased = scripted_run<Erased>();
  const auto typed = scripted_run<TypedManualActivity>();
  REQUIRE(typed.size() == erased.size());
  REQUIRE(vigil::test::cycles_of(typed).size() == 35);
  REQUIRE(only<task::ExceptionReport>(typed).size() == 1);
  for (std::size_t i = 0; i < typed.size(); ++i) {
    INFO("message " << i);
    REQUIRE(typed[i].index() == erased[i].index());
    if (const auto* a = std::get_if<task::CycleSample>(&typed[i])) {
      const auto& b = std::get<task::CycleSample>(erased[i]);
      CHECK(a->cycle() == b.cycle());
      CHECK(a->release_ns == b.release_ns);
      CHECK(a->start_ns == b.start_ns);
      CHECK(a->end_ns == b.end_ns);
      CHECK(a->overhead_ns == b.overhead_ns);
      CHECK(a->overrun == b.overrun);
      CHECK(a->missed_before == b.missed_before);
      CHECK(a->state == b.state);
      CHECK(a->counters.overruns == b.counters.overruns);
      CHECK(a->counters.missed_cycles == b.counters.missed_cycles);
      CHECK(a->counters.exceptions == b.counters.exceptions);
    }
  }
}

namespace {
class Bare : public TaskCore {
 public:
  Bare() : TaskCore("bare") {}
  int updates = 0;
  Nanos release = 0;

 protected:
  void update_hook() override {
    ++updates;
    release = cycle().release_ns;
  }
};
}  // namespace

TEST_CASE("TypedManualActivity steps a plain TaskCore through its virtual hook", "[exec][manual]") {
  vigil::test::FakeClock fc;
  Bare task;
  TypedManualActivity act(task, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(task.configure());
  REQUIRE(act.start(fc.now()));
  for (int i = 0; i < 3; ++i) {
    fc.set(act.next_release());
    REQUIRE(act.step());
  }
  CHECK(task.updates == 3);
  CHECK(task.release == fc.now());  // cycle() was the activity's context
  CHECK(&act.task() == &task);
  REQUIRE(act.stop());
  CHECK_FALSE(act.step());
  CHECK(task.updates == 3);
}
