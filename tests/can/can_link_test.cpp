// The netlink reading of a CAN controller's state (vigil/can/can_link.hpp): the parser against
// RTM_NEWLINK messages built by hand from the kernel's UAPI headers (linux/netlink.h,
// linux/rtnetlink.h, linux/if_link.h, linux/can/netlink.h), bad input, the live query on `lo`,
// and the CAN monitor judging the readings.
#include "vigil/can/can_link.hpp"

#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>

#include <fmt/format.h>

#include <array>
#include <catch2/catch.hpp>
#include <cerrno>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "vigil/can/can_monitor.hpp"

using namespace vigil::can;

namespace {

// A netlink message under construction: the header, the ifinfomsg, nested attributes.
class Message {
 public:
  explicit Message(std::uint16_t type = RTM_NEWLINK) {
    nlmsghdr h{};
    h.nlmsg_type = type;
    put(&h, sizeof(h));
    if (type == RTM_NEWLINK) {
      ifinfomsg ifi{};
      ifi.ifi_index = 7;
      ifi.ifi_flags = IFF_UP;
      put(&ifi, sizeof(ifi));
    }
  }
  // Opens a nested attribute; `close` it with the value returned.
  std::size_t open(std::uint16_t type) {
    const std::size_t at = bytes_.size();
    nlattr a{};
    a.nla_type = static_cast<std::uint16_t>(type | NLA_F_NESTED);  // as the kernel sets it
    put(&a, sizeof(a));
    return at;
  }
  void close(std::size_t at) {
    const auto len = static_cast<std::uint16_t>(bytes_.size() - at);
    std::memcpy(bytes_.data() + at, &len, sizeof(len));
  }
  void attr(std::uint16_t type, const void* p, std::size_t n) {
    nlattr a{};
    a.nla_len = static_cast<std::uint16_t>(sizeof(a) + n);
    a.nla_type = type;
    put(&a, sizeof(a));
    put(p, n);
    while (bytes_.size() % 4 != 0) bytes_.push_back(0);  // NLA_ALIGN
  }
  void text(std::uint16_t type, const char* s) { attr(type, s, std::strlen(s) + 1); }
  template <class T>
  void value(std::uint16_t type, const T& v) {
    attr(type, &v, sizeof(v));
  }
  std::vector<std::uint8_t> done() {
    const auto len = static_cast<std::uint32_t>(bytes_.size());
    std::memcpy(bytes_.data(), &len, sizeof(len));  // nlmsg_len
    return bytes_;
  }

 private:
  void put(const void* p, std::size_t n) {
    const std::size_t at = bytes_.size();
    bytes_.resize(at + n);
    std::memcpy(bytes_.data() + at, p, n);
  }
  std::vector<std::uint8_t> bytes_;
};

can_bittiming bittiming(std::uint32_t bitrate, std::uint32_t sample_point) {
  can_bittiming bt{};
  bt.bitrate = bitrate;
  bt.sample_point = sample_point;
  bt.tq = 125;
  return bt;
}

// What `ip -details -statistics link show can0` would print of an error-passive FD controller.
std::vector<std::uint8_t> can0_message(std::uint32_t state = CAN_STATE_ERROR_PASSIVE) {
  Message m;
  m.text(IFLA_IFNAME, "can0");
  const std::size_t info = m.open(IFLA_LINKINFO);
  m.text(IFLA_INFO_KIND, "can");
  const std::size_t data = m.open(IFLA_INFO_DATA);
  m.value(IFLA_CAN_BITTIMING, bittiming(500000, 875));
  m.value(IFLA_CAN_CLOCK, std::uint32_t{80000000});  // not read
  m.value(IFLA_CAN_STATE, state);
  m.value(IFLA_CAN_RESTART_MS, std::uint32_t{100});
  can_berr_counter berr{};
  berr.txerr = 130;
  berr.rxerr = 5;
  m.value(IFLA_CAN_BERR_COUNTER, berr);
  m.value(IFLA_CAN_DATA_BITTIMING, bittiming(2000000, 750));
  m.close(data);
  can_device_stats stats{};
  stats.bus_error = 42;
  stats.error_warning = 3;
  stats.error_passive = 2;
  stats.bus_off = 1;
  stats.arbitration_lost = 9;
  stats.restarts = 1;
  m.value(IFLA_INFO_XSTATS, stats);
  m.close(info);
  m.value(IFLA_MTU, std::uint32_t{72});  // an attribute after the nest: read past it
  rtnl_link_stats64 counters{};
  counters.rx_packets = 1000;
  counters.tx_packets = 500;
  counters.rx_errors = 42;
  counters.tx_errors = 7;
  counters.rx_dropped = 3;
  counters.tx_dropped = 1;
  m.value(IFLA_STATS64, counters);
  rtnl_link_stats narrow{};  // the 32-bit copy: the 64-bit one wins
  narrow.rx_packets = 1;
  m.value(IFLA_STATS, narrow);
  return m.done();
}

// Where attribute `type` of the top level begins in `msg` (for corrupting its length).
std::size_t top_attr(const std::vector<std::uint8_t>& msg, std::uint16_t type) {
  std::size_t at = NLMSG_ALIGN(sizeof(nlmsghdr)) + NLMSG_ALIGN(sizeof(ifinfomsg));
  while (at + 4 <= msg.size()) {
    std::uint16_t len = 0;
    std::uint16_t t = 0;
    std::memcpy(&len, msg.data() + at, 2);
    std::memcpy(&t, msg.data() + at + 2, 2);
    if ((t & NLA_TYPE_MASK) == type) return at;
    at += NLA_ALIGN(len);
  }
  FAIL("no attribute " << type);
  return 0;
}

}  // namespace

