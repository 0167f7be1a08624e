#include "vigil/exec/schedule.hpp"

#include <catch2/catch.hpp>

using namespace vigil;

TEST_CASE("Without overrun the schedule advances by one period", "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::Skip);
  s.start(1000);
  const auto o = s.advance(1050);
  CHECK_FALSE(o.overrun);
  CHECK(o.missed == 0);
  CHECK(s.release() == 1100);
  CHECK_FALSE(s.advance(1200).overrun);  // ending exactly at the next release is on time
  CHECK(s.release() == 1200);
}

TEST_CASE("Skip jumps to the first release at or after the end and counts the skipped ones",
          "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::Skip);
  s.start(1000);
  auto o = s.advance(1150);  // releases 1100 passed
  CHECK(o.overrun);
  CHECK(o.missed == 1);
  CHECK(s.release() == 1200);
  o = s.advance(1500);  // ends exactly on 1500: 1300, 1400 missed, 1500 runs now
  CHECK(o.overrun);
  CHECK(o.missed == 2);
  CHECK(s.release() == 1500);
  CHECK(s.overruns() == 2);
  CHECK(s.missed() == 3);
}

TEST_CASE("CatchUp runs every release, late, and misses none", "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::CatchUp);
  s.start(1000);
  auto o = s.advance(1350);
  CHECK(o.overrun);
  CHECK(o.missed == 0);
  CHECK(s.release() == 1100);
  CHECK(s.advance(1360).overrun);  // 1100's cycle ends after 1200
  CHECK(s.release() == 1200);
  CHECK(s.advance(1370).overrun);
  CHECK_FALSE(s.advance(1380).overrun);  // 1300's cycle ends before 1400: caught up
  CHECK(s.release() == 1400);
  CHECK(s.missed() == 0);
}

TEST_CASE("Reanchor restarts the schedule from the late end", "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::Reanchor);
  s.start(1000);
  const auto o = s.advance(1250);
  CHECK(o.overrun);
  CHECK(o.missed == 2);  // 1100 and 1200 passed
  CHECK(s.release() == 1350);
}

TEST_CASE("The overrun limit fires at N overruns within M cycles", "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::CatchUp, {.max_overruns = 3, .window_cycles = 5});
  s.start(0);
  auto step = [&](bool late) {
    const Nanos r = s.release();
    return s.advance(late ? r + 150 : r + 50);
  };
  CHECK_FALSE(step(true).limit_reached);
  CHECK_FALSE(step(false).limit_reached);
  CHECK_FALSE(step(true).limit_reached);
  CHECK_FALSE(step(false).limit_reached);
  CHECK_FALSE(step(false).limit_reached);
  CHECK_FALSE(step(true).limit_reached);  // the first overrun left the window
  CHECK(step(true).limit_reached);        // cycles 3, 6, 7 within 5 cycles
}

TEST_CASE("advance_on_time takes only the on-time cycle of a schedule without a limit",
          "[exec][schedule]") {
  Schedule s(100, OverrunPolicy::Skip);
  s.start(1000);
  CHECK(s.advance_on_time(1100));  // ending exactly at the next release is on time
  CHECK(s.release() == 1100);
  CHECK_FALSE(s.advance_on_time(1250));  // late: nothing changes, advance() decides
  CHECK(s.release() == 1100);
  CHECK(s.overruns() == 0);
  const auto o = s.advance(1250);
  CHECK(o.overrun);
  CHECK(o.missed == 1);
  CHECK(s.release() == 1300);

  // With an overrun limit every cycle goes through advance(), which keeps the window.
  Schedule limited(100, OverrunPolicy::CatchUp, {.max_overruns = 2, .window_cycles = 4});
  limited.start(0);
  CHECK_FALSE(limited.advance_on_time(50));
  CHECK(limited.release() == 0);
}
