#include "vigil/can/socketcan.hpp"

// The control-buffer tests build what recvmsg(2) returns: tests may include OS headers.
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>

#include <catch2/catch.hpp>
#include <cerrno>
#include <cstring>
#include <string>

#include "can_test_support.hpp"

using namespace vigil::can;
using vigil::Nanos;

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
  // vcan has no controller: the hardware option falls back to the kernel's software stamp.
  auto hw = SocketCan::open(
      kInterface, {.read_timeout_ns = vigil::kNanosPerSecond, .timestamp = RxTimestamp::Hardware});
  REQUIRE(hw.has_value());
  const vigil::Nanos before = vigil::platform::now_ns();

  CanRegistry registry;
  Sniffer<64> writer(registry, "writer");
  Sniffer<64> reader(registry, "reader");
  const Frame sent = Frame::classic(0x18FEF121, {1, 2, 3, 4, 5, 6, 7, 8}, IdFormat::Extended);
  REQUIRE(tx->write(sent, writer) == IoStatus::Ok);
  REQUIRE(tx->write(Frame::remote(0x123, 2), writer) == IoStatus::Ok);
  Frame got;
  REQUIRE(rx->read(got, reader) == IoStatus::Ok);
  // Its receive timestamp, on vigil's clock: after the write began, no later than the read.
  CHECK(got.timestamp >= before - vigil::kNanosPerMilli);
  CHECK(got.timestamp <= vigil::platform::now_ns());
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
  Frame stamped;
  REQUIRE(hw->read(stamped) == IoStatus::Ok);
  CHECK(stamped.id == 0x18FEF121);
  CHECK(stamped.timestamp <= vigil::platform::now_ns());

  // A read with nothing to read times out.
  auto quick = SocketCan::open(kInterface, {.read_timeout_ns = 10 * vigil::kNanosPerMilli});
  REQUIRE(quick.has_value());
  CHECK(quick->read(got) == IoStatus::Timeout);
  // CAN FD frames need the fd option.
  CHECK(tx->write(Frame::fd_frame(0x1, {1, 2, 3})) == IoStatus::Error);
  CHECK(tx->last_error() == EINVAL);
}

