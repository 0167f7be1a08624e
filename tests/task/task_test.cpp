#include "vigil/task/task.hpp"

#include <catch2/catch.hpp>
#include <string>

#include "support/drain.hpp"
#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"

using namespace vigil;
using namespace vigil::task;
using vigil::test::drain;
using vigil::test::only;
using vigil::test::Probe;

TEST_CASE("configure sends the component's identity and the transition", "[task][task]") {
  Registry<Message> reg;
  Probe p("motor", {.detectors = Detectors::Allocation}, reg);
  REQUIRE(p.configure());
  const auto ms = drain(*p.port());
  const auto infos = only<TaskInfo>(ms);
  REQUIRE(infos.size() == 1);
  CHECK(infos[0].name == std::string_view("motor"));
  CHECK(infos[0].detectors == Detectors::Allocation);
  CHECK(infos[0].port_capacity == kDefaultPortCapacity);
  CHECK_FALSE(infos[0].threaded);
  const auto changes = only<StateChange>(ms);
  REQUIRE(changes.size() == 1);
  CHECK(changes[0].from == TaskState::PreOperational);
  CHECK(changes[0].to == TaskState::Stopped);
  CHECK(changes[0].hook == Hook::Configure);
  CHECK_FALSE(changes[0].refused);
}

TEST_CASE("Every cycle sends a sample with exact cumulative counters", "[task][task]") {
  Registry<Message> reg;
  vigil::test::FakeClock fc;
  Probe p("motor", {}, reg);
  ManualActivity act(p, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  (void)drain(*p.port());
  for (int i = 0; i < 5; ++i) {
    fc.set(act.next_release() + 10);
    REQUIRE(act.step());
  }
  const auto samples = vigil::test::cycles_of(drain(*p.port()));
  REQUIRE(samples.size() == 5);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    CHECK(samples[i].cycle() == i + 1);
    CHECK(samples[i].cycle() == i + 1);
    CHECK(samples[i].start_ns - samples[i].release_ns == 10);  // wake-up latency
    CHECK(samples[i].execution_ns() == 0);                     // the fake clock stood still
    CHECK_FALSE(samples[i].overrun);
    CHECK(samples[i].state == TaskState::Running);
  }
}

TEST_CASE("An exception in on_update is reported with hook, type and what()", "[task][task]") {
  Registry<Message> reg;
  Probe p("motor", {}, reg);
  p.script.throw_update_at = 3;
  REQUIRE(p.configure());
  REQUIRE(p.start());
  (void)drain(*p.port());
  CHECK(p.update());
  CHECK(p.update());
  CHECK_FALSE(p.update());
  const auto ms = drain(*p.port());
  const auto ex = only<ExceptionReport>(ms);
  REQUIRE(ex.size() == 1);
  CHECK(ex[0].hook == Hook::Update);
  CHECK(ex[0].count == 1);
  CHECK(ex[0].type == std::string_view(typeid(std::out_of_range).name()));
  CHECK(ex[0].message == std::string_view("update failed at cycle 3"));
  const auto samples = vigil::test::cycles_of(ms);
  REQUIRE(samples.size() == 3);
  CHECK(samples[2].state == TaskState::Exception);
  CHECK(samples[2].counters.exceptions == 1);
  const auto changes = only<StateChange>(ms);
  REQUIRE(changes.size() == 1);
  CHECK(changes[0].to == TaskState::Exception);
  CHECK(changes[0].hook == Hook::Update);
}

namespace {
class Validating : public Task<Validating> {
 public:
  explicit Validating(Registry<Message>& r) : Task("validating", {}, r) {}
  bool valid = false;
  void on_update() {}
  vigil::expected<void, std::string> on_configure() {
    if (!valid) return vigil::unexpected(std::string("gain must be positive"));
    return {};
  }
};

class Quiet : public Task<Quiet> {
  friend class vigil::Task<Quiet>;

 public:
  explicit Quiet(Registry<Message>& r) : Task("quiet", {}, r) {}
  int n = 0;

 private:
  void on_update() { ++n; }
};
}  // namespace

TEST_CASE("An optional hook returning vigil::expected refuses with the error as reason",
          "[task][task]") {
  Registry<Message> reg;
  Validating v(reg);
  CHECK_FALSE(v.configure());
  CHECK(v.state() == TaskState::PreOperational);
  const auto changes = only<StateChange>(drain(*v.port()));
  REQUIRE(changes.size() == 1);
  CHECK(changes[0].refused);
  CHECK(changes[0].reason == std::string_view("gain must be positive"));
  v.valid = true;
  CHECK(v.configure());
}

