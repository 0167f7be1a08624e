#include "vigil/task/task_core.hpp"

#include <catch2/catch.hpp>
#include <stdexcept>

#include "support/probe.hpp"

using namespace vigil;
using namespace vigil::task;
using vigil::test::Probe;

TEST_CASE("Every legal transition of the lifecycle, with hooks checking their state",
          "[task][state]") {
  Registry<Message> reg;
  Probe p("probe", {}, reg);
  CHECK(p.state() == TaskState::PreOperational);
  CHECK(p.configure());
  CHECK(p.state() == TaskState::Stopped);
  CHECK(p.configure());  // reconfigure from Stopped
  CHECK(p.state() == TaskState::Stopped);
  CHECK(p.start());
  CHECK(p.state() == TaskState::Running);
  CHECK(p.update());
  CHECK(p.updates == 1);
  CHECK(p.stop());
  CHECK(p.state() == TaskState::Stopped);
  CHECK(p.cleanup());
  CHECK(p.state() == TaskState::PreOperational);
  CHECK(p.configures == 2);
  CHECK(p.starts == 1);
  CHECK(p.stops == 1);
  CHECK(p.cleanups == 1);
  CHECK(p.state_errors.empty());
}

TEST_CASE("Illegal commands do nothing and return false", "[task][state]") {
  Registry<Message> reg;
  Probe p("probe", {}, reg);
  // From PreOperational.
  CHECK_FALSE(p.start());
  CHECK_FALSE(p.update());
  CHECK_FALSE(p.stop());
  CHECK_FALSE(p.cleanup());
  CHECK_FALSE(p.recover());
  CHECK(p.state() == TaskState::PreOperational);
  // From Stopped.
  REQUIRE(p.configure());
  CHECK_FALSE(p.update());
  CHECK_FALSE(p.stop());
  CHECK_FALSE(p.recover());
  CHECK(p.state() == TaskState::Stopped);
  // From Running.
  REQUIRE(p.start());
  CHECK_FALSE(p.configure());
  CHECK_FALSE(p.start());
  CHECK_FALSE(p.cleanup());
  CHECK_FALSE(p.recover());
  CHECK(p.state() == TaskState::Running);
  CHECK(p.configures == 1);
  CHECK(p.starts == 1);
  CHECK(p.updates == 0);
  CHECK(p.state_errors.empty());
}

TEST_CASE("A hook returning false refuses its transition", "[task][state]") {
  Registry<Message> reg;
  Probe p("probe", {}, reg);
  SECTION("configure") {
    p.script.refuse_configure = true;
    CHECK_FALSE(p.configure());
    CHECK(p.state() == TaskState::PreOperational);
  }
  SECTION("configure from Stopped goes back to PreOperational") {
    REQUIRE(p.configure());
    p.script.refuse_configure = true;
    CHECK_FALSE(p.configure());
    CHECK(p.state() == TaskState::PreOperational);
  }
  SECTION("start") {
    REQUIRE(p.configure());
    p.script.refuse_start = true;
    CHECK_FALSE(p.start());
    CHECK(p.state() == TaskState::Stopped);
  }
  SECTION("stop") {
    REQUIRE(p.configure());
    REQUIRE(p.start());
    p.script.refuse_stop = true;
    CHECK_FALSE(p.stop());
    CHECK(p.state() == TaskState::Running);
  }
  SECTION("cleanup") {
    REQUIRE(p.configure());
    p.script.refuse_cleanup = true;
    CHECK_FALSE(p.cleanup());
    CHECK(p.state() == TaskState::Stopped);
  }
  CHECK(p.state_errors.empty());
}

TEST_CASE("An exception in any hook moves the task to Exception, recover leaves it",
          "[task][state]") {
  Registry<Message> reg;
  Probe p("probe", {}, reg);
  SECTION("configure") {
    p.script.throw_configure = true;
    CHECK_FALSE(p.configure());
  }
  SECTION("start") {
    REQUIRE(p.configure());
    p.script.throw_start = true;
    CHECK_FALSE(p.start());
  }
  SECTION("update") {
    REQUIRE(p.configure());
    REQUIRE(p.start());
    p.script.throw_update_at = 2;
    CHECK(p.update());
    CHECK_FALSE(p.update());
    CHECK_FALSE(p.update());  // not run again
    CHECK(p.updates == 2);
  }
  SECTION("stop") {
    REQUIRE(p.configure());
    REQUIRE(p.start());
    p.script.throw_stop = true;
    CHECK_FALSE(p.stop());
  }
  SECTION("cleanup") {
    REQUIRE(p.configure());
    p.script.throw_cleanup = true;
    CHECK_FALSE(p.cleanup());
  }
  CHECK(p.state() == TaskState::Exception);
  CHECK_FALSE(p.start());
  CHECK_FALSE(p.configure());
  CHECK(p.recover());
  CHECK(p.state() == TaskState::PreOperational);
  p.script = {};
  CHECK(p.configure());
  CHECK(p.start());
  CHECK(p.update());
  CHECK(p.state_errors.empty());
}

TEST_CASE("FatalError is final", "[task][state]") {
  Registry<Message> reg;
  Probe p("probe", {}, reg);
  REQUIRE(p.configure());
  p.fatal("broken hardware");
  CHECK(p.state() == TaskState::FatalError);
  CHECK_FALSE(p.configure());
  CHECK_FALSE(p.start());
  CHECK_FALSE(p.recover());
  CHECK_FALSE(p.cleanup());
  CHECK(p.state() == TaskState::FatalError);
}

namespace {
// A plain TaskCore subclass (no supervision): TaskCore itself catches its hooks' exceptions.
class Plain : public TaskCore {
 public:
  Plain() : TaskCore("plain") {}
  bool throw_now = false;
  int updates = 0;

 protected:
  void update_hook() override {
    ++updates;
    if (throw_now) throw std::runtime_error("plain failure");
  }
  void on_exception(Hook, std::string_view, std::string_view what) noexcept override {
    last_what = std::string(what);
  }

 public:
  std::string last_what;
};
}  // namespace

TEST_CASE("TaskCore catches exceptions of plain subclasses too", "[task][state]") {
  Plain p;
  REQUIRE(p.configure());
  REQUIRE(p.start());
  CHECK(p.update());
  p.throw_now = true;
  CHECK_FALSE(p.update());
  CHECK(p.state() == TaskState::Exception);
  CHECK(p.last_what == "plain failure");
}
