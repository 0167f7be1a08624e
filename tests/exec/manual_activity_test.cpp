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
