#include "vigil/task/messages.hpp"

#include <catch2/catch.hpp>
#include <type_traits>

using namespace vigil;
using namespace vigil::task;

TEST_CASE("Every message type is trivially copyable and Message stays small", "[task][messages]") {
  STATIC_REQUIRE(std::is_trivially_copyable_v<TaskInfo>);
  STATIC_REQUIRE(std::is_trivially_copyable_v<CycleSample>);
  STATIC_REQUIRE(std::is_trivially_copyable_v<RealTimeLoss>);
  STATIC_REQUIRE(std::is_trivially_copyable_v<ExceptionReport>);
  STATIC_REQUIRE(std::is_trivially_copyable_v<StateChange>);
  STATIC_REQUIRE(std::is_trivially_copyable_v<Message>);
  STATIC_REQUIRE(sizeof(Message) <= 256);
}

TEST_CASE("CycleSample user time is end minus start", "[task][messages]") {
  CycleSample s;
  s.start_ns = 100;
  s.end_ns = 350;
  CHECK(s.execution_ns() == 250);
}

TEST_CASE("Detectors combine as a bit mask", "[task][messages]") {
  const auto d = Detectors::Allocation | Detectors::Blocking;
  CHECK(has(d, Detectors::Allocation));
  CHECK(has(d, Detectors::Blocking));
  CHECK_FALSE(has(d, Detectors::PageFaults));
  CHECK(has(Detectors::All, Detectors::ModeSwitch));
  CHECK_FALSE(has(Detectors::None, Detectors::Allocation));
}