TEST_CASE("SocketCAN finds the receive timestamp in recvmsg's control buffer", "[can][socketcan]") {
  constexpr std::size_t kSize = CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(3 * sizeof(timespec));
  alignas(cmsghdr) unsigned char buffer[kSize];
  std::memset(buffer, 0, sizeof buffer);
  msghdr msg{};
  msg.msg_control = buffer;
  msg.msg_controllen = sizeof buffer;
  const auto put = [&](cmsghdr* c, int level, int type, const timespec* t, std::size_t n) {
    c->cmsg_level = level;
    c->cmsg_type = type;
    c->cmsg_len = CMSG_LEN(n * sizeof(timespec));
    std::memcpy(CMSG_DATA(c), t, n * sizeof(timespec));
    return CMSG_SPACE(n * sizeof(timespec));
  };
  const timespec software{1'700'000'000, 123'456'789};
  const Nanos software_ns = 1'700'000'000 * vigil::kNanosPerSecond + 123'456'789;
  CHECK(detail::receive_stamp(buffer, 0, false).ns == -1);  // no control message at all

  // SO_TIMESTAMPNS.
  std::size_t used = put(CMSG_FIRSTHDR(&msg), SOL_SOCKET, SCM_TIMESTAMPNS, &software, 1);
  CHECK(detail::receive_stamp(buffer, used, false).ns == software_ns);
  CHECK(detail::receive_stamp(buffer, used, true).ns == software_ns);  // no hardware stamp given

  // SO_TIMESTAMPING: ts[0] software, ts[2] raw hardware (zero when the driver gives none).
  std::memset(buffer, 0, sizeof buffer);
  timespec three[3] = {software, {0, 0}, {0, 0}};
  used = put(CMSG_FIRSTHDR(&msg), SOL_SOCKET, SCM_TIMESTAMPING, three, 3);
  CHECK(detail::receive_stamp(buffer, used, true).ns == software_ns);
  three[2] = timespec{5, 7};
  used = put(CMSG_FIRSTHDR(&msg), SOL_SOCKET, SCM_TIMESTAMPING, three, 3);
  CHECK(detail::receive_stamp(buffer, used, true).ns == 5 * vigil::kNanosPerSecond + 7);
  CHECK(detail::receive_stamp(buffer, used, true).hardware);
  CHECK_FALSE(detail::receive_stamp(buffer, used, false).hardware);
  CHECK(detail::receive_stamp(buffer, used, false).ns == software_ns);

  // Messages of other levels are skipped; the stamp after them is found.
  std::memset(buffer, 0, sizeof buffer);
  cmsghdr* first = CMSG_FIRSTHDR(&msg);
  used = put(first, IPPROTO_IP, SCM_TIMESTAMPNS, &software, 1);
  msg.msg_controllen = sizeof buffer;
  const timespec other{1, 2};
  used += put(CMSG_NXTHDR(&msg, first), SOL_SOCKET, SCM_TIMESTAMPNS, &other, 1);
  CHECK(detail::receive_stamp(buffer, used, false).ns == vigil::kNanosPerSecond + 2);
  CHECK(detail::receive_stamp(buffer, CMSG_SPACE(sizeof(timespec)), false).ns == -1);
}

namespace {
constexpr Nanos kUs = vigil::kNanosPerMicro;
constexpr Nanos kMs = vigil::kNanosPerMilli;
constexpr Nanos kRealtime = 1'700'000'000 * vigil::kNanosPerSecond;  // source - vigil's clock
}  // namespace

TEST_CASE("StampMapper gives a late reader's frames the times they arrived", "[can][socketcan]") {
  StampMapper m;
  Nanos previous = 0;
  for (Nanos k = 1; k <= 200; ++k) {
    const Nanos arrived = k * 10 * kMs;
    // Read 50 us after arrival, except frames 50..59 (500..590 ms): found together at 595 ms.
    const Nanos read = k >= 50 && k < 60 ? 595 * kMs + (k - 50) * kUs : arrived + 50 * kUs;
    const Nanos t = m.map(kRealtime + arrived, read);
    INFO("frame " << k);
    CHECK(t <= read);
    CHECK(t >= previous);
    if (k > 1) CHECK(t == arrived + 50 * kUs);  // its arrival, to the smallest wait seen
    previous = t;
  }
}

TEST_CASE("StampMapper never gives a time later than the read, nor earlier than the last",
          "[can][socketcan]") {
  StampMapper m;
  // A backlog at start: the first frames were waiting 30 ms; then one is read at once.
  CHECK(m.map(kRealtime + 10 * kMs, 40 * kMs) == 40 * kMs);
  CHECK(m.map(kRealtime + 20 * kMs, 40 * kMs + 1 * kUs) == 40 * kMs + 1 * kUs);
  CHECK(m.map(kRealtime + 30 * kMs, 40 * kMs + 2 * kUs) == 40 * kMs + 2 * kUs);
  CHECK(m.map(kRealtime + 50 * kMs, 50 * kMs + 10 * kUs) == 50 * kMs + 10 * kUs);
  CHECK(m.map(kRealtime + 60 * kMs, 60 * kMs + 30 * kUs) == 60 * kMs + 10 * kUs);

  // The source clock steps forward by 2 s: followed at once.
  CHECK(m.map(kRealtime + 2 * vigil::kNanosPerSecond + 70 * kMs, 70 * kMs + 20 * kUs) ==
        70 * kMs + 20 * kUs);
  CHECK(m.map(kRealtime + 2 * vigil::kNanosPerSecond + 80 * kMs, 80 * kMs + 40 * kUs) ==
        80 * kMs + 20 * kUs);
  // ... and back by 3 s: the estimate starts over (the frame gets its read time).
  CHECK(m.map(kRealtime - vigil::kNanosPerSecond + 90 * kMs, 90 * kMs + 60 * kUs) ==
        90 * kMs + 60 * kUs);
  CHECK(m.map(kRealtime - vigil::kNanosPerSecond + 100 * kMs, 100 * kMs + 70 * kUs) ==
        100 * kMs + 60 * kUs);
}

TEST_CASE("StampMapper follows a clock that drifts", "[can][socketcan]") {
  // A controller clock 100 ppm slow against vigil's: within 2 windows the error stays < 0.25 ms.
  StampMapper m;
  for (Nanos k = 1; k <= 3000; ++k) {
    const Nanos arrived = k * 10 * kMs;  // 30 s
    const Nanos stamp = 5 * vigil::kNanosPerSecond + arrived - arrived / 10'000;
    const Nanos t = m.map(stamp, arrived + 20 * kUs);
    INFO("frame " << k);
    CHECK(t <= arrived + 20 * kUs);
    CHECK(t >= arrived + 20 * kUs - 250 * kUs);
  }
}
