#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "vigil/can/log/candump.hpp"

using vigil::can::CandumpReader;
using vigil::can::Direction;
using vigil::can::FdFlags;
using vigil::can::Frame;
using vigil::can::IdFormat;
using vigil::can::LogEntry;
using vigil::can::TimestampDigits;
using vigil::can::write_candump_line;

namespace {

std::string line_of(const Frame& f, std::optional<Direction> dir = std::nullopt,
                    TimestampDigits digits = TimestampDigits::Micro) {
  std::string out;
  write_candump_line(out, f, "can0", dir, {digits});
  return out;
}

Frame at(Frame f, vigil::Nanos ts) {
  f.timestamp = ts;
  return f;
}

// A scratch directory removed at the end of the test.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() /
           ("vigil_can_test_" + std::to_string(::getpid()) + "_" +
            std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

// Random valid frames of every kind, with microsecond timestamps (what candump -l keeps).
Frame random_frame(std::mt19937_64& rng, std::uint64_t i) {
  auto pick = [&](std::uint64_t n) { return static_cast<std::uint32_t>(rng() % n); };
  Frame f;
  f.timestamp = static_cast<vigil::Nanos>(1'600'000'000'000'000ULL + i * 137 + pick(1000)) * 1000;
  f.bus = static_cast<std::uint8_t>(pick(4));
  const auto kind = pick(4);
  f.extended = pick(2) == 1;
  f.id = f.extended ? pick(vigil::can::kMaxExtendedId + 1) : pick(vigil::can::kMaxStandardId + 1);
  if (kind == 0) {  // Classical CAN, sometimes with a raw DLC 9..15
    f.length = static_cast<std::uint8_t>(pick(9));
    if (f.length == 8 && pick(2) == 1) f.length = static_cast<std::uint8_t>(9 + pick(7));
  } else if (kind == 1) {  // remote
    f.rtr = true;
    f.length = static_cast<std::uint8_t>(pick(16));
  } else if (kind == 2) {  // CAN FD
    f.fd = true;
    f.brs = pick(2) == 1;
    f.esi = pick(2) == 1;
    f.length = vigil::can::dlc_to_length(static_cast<std::uint8_t>(pick(16)));
  } else {  // error frame
    f.extended = false;
    f.error = true;
    f.id = pick(vigil::can::kMaxExtendedId + 1);
    f.length = static_cast<std::uint8_t>(pick(9));
  }
  for (std::size_t b = 0; b < f.data_size(); ++b) f.data[b] = static_cast<std::uint8_t>(rng());
  return f;
}

std::vector<std::string> split(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  for (std::string t; in >> t;) out.push_back(t);
  return out;
}

std::string hex_id(const Frame& f) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%X%s", f.id, f.extended ? "x" : "");
  return buf;
}

std::string hex_byte(std::uint8_t b) {
  char buf[4];
  std::snprintf(buf, sizeof buf, "%02X", b);
  return buf;
}

}  // namespace

TEST_CASE("candump writer produces exactly the lines candump -l writes", "[can][candump][writer]") {
  constexpr vigil::Nanos t = 1'648'583'717'428'998'000LL;
  CHECK(line_of(at(Frame::classic(0x123, {0x11, 0x22}), t)) ==
        "(1648583717.428998) can0 123#1122\n");
  CHECK(line_of(at(Frame::classic(0x1, {}), 1'000'001'000)) == "(0000000001.000001) can0 001#\n");
  CHECK(line_of(Frame::classic(0x0CF00400, {0x70, 0x7D, 0xab}, IdFormat::Extended)) ==
        "(0000000000.000000) can0 0CF00400#707DAB\n");
  CHECK(line_of(Frame::remote(0x7DF)) == "(0000000000.000000) can0 7DF#R\n");
  CHECK(line_of(Frame::remote(0x7DF, 3)) == "(0000000000.000000) can0 7DF#R3\n");
  CHECK(line_of(Frame::remote(0x7DF, 8)) == "(0000000000.000000) can0 7DF#R8\n");
  CHECK(line_of(Frame::remote(0x7DF, 9)) == "(0000000000.000000) can0 7DF#R8_9\n");
  CHECK(line_of(Frame::remote(0x1234, 2, IdFormat::Extended)) ==
        "(0000000000.000000) can0 00001234#R2\n");
  CHECK(line_of(Frame::fd_frame(0x123, {})) == "(0000000000.000000) can0 123##4\n");
  CHECK(line_of(Frame::fd_frame(0x123, {0xAA}, IdFormat::Standard, {.brs = true})) ==
        "(0000000000.000000) can0 123##5AA\n");
  CHECK(line_of(Frame::fd_frame(0x123, {0xAA}, IdFormat::Standard, {.esi = true})) ==
        "(0000000000.000000) can0 123##6AA\n");
  CHECK(line_of(Frame::fd_frame(0x18FEF121, {1, 2, 3, 4, 5, 6, 7, 8, 9}, IdFormat::Extended,
                                FdFlags{true, true})) ==
        "(0000000000.000000) can0 18FEF121##7010203040506070809000000\n");
  CHECK(line_of(Frame::error_frame(0x4, {0, 4, 0, 0, 0, 0, 0, 0})) ==
        "(0000000000.000000) can0 20000004#0004000000000000\n");
  Frame raw = Frame::classic(0x321, {0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11});
  raw.length = 11;
  CHECK(line_of(raw) == "(0000000000.000000) can0 321#8877665544332211_B\n");
  CHECK(line_of(Frame::classic(0x123, {1}), Direction::Tx) ==
        "(0000000000.000000) can0 123#01 T\n");
  CHECK(line_of(Frame::classic(0x123, {1}), Direction::Rx) ==
        "(0000000000.000000) can0 123#01 R\n");
  CHECK(line_of(at(Frame::classic(0x123, {}), t + 123), std::nullopt, TimestampDigits::Nano) ==
        "(1648583717.428998123) can0 123#\n");
  CHECK(line_of(at(Frame::classic(0x123, {}), 1'000'001'999)) ==
        "(0000000001.000001) can0 123#\n");  // truncated like candump
  CHECK(line_of(at(Frame::classic(0x123, {}), -5)) == "(0000000000.000000) can0 123#\n");

  std::ostringstream os;
  write_candump_line(os, at(Frame::classic(0x123, {0x11, 0x22}), t), "vcan10", Direction::Tx);
  CHECK(os.str() == "(1648583717.428998) vcan10 123#1122 T\n");
}

TEST_CASE("candump writer then reader round-trips every kind of frame exactly",
          "[can][candump][writer]") {
  std::mt19937_64 rng(20240531);
  const std::vector<std::string> names{"can0", "vcan1", "slcan2", "can3"};
  std::vector<LogEntry> written;
  std::string text;
  for (std::uint64_t i = 0; i < 20'000; ++i) {
    LogEntry e{random_frame(rng, i), std::nullopt};
    const auto d = rng() % 3;
    if (d == 1) e.direction = Direction::Rx;
    if (d == 2) e.direction = Direction::Tx;
    REQUIRE(e.frame.valid());
    write_candump_line(text, e.frame, names[e.frame.bus], e.direction);
    written.push_back(e);
  }
  std::istringstream in(text);
  CandumpReader reader(in, "<round-trip>");
  std::size_t i = 0;
  std::size_t mismatches = 0;
  for (;;) {
    auto e = reader.next();
    REQUIRE(e.has_value());
    if (!*e) break;
    REQUIRE(i < written.size());
    LogEntry got = **e;
    CHECK(reader.interfaces().at(got.frame.bus) == names[written[i].frame.bus]);
    got.frame.bus = written[i].frame.bus;  // the reader numbers interfaces by first appearance
    if (!(got == written[i]) && ++mismatches <= 3) {
      std::string back;
      write_candump_line(back, got.frame, "read", got.direction);
      std::string sent;
      write_candump_line(sent, written[i].frame, "sent", written[i].direction);
      WARN("entry " << i << " differs:\n" << sent << back);
    }
    ++i;
  }
  CHECK(i == written.size());
  CHECK(mismatches == 0);
  CHECK(reader.malformed_count() == 0);

  // parse_candump_frame(frame field of write(frame)) == frame, too.
  for (std::size_t k = 0; k < 200; ++k) {
    const Frame f = random_frame(rng, k);
    std::string line;
    write_candump_line(line, f, "can0");
    const auto start = line.find(' ', line.find(')')) + 1;
    const auto frame_field = line.substr(line.find(' ', start) + 1);
    auto parsed = vigil::can::parse_candump_frame(frame_field.substr(0, frame_field.size() - 1));
    REQUIRE(parsed.has_value());
    parsed->timestamp = f.timestamp;
    parsed->bus = f.bus;
    CHECK(*parsed == f);
  }
}

TEST_CASE("write_candump_file and read_candump_file round-trip a log", "[can][candump][writer]") {
  TempDir dir;
  const std::vector<std::string> names{"can0", "can1"};
  std::vector<LogEntry> entries{
      {at(Frame::classic(0x123, {1, 2, 3}), 1'000'000'000), std::nullopt},
      {at(Frame::remote(0x10, 2), 1'000'001'000), Direction::Tx},
      {at(Frame::fd_frame(0x456, {9, 8, 7}), 2'000'000'000), Direction::Rx},
  };
  entries[1].frame.bus = 1;
  entries[2].frame.bus = 7;  // no name given: written as can7
  const auto path = dir.path / "out.log";
  REQUIRE(vigil::can::write_candump_file(path, entries, names).has_value());
  const auto log = vigil::can::read_candump_file(path);
  REQUIRE(log.has_value());
  CHECK(log->interfaces == std::vector<std::string>{"can0", "can1", "can7"});
  REQUIRE(log->entries.size() == 3);
  auto expected = entries;
  expected[2].frame.bus = 2;
  CHECK(log->entries == expected);

  const auto bad =
      vigil::can::write_candump_file(dir.path / "no" / "such" / "dir.log", entries, names);
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().code == ENOENT);
}

TEST_CASE("log2asc accepts a log written by vigil frame for frame", "[can][candump][log2asc]") {
  const char* tool = "/usr/bin/log2asc";
  if (!std::filesystem::exists(tool)) {
    WARN("log2asc (can-utils) is not installed: skipped");
    return;
  }
  TempDir dir;
  std::vector<LogEntry> entries;
  const vigil::Nanos t0 = 1'700'000'000'000'000'000LL;
  auto add = [&](Frame f, std::optional<Direction> d = std::nullopt) {
    f.timestamp = t0 + static_cast<vigil::Nanos>(entries.size()) * 1'500'000;  // 1.5 ms apart
    entries.push_back({f, d});
  };
  add(Frame::classic(0x123, {0x11, 0x22}));
  add(Frame::classic(0x0CF00400, {0x70, 0x7D, 0x83, 0xC3, 0x12, 0x00, 0x0F, 0x84},
                     IdFormat::Extended),
      Direction::Tx);
  add(Frame::classic(0x7FF, {}));
  add(Frame::remote(0x100));
  add(Frame::remote(0x1ABCDEF, 5, IdFormat::Extended), Direction::Rx);
  add(Frame::fd_frame(0x321, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}, IdFormat::Standard,
                      {.brs = true}));
  std::vector<std::uint8_t> sixty_four(64);
  for (std::size_t i = 0; i < 64; ++i) sixty_four[i] = static_cast<std::uint8_t>(i * 3);
  add(Frame::fd_frame(0x18FEF121, sixty_four, IdFormat::Extended, {.brs = true, .esi = true}),
      Direction::Tx);
  add(Frame::fd_frame(0x0, {}));
  add(Frame::error_frame(0x4, {0, 4, 0, 0, 0, 0, 0, 0}));
  add(Frame::error_frame(0x80, {}));

  const auto in = dir.path / "in.log";
  const auto out = dir.path / "out.asc";
  REQUIRE(
      vigil::can::write_candump_file(in, entries, std::vector<std::string>{"can0"}).has_value());
  const std::string command = std::string(tool) + " -I '" + in.string() + "' -O '" + out.string() +
                              "' can0 2>'" + (dir.path / "err.txt").string() + "'";
  const int rc = std::system(command.c_str());
  REQUIRE(rc == 0);

  std::ifstream asc(out);
  std::vector<std::string> lines;
  for (std::string l; std::getline(asc, l);) lines.push_back(l);
  REQUIRE(lines.size() == 3 + entries.size());  // "date", "base hex", "no internal events"
  CHECK_THAT(lines[0], Catch::StartsWith("date "));
  CHECK_THAT(lines[1], Catch::StartsWith("base hex"));
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Frame& f = entries[i].frame;
    const auto tok = split(lines[3 + i]);
    INFO("frame " << i << ": " << lines[3 + i]);
    REQUIRE(tok.size() >= 3);
    char rel[32];
    const auto us = (f.timestamp - t0) / 1000;
    std::snprintf(rel, sizeof rel, "%lld.%06lld", static_cast<long long>(us / 1'000'000),
                  static_cast<long long>(us % 1'000'000));
    CHECK(tok[0] == rel);
    const std::string dir_text = entries[i].direction == Direction::Tx ? "Tx" : "Rx";
    if (f.error) {
      CHECK(tok[1] == "1");
      CHECK(tok[2] == "ErrorFrame");
    } else if (f.fd) {
      REQUIRE(tok.size() >= 9 + f.data_size());
      CHECK(tok[1] == "CANFD");
      CHECK(tok[2] == "1");
      CHECK(tok[3] == dir_text);
      CHECK(tok[4] == hex_id(f));
      CHECK(tok[5] == (f.brs ? "1" : "0"));
      CHECK(tok[6] == (f.esi ? "1" : "0"));
      CHECK(tok[8] == std::to_string(f.length));
      for (std::size_t b = 0; b < f.data_size(); ++b) CHECK(tok[9 + b] == hex_byte(f.data[b]));
    } else {
      REQUIRE(tok.size() >= 6 + f.data_size());
      CHECK(tok[1] == "1");
      CHECK(tok[2] == hex_id(f));
      CHECK(tok[3] == dir_text);
      CHECK(tok[4] == (f.rtr ? "r" : "d"));
      CHECK(tok[5] == std::to_string(f.length));
      CHECK(tok.size() == 6 + f.data_size());
      for (std::size_t b = 0; b < f.data_size(); ++b) CHECK(tok[6 + b] == hex_byte(f.data[b]));
    }
  }
}