TEST_CASE("Hooks may be private with a friend declaration", "[task][task]") {
  Registry<Message> reg;
  Quiet q(reg);
  REQUIRE(q.configure());
  REQUIRE(q.start());
  CHECK(q.update());
  CHECK(q.n == 1);
}

namespace {
struct TinyPort {
  static constexpr std::size_t port_capacity = 4;
};
}  // namespace

TEST_CASE("A full port drops samples but keeps identity, exceptions and exact counts",
          "[task][task]") {
  Registry<Message> reg;
  vigil::test::BasicProbe<TinyPort> p("tiny", {}, reg);
  p.script.throw_update_at = 50;
  REQUIRE(p.configure());  // TaskInfo + StateChange: 2 of 4 slots
  REQUIRE(p.start());      // TaskInfo + StateChange: full
  for (int i = 0; i < 50; ++i) (void)p.update();
  auto first = drain(*p.port());
  CHECK(first.size() == 4);
  CHECK(p.port()->dropped() == 50);  // the 50 samples; kept messages are not drops
  // The exception report and the state change were kept and go out before the next sample.
  (void)p.recover();
  const auto ms = drain(*p.port());
  const auto ex = only<ExceptionReport>(ms);
  REQUIRE(ex.size() == 1);
  CHECK(ex[0].count == 1);
}

namespace {
// A clock that moves 10 ns at every read: supervision's own reads show as overhead.
Nanos ticking_now(const void* ctx) noexcept {
  auto* t = static_cast<Nanos*>(const_cast<void*>(ctx));
  return *t += 10;
}
}  // namespace

TEST_CASE("A task reads the clock of its run, looked at again when it restarts", "[task][task]") {
  // Supervision looks at the cycle's clock once per run (its first cycle), not every cycle: a
  // task moved to an activity with another clock reads that clock from its next start.
  Registry<Message> reg;
  vigil::test::FakeClock a;
  vigil::test::FakeClock b;
  b.set(5'000'000'000);
  Probe p("motor", {}, reg);
  REQUIRE(p.configure());
  for (auto* fc : {&a, &b, &a}) {
    ManualActivity act(p, {.name = "m", .clock = fc->clock()});
    REQUIRE(act.start());
    for (int i = 0; i < 2; ++i) {
      fc->advance(100);
      REQUIRE(act.step());
    }
    REQUIRE(act.stop());
  }
  // The process's clock, on an activity that passes no Clock: TaskCore::update().
  REQUIRE(p.start());
  const Nanos before = platform::now_ns();
  REQUIRE(p.update());
  const Nanos after = platform::now_ns();
  const auto samples = vigil::test::cycles_of(drain(*p.port()));
  REQUIRE(samples.size() == 7);
  const Nanos expected[] = {1'000'000'100, 1'000'000'200, 5'000'000'100,
                            5'000'000'200, 1'000'000'300, 1'000'000'400};
  for (std::size_t i = 0; i < 6; ++i) {
    INFO("cycle " << samples[i].cycle());
    CHECK(samples[i].start_ns == expected[i]);
    CHECK(samples[i].end_ns == expected[i]);
  }
  CHECK(samples[6].start_ns >= before);
  CHECK(samples[6].end_ns <= after);
}

TEST_CASE("Supervision's overhead is measured on one cycle in N and sent with the next sample",
          "[task][task]") {
  for (const std::uint32_t every : {0U, 1U, 3U, 4U}) {  // any N, not only powers of two
    Registry<Message> reg;
    Nanos t = 1'000;
    Probe p("motor", {.overhead_sample_every = every}, reg);
    ManualActivity act(p, {.name = "m", .clock = Clock{&ticking_now, &t}});
    REQUIRE(p.configure());
    REQUIRE(act.start());
    for (int i = 0; i < 12; ++i) REQUIRE(act.step());
    const auto samples = vigil::test::cycles_of(drain(*p.port()));
    REQUIRE(samples.size() == 12);
    for (std::size_t i = 0; i < samples.size(); ++i) {
      INFO("every " << every << ", sample of cycle " << samples[i].cycle());
      // Cycle k (0-based) is measured when k % every == 0; its sample k + 1 carries it: two
      // reads before on_update and one after, 10 ns apart.
      const bool carries = every != 0 && i >= 1 && (i - 1) % every == 0;
      CHECK(samples[i].overhead_ns == (carries ? 20 : 0));
    }
  }
}
