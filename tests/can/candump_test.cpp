#include "vigil/can/log/candump.hpp"

#include <catch2/catch.hpp>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "support/line_generator.hpp"
#include "support/mutated_lines.hpp"
#include "support/shared_data.hpp"
#include "vigil/platform/rt_loss.hpp"

using vigil::can::CandumpReader;
using vigil::can::Direction;
using vigil::can::Frame;
using vigil::can::LogEntry;
using vigil::can::OnMalformed;
using vigil::can::ParseError;
using vigil::can::ReaderOptions;

namespace {

struct ReadResult {
  std::vector<LogEntry> entries;
  std::vector<std::string> interfaces;
  std::uint64_t malformed = 0;
  std::vector<ParseError> errors;
};

ReadResult read_text(const std::string& text, ReaderOptions options = {}) {
  std::istringstream in(text);
  CandumpReader reader(in, "t.log", std::move(options));
  ReadResult r;
  for (;;) {
    auto e = reader.next();
    REQUIRE(e.has_value());
    if (!*e) break;
    r.entries.push_back(**e);
  }
  r.interfaces = reader.interfaces();
  r.malformed = reader.malformed_count();
  r.errors = reader.errors();
  return r;
}

// Reads one good line then `line`: returns the error reported for line 2.
ParseError error_of(const std::string& line) {
  const ReadResult r = read_text("(1.000000) can0 123#11\n" + line + "\n");
  REQUIRE(r.entries.size() == 1);
  REQUIRE(r.malformed == 1);
  REQUIRE(r.errors.size() == 1);
  CHECK(r.errors[0].source == "t.log");
  CHECK(r.errors[0].line == 2);
  return r.errors[0];
}

Frame frame_of(const std::string& frame_text) {
  const ReadResult r = read_text("(1.000000) can0 " + frame_text + "\n");
  INFO(frame_text);
  REQUIRE(r.malformed == 0);
  REQUIRE(r.entries.size() == 1);
  return r.entries[0].frame;
}

char* put_padded(char* p, std::uint64_t v, int width) {
  char tmp[24];
  auto [end, ec] = std::to_chars(tmp, tmp + sizeof tmp, v);
  (void)ec;
  for (auto n = static_cast<int>(end - tmp); n < width; ++n) *p++ = '0';
  for (char* q = tmp; q != end; ++q) *p++ = *q;
  return p;
}

char* put_hex(char* p, std::uint64_t v, int digits) {
  constexpr char kHex[] = "0123456789ABCDEF";
  for (int i = digits - 1; i >= 0; --i) *p++ = kHex[(v >> (4 * i)) & 0xF];
  return p;
}

constexpr std::uint64_t kBaseUs = 1'700'000'000'000'000ULL;

// Line i of the generated log: 3 interfaces, extended ids, 8 data bytes, 100 us apart.
std::size_t make_candump_line(std::uint64_t i, char* out) {
  const std::uint64_t us = kBaseUs + i * 100;
  char* p = out;
  *p++ = '(';
  p = put_padded(p, us / 1'000'000, 10);
  *p++ = '.';
  p = put_padded(p, us % 1'000'000, 6);
  const char* iface = i % 3 == 0 ? ") can0 " : (i % 3 == 1 ? ") can1 " : ") vcan2 ");
  for (const char* c = iface; *c != '\0'; ++c) *p++ = *c;
  p = put_hex(p, 0x18FEF100 + (i % 64), 8);
  *p++ = '#';
  p = put_hex(p, i * 0x9E3779B97F4A7C15ULL, 16);
  *p++ = '\n';
  return static_cast<std::size_t>(p - out);
}

constexpr const char* kTruckLog = "can/j1939_truck_candump-2022-03-29.log";

}  // namespace

