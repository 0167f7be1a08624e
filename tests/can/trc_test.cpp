#include "vigil/can/log/trc.hpp"

#include <catch2/catch.hpp>
#include <charconv>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "support/line_generator.hpp"
#include "support/mutated_lines.hpp"
#include "vigil/platform/rt_loss.hpp"

using vigil::Nanos;
using vigil::can::Direction;
using vigil::can::Frame;
using vigil::can::LogEntry;
using vigil::can::OnMalformed;
using vigil::can::ParseError;
using vigil::can::ReaderOptions;
using vigil::can::TrcReader;
using vigil::can::TrcVersion;

namespace {

constexpr Nanos kMs = 1'000'000;

struct TrcResult {
  std::vector<LogEntry> entries;
  std::uint64_t malformed = 0;
  std::uint64_t skipped = 0;
  std::vector<ParseError> errors;
  TrcVersion version = TrcVersion::V1_0;
  std::optional<Nanos> start;
};

TrcResult read_trc(const std::string& text, ReaderOptions options = {}) {
  std::istringstream in(text);
  TrcReader reader(in, "t.trc", std::move(options));
  TrcResult r;
  for (;;) {
    auto e = reader.next();
    REQUIRE(e.has_value());
    if (!*e) break;
    r.entries.push_back(**e);
  }
  r.malformed = reader.malformed_count();
  r.skipped = reader.skipped_count();
  r.errors = reader.errors();
  r.version = reader.version();
  r.start = reader.start_time();
  return r;
}

std::vector<std::uint8_t> bytes_of(const Frame& f) {
  return {f.data.begin(), f.data.begin() + static_cast<std::ptrdiff_t>(f.data_size())};
}

const std::string kV21Header =
    ";$FILEVERSION=2.1\r\n"
    ";$STARTTIME=25569.5\r\n"
    ";$COLUMNS=N,O,T,B,I,d,R,L,D\r\n";

// Reads kV21Header + one good record + `line`; returns the error of line 5.
ParseError v21_error(const std::string& line) {
  const TrcResult r =
      read_trc(kV21Header + "      1      1.000 DT 1  0100 Rx -  1    AA\r\n" + line + "\r\n");
  REQUIRE(r.entries.size() == 1);
  REQUIRE(r.malformed == 1);
  REQUIRE(r.errors.size() == 1);
  CHECK(r.errors[0].line == 5);
  return r.errors[0];
}

}  // namespace

