// The RT side: arguments round-trip exactly through a record; strings are cut at the bound.
#include <fmt/format.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "log_support.hpp"
#include "vigil/log/log.hpp"
#include "vigil/task/state.hpp"

using namespace vigil;
using vigil::test::LogBench;

namespace {

enum class Plain : std::int16_t { A = -3, B = 7 };       // no to_string, no formatter
enum class Gear : std::uint8_t { Park = 0, Drive = 2 };  // ADL to_string
[[maybe_unused]] const char* to_string(Gear g) { return g == Gear::Park ? "park" : "drive"; }
enum Unscoped : unsigned long long { kBig = 0xFFFF'FFFF'FFFFULL };

template <class T>
std::string round_trip(T v) {
  LogBench<> b;
  VIGIL_LOG_INFO("{}", v);
  return b.text();
}

}  // namespace

TEST_CASE("Integers of every width round-trip exactly", "[log][record]") {
  CHECK(round_trip(std::numeric_limits<std::int8_t>::min()) == "-128");
  CHECK(round_trip(std::numeric_limits<std::uint8_t>::max()) == "255");
  CHECK(round_trip(std::numeric_limits<std::int16_t>::min()) == "-32768");
  CHECK(round_trip(std::numeric_limits<std::uint16_t>::max()) == "65535");
  CHECK(round_trip(std::numeric_limits<std::int32_t>::min()) == "-2147483648");
  CHECK(round_trip(std::numeric_limits<std::uint32_t>::max()) == "4294967295");
  CHECK(round_trip(std::numeric_limits<std::int64_t>::min()) == "-9223372036854775808");
  CHECK(round_trip(std::numeric_limits<std::int64_t>::max()) == "9223372036854775807");
  CHECK(round_trip(std::numeric_limits<std::uint64_t>::max()) == "18446744073709551615");
  CHECK(round_trip(static_cast<long long>(-42)) == "-42");
  CHECK(round_trip(static_cast<unsigned short>(42)) == "42");
}

TEST_CASE("Floating point values, bool and char round-trip exactly", "[log][record]") {
  for (const double d : {0.1, -1e300, 5e-324, 2.41, 1.0 / 3.0, -0.0}) {
    CHECK(round_trip(d) == fmt::format("{}", d));
  }
  CHECK(round_trip(std::numeric_limits<double>::infinity()) == "inf");
  CHECK(round_trip(std::nan("")) == "nan");
  CHECK(round_trip(0.1F) == fmt::format("{}", 0.1F));
  CHECK(round_trip(static_cast<long double>(1.0L / 3.0L)) == fmt::format("{}", 1.0L / 3.0L));
  CHECK(round_trip(true) == "true");
  CHECK(round_trip('x') == "x");
  LogBench<> b;
  VIGIL_LOG_INFO("{:.3f} {:>6} {:#x} {:08.2f}", 3.14159, 42, 255U, -2.5);
  CHECK(b.text() == "3.142     42 0xff -0002.50");
}

TEST_CASE("Enums: through to_string, through their number", "[log][record]") {
  CHECK(round_trip(Gear::Drive) == "drive");
  CHECK(round_trip(Plain::A) == "-3");
  CHECK(round_trip(kBig) == std::to_string(0xFFFF'FFFF'FFFFULL));
  CHECK(round_trip(TaskState::Running) == "Running");  // vigil's own enums have to_string
  CHECK(round_trip(log::Level::Warn) == "WARN");
}