TEST_CASE("netlink: an RTM_NEWLINK of a CAN controller gives its state, counters and bitrates",
          "[can][link]") {
  const auto msg = can0_message();
  const auto info = parse_link_message(msg);
  REQUIRE(info.has_value());
  CHECK(info->index == 7);
  CHECK(info->name == "can0");
  CHECK(info->kind == "can");
  CHECK(info->is_can());
  CHECK(info->up);
  REQUIRE(info->state);
  CHECK(*info->state == LinkControllerState::ErrorPassive);
  CHECK(controller_state(*info->state) == ControllerState::ErrorPassive);
  CHECK(to_string(*info->state) == "error passive");
  CHECK(info->tx_errors == std::uint16_t{130});
  CHECK(info->rx_errors == std::uint16_t{5});
  CHECK(info->bitrate == 500000u);
  CHECK(info->sample_point == 875u);
  CHECK(info->data_bitrate == 2000000u);
  CHECK(info->restart_ms == 100u);
  REQUIRE(info->device_stats);
  CHECK(info->device_stats->bus_error == 42);
  CHECK(info->device_stats->error_warning == 3);
  CHECK(info->device_stats->error_passive == 2);
  CHECK(info->device_stats->bus_off == 1);
  CHECK(info->device_stats->arbitration_lost == 9);
  CHECK(info->device_stats->restarts == 1);
  REQUIRE(info->counters);
  CHECK(info->counters->rx_packets == 1000);
  CHECK(info->counters->tx_packets == 500);
  CHECK(info->counters->rx_errors == 42);
  CHECK(info->counters->tx_errors == 7);
  CHECK(info->counters->rx_dropped == 3);
  CHECK(info->counters->tx_dropped == 1);
  CHECK(info->skipped == 0);

  // Only the 32-bit counters (an old kernel): read from IFLA_STATS.
  Message old;
  rtnl_link_stats narrow{};
  narrow.rx_packets = 9;
  narrow.tx_errors = 4;
  old.value(IFLA_STATS, narrow);
  const auto o = parse_link_message(old.done());
  REQUIRE(o.has_value());
  REQUIRE(o->counters);
  CHECK(o->counters->rx_packets == 9);
  CHECK(o->counters->tx_errors == 4);

  // Every state of enum can_state.
  for (std::uint32_t s = CAN_STATE_ERROR_ACTIVE; s <= CAN_STATE_SLEEPING; ++s) {
    const auto i = parse_link_message(can0_message(s));
    REQUIRE(i.has_value());
    REQUIRE(i->state);
    CHECK(static_cast<std::uint32_t>(*i->state) == s);
  }
  CHECK(controller_state(LinkControllerState::BusOff) == ControllerState::BusOff);
  CHECK(controller_state(LinkControllerState::Stopped) == ControllerState::Unknown);
}

