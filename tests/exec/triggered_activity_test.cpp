#include "vigil/exec/triggered_activity.hpp"

#include <catch2/catch.hpp>
#include <thread>

#include "support/drain.hpp"
#include "support/probe.hpp"

using namespace vigil;
using vigil::test::drain;
using vigil::test::only;

TEST_CASE("TriggeredActivity runs one cycle per trigger when triggers are spaced",
          "[exec][triggered]") {
  Registry<task::Message> reg;
  vigil::test::Probe p("t", {}, reg);
  TriggeredActivity act(p, {.name = "trig"});
  REQUIRE(p.configure());
  REQUIRE(act.start().has_value());
  for (int i = 1; i <= 20; ++i) {
    act.trigger();
    const auto deadline = platform::now_ns() + 5 * kNanosPerSecond;
    while (act.cycles() < static_cast<std::uint64_t>(i) && platform::now_ns() < deadline) {
      std::this_thread::yield();
    }
  }
  act.stop();
  CHECK(act.cycles() == 20);
  CHECK(p.updates == 20);
  CHECK(p.state() == TaskState::Stopped);
  const auto samples = vigil::test::cycles_of(drain(*p.port()));
  REQUIRE(samples.size() == 20);
  for (const auto& s : samples) CHECK(s.start_ns >= s.release_ns);  // released by the trigger
}

TEST_CASE("Triggers that arrive during a cycle are coalesced, never lost", "[exec][triggered]") {
  Registry<task::Message> reg;
  vigil::test::Probe p("t", {}, reg);
  p.work = [] { std::this_thread::sleep_for(std::chrono::milliseconds(2)); };
  TriggeredActivity act(p, {.name = "trig"});
  REQUIRE(p.configure());
  REQUIRE(act.start().has_value());
  for (int i = 0; i < 50; ++i) act.trigger();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const auto n = act.cycles();
  act.stop();
  CHECK(n >= 1);
  CHECK(n <= 50);
  // The last trigger is always served: after the burst the task ran at least once more.
  CHECK(p.updates == n);
}
