#include "vigil/can/frame.hpp"

#include <array>
#include <catch2/catch.hpp>
#include <cstring>
#include <type_traits>

using vigil::can::Direction;
using vigil::can::dlc_to_length;
using vigil::can::Frame;
using vigil::can::IdFormat;
using vigil::can::is_fd_length;
using vigil::can::length_to_dlc;

static_assert(std::is_trivially_copyable_v<Frame>);
static_assert(sizeof(Frame) == 80);
static_assert(Frame::classic(0x123, {1, 2}).length == 2, "factories are constexpr");

TEST_CASE("DLC and CAN FD length convert both ways as ISO 11898-1 says", "[can][frame]") {
  constexpr std::array<int, 16> kLength{0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
  for (std::uint8_t dlc = 0; dlc < 16; ++dlc) {
    CHECK(dlc_to_length(dlc) == kLength[dlc]);
    CHECK(length_to_dlc(dlc_to_length(dlc)) == dlc);
    CHECK(is_fd_length(dlc_to_length(dlc)));
  }
  CHECK(length_to_dlc(9) == 9);
  CHECK(length_to_dlc(13) == 10);
  CHECK(length_to_dlc(33) == 14);
  CHECK(length_to_dlc(49) == 15);
  CHECK(length_to_dlc(65) == 15);
  CHECK(length_to_dlc(1000) == 15);
  CHECK(dlc_to_length(0x1F) == 64);  // only the low nibble counts
  int valid = 0;
  for (std::size_t len = 0; len <= 100; ++len) valid += is_fd_length(len) ? 1 : 0;
  CHECK(valid == 16);
  CHECK_FALSE(is_fd_length(9));
  CHECK_FALSE(is_fd_length(65));
}

TEST_CASE("Frame factories build classic, CAN FD, remote and error frames", "[can][frame]") {
  const Frame a = Frame::classic(0x123, {0x11, 0x22, 0x33});
  CHECK(a.id == 0x123);
  CHECK(a.length == 3);
  CHECK_FALSE(a.extended);
  CHECK_FALSE(a.fd);
  CHECK(a.data_size() == 3);
  CHECK(a.payload()[2] == 0x33);
  CHECK(a.dlc() == 3);
  CHECK(a.valid());

  const std::array<std::uint8_t, 10> ten{1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  const Frame cut = Frame::classic(0x18FEF121, ten, IdFormat::Extended);
  CHECK(cut.extended);
  CHECK(cut.length == 8);
  CHECK(cut.valid());

  const Frame fd = Frame::fd_frame(0x100, ten, IdFormat::Standard, {.brs = true});
  CHECK(fd.fd);
  CHECK(fd.brs);
  CHECK_FALSE(fd.esi);
  CHECK(fd.length == 12);  // padded to the next CAN FD length
  CHECK(fd.data_size() == 12);
  CHECK(fd.data[9] == 10);
  CHECK(fd.data[10] == 0);
  CHECK(fd.dlc() == 9);
  CHECK(fd.valid());

  const Frame rtr = Frame::remote(0x7DF, 8);
  CHECK(rtr.rtr);
  CHECK(rtr.length == 8);
  CHECK(rtr.data_size() == 0);
  CHECK(rtr.valid());
  CHECK(Frame::remote(0x7DF, 200).length == 15);

  const Frame err = Frame::error_frame(0x4, {0, 4});
  CHECK(err.error);
  CHECK(err.id == 4);
  CHECK(err.length == 2);
  CHECK(err.valid());
}

TEST_CASE("Frame aggregate init with designated initializers reads naturally", "[can][frame]") {
  const Frame f{.timestamp = 42, .id = 0x1ABCDEF0, .bus = 2, .length = 9, .extended = true};
  CHECK(f.timestamp == 42);
  CHECK(f.bus == 2);
  CHECK(f.data_size() == 8);  // Classical CAN DLC 9..15 still carries 8 bytes
  CHECK(f.dlc() == 9);
  CHECK(f.valid());
}

TEST_CASE("Frame::valid rejects frames that cannot exist on a bus", "[can][frame]") {
  CHECK_FALSE(Frame{.id = 0x800}.valid());
  CHECK(Frame{.id = 0x800, .extended = true}.valid());
  CHECK_FALSE(Frame{.id = 0x20000000, .extended = true}.valid());
  CHECK_FALSE(Frame{.length = 16}.valid());
  CHECK_FALSE(Frame{.length = 9, .fd = true}.valid());
  CHECK_FALSE(Frame{.rtr = true, .fd = true}.valid());
  CHECK_FALSE(Frame{.brs = true}.valid());
  CHECK_FALSE(Frame{.length = 9, .error = true}.valid());
}

TEST_CASE("Frame equality compares fields and the used data bytes only", "[can][frame]") {
  Frame a = Frame::classic(0x123, {1, 2});
  Frame b = a;
  b.data[5] = 0xEE;  // beyond length: not part of the frame
  CHECK(a == b);
  b.data[1] = 3;
  CHECK_FALSE(a == b);
  b = a;
  b.bus = 1;
  CHECK_FALSE(a == b);
  b = a;
  b.extended = true;
  CHECK_FALSE(a == b);
  Frame r1 = Frame::remote(0x10, 4);
  Frame r2 = r1;
  r2.data[0] = 0x55;  // remote frames carry no data
  CHECK(r1 == r2);
  // Trivially copyable: memcpy is a valid copy.
  Frame c;
  std::memcpy(&c, &a, sizeof(Frame));
  CHECK(c == a);
  CHECK(to_string(Direction::Rx) == "Rx");
  CHECK(to_string(Direction::Tx) == "Tx");
}