TEST_CASE("candump reader parses standard and extended data frames with exact timestamps",
          "[can][candump]") {
  const ReadResult r = read_text(
      "(1648583717.428998) can1 0CF00400#707D83C312000F84\n"
      "(0000000001.000001) vcan0 123#\n"
      "(1648583717.430971) can1 7FF#0102\n");
  REQUIRE(r.malformed == 0);
  REQUIRE(r.entries.size() == 3);
  const Frame& a = r.entries[0].frame;
  CHECK(a.timestamp == 1'648'583'717'428'998'000LL);
  CHECK(a.id == 0x0CF00400);
  CHECK(a.extended);
  CHECK_FALSE(a.fd);
  CHECK(a.length == 8);
  CHECK(a.data[0] == 0x70);
  CHECK(a.data[7] == 0x84);
  CHECK(a.bus == 0);
  CHECK_FALSE(r.entries[0].direction.has_value());
  const Frame& b = r.entries[1].frame;
  CHECK(b.timestamp == 1'000'001'000LL);
  CHECK(b.id == 0x123);
  CHECK_FALSE(b.extended);
  CHECK(b.length == 0);
  CHECK(b.bus == 1);
  CHECK(r.entries[2].frame.bus == 0);
  CHECK(r.entries[2].frame.id == 0x7FF);
  CHECK(r.interfaces == std::vector<std::string>{"can1", "vcan0"});
}

TEST_CASE("candump reader accepts upper and lower case hex everywhere", "[can][candump]") {
  CHECK(frame_of("1aB#deADbeEF").id == 0x1AB);
  const Frame f = frame_of("1abcdef0#deADbeEF");
  CHECK(f.id == 0x1ABCDEF0);
  CHECK(f.extended);
  CHECK(f.data[0] == 0xDE);
  CHECK(f.data[3] == 0xEF);
  CHECK(frame_of("123##1aB").data[0] == 0xAB);
  CHECK(frame_of("123#R").rtr);
}

TEST_CASE("candump reader parses remote frames with and without a length", "[can][candump]") {
  Frame f = frame_of("123#R");
  CHECK(f.rtr);
  CHECK(f.length == 0);
  CHECK(f.data_size() == 0);
  CHECK(frame_of("123#r").rtr);
  CHECK(frame_of("123#R0").length == 0);
  CHECK(frame_of("123#R7").length == 7);
  f = frame_of("123#R8_9");
  CHECK(f.length == 9);
  CHECK(f.dlc() == 9);
  f = frame_of("12345678#R3");
  CHECK(f.extended);
  CHECK(f.rtr);
  CHECK(f.length == 3);
}

TEST_CASE("candump reader parses CAN FD frames and their flags", "[can][candump]") {
  Frame f = frame_of("123##0");
  CHECK(f.fd);
  CHECK(f.length == 0);
  CHECK_FALSE(f.brs);
  CHECK_FALSE(f.esi);
  f = frame_of("123##1112233");
  CHECK(f.brs);
  CHECK_FALSE(f.esi);
  CHECK(f.length == 3);
  CHECK(f.data[2] == 0x33);
  f = frame_of("123##2");
  CHECK(f.esi);
  CHECK_FALSE(f.brs);
  f = frame_of("123##3");
  CHECK(f.brs);
  CHECK(f.esi);
  f = frame_of("123##5AA");  // CANFD_FDF | CANFD_BRS, as can-utils 2025.01 writes
  CHECK(f.brs);
  CHECK_FALSE(f.esi);
  CHECK(f.length == 1);
  f = frame_of("123##4000102030405060708090A0B");
  CHECK(f.length == 12);
  CHECK(f.data[11] == 0x0B);
  std::string sixty_four;
  for (int i = 0; i < 64; ++i) sixty_four += "A5";
  f = frame_of("18FEF121##1" + sixty_four);
  CHECK(f.length == 64);
  CHECK(f.extended);
  CHECK(f.data[63] == 0xA5);
  f = frame_of("123##1.11.22.33");
  CHECK(f.length == 3);
}

TEST_CASE("candump reader parses error frames (CAN_ERR_FLAG in an 8-digit id)", "[can][candump]") {
  Frame f = frame_of("20000004#0004000000000000");
  CHECK(f.error);
  CHECK_FALSE(f.extended);
  CHECK(f.id == 0x4);
  CHECK(f.length == 8);
  CHECK(f.data[1] == 0x04);
  f = frame_of("3FFFFFFF#");
  CHECK(f.error);
  CHECK(f.id == 0x1FFFFFFF);
  CHECK(f.length == 0);
}

TEST_CASE("candump reader accepts '.' separators between data bytes", "[can][candump]") {
  Frame f = frame_of("123#11.22.33");
  CHECK(f.length == 3);
  CHECK(f.data[1] == 0x22);
  f = frame_of("123#11.2233.44556677.88");
  CHECK(f.length == 8);
  CHECK(f.data[7] == 0x88);
  CHECK(frame_of("123#.11.").length == 1);  // can-utils accepts a leading and a trailing one
}

TEST_CASE("candump reader parses the raw DLC suffix of Classical CAN frames", "[can][candump]") {
  Frame f = frame_of("123#1122334455667788_9");
  CHECK(f.length == 9);
  CHECK(f.data_size() == 8);
  CHECK(f.data[7] == 0x88);
  CHECK(frame_of("123#1122334455667788_F").length == 15);
  CHECK(frame_of("123#1122334455667788_f").length == 15);
}

TEST_CASE("candump reader reads the direction of candump -x and tolerates blanks",
          "[can][candump]") {
  const ReadResult r = read_text(
      "(1.000000) can0 123#11 R\n"
      "(1.000001) can0 123#11 T\n"
      "(1.000002)   can0\t123#11\tT  \n"
      "(1.000003) can0 123#11   \n");
  REQUIRE(r.malformed == 0);
  REQUIRE(r.entries.size() == 4);
  CHECK(r.entries[0].direction == Direction::Rx);
  CHECK(r.entries[1].direction == Direction::Tx);
  CHECK(r.entries[2].direction == Direction::Tx);
  CHECK_FALSE(r.entries[3].direction.has_value());
}

TEST_CASE("candump reader timestamps are exact for 1 to 9 fraction digits", "[can][candump]") {
  const ReadResult r = read_text(
      "(1648586979.907437) can0 123#\n"     // candump -l
      "(1648586979.907437123) can0 123#\n"  // candump -l -N
      "(001.5) can0 123#\n"                 // decimal meaning: 1.5 s
      "(000.000123) can0 123#\n"            // candump -tz
      "(9223372036.854775807) can0 123#\n"  // the largest Nanos
      "(0.0) can0 123#\n");
  REQUIRE(r.malformed == 0);
  REQUIRE(r.entries.size() == 6);
  CHECK(r.entries[0].frame.timestamp == 1'648'586'979'907'437'000LL);
  CHECK(r.entries[1].frame.timestamp == 1'648'586'979'907'437'123LL);
  CHECK(r.entries[2].frame.timestamp == 1'500'000'000LL);
  CHECK(r.entries[3].frame.timestamp == 123'000LL);
  CHECK(r.entries[4].frame.timestamp == INT64_MAX);
  CHECK(r.entries[5].frame.timestamp == 0);
}

TEST_CASE("candump reader ignores comment lines, empty lines and DROPCOUNT lines",
          "[can][candump]") {
  const ReadResult r = read_text(
      "# a comment\n"
      "\n"
      "DROPCOUNT: dropped 2 CAN frames on 'can0' socket (total drops 2)\n"
      " (1.000000) can0 123#11\n"  // does not start with '(': a comment, as in log2asc
      "(1.000000) can0 123#11\n"
      "garbage that is not a frame\n");
  CHECK(r.malformed == 0);
  CHECK(r.entries.size() == 1);
}

TEST_CASE("candump reader handles empty input and CRLF line endings", "[can][candump]") {
  ReadResult r = read_text("");
  CHECK(r.entries.empty());
  CHECK(r.malformed == 0);
  CHECK(r.interfaces.empty());
  r = read_text("\n\n\r\n");
  CHECK(r.entries.empty());
  CHECK(r.malformed == 0);
  r = read_text("(1.000000) can0 123#1122\r\n(1.000001) can0 123#33 T\r\n(2.0) can0 7FF#R\r\n");
  REQUIRE(r.malformed == 0);
  REQUIRE(r.entries.size() == 3);
  CHECK(r.entries[0].frame.length == 2);
  CHECK(r.entries[1].direction == Direction::Tx);
  CHECK(r.entries[2].frame.rtr);
  r = read_text("\xEF\xBB\xBF(1.000000) can0 123#1122\n");  // UTF-8 byte order mark
  CHECK(r.entries.size() == 1);
  r = read_text("(1.000000) can0 123#1122");  // no final newline
  REQUIRE(r.entries.size() == 1);
  CHECK(r.entries[0].frame.data[1] == 0x22);
}

TEST_CASE("candump reader reports every malformed line with file, line, column and reason",
          "[can][candump]") {
  struct Case {
    const char* line;
    const char* message;
    std::uint32_t column;
  };
  // The frame field starts at column 17 of "(1.000000) can0 ".
  const std::vector<Case> cases = {
      {"(1.000000) can0 12G#11", "invalid character 'G' in identifier", 19},
      {"(1.000000) can0 1234#11", "identifier has 4 hex digits", 17},
      {"(1.000000) can0 123456789#11", "identifier has 9 hex digits", 17},
      {"(1.000000) can0 12311", "missing '#' after the identifier", 22},
      {"(1.000000) can0 123#112", "odd number of hex digits in data", 23},
      {"(1.000000) can0 123#1G", "invalid character 'G' in data", 22},
      {"(1.000000) can0 123#112233445566778899", "more than 8 data bytes", 37},
      {"(1.000000) can0 800#11", "standard identifier 800 exceeds 7FF", 17},
      {"(1.000000) can0 40000000#11", "bits above the 29-bit id", 17},
      {"(1.000000) can0 45123#81:00:12345678#11", "CAN XL", 17},
      {"(1.000000) can0 123##0112233445566778899", "9 data bytes is not a CAN FD length", 23},
      {"(1.000000) can0 123##G11", "CAN FD flags after '##' must be one hex digit", 22},
      {"(1.000000) can0 123##811", "unknown CAN FD flag bits", 22},
      {"(1.000000) can0 123##", "CAN FD flags after '##' must be one hex digit", 22},
      {"(1.000000) can0 123#R9", "remote frame length must be one digit 0-8", 22},
      {"(1.000000) can0 123#R8_8", "raw DLC after '_' must be one of 9-F", 24},
      {"(1.000000) can0 123#R1x", "unexpected 'x' after the remote frame", 23},
      {"(1.000000) can0 123#11_9", "a raw DLC ('_') needs 8 data bytes", 23},
      {"(1.000000) can0 123#1122334455667788_", "raw DLC after '_' must be one of 9-F", 38},
      {"(1.000000) can0 123##01122_9", "a CAN FD frame has no raw DLC", 27},
      {"(1.000000) can0 20000000#R", "an error frame cannot be a remote frame", 26},
      {"(1.000000) can0 20000000#0000000000000000_9", "an error frame has no raw DLC", 42},
      {"(1.000000) can0 20000000##0", "an error frame cannot be a CAN FD frame", 26},
      {"(1.000000) can0 123#11..22", "invalid character '.' in data", 24},
      {"(1.000000) can0 123#11 X", "unexpected text after the frame", 24},
      {"(1.000000) can0 123#11 Rx", "unexpected text after the frame", 24},
      {"(1.000000) can0 123#11 R x", "unexpected text after the direction", 26},
      {"(1.000000) can0 123#11\x01", "invalid character byte 0x01 in data", 23},
      {"(abc) can0 123#11", "timestamp: expected digits after '('", 2},
      {"(1.2.3) can0 123#11", "timestamp: expected ')'", 5},
      {"(1700000000) can0 123#11", "timestamp: expected '.' after the seconds", 12},
      {"(1700000000.) can0 123#11", "timestamp: expected digits after '.'", 13},
      {"(1.1234567890) can0 123#11", "more than 9 fraction digits", 13},
      {"(99999999999.000000) can0 123#11", "timestamp out of range", 2},
      {"(9223372036.854775808) can0 123#11", "timestamp out of range", 2},
      {"(1.000000", "timestamp: expected ')'", 10},
      {"(1.000000)can0 123#11", "expected a space after the timestamp", 11},
      {"(1.000000) 123#11", "missing interface name before the frame", 12},
      {"(1.000000) can0", "missing frame after the interface name", 16},
      {"(1.000000) can0 ", "missing frame after the interface name", 17},
      {"(1.000000)", "missing interface name and frame", 11},
  };
  for (const Case& c : cases) {
    INFO(c.line);
    const ParseError e = error_of(c.line);
    CHECK_THAT(e.message, Catch::Contains(c.message));
    CHECK(e.column == c.column);
    CHECK_THAT(e.to_string(), Catch::StartsWith("t.log:2:" + std::to_string(c.column) + ": "));
  }
}

TEST_CASE("candump reader in Skip mode counts, calls back and keeps the first N errors",
          "[can][candump]") {
  std::vector<std::string> seen;
  ReaderOptions options;
  options.max_kept_errors = 2;
  options.on_error = [&](const ParseError& e) { seen.push_back(e.to_string()); };
  const ReadResult r = read_text(
      "(1.000000) can0 123#11\n"
      "(1.000000) can0 12#11\n"
      "(1.000000) can0 123#11\n"
      "(x) can0 123#11\n"
      "(1.000000) can0 123#1\n"
      "(1.000000) can0 123#22\n",
      options);
  CHECK(r.entries.size() == 3);
  CHECK(r.malformed == 3);
  REQUIRE(r.errors.size() == 2);
  CHECK(r.errors[0].line == 2);
  CHECK(r.errors[1].line == 4);
  REQUIRE(seen.size() == 3);
  CHECK_THAT(seen[2], Catch::StartsWith("t.log:5:21: odd number of hex digits"));
}

TEST_CASE("candump reader in Stop mode fails at the first malformed line and stays failed",
          "[can][candump]") {
  std::istringstream in(
      "(1.000000) can0 123#11\n"
      "(1.000001) can0 123#11\n"
      "(1.000002) can0 123#1Z\n"
      "(1.000003) can0 123#11\n");
  ReaderOptions options;
  options.on_malformed = OnMalformed::Stop;
  CandumpReader reader(in, "stop.log", options);
  REQUIRE(reader.next().value().has_value());
  REQUIRE(reader.next().value().has_value());
  const auto bad = reader.next();
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().code == EINVAL);
  CHECK(bad.error().message == "stop.log:3:22: invalid character 'Z' in data");
  const auto again = reader.next();
  REQUIRE_FALSE(again.has_value());
  CHECK(again.error().message == bad.error().message);
  CHECK(reader.malformed_count() == 1);
  CHECK(reader.line_number() == 3);
}

TEST_CASE("candump reader gives up to 256 interfaces their own bus index", "[can][candump]") {
  std::string text;
  for (int i = 0; i < 257; ++i) text += "(1.000000) if" + std::to_string(i) + " 123#11\n";
  text += "(1.000000) if255 123#11\n";
  const ReadResult r = read_text(text);
  REQUIRE(r.entries.size() == 257);
  CHECK(r.interfaces.size() == 256);
  CHECK(r.entries[255].frame.bus == 255);
  CHECK(r.entries[256].frame.bus == 255);
  REQUIRE(r.errors.size() == 1);
  CHECK(r.errors[0].line == 257);
  CHECK_THAT(r.errors[0].message, Catch::Contains("more than 256 interfaces"));
}

TEST_CASE("candump reader skips lines longer than the limit without storing them",
          "[can][candump]") {
  ReaderOptions options;
  options.max_line_bytes = 64;
  const std::string long_line = "(1.000000) can0 123#" + std::string(200, 'A');
  const ReadResult r = read_text(
      "(1.000000) can0 123#11\n" + long_line + "\n(1.000000) can0 123#22\n" + long_line, options);
  REQUIRE(r.entries.size() == 2);
  CHECK(r.entries[1].frame.data[0] == 0x22);
  CHECK(r.malformed == 2);
  REQUIRE(r.errors.size() == 2);
  CHECK(r.errors[0].to_string() == "t.log:2:1: line longer than 64 bytes");
  CHECK(r.errors[1].line == 4);
}

TEST_CASE("candump reader streams 2 million generated lines in constant memory",
          "[can][candump][stream]") {
  constexpr std::uint64_t kLines = 2'000'000;
  vigil::test::LineGenerator gen(kLines, make_candump_line);
  std::istream in(&gen);
  CandumpReader reader(in, "<generated>");
  // Warm-up: the interface table fills on the first lines.
  for (int i = 0; i < 10; ++i) REQUIRE(reader.next().value().has_value());
  std::uint64_t count = 10;
  std::uint64_t mismatches = 0;
  const std::uint64_t allocations_before = vigil::platform::thread_allocations();
  for (;;) {
    auto e = reader.next();
    if (!e || !*e) break;
    const Frame& f = (*e)->frame;
    const auto expected_ts = static_cast<vigil::Nanos>((kBaseUs + count * 100) * 1000);
    if (f.timestamp != expected_ts || f.id != 0x18FEF100 + (count % 64) || f.length != 8 ||
        f.bus != count % 3) {
      ++mismatches;
    }
    ++count;
  }
  const std::uint64_t allocations = vigil::platform::thread_allocations() - allocations_before;
  CHECK(count == kLines);
  CHECK(mismatches == 0);
  CHECK(reader.malformed_count() == 0);
  CHECK(reader.line_number() == kLines);
  CHECK(reader.interfaces().size() == 3);
  if (vigil::platform::allocation_counting_available()) {
    CHECK(allocations == 0);
  } else {
    WARN("allocation counting unavailable (sanitizer build): constant memory not measured");
  }
}

TEST_CASE("candump reader skips a 100 MB line without a newline in constant memory",
          "[can][candump][stream]") {
  // 400 000 chunks of 250 bytes with no '\n', then one good line.
  constexpr std::uint64_t kChunks = 400'000;
  auto make = [](std::uint64_t i, char* out) -> std::size_t {
    if (i + 1 == kChunks + 1) {
      const char good[] = "\n(2.000000) can0 321#AB\n";
      std::memcpy(out, good, sizeof good - 1);
      return sizeof good - 1;
    }
    std::memset(out, i == 0 ? '(' : '7', 250);
    return 250;
  };
  vigil::test::LineGenerator gen(kChunks + 1, make);
  std::istream in(&gen);
  CandumpReader reader(in, "<huge>");
  const std::uint64_t allocations_before = vigil::platform::thread_allocations();
  auto first = reader.next();  // reports the long line (kept: one allocation), then the frame
  const std::uint64_t allocations = vigil::platform::thread_allocations() - allocations_before;
  REQUIRE(first.has_value());
  REQUIRE(first->has_value());
  CHECK((*first)->frame.id == 0x321);
  CHECK(reader.malformed_count() == 1);
  CHECK(reader.errors().at(0).line == 1);
  CHECK_FALSE(reader.next().value().has_value());
  if (vigil::platform::allocation_counting_available()) {
    CHECK(allocations < 10);  // the error report only, not the 100 MB
  }
}

TEST_CASE("candump reader opens files and names them in errors", "[can][candump]") {
  const auto missing = CandumpReader::open("/nonexistent/dir/x.log");
  REQUIRE_FALSE(missing.has_value());
  CHECK(missing.error().code == ENOENT);
  CHECK_THAT(missing.error().message, Catch::Contains("/nonexistent/dir/x.log"));
  const auto dir = CandumpReader::open(VIGIL_CAN_TEST_DATA_DIR);
  REQUIRE_FALSE(dir.has_value());
  CHECK(dir.error().code == EISDIR);
  const auto all = vigil::can::read_candump_file("/nonexistent/dir/x.log");
  REQUIRE_FALSE(all.has_value());
  CHECK(all.error().code == ENOENT);
}

TEST_CASE("read_candump_file reads the hand-written sample with every construct",
          "[can][candump]") {
  const auto log =
      vigil::can::read_candump_file(std::string(VIGIL_CAN_TEST_DATA_DIR) + "/sample.log");
  REQUIRE(log.has_value());
  CHECK(log->malformed == 0);
  CHECK(log->interfaces == std::vector<std::string>{"can0", "vcan1"});
  REQUIRE(log->entries.size() == 10);
  const auto& e = log->entries;
  CHECK(e[0].frame.length == 0);
  CHECK(e[1].frame.length == 8);
  CHECK(e[2].frame.bus == 1);
  CHECK(e[2].frame.extended);
  CHECK(e[2].frame.id == 0x1FFFFFFF);
  CHECK(e[2].direction == Direction::Rx);
  CHECK(e[3].frame.rtr);
  CHECK(e[4].frame.length == 15);
  CHECK(e[4].direction == Direction::Tx);
  CHECK(e[5].frame.fd);
  CHECK(e[5].frame.brs);
  CHECK(e[5].frame.length == 3);
  CHECK(e[6].frame.error);
  CHECK(e[6].frame.id == 0x80);
  CHECK(e[7].frame.length == 3);
  CHECK(e[8].frame.length == 9);
  CHECK(e[9].frame.timestamp == 1'700'000'000'123'456'789LL);
  CHECK(e[9].frame.fd);
  CHECK(e[9].frame.brs);
  CHECK(e[9].frame.esi);
  CHECK(e[9].frame.length == 12);
}

TEST_CASE("parse_candump_frame parses a cansend-style frame or says where it is wrong",
          "[can][candump]") {
  const auto f = vigil::can::parse_candump_frame("18FEF121##3AABB.CC.DD");
  REQUIRE(f.has_value());
  CHECK(f->id == 0x18FEF121);
  CHECK(f->fd);
  CHECK(f->length == 4);
  const auto bad = vigil::can::parse_candump_frame("123#1");
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().message == "column 5: odd number of hex digits in data");
  CHECK_FALSE(vigil::can::parse_candump_frame("").has_value());
  CHECK_FALSE(vigil::can::parse_candump_frame("#").has_value());
}

TEST_CASE("candump reader reads the real J1939 truck capture exactly", "[can][candump][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  const auto path = vigil::test::shared_data(kTruckLog);
  ReaderOptions options;
  options.on_malformed = OnMalformed::Stop;
  const auto log = vigil::can::read_candump_file(path, options);
  REQUIRE(log.has_value());
  const auto& e = log->entries;
  CHECK(log->malformed == 0);
  REQUIRE(e.size() == 19535);
  CHECK(log->interfaces == std::vector<std::string>{"can1"});
  CHECK(e.front().frame.timestamp == 1'648'583'717'428'998'000LL);
  CHECK(e.back().frame.timestamp == 1'648'586'979'907'437'000LL);
  std::map<std::uint32_t, std::size_t> per_id;
  bool all_extended_dlc8 = true;
  for (const LogEntry& x : e) {
    ++per_id[x.frame.id];
    all_extended_dlc8 = all_extended_dlc8 && x.frame.extended && !x.frame.fd && !x.frame.rtr &&
                        !x.frame.error && x.frame.length == 8 && x.frame.bus == 0;
  }
  CHECK(per_id.size() == 23);
  CHECK(per_id[0x0CF00400] == 2686);
  CHECK(per_id[0x18FEF121] == 5235);
  CHECK(all_extended_dlc8);
}

TEST_CASE("candump reader survives mutated input and returns only valid frames",
          "[can][candump][fuzz]") {
  const std::vector<std::string> seeds = {
      "(1648583717.428998) can1 0CF00400#707D83C312000F84",
      "(0000000001.000001) vcan0 123#",
      "(1.000000) can0 123#R8_9 T",
      "(1.000000) can0 12345678#r3",
      "(1.000000) can0 123##5112233445566778899AABBCC",
      "(1.123456789) can0 20000004#0004000000000000 R",
      "(1.000000) can0 321#11.22.33",
      "(1.000000) can0 321#1122334455667788_F",
      "DROPCOUNT: dropped 2 CAN frames",
  };
  const std::string alphabet = "0123456789abcdefABCDEFRrT#._() \t\r-xX:";
  std::istringstream in(vigil::test::mutated_lines(seeds, alphabet, 200'000, 12345));
  CandumpReader reader(in, "<fuzz>");
  const auto read = vigil::test::read_through(reader);
  REQUIRE(read.every_call_ok);
  CHECK(read.invalid == 0);
  CHECK(read.frames > 1000);
  CHECK(reader.malformed_count() > 1000);
}