TEST_CASE("Strings of every kind are copied up to 32 bytes, the cut marked", "[log][record]") {
  const std::string s32(32, 'a');
  const std::string s33 = std::string(32, 'b') + "c";
  CHECK(round_trip(std::string("short")) == "short");
  CHECK(round_trip(std::string_view("view")) == "view");
  CHECK(round_trip(FixedString<16>("fixed")) == "fixed");
  CHECK(round_trip(static_cast<const char*>("pointer")) == "pointer");
  CHECK(round_trip(static_cast<const char*>(nullptr)) == "(null)");
  CHECK(round_trip(std::string()) == "");
  CHECK(round_trip(s32) == s32);                           // exactly the bound: not cut
  CHECK(round_trip(s33) == std::string(32, 'b') + "...");  // one more: cut and marked
  CHECK(round_trip(s33.c_str()) == std::string(32, 'b') + "...");
  {
    LogBench<> b;
    VIGIL_LOG_INFO("{}|{}", "literal", s33);  // a char array and a std::string in one call
    CHECK(b.text() == "literal|" + std::string(32, 'b') + "...");
  }
  {
    // A 3-byte UTF-8 character across the bound is not split.
    const std::string utf = std::string(31, 'x') + "\xe2\x82\xac" + "tail";  // 31 + euro sign
    CHECK(round_trip(utf) == std::string(31, 'x') + "...");
  }
  {
    char buf[8] = {'a', 'b', 'c', '\0', 'z', 'z', 'z', 'z'};  // a buffer: up to its NUL
    CHECK(round_trip(buf) == "abc");
  }
}

TEST_CASE("Strings share what the numbers leave of the 88 bytes", "[log][record]") {
  const std::string a(40, 'a'), b(40, 'b'), c(40, 'c');
  LogBench<> bench;
  // 3 strings (3 length bytes) and an int64 (8): 88 - 11 = 77 bytes of text: 32 + 32 + 13.
  VIGIL_LOG_INFO("{} {} {} {}", a, b, c, std::int64_t{-7});
  const auto recs = bench.records();
  REQUIRE(recs.size() == 1);
  CHECK(recs[0].size <= log::kPayloadBytes);
  CHECK(LogBench<>::decode(recs[0]) == std::string(32, 'a') + "... " + std::string(32, 'b') +
                                           "... " + std::string(13, 'c') + "... -7");
}

TEST_CASE("Eleven doubles fill a record exactly", "[log][record]") {
  LogBench<> b;
  VIGIL_LOG_INFO("{} {} {} {} {} {} {} {} {} {} {}", 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5, 8.5, 9.5,
                 10.5, 11.5);
  const auto recs = b.records();
  REQUIRE(recs.size() == 1);
  CHECK(recs[0].size == 88);
  CHECK(LogBench<>::decode(recs[0]) == "1.5 2.5 3.5 4.5 5.5 6.5 7.5 8.5 9.5 10.5 11.5");
}

TEST_CASE("Pointers are logged as addresses", "[log][record]") {
  int x = 0;
  CHECK(round_trip(&x) == fmt::format("{}", static_cast<const void*>(&x)));
  CHECK(round_trip(nullptr) == "0x0");
}

TEST_CASE("A record carries its call site, cycle and the cycle's time", "[log][record]") {
  LogBench<> b("site", 17, 123'456'789);
  const int line = __LINE__ + 1;
  VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", 3, 2.41);
  const auto recs = b.records();
  REQUIRE(recs.size() == 1);
  const log::LogRecord& r = recs[0];
  CHECK(r.cycle == 17);
  CHECK(r.time_ns == 123'456'789);
  CHECK(r.dropped == 0);
  REQUIRE(r.site != nullptr);
  CHECK(r.site->level == log::Level::Warn);
  CHECK(r.site->format == "joint {} limit reached: {:.2f} rad");
  CHECK(r.site->line == static_cast<std::uint32_t>(line));
  CHECK(r.site->file.ends_with("record_test.cpp"));
  CHECK(LogBench<>::decode(r) == "joint 3 limit reached: 2.41 rad");
}

TEST_CASE("One static call site per call site, shared by every call", "[log][record]") {
  LogBench<> b;
  for (int i = 0; i < 3; ++i) VIGIL_LOG_INFO("i = {}", i);
  VIGIL_LOG_INFO("i = {}", 9);  // same text, another call site
  const auto recs = b.records();
  REQUIRE(recs.size() == 4);
  CHECK(recs[0].site == recs[1].site);
  CHECK(recs[1].site == recs[2].site);
  CHECK(recs[3].site != recs[0].site);
  CHECK(LogBench<>::decode(recs[2]) == "i = 2");
}

TEST_CASE("LogRecord fits in Message", "[log][record]") {
  STATIC_REQUIRE(sizeof(log::LogRecord) == 120);
  STATIC_REQUIRE(std::is_trivially_copyable_v<log::LogRecord>);
  STATIC_REQUIRE(sizeof(task::Message) <= 128);
}