TEST_CASE("netlink: links that are not CAN controllers", "[can][link]") {
  SECTION("a loopback: no link info") {
    Message m;
    m.text(IFLA_IFNAME, "lo");
    const auto info = parse_link_message(m.done());
    REQUIRE(info.has_value());
    CHECK(info->name == "lo");
    CHECK(info->kind.empty());
    CHECK_FALSE(info->is_can());
    CHECK_FALSE(info->state);
  }
  SECTION("a virtual CAN device: CAN, no controller") {
    Message m;
    m.text(IFLA_IFNAME, "vcan0");
    const std::size_t info = m.open(IFLA_LINKINFO);
    m.text(IFLA_INFO_KIND, "vcan");
    m.close(info);
    const auto i = parse_link_message(m.done());
    REQUIRE(i.has_value());
    CHECK(i->is_can());
    CHECK_FALSE(i->state);
    CHECK_FALSE(i->bitrate);
  }
  SECTION("another kind's statistics are not read as a CAN device's") {
    Message m;
    const std::size_t info = m.open(IFLA_LINKINFO);
    m.text(IFLA_INFO_KIND, "bridge");
    const std::array<std::uint8_t, 64> other{};
    m.attr(IFLA_INFO_XSTATS, other.data(), other.size());
    m.close(info);
    const auto i = parse_link_message(m.done());
    REQUIRE(i.has_value());
    CHECK_FALSE(i->is_can());
    CHECK_FALSE(i->device_stats);
  }
}

TEST_CASE("netlink: bad messages are refused with where and why, never read beyond",
          "[can][link][bad]") {
  const auto good = can0_message();

  SECTION("every truncation") {
    for (std::size_t n = 0; n < good.size(); ++n) {
      const auto r = parse_link_message(std::span(good.data(), n));
      REQUIRE_FALSE(r.has_value());  // nlmsg_len says more than there is
      CHECK_FALSE(r.error().message.empty());
    }
  }
  SECTION("an attribute longer than its container") {
    auto msg = good;
    const std::size_t at = top_attr(msg, IFLA_LINKINFO);
    const std::uint16_t len = 0x7FF0;
    std::memcpy(msg.data() + at, &len, 2);
    const auto r = parse_link_message(msg);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == EINVAL);
    CHECK_THAT(r.error().message, Catch::Contains("IFLA_LINKINFO") && Catch::Contains("beyond") &&
                                      Catch::Contains(fmt::format("offset {}", at)));
  }
  SECTION("an attribute shorter than its own header") {
    auto msg = good;
    const std::size_t at = top_attr(msg, IFLA_IFNAME);
    const std::uint16_t len = 2;
    std::memcpy(msg.data() + at, &len, 2);
    const auto r = parse_link_message(msg);
    REQUIRE_FALSE(r.has_value());
    CHECK_THAT(r.error().message, Catch::Contains("IFLA_IFNAME") && Catch::Contains("below"));
  }
  SECTION("a nested attribute beyond its nest") {
    Message m;
    const std::size_t info = m.open(IFLA_LINKINFO);
    m.text(IFLA_INFO_KIND, "can");
    const std::size_t data = m.open(IFLA_INFO_DATA);
    m.value(IFLA_CAN_STATE, std::uint32_t{CAN_STATE_BUS_OFF});
    m.close(data);
    m.close(info);
    auto msg = m.done();
    // IFLA_CAN_STATE's length, 8, made 12: beyond IFLA_INFO_DATA (which ends with the message).
    const std::size_t state_at = msg.size() - 8;
    const std::uint16_t len = 12;
    std::memcpy(msg.data() + state_at, &len, 2);
    const auto r = parse_link_message(msg);
    REQUIRE_FALSE(r.has_value());
    CHECK_THAT(r.error().message, Catch::Contains("IFLA_CAN_STATE") && Catch::Contains("beyond"));
  }
  SECTION("structures shorter than the kernel's are skipped and counted; the rest is read") {
    Message m;
    const std::size_t info = m.open(IFLA_LINKINFO);
    m.text(IFLA_INFO_KIND, "can");
    const std::size_t data = m.open(IFLA_INFO_DATA);
    const std::uint16_t half = 130;
    m.value(IFLA_CAN_BERR_COUNTER, half);                       // 2 of 4 bytes
    m.value(IFLA_CAN_BITTIMING, std::uint32_t{500000});         // 4 of 32 bytes
    m.value(IFLA_CAN_STATE, std::uint32_t{CAN_STATE_MAX + 3});  // no such state
    m.close(data);
    m.value(IFLA_INFO_XSTATS, std::uint32_t{1});  // 4 of 24 bytes
    m.close(info);
    m.value(IFLA_STATS64, std::uint64_t{1});  // 8 of at least 64 bytes
    const auto i = parse_link_message(m.done());
    REQUIRE(i.has_value());
    CHECK(i->skipped == 5);
    CHECK_FALSE(i->counters);
    CHECK_FALSE(i->tx_errors);
    CHECK_FALSE(i->bitrate);
    CHECK_FALSE(i->state);
    CHECK_FALSE(i->device_stats);
    CHECK_THAT(i->skipped_detail, Catch::Contains("(IFLA_CAN_BERR_COUNTER): 2 bytes, 4 needed") &&
                                      Catch::Contains("IFLA_CAN_BITTIMING") &&
                                      Catch::Contains("state 9 unknown") &&
                                      Catch::Contains("IFLA_INFO_XSTATS") &&
                                      Catch::Contains("(IFLA_STATS64): 8 bytes, 64 needed"));
  }
  SECTION("an error answer, another message type") {
    Message e(NLMSG_ERROR);
    const int err = -ENODEV;
    const nlmsghdr original{};
    auto msg = e.done();
    const std::size_t at = msg.size();
    msg.resize(at + sizeof(err) + sizeof(original));
    std::memcpy(msg.data() + at, &err, sizeof(err));
    std::memcpy(msg.data() + at + sizeof(err), &original, sizeof(original));
    const auto len = static_cast<std::uint32_t>(msg.size());
    std::memcpy(msg.data(), &len, 4);
    const auto r = parse_link_message(msg);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == ENODEV);
    // Not a negative errno: INT_MIN (no negation; found by the fuzzer) and a positive code.
    for (const int bad : {std::numeric_limits<int>::min(), 5}) {
      std::memcpy(msg.data() + at, &bad, sizeof(bad));
      const auto b = parse_link_message(msg);
      REQUIRE_FALSE(b.has_value());
      CHECK(b.error().code == EINVAL);
      CHECK_THAT(b.error().message, Catch::Contains("not a negative errno"));
    }

    const auto other = parse_link_message(Message(RTM_NEWADDR).done());
    REQUIRE_FALSE(other.has_value());
    CHECK_THAT(other.error().message, Catch::Contains("not RTM_NEWLINK"));
  }
  SECTION("random corruption never crashes") {
    std::mt19937 rng(48);
    std::size_t parsed = 0;
    for (int i = 0; i < 20000; ++i) {
      auto msg = good;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < flips; ++k) {
        msg[rng() % msg.size()] = static_cast<std::uint8_t>(rng());
      }
      const auto r = parse_link_message(msg);
      if (r) ++parsed;
    }
    CHECK(parsed > 0);  // most flips hit payloads, not lengths
  }
}

