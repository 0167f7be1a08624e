#include "vigil/monitor/status.hpp"

#include <catch2/catch.hpp>

using vigil::Status;
using vigil::StatusLevel;
using vigil::StatusMessage;

TEST_CASE("Status levels are ordered Ok < Warn < Error < Stale", "[monitor][status]") {
  STATIC_REQUIRE(vigil::worst(StatusLevel::Ok, StatusLevel::Warn) == StatusLevel::Warn);
  STATIC_REQUIRE(vigil::worst(StatusLevel::Error, StatusLevel::Warn) == StatusLevel::Error);
  STATIC_REQUIRE(vigil::worst(StatusLevel::Error, StatusLevel::Stale) == StatusLevel::Stale);
  STATIC_REQUIRE(vigil::worst(StatusLevel::Stale, StatusLevel::Ok) == StatusLevel::Stale);
  // ROS diagnostics' numeric levels.
  STATIC_REQUIRE(static_cast<int>(StatusLevel::Ok) == 0);
  STATIC_REQUIRE(static_cast<int>(StatusLevel::Warn) == 1);
  STATIC_REQUIRE(static_cast<int>(StatusLevel::Error) == 2);
  STATIC_REQUIRE(static_cast<int>(StatusLevel::Stale) == 3);
}

TEST_CASE("Status levels are spelled OK, WARN, ERROR, STALE and parse back", "[monitor][status]") {
  for (auto l : {StatusLevel::Ok, StatusLevel::Warn, StatusLevel::Error, StatusLevel::Stale}) {
    REQUIRE(vigil::parse_status_level(vigil::to_string(l)) == l);
  }
  CHECK(std::string(vigil::to_string(StatusLevel::Stale)) == "STALE");
  CHECK_FALSE(vigil::parse_status_level("ok").has_value());
  CHECK_FALSE(vigil::parse_status_level("").has_value());
}

TEST_CASE("A new status is OK without messages", "[monitor][status]") {
  const Status s;
  CHECK(s.ok());
  CHECK(s.level() == StatusLevel::Ok);
  CHECK(s.messages().empty());
  CHECK(s.summary().empty());
}

TEST_CASE("Merge: the worst level wins, in any order", "[monitor][status]") {
  Status a;
  a.merge(StatusLevel::Error, "e");
  a.merge(StatusLevel::Warn, "w");
  a.merge(StatusLevel::Ok, "");
  CHECK(a.level() == StatusLevel::Error);

  Status b;
  b.merge(StatusLevel::Warn, "w");
  b.merge(StatusLevel::Stale, "s");
  b.merge(StatusLevel::Error, "e");
  CHECK(b.level() == StatusLevel::Stale);
}

TEST_CASE("Merge keeps every non-empty message of every check, in order", "[monitor][status]") {
  Status s;
  s.merge(StatusLevel::Warn, "near overrun");
  s.merge(StatusLevel::Error, "exception");
  s.merge(StatusLevel::Warn, "drops");  // less severe, still kept
  s.merge(StatusLevel::Ok, "info");     // an Ok finding may explain too
  REQUIRE(s.messages().size() == 4);
  CHECK(s.messages()[0] == StatusMessage{StatusLevel::Warn, "near overrun"});
  CHECK(s.messages()[1] == StatusMessage{StatusLevel::Error, "exception"});
  CHECK(s.messages()[2] == StatusMessage{StatusLevel::Warn, "drops"});
  CHECK(s.messages()[3] == StatusMessage{StatusLevel::Ok, "info"});
  CHECK(s.summary() == "near overrun; exception; drops; info");
  CHECK(s.summary(" | ") == "near overrun | exception | drops | info");
}

TEST_CASE("An empty message never swallows another", "[monitor][status]") {
  // ROS 2's DiagnosticStatusWrapper::mergeSummary(ERROR, "") replaces the WARN message with "".
  SECTION("a worse level with an empty message keeps the explanation") {
    Status s;
    s.merge(StatusLevel::Warn, "near overrun");
    s.merge(StatusLevel::Error, "");
    CHECK(s.level() == StatusLevel::Error);
    REQUIRE(s.messages().size() == 1);
    CHECK(s.messages()[0].text == "near overrun");
  }
  SECTION("an equal level with an empty message adds nothing") {
    Status s;
    s.merge(StatusLevel::Warn, "a");
    s.merge(StatusLevel::Warn, "");
    s.merge(StatusLevel::Warn, "b");
    CHECK(s.summary() == "a; b");
  }
  SECTION("an empty message first, then a real one") {
    Status s;
    s.merge(StatusLevel::Error, "");
    s.merge(StatusLevel::Warn, "why");
    CHECK(s.level() == StatusLevel::Error);
    REQUIRE(s.messages().size() == 1);
    CHECK(s.messages()[0] == StatusMessage{StatusLevel::Warn, "why"});
  }
  SECTION("merging an empty status changes nothing") {
    Status s(StatusLevel::Warn, "a");
    s.merge(Status{});
    CHECK(s == Status(StatusLevel::Warn, "a"));
  }
}

TEST_CASE("Merging statuses keeps the worst level and appends the messages", "[monitor][status]") {
  Status a(StatusLevel::Warn, "a");
  Status b(StatusLevel::Stale, "b");
  b.merge(StatusLevel::Ok, "c");
  a.merge(b);
  CHECK(a.level() == StatusLevel::Stale);
  CHECK(a.summary() == "a; b; c");
  CHECK(a.messages()[1].level == StatusLevel::Stale);
}

TEST_CASE("A status built with an empty message has no message", "[monitor][status]") {
  const Status s(StatusLevel::Error);
  CHECK(s.level() == StatusLevel::Error);
  CHECK(s.messages().empty());
}

TEST_CASE("clear() returns to OK without messages", "[monitor][status]") {
  Status s(StatusLevel::Error, "x");
  s.clear();
  CHECK(s == Status{});
}
