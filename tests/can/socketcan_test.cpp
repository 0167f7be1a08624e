#include "vigil/can/socketcan.hpp"

#include <catch2/catch.hpp>
#include <cerrno>
#include <string>

#include "can_test_support.hpp"

using namespace vigil::can;

namespace {

// Why SocketCAN tests cannot run here, or empty when they can. A kernel without PF_CAN fails
// socket() with EAFNOSUPPORT: the tests are skipped with that reason, not failed.
std::string socketcan_missing() {
  const auto available = socketcan_available();
  if (available) return {};
  if (available.error().code == EAFNOSUPPORT) {
    return "this kernel has no PF_CAN (socket(PF_CAN, SOCK_RAW, CAN_RAW) failed with "
           "EAFNOSUPPORT): load the can and can_raw modules to run this test";
  }
  return "SocketCAN is not usable: " + available.error().message;
}

// The virtual interface the round-trip test uses; skipped with a reason when absent.
constexpr const char* kInterface = "vcan0";

}  // namespace

TEST_CASE("SocketCAN availability is reported with its errno", "[can][socketcan]") {
  const auto available = socketcan_available();
  if (!available) {
    CHECK(available.error().code != 0);
    CHECK(available.error().message.find("socket(PF_CAN") == 0);
    if (available.error().code == EAFNOSUPPORT) WARN("skipped: " << socketcan_missing());
  }
}

TEST_CASE("SocketCAN refuses bad interface names before touching the kernel", "[can][socketcan]") {
  const auto missing = socketcan_missing();
  const auto empty = SocketCan::open("");
  REQUIRE_FALSE(empty.has_value());
  CHECK(empty.error().code == ENAMETOOLONG);
  const auto long_name = SocketCan::open("an-interface-name-too-long");
  REQUIRE_FALSE(long_name.has_value());
  CHECK(long_name.error().code == ENAMETOOLONG);
  if (!missing.empty()) {
    const auto none = SocketCan::open("can0");
    REQUIRE_FALSE(none.has_value());
    CHECK(none.error().code == EAFNOSUPPORT);
    WARN("skipped the rest: " << missing);
    return;
  }
  const auto none = SocketCan::open("vigil-nodev9");
  REQUIRE_FALSE(none.has_value());
  CHECK(none.error().code == ENODEV);
  CHECK(none.error().message.find("vigil-nodev9") != std::string::npos);
}

TEST_CASE("SocketCAN round trip on vcan0 through two sniffers", "[can][socketcan]") {
  const auto missing = socketcan_missing();
  if (!missing.empty()) {
    WARN("skipped: " << missing);
    return;
  }
  auto tx = SocketCan::open(kInterface, {.bus = 0});
  if (!tx && tx.error().code == ENODEV) {
    WARN("skipped: no " << kInterface << " interface (ip link add dev vcan0 type vcan && "
                        << "ip link set up vcan0)");
    return;
  }
  REQUIRE(tx.has_value());
  auto rx = SocketCan::open(kInterface, {.bus = 3, .read_timeout_ns = vigil::kNanosPerSecond});
  REQUIRE(rx.has_value());

  CanRegistry registry;
  Sniffer<64> writer(registry, "writer");
  Sniffer<64> reader(registry, "reader");
  const Frame sent = Frame::classic(0x18FEF121, {1, 2, 3, 4, 5, 6, 7, 8}, IdFormat::Extended);
  REQUIRE(tx->write(sent, writer) == IoStatus::Ok);
  REQUIRE(tx->write(Frame::remote(0x123, 2), writer) == IoStatus::Ok);
  Frame got;
  REQUIRE(rx->read(got, reader) == IoStatus::Ok);
  CHECK(got.id == 0x18FEF121);
  CHECK(got.extended);
  CHECK(got.bus == 3);
  CHECK(got.payload().size() == 8);
  CHECK(got.data[7] == 8);
  REQUIRE(rx->read(got, reader) == IoStatus::Ok);
  CHECK(got.rtr);
  CHECK(got.length == 2);
  CHECK(writer.totals().tx == 2);
  CHECK(reader.totals().rx == 2);
  CHECK(reader.ids().size() == 2);

  // A read with nothing to read times out.
  auto quick = SocketCan::open(kInterface, {.read_timeout_ns = 10 * vigil::kNanosPerMilli});
  REQUIRE(quick.has_value());
  CHECK(quick->read(got) == IoStatus::Timeout);
  // CAN FD frames need the fd option.
  CHECK(tx->write(Frame::fd_frame(0x1, {1, 2, 3})) == IoStatus::Error);
  CHECK(tx->last_error() == EINVAL);
}