TEST_CASE("TRC reader reads a version 1.1 file of PCAN-View", "[can][trc]") {
  auto reader = TrcReader::open(std::string(VIGIL_CAN_TEST_DATA_DIR) + "/sample_v1_1.trc");
  REQUIRE(reader.has_value());
  std::vector<LogEntry> e;
  for (;;) {
    auto x = reader->next();
    REQUIRE(x.has_value());
    if (!*x) break;
    e.push_back(**x);
  }
  CHECK(reader->version() == TrcVersion::V1_1);
  constexpr Nanos start = 1'639'837'687'062'000'960LL;  // 44548.6028595139 days, rounded
  REQUIRE(reader->start_time().has_value());
  CHECK(*reader->start_time() == start);
  CHECK(reader->malformed_count() == 0);
  CHECK(reader->skipped_count() == 1);  // the Warng line
  REQUIRE(e.size() == 5);
  CHECK(e[0].frame.timestamp == start + 1059 * kMs + 900'000);
  CHECK(e[0].frame.id == 0x300);
  CHECK_FALSE(e[0].frame.extended);
  CHECK(e[0].direction == Direction::Rx);
  CHECK(bytes_of(e[0].frame) == std::vector<std::uint8_t>{0, 1, 2, 3, 4, 5, 6, 7});
  CHECK(e[1].frame.extended);
  CHECK(e[1].frame.id == 0x18FEF121);
  CHECK(e[1].direction == Direction::Tx);
  CHECK(bytes_of(e[1].frame) == std::vector<std::uint8_t>{0xAA, 0xBB, 0xCC});
  CHECK(e[2].frame.rtr);
  CHECK(e[2].frame.length == 3);
  CHECK(e[2].frame.id == 0x100);
  CHECK(e[3].frame.error);
  CHECK(e[3].frame.id == 0);
  CHECK(bytes_of(e[3].frame) == std::vector<std::uint8_t>{0x08, 0x00, 0x19, 0x08, 0x08});
  CHECK(e[3].frame.timestamp == start + 1300 * kMs + 200'000);
  CHECK(e[4].frame.id == 0x7FF);
  CHECK(e[4].frame.length == 0);
}

TEST_CASE("TRC reader reads a version 2.1 file with CAN FD, error, remote and status records",
          "[can][trc]") {
  const auto log =
      vigil::can::read_trc_file(std::string(VIGIL_CAN_TEST_DATA_DIR) + "/sample_v2_1.trc");
  REQUIRE(log.has_value());
  CHECK(log->malformed == 0);
  CHECK(log->skipped == 3);  // EV, ST, EC
  const auto& e = log->entries;
  REQUIRE(e.size() == 9);
  constexpr Nanos start = 43'200'000'000'000LL;  // 25569.5 days: 1970-01-01 12:00 UTC
  CHECK(e[0].frame.timestamp == start + 1059 * kMs + 900'000);
  CHECK(e[0].frame.bus == 0);
  CHECK(e[0].frame.length == 7);
  CHECK(e[0].direction == Direction::Rx);
  // FD, DLC 9 = 12 bytes, bus 2
  CHECK(e[1].frame.fd);
  CHECK_FALSE(e[1].frame.brs);
  CHECK_FALSE(e[1].frame.esi);
  CHECK(e[1].frame.length == 12);
  CHECK(e[1].frame.bus == 1);
  CHECK(e[1].frame.data[11] == 0x0C);
  CHECK(e[1].direction == Direction::Tx);
  CHECK(e[1].frame.timestamp == start + 1334 * kMs + 416'000);
  // FB = BRS, FE = ESI, BI = both
  CHECK((e[2].frame.fd && e[2].frame.brs && !e[2].frame.esi && e[2].frame.extended));
  CHECK(e[2].frame.id == 0x18EFC034);
  CHECK((e[3].frame.fd && !e[3].frame.brs && e[3].frame.esi && e[3].frame.length == 0));
  CHECK((e[4].frame.fd && e[4].frame.brs && e[4].frame.esi && e[4].frame.length == 1));
  // ER: error frame carrying PEAK's error record bytes
  CHECK(e[5].frame.error);
  CHECK(bytes_of(e[5].frame) == std::vector<std::uint8_t>{0x04, 0x00, 0x02, 0x00, 0x00});
  CHECK(e[5].direction == Direction::Rx);
  CHECK(e[6].frame.id == 0x18EFC034);
  CHECK_FALSE(e[6].frame.fd);
  CHECK(e[7].frame.rtr);
  CHECK(e[7].frame.length == 3);
  CHECK(e[7].frame.id == 0x100);
  // Classical CAN with DLC 12: 8 data bytes, length keeps the DLC
  CHECK(e[8].frame.length == 12);
  CHECK(e[8].frame.data_size() == 8);
  CHECK(e[8].frame.bus == 2);
}

TEST_CASE("TRC reader reads version 1.0 files (no header) with ERROR and RTR records",
          "[can][trc]") {
  const TrcResult r = read_trc(
      ";##########################################################################\n"
      ";   C:\\TraceFile.trc\n"
      ";   Start time: 11.09.2002 16:00:20.682\n"
      "     1)      1841  0001  8  00 00 00 00 00 00 00 00\n"
      "     2)      1842  0008  4  ERROR 00 19 08 08\n"
      "     3)      1843  FFFFFFFF  4  00 00 00 04 ------BUSLIGHT\n"
      "     4)      1844  0100  3  RTR\n");
  CHECK(r.version == TrcVersion::V1_0);
  CHECK_FALSE(r.start.has_value());
  CHECK(r.malformed == 0);
  CHECK(r.skipped == 1);
  REQUIRE(r.entries.size() == 3);
  CHECK(r.entries[0].frame.timestamp == 1841 * kMs);
  CHECK(r.entries[0].frame.id == 1);
  CHECK_FALSE(r.entries[0].direction.has_value());
  CHECK(r.entries[1].frame.error);
  CHECK(bytes_of(r.entries[1].frame) == std::vector<std::uint8_t>{0x08, 0x00, 0x19, 0x08, 0x08});
  CHECK(r.entries[2].frame.rtr);
  CHECK(r.entries[2].frame.length == 3);
}

TEST_CASE("TRC reader reads versions 1.2 and 1.3 with their bus and reserved columns",
          "[can][trc]") {
  TrcResult r = read_trc(
      ";$FILEVERSION=1.2\n"
      ";$STARTTIME=39878.6772258947\n"
      "1) 1059.900 1 Rx 0300 7 00 00 00 00 04 00 00\n"
      "3) 1298.945 2 Tx 0400 2 00 00\n"
      "5) 1346.834 1 Warng FFFFFFFF 4 00 00 00 04 BUSLIGHT\n"
      "6) 1349.222 1 Error 0008 4 00 19 08 08\n"
      "7) 1352.743 1 Rx 0100 3 RTR\n");
  CHECK(r.version == TrcVersion::V1_2);
  CHECK(r.start == 1'236'356'112'317'302'080LL);
  CHECK(r.malformed == 0);
  CHECK(r.skipped == 1);
  REQUIRE(r.entries.size() == 4);
  CHECK(r.entries[1].frame.bus == 1);
  CHECK(r.entries[1].direction == Direction::Tx);
  CHECK(r.entries[2].frame.error);
  CHECK(r.entries[3].frame.rtr);

  r = read_trc(
      ";$FILEVERSION=1.3\n"
      ";$STARTTIME=44548.6028595139\n"
      "     1)        17535.4 1  Tx    00000100 -  8    00 00 00 00 00 00 00 00\n"
      "     2)        17700.3 2  Rx        0000 -  2    01 02\n"
      "     3)      1346.834 1  Warng FFFFFFFF -  4    00 00 00 04 BUSLIGHT\n");
  CHECK(r.version == TrcVersion::V1_3);
  CHECK(r.malformed == 0);
  CHECK(r.skipped == 1);
  REQUIRE(r.entries.size() == 2);
  CHECK(r.entries[0].frame.extended);
  CHECK(r.entries[0].frame.id == 0x100);
  CHECK(r.entries[1].frame.bus == 1);
  CHECK(r.entries[1].frame.timestamp == 1'639'837'687'062'000'960LL + 17700 * kMs + 300'000);
}

TEST_CASE("TRC reader reads version 2.0 files, whose status records leave columns blank",
          "[can][trc]") {
  const TrcResult r = read_trc(
      ";$FILEVERSION=2.0\r\n"
      ";$STARTTIME=42209.4075997106\r\n"
      ";$COLUMNS=N,O,T,I,d,l,D\r\n"
      ";---+-- ------+------ +- --+----- +- +- +- -- -- -- -- -- -- --\r\n"
      "      1      1059.900 DT     0300 Rx 7  00 00 00 00 04 00 00\r\n"
      "      5      1334.416 FD     0500 Tx 12 01 02 03 04 05 06 07 08 09 0A 0B 0C\r\n"
      "      6      1334.522 ER          Rx    04 00 02 00 00\r\n"
      "      7      1334.531 ST          Rx    00 00 00 08\r\n"
      "      8      1334.643 EC          Rx    02 02\r\n"
      "      9      1335.156 DT 18EFC034 Tx 8  01 02 03 04 05 06 07 08\r\n"
      "     10      1336.543 RR     0100 Rx 3\r\n");
  CHECK(r.version == TrcVersion::V2_0);
  CHECK(r.start == 1'437'731'216'614'995'840LL);
  CHECK(r.malformed == 0);
  CHECK(r.skipped == 2);
  REQUIRE(r.entries.size() == 5);
  CHECK(r.entries[1].frame.fd);
  CHECK(r.entries[1].frame.length == 12);
  CHECK(r.entries[2].frame.error);
  CHECK(r.entries[2].frame.length == 5);
  CHECK(r.entries[2].direction == Direction::Rx);
  CHECK(r.entries[2].frame.timestamp == *r.start + 1334 * kMs + 522'000);
  CHECK(r.entries[3].frame.id == 0x18EFC034);
  CHECK(r.entries[4].frame.rtr);
  CHECK(r.entries[4].frame.length == 3);
}

TEST_CASE("TRC reader follows $COLUMNS and defaults without header values", "[can][trc]") {
  // Data length (l) instead of DLC, three-digit standard ids, no $STARTTIME.
  TrcResult r = read_trc(
      ";$FILEVERSION=2.1\n"
      ";$COLUMNS=N,O,T,B,I,d,R,l,D\n"
      "1 0.100 DT 1 123 Rx - 2 34 12\n"
      "2 0.200 FD 1 124 Rx - 12 00 01 02 03 04 05 06 07 08 09 0A 0B\n"
      "3 0.300 FD 1 124 Rx - 9 00 01 02 03 04 05 06 07 08\n");
  CHECK_FALSE(r.start.has_value());
  REQUIRE(r.entries.size() == 2);
  CHECK(r.entries[0].frame.timestamp == 100'000);
  CHECK(r.entries[0].frame.id == 0x123);
  CHECK(r.entries[1].frame.length == 12);
  REQUIRE(r.errors.size() == 1);
  CHECK_THAT(r.errors[0].to_string(),
             Catch::StartsWith("t.trc:5:23: data length 9 is not a CAN FD length"));

  // Reordered columns without bus and reserved.
  r = read_trc(
      ";$FILEVERSION=2.1\n"
      ";$COLUMNS=O,N,T,d,I,L,D\n"
      "5.5 1 DT Tx 00000123 2 AB CD\n");
  REQUIRE(r.entries.size() == 1);
  CHECK(r.entries[0].frame.timestamp == 5 * kMs + 500'000);
  CHECK(r.entries[0].frame.extended);
  CHECK(r.entries[0].direction == Direction::Tx);

  // A UTF-8 byte order mark before the first line is ignored.
  r = read_trc("\xEF\xBB\xBF;$FILEVERSION=2.0\n1 1.000 DT 0100 Rx 1 AA\n");
  CHECK(r.version == TrcVersion::V2_0);
  CHECK(r.entries.size() == 1);

  // A 2.1 file without $COLUMNS uses PEAK's default layout.
  r = read_trc(";$FILEVERSION=2.1\n1 1.000 DT 1 0100 Rx - 1 AA\n");
  REQUIRE(r.entries.size() == 1);
  CHECK(r.entries[0].frame.data[0] == 0xAA);
}

TEST_CASE("TRC reader converts $STARTTIME exactly to nanoseconds since the Unix epoch",
          "[can][trc]") {
  const auto start_of = [](const std::string& value) {
    return read_trc(";$FILEVERSION=2.1\n;$STARTTIME=" + value + "\n").start;
  };
  CHECK(start_of("25569") == 0);
  CHECK(start_of("25569.5") == 43'200'000'000'000LL);
  CHECK(start_of("25570.0000000000") == 86'400'000'000'000LL);
  CHECK(start_of("41766.4648963872") == 1'399'460'967'047'854'080LL);
  CHECK(start_of("44548.6028595139") == 1'639'837'687'062'000'960LL);
  CHECK(start_of("25568") == -86'400'000'000'000LL);
  CHECK(start_of(" 25569.25 ") == 21'600'000'000'000LL);
  const TrcResult bad =
      read_trc(";$FILEVERSION=2.1\n;$STARTTIME=yesterday\n1 1.0 DT 1 0100 Rx - 0\n");
  CHECK_FALSE(bad.start.has_value());
  CHECK(bad.entries.size() == 1);  // reading goes on with offsets from 0
  REQUIRE(bad.errors.size() == 1);
  CHECK(bad.errors[0].to_string() == "t.trc:2:13: $STARTTIME 'yesterday' is not a number of days");
}

TEST_CASE("TRC reader reports malformed records with file, line, column and reason", "[can][trc]") {
  struct Case {
    const char* line;
    const char* message;
    std::uint32_t column;
  };
  const std::vector<Case> cases = {
      {"2 1.0 XX 1 0100 Rx - 0", "unknown record type 'XX'", 7},
      {"2 1.0 DT 1 01G0 Rx - 0", "identifier '01G0' is not hexadecimal", 12},
      {"2 1.0 DT 1 123456789 Rx - 0", "must have 1 to 8 hex digits", 12},
      {"2 1.0 DT 1 0800 Rx - 0", "identifier 0800 exceeds 7FF", 12},
      {"2 1.0 DT 1 20000000 Rx - 0", "identifier 20000000 exceeds 1FFFFFFF", 12},
      {"2 1.0 DT 1 0100 Rx - 8 00 11", "expected 8 data bytes, found 2", 24},
      {"2 1.0 DT 1 0100 Rx - 2 00 1G", "'1G' is not a data byte", 27},
      {"2 1.0 DT 1 0100 Rx - 1 001", "'001' is not a data byte", 24},
      {"2 12a.5 DT 1 0100 Rx - 0", "time offset '12a.5' is not a number", 3},
      {"2 1.1234567 DT 1 0100 Rx - 0", "more than 6 decimals", 3},
      {"2 1.0 DT 1", "missing identifier column", 11},
      {"2 1.0", "missing type column", 6},
      {"2 1.0 DT 1 0100 Rz - 0", "direction 'Rz' must be Rx or Tx", 17},
      {"2 1.0 DT 0 0100 Rx - 0", "bus '0' is not a number 1-256", 10},
      {"2 1.0 DT x 0100 Rx - 0", "bus 'x' is not a number 1-256", 10},
      {"2 1.0 DT 1 0100 Rx - 16", "DLC '16' is not a number 0-15", 22},
      {"2 1.0 RR 1 0100 Rx - 2 00 11", "a remote frame carries no data bytes", 24},
      {"2) 1.0 DT 1 0100 Rx - 0", "message number must be digits", 1},
      {"2 1.0 ER 1 - Rx - 9 01 02 03 04 05 06 07 08 09", "more than 8 data bytes", 45},
      {"2 1.0 ER 1 - - - 0", "error record without a direction", 19},
  };
  for (const Case& c : cases) {
    INFO(c.line);
    const ParseError e = v21_error(c.line);
    CHECK_THAT(e.message, Catch::Contains(c.message));
    CHECK(e.column == c.column);
    CHECK_THAT(e.to_string(), Catch::StartsWith("t.trc:5:" + std::to_string(c.column) + ": "));
  }
  // Version 1 specifics.
  const TrcResult r = read_trc(
      ";$FILEVERSION=1.1\n"
      "     1)      1059.9  Rx         0300  8  00 00\n"
      "     2       1059.9  Rx         0300  0\n"
      "     3)      1059.9  Foo        0300  0\n"
      "     4)      1059.9  Rx         0300  2  RTR 00\n"
      "     5)      1059.9  Rx         0300  9  00 01 02 03 04 05 06 07\n");
  CHECK(r.entries.size() == 1);  // DLC 9 on Classical CAN: 8 bytes
  REQUIRE(r.errors.size() == 4);
  CHECK(r.errors[0].to_string() == "t.trc:2:42: expected 8 data bytes, found 2");
  CHECK(r.errors[1].to_string() == "t.trc:3:6: message number must be digits followed by ')'");
  CHECK(r.errors[2].to_string() == "t.trc:4:22: unknown record type 'Foo'");
  CHECK(r.errors[3].to_string() == "t.trc:5:42: a remote frame carries no data bytes");
}

TEST_CASE("TRC reader fails on a header it cannot use, whatever the policy", "[can][trc]") {
  std::istringstream in(";$FILEVERSION=3.0\n1 1.0 DT 1 0100 Rx - 0\n");
  TrcReader reader(in, "t.trc");
  const auto e = reader.next();
  REQUIRE_FALSE(e.has_value());
  CHECK(e.error().code == EINVAL);
  CHECK(e.error().message ==
        "t.trc:1:15: unsupported $FILEVERSION '3.0' (1.0 to 1.3, 2.0 and 2.1 are supported)");
  CHECK_FALSE(reader.next().has_value());

  std::istringstream cols(";$FILEVERSION=2.1\n;$COLUMNS=N,O,T,X,D\n1 1.0 DT\n");
  TrcReader bad_columns(cols, "c.trc");
  const auto f = bad_columns.next();
  REQUIRE_FALSE(f.has_value());
  CHECK_THAT(f.error().message, Catch::Contains("$COLUMNS: unknown column 'X'"));
  CHECK_THAT(f.error().message, Catch::Contains("(line 2)"));

  std::istringstream few(";$FILEVERSION=2.0\n;$COLUMNS=N,O,T,d,D\n1 1.0 DT Rx\n");
  TrcReader few_columns(few, "f.trc");
  const auto g = few_columns.next();
  REQUIRE_FALSE(g.has_value());
  CHECK_THAT(g.error().message, Catch::Contains("must name at least O, T, I, D and L or l"));
}

TEST_CASE("TRC reader handles empty files, comments only and Stop mode", "[can][trc]") {
  TrcResult r = read_trc("");
  CHECK(r.entries.empty());
  CHECK(r.malformed == 0);
  r = read_trc(";$FILEVERSION=2.1\r\n;\r\n; only comments\r\n\r\n   \r\n");
  CHECK(r.entries.empty());
  CHECK(r.malformed == 0);
  CHECK(r.version == TrcVersion::V2_1);

  std::istringstream in(kV21Header + "1 1.0 DT 1 0100 Rx - 0\r\n2 1.0 DT 1 0100 Rx - 1\r\n");
  ReaderOptions options;
  options.on_malformed = OnMalformed::Stop;
  TrcReader reader(in, "s.trc", options);
  REQUIRE(reader.next().value().has_value());
  const auto e = reader.next();
  REQUIRE_FALSE(e.has_value());
  CHECK(e.error().message == "s.trc:5:23: expected 1 data bytes, found 0");
  CHECK(reader.line_number() == 5);
}

TEST_CASE("TRC reader streams a million generated records in constant memory",
          "[can][trc][stream]") {
  constexpr std::uint64_t kLines = 1'000'000;
  auto make = [](std::uint64_t i, char* out) -> std::size_t {
    if (i < 3) {
      static constexpr const char* kHeader[] = {";$FILEVERSION=2.1\r\n", ";$STARTTIME=25569\r\n",
                                                ";$COLUMNS=N,O,T,B,I,d,R,L,D\r\n"};
      const std::size_t n = std::strlen(kHeader[i]);
      std::memcpy(out, kHeader[i], n);
      return n;
    }
    char* p = std::to_chars(out, out + 20, i - 2).ptr;
    *p++ = ' ';
    p = std::to_chars(p, p + 20, i).ptr;  // i ms
    const char rest[] = ".250 FB 2 18FEF121 Rx - 9 00 01 02 03 04 05 06 07 08 09 0A 0B\r\n";
    std::memcpy(p, rest, sizeof rest - 1);
    return static_cast<std::size_t>(p - out) + sizeof rest - 1;
  };
  vigil::test::LineGenerator gen(kLines + 3, make);
  std::istream in(&gen);
  TrcReader reader(in, "<generated>");
  REQUIRE(reader.next().value().has_value());
  std::uint64_t count = 1;
  std::uint64_t mismatches = 0;
  const std::uint64_t before = vigil::platform::thread_allocations();
  for (;;) {
    auto e = reader.next();
    if (!e || !*e) break;
    const Frame& f = (*e)->frame;
    if (f.timestamp != static_cast<Nanos>(count + 3) * kMs + 250'000 || f.length != 12 || !f.brs ||
        f.bus != 1) {
      ++mismatches;
    }
    ++count;
  }
  const std::uint64_t allocations = vigil::platform::thread_allocations() - before;
  CHECK(count == kLines);
  CHECK(mismatches == 0);
  CHECK(reader.malformed_count() == 0);
  if (vigil::platform::allocation_counting_available()) {
    CHECK(allocations == 0);
  } else {
    WARN("allocation counting unavailable (sanitizer build): constant memory not measured");
  }
}

TEST_CASE("TRC reader opens files and reports missing ones", "[can][trc]") {
  const auto missing = TrcReader::open("/nonexistent/trace.trc");
  REQUIRE_FALSE(missing.has_value());
  CHECK(missing.error().code == ENOENT);
  CHECK_THAT(missing.error().message, Catch::Contains("/nonexistent/trace.trc"));
  CHECK_FALSE(vigil::can::read_trc_file("/nonexistent/trace.trc").has_value());
  CHECK(std::string(to_string(TrcVersion::V2_1)) == "2.1");
}

TEST_CASE("TRC reader survives mutated input and returns only valid frames", "[can][trc][fuzz]") {
  const std::vector<std::string> seeds21 = {
      "      1      1059.900 DT 1      0300 Rx -  7    00 00 00 00 04 00 00",
      "      2      1334.416 FD 2      0500 Tx -  9    01 02 03 04 05 06 07 08 09 0A 0B 0C",
      "      3      1334.420 FB 1  18EFC034 Rx -  8    01 02 03 04 05 06 07 08",
      "      6      1334.222 ER 1         - Rx -  5    04 00 02 00 00",
      "      7      1334.224 EV 1  User-defined event for bus 1",
      "      8      1334.231 ST 1         - Rx -  4    00 00 00 08",
      "     11      1336.543 RR 1      0100 Rx -  3",
      "     12      1337.000 DT 3      0123 Rx -  12   01 02 03 04 05 06 07 08",
  };
  const std::vector<std::string> seeds20 = {
      "      1      1059.900 DT     0300 Rx 7  00 00 00 00 04 00 00",
      "      5      1334.416 FD     0500 Tx 12 01 02 03 04 05 06 07 08 09 0A 0B 0C",
      "      6      1334.522 ER          Rx    04 00 02 00 00",
      "      7      1334.531 ST          Rx    00 00 00 08",
      "      9      1335.156 DT 18EFC034 Tx 8  01 02 03 04 05 06 07 08",
      "     10      1336.543 RR     0100 Rx 3",
  };
  const std::vector<std::string> seeds11 = {
      "     1)      1059.9  Rx         0300  8  00 01 02 03 04 05 06 07",
      "     2)      1060.0  Tx     18FEF121  3  AA BB CC",
      "     3)      1100.5  Warng  FFFFFFFF  4  00 00 00 08  BUSHEAVY",
      "     4)      1200.1  Rx         0100  3  RTR",
      "     5)      1300.2  Error      0008  4  00 19 08 08",
  };
  const std::string alphabet = "0123456789ABCDEFabcdef -.;$RxTDFBIEST)\t";
  const std::vector<std::pair<std::string, const std::vector<std::string>*>> variants = {
      {";$FILEVERSION=2.1\n;$STARTTIME=44548.6028595139\n", &seeds21},
      {";$FILEVERSION=2.0\n;$COLUMNS=N,O,T,I,d,l,D\n", &seeds20},
      {";$FILEVERSION=1.1\n;$STARTTIME=44548.6028595139\n", &seeds11},
  };
  for (const auto& [header, seeds_ptr] : variants) {
    const std::vector<std::string>& seeds = *seeds_ptr;
    std::istringstream in(header + seeds[0] + "\n" +
                          vigil::test::mutated_lines(seeds, alphabet, 100'000, 777));
    TrcReader reader(in, "<fuzz>");
    const auto read = vigil::test::read_through(reader);
    REQUIRE(read.every_call_ok);
    CHECK(read.invalid == 0);
    CHECK(read.frames > 1000);
    CHECK(reader.malformed_count() > 1000);
  }
}
