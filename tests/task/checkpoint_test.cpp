// Checkpoints on the real-time side: declared when configured, reported from the cycle.
#include <catch2/catch.hpp>
#include <stdexcept>
#include <string>

#include "support/drain.hpp"
#include "support/fake_clock.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/task/instrumentation.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::task;
using vigil::test::drain;
using vigil::test::only;

namespace {

class Stepper : public vigil::Task<Stepper> {
 public:
  Stepper(std::string name, Registry<Message>& reg) : Task(std::move(name), {}, reg) {}
  vigil::test::FakeClock* clock = nullptr;
  CheckpointId read, write;
  CheckpointId foreign;  // an id another component declared, when set
  bool misuse = false;

  bool on_configure() {
    read = declare_checkpoint("read");
    write = declare_checkpoint("write");
    return true;
  }
  void on_update() {
    checkpoint(read);
    clock->advance(100);
    checkpoint(write, cycle().start_ns + 50);  // a time the cycle has: no clock read
    if (misuse) checkpoint(foreign);
  }
};

}  // namespace

TEST_CASE("A task reports declared checkpoints with time, cycle, count and name",
          "[task][checkpoint]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  Stepper s("stepper", reg);
  s.clock = &fc;
  ManualActivity act(s, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(s.configure());
  CHECK(s.read.valid());
  CHECK(s.read.index() == 0);
  CHECK(s.write.index() == 1);
  CHECK(s.declare_checkpoint("read") == s.read);  // the same name: the same id
  REQUIRE(act.start(fc.now()));
  std::vector<Nanos> starts;
  for (int i = 0; i < 3; ++i) {
    fc.set(act.next_release() + 10);
    starts.push_back(fc.now());
    REQUIRE(act.step());
  }
  const auto reports = only<health::CheckpointReport>(drain(*s.port()));
  REQUIRE(reports.size() == 6);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& r = reports[2 * i];
    const auto& w = reports[2 * i + 1];
    CHECK(r.name.view() == "read");
    CHECK(r.index == 0);
    CHECK(r.time_ns == starts[i]);  // the recorder's clock, the activity's fake one
    CHECK(r.cycle == i + 1);
    CHECK(r.count == i + 1);
    CHECK(r.misuses == 0);
    CHECK(w.name.view() == "write");
    CHECK(w.time_ns == starts[i] + 50);
    CHECK(w.count == i + 1);
  }
  CHECK(s.checkpoint_misuses() == 0);
}

TEST_CASE("A checkpoint name must be 1 to 63 bytes, declared before the component runs",
          "[task][checkpoint]") {
  Registry<Message> reg;
  Instrumentation in("x", {}, reg);
  CHECK_THROWS_AS(in.declare_checkpoint(""), std::invalid_argument);
  CHECK_THROWS_AS(in.declare_checkpoint(std::string(64, 'a')), std::invalid_argument);
  const CheckpointId a = in.declare_checkpoint(std::string(63, 'a'));
  CHECK(a.valid());
  in.init();
  CHECK_THROWS_AS(in.declare_checkpoint("late"), std::logic_error);  // while running
  CHECK(in.declare_checkpoint(std::string(63, 'a')) == a);           // known: still answered
}

TEST_CASE("Reporting an id the component did not declare is a counted, reported misuse",
          "[task][checkpoint]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  Instrumentation other("other", {}, reg);
  const CheckpointId theirs = other.declare_checkpoint("theirs");
  Stepper s("stepper", reg);
  s.clock = &fc;
  s.misuse = true;
  ManualActivity act(s, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(s.configure());
  REQUIRE(act.start(fc.now()));
  SECTION("another component's id") { s.foreign = theirs; }
  SECTION("a default-constructed id") { s.foreign = CheckpointId{}; }
  REQUIRE(act.step());
  REQUIRE(act.step());
  CHECK(s.checkpoint_misuses() == 2);
  const auto reports = only<health::CheckpointReport>(drain(*s.port()));
  REQUIRE(reports.size() == 6);
  CHECK(reports[2].index == health::kMisuseIndex);
  CHECK(reports[2].misuses == 1);
  CHECK(reports[5].index == health::kMisuseIndex);
  CHECK(reports[5].misuses == 2);
  CHECK(reports[3].misuses == 1);  // carried by the following reports too
  CHECK(only<health::CheckpointReport>(drain(*other.port())).empty());
}

TEST_CASE("Instrumentation and UpdateGuard users report checkpoints", "[task][checkpoint]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  Instrumentation in("legacy", {}, reg);
  const CheckpointId got = in.declare_checkpoint("frame_received");
  in.init({.activity = "loop", .period_ns = 1000}, fc.clock());
  for (int i = 0; i < 2; ++i) {
    fc.advance(1000);
    UpdateGuard guard(in);
    in.checkpoint(got);
  }
  const auto reports = only<health::CheckpointReport>(drain(*in.port()));
  REQUIRE(reports.size() == 2);
  CHECK(reports[1].name.view() == "frame_received");
  CHECK(reports[1].time_ns == fc.now());
  CHECK(reports[1].cycle == 2);
  CHECK(reports[1].count == 2);
}
