// Levels at run time (per component, reloadable), drops, and calls outside a cycle.
#include <catch2/catch.hpp>
#include <thread>

#include "log_support.hpp"
#include "vigil/log/log.hpp"

using namespace vigil;
using vigil::test::LogBench;

namespace {
int evaluated = 0;
int count_evaluation() { return ++evaluated; }
}  // namespace

TEST_CASE("The run-time level filters per component, before the arguments are evaluated",
          "[log][level]") {
  LogBench<> motor("level_motor");
  CHECK(motor.source.level() == log::Level::Info);  // the default
  evaluated = 0;
  VIGIL_LOG_DEBUG("debug {}", count_evaluation());
  CHECK(evaluated == 0);
  CHECK(motor.records().empty());
  VIGIL_LOG_INFO("info {}", count_evaluation());
  CHECK(evaluated == 1);
  CHECK(motor.records().size() == 1);

  log::set_level("level_motor", log::Level::Warn);
  CHECK(motor.source.level() == log::Level::Warn);
  VIGIL_LOG_INFO("info {}", count_evaluation());
  VIGIL_LOG_WARN("warn {}", count_evaluation());
  VIGIL_LOG_ERROR("error {}", count_evaluation());
  CHECK(evaluated == 3);
  const auto recs = motor.records();
  REQUIRE(recs.size() == 2);
  CHECK(recs[0].site->level == log::Level::Warn);
  CHECK(recs[1].site->level == log::Level::Error);

  log::set_level("level_motor", log::Level::Debug);
  VIGIL_LOG_DEBUG("debug");
  CHECK(motor.records().size() == 1);
  log::set_level("level_motor", log::Level::Off);
  VIGIL_LOG_ERROR("error");
  CHECK(motor.records().empty());
  log::reset_level("level_motor");
  CHECK(motor.source.level() == log::Level::Info);
}

TEST_CASE("A level set by name applies to components created later, and only to them",
          "[log][level]") {
  log::set_level("level_later", log::Level::Error);
  LogBench<> later("level_later");
  LogBench<> other("level_other");
  CHECK(later.source.level() == log::Level::Error);
  CHECK(other.source.level() == log::Level::Info);
  CHECK(log::level_of("level_later") == log::Level::Error);
  log::reset_level("level_later");
  CHECK(later.source.level() == log::Level::Info);
}

TEST_CASE("The default level applies to components without their own", "[log][level]") {
  LogBench<> a("level_default_a");
  log::set_level("level_default_b", log::Level::Debug);
  LogBench<> b("level_default_b");
  log::set_default_level(log::Level::Error);
  CHECK(a.source.level() == log::Level::Error);
  CHECK(b.source.level() == log::Level::Debug);
  log::set_default_level(log::Level::Info);
  CHECK(a.source.level() == log::Level::Info);
  log::reset_level("level_default_b");
}

TEST_CASE("The level can be changed from another thread while the component logs", "[log][level]") {
  LogBench<1024> c("level_threads");
  std::thread t([] { log::set_level("level_threads", log::Level::Error); });
  t.join();
  VIGIL_LOG_WARN("filtered now");
  CHECK(c.records().empty());
  log::reset_level("level_threads");
}

TEST_CASE("Parsing levels", "[log][level]") {
  CHECK(log::parse_level("debug") == log::Level::Debug);
  CHECK(log::parse_level("INFO") == log::Level::Info);
  CHECK(log::parse_level("Warning") == log::Level::Warn);
  CHECK(log::parse_level("error") == log::Level::Error);
  CHECK(log::parse_level("off") == log::Level::Off);
  CHECK_FALSE(log::parse_level("verbose").has_value());
  CHECK(std::string(log::to_string(log::Level::Warn)) == "WARN");
}

TEST_CASE("A full port drops records and counts them per component", "[log][drops]") {
  LogBench<4> c("drops_small");
  for (int i = 0; i < 10; ++i) VIGIL_LOG_INFO("line {}", i);
  CHECK(c.source.dropped() == 6);
  CHECK(c.source.pushed() == 4);
  CHECK(c.port.dropped() == 6);  // the port's counter too, as for every dropped message
  CHECK(log::dropped("drops_small") == 6);
  auto first = c.records();
  REQUIRE(first.size() == 4);
  CHECK(LogBench<4>::decode(first[3]) == "line 3");
  CHECK(first[3].dropped == 0);
  VIGIL_LOG_INFO("after");
  const auto next = c.records();
  REQUIRE(next.size() == 1);
  CHECK(next[0].dropped == 6);  // the next record tells the supervisor what was lost
}

TEST_CASE("Outside a supervised cycle a call is counted and dropped", "[log][drops]") {
  const auto before = log::unattributed();
  CHECK(log::current() == nullptr);
  VIGIL_LOG_ERROR("nobody to attribute this to: {}", 1);
  CHECK(log::unattributed() == before + 1);
  {
    LogBench<> c("unattributed");
    CHECK(log::current() == &c.source);
    VIGIL_LOG_ERROR("attributed");
    CHECK(c.records().size() == 1);
  }
  CHECK(log::current() == nullptr);
}

TEST_CASE("Nested cycles restore the outer source", "[log][level]") {
  LogBench<> outer("nest_outer", 5);
  {
    LogBench<> inner("nest_inner", 9);
    VIGIL_LOG_INFO("inner");
    const auto r = inner.records();
    REQUIRE(r.size() == 1);
    CHECK(r[0].cycle == 9);
  }
  VIGIL_LOG_INFO("outer");
  const auto r = outer.records();
  REQUIRE(r.size() == 1);
  CHECK(r[0].cycle == 5);
}