TEST_CASE("netlink: the live query names the interface when it is no CAN controller",
          "[can][link]") {
  const auto lo = query_link("lo");
  REQUIRE_FALSE(lo.has_value());
  CHECK_THAT(lo.error().message, Catch::StartsWith("CAN interface lo: ") &&
                                     Catch::Contains("not a CAN device (link kind: none)"));
  const auto none = query_link("vigil-nodev9");
  REQUIRE_FALSE(none.has_value());
  CHECK(none.error().code == ENODEV);
  CHECK_THAT(none.error().message, Catch::Contains("vigil-nodev9: no such interface"));
  const auto long_name = query_link("an-interface-name-too-long");
  REQUIRE_FALSE(long_name.has_value());
  CHECK_THAT(long_name.error().message, Catch::Contains("an-interface-name-too-long"));
}

TEST_CASE("CAN monitor: the live controller state judges the bus like error frames do",
          "[can][link][monitor]") {
  auto config = load_can_config_string("buses: {1: {interface: can1}}\n");
  REQUIRE(config.has_value());
  CanMonitor monitor(*config);
  const auto reading = [](LinkControllerState s) {
    LinkReading l;
    l.bus = 1;
    l.interface = "can1";
    l.reads = 1;
    LinkInfo i;
    i.kind = "can";
    i.up = true;
    i.state = s;
    i.tx_errors = 140;
    i.rx_errors = 0;
    i.bitrate = 250000;
    l.info = i;
    return l;
  };
  const vigil::Nanos now = 10 * vigil::kNanosPerSecond;

  monitor.set_links({reading(LinkControllerState::ErrorPassive)});
  CanReport r = monitor.evaluate(CanSnapshot{}, now);
  const BusReport* b = r.find_bus(1);
  REQUIRE(b != nullptr);  // reported before any frame
  CHECK(b->live_state);
  CHECK(b->controller_state == ControllerState::ErrorPassive);
  CHECK(b->status.level() == vigil::StatusLevel::Warn);
  CHECK_THAT(b->status.summary(), Catch::Contains("controller error passive (can1, read live; "
                                                  "error counters tx 140 rx 0)"));
  // No bitrate configured: the interface's counts the load.
  CHECK(b->bitrate_from_link);
  CHECK(b->config.settings.bitrate == 250000);
  CHECK(r.status.level() == vigil::StatusLevel::Warn);

  monitor.set_links({reading(LinkControllerState::BusOff)});
  r = monitor.evaluate(CanSnapshot{}, now);
  REQUIRE(r.find_bus(1) != nullptr);
  CHECK(r.find_bus(1)->status.level() == vigil::StatusLevel::Error);
  CHECK_THAT(r.find_bus(1)->status.summary(), Catch::Contains("controller bus off"));

  monitor.set_links({reading(LinkControllerState::ErrorActive)});
  CHECK(monitor.evaluate(CanSnapshot{}, now).find_bus(1)->status.level() == vigil::StatusLevel::Ok);
  monitor.set_links({reading(LinkControllerState::Stopped)});
  CHECK(monitor.evaluate(CanSnapshot{}, now).find_bus(1)->status.level() ==
        vigil::StatusLevel::Warn);

  // A configured bitrate wins; a different one on the interface is a WARN.
  auto configured = load_can_config_string("buses: {1: {interface: can1, bitrate: 500k}}\n");
  REQUIRE(configured.has_value());
  monitor.set_config(*configured);
  monitor.set_links({reading(LinkControllerState::ErrorActive)});
  r = monitor.evaluate(CanSnapshot{}, now);
  CHECK_FALSE(r.find_bus(1)->bitrate_from_link);
  CHECK(r.find_bus(1)->config.settings.bitrate == 500000);
  CHECK(r.find_bus(1)->status.level() == vigil::StatusLevel::Warn);
  CHECK_THAT(r.find_bus(1)->status.summary(),
             Catch::Contains("configured bitrate 500000 differs from can1's 250000"));

  // A reading that failed: the reason, WARN; the nodes are judged as ever.
  LinkReading failed;
  failed.bus = 1;
  failed.interface = "lo";
  failed.error = "CAN interface lo: not a CAN device (link kind: none)";
  failed.reads = failed.failures = 1;
  monitor.set_links({failed});
  r = monitor.evaluate(CanSnapshot{}, now);
  REQUIRE(r.find_bus(1) != nullptr);
  CHECK(r.find_bus(1)->status.level() == vigil::StatusLevel::Warn);
  CHECK_THAT(r.find_bus(1)->status.summary(), Catch::Contains("lo: not a CAN device"));
}

TEST_CASE("CAN config: buses.<bus>.interface", "[can][link][config]") {
  auto ok = load_can_config_string("buses: {0: {interface: can0}, 1: {interface: vcan1}}\n");
  REQUIRE(ok.has_value());
  REQUIRE(ok->buses.size() == 2);
  CHECK(ok->buses[0].interface == std::string("can0"));
  auto all = load_can_config_string("buses: {all: {interface: can0}}\n", "can.yaml");
  REQUIRE_FALSE(all.has_value());
  CHECK_THAT(vigil::config::to_string(all.error()),
             Catch::StartsWith("can.yaml:1:") && Catch::Contains("buses.all.interface"));
  auto bad = load_can_config_string("buses: {0: {interface: 'can/0'}}\n", "can.yaml");
  REQUIRE_FALSE(bad.has_value());
  CHECK_THAT(vigil::config::to_string(bad.error()), Catch::Contains("no interface name"));
  auto long_name =
      load_can_config_string("buses: {0: {interface: an-interface-name-too-long}}\n", "can.yaml");
  REQUIRE_FALSE(long_name.has_value());
}
