#include "vigil/can/can_link.hpp"

// The kernel's UAPI headers: the message layout and the attribute numbers (see the header).
#include <fmt/format.h>
#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <functional>
#include <vector>

namespace vigil::can {

namespace {

constexpr std::size_t kAlign = 4;  // NLMSG_ALIGNTO, NLA_ALIGNTO
constexpr std::size_t align(std::size_t n) { return (n + kAlign - 1) & ~(kAlign - 1); }

template <class T>
T load(std::span<const std::uint8_t> bytes, std::size_t at) {
  T v{};
  std::memcpy(&v, bytes.data() + at, sizeof(T));
  return v;
}

Error fail(int code, std::string message) { return Error{code, std::move(message)}; }

// Names of the attributes read, for the errors.
std::string attr_name(std::string_view level, std::uint16_t type) {
  std::string_view n;
  if (level == "link") {
    switch (type) {
      case IFLA_IFNAME:
        n = "IFLA_IFNAME";
        break;
      case IFLA_LINKINFO:
        n = "IFLA_LINKINFO";
        break;
      case IFLA_STATS:
        n = "IFLA_STATS";
        break;
      case IFLA_STATS64:
        n = "IFLA_STATS64";
        break;
      default:
        break;
    }
  } else if (level == "linkinfo") {
    switch (type) {
      case IFLA_INFO_KIND:
        n = "IFLA_INFO_KIND";
        break;
      case IFLA_INFO_DATA:
        n = "IFLA_INFO_DATA";
        break;
      case IFLA_INFO_XSTATS:
        n = "IFLA_INFO_XSTATS";
        break;
      default:
        break;
    }
  } else {
    switch (type) {
      case IFLA_CAN_BITTIMING:
        n = "IFLA_CAN_BITTIMING";
        break;
      case IFLA_CAN_STATE:
        n = "IFLA_CAN_STATE";
        break;
      case IFLA_CAN_RESTART_MS:
        n = "IFLA_CAN_RESTART_MS";
        break;
      case IFLA_CAN_BERR_COUNTER:
        n = "IFLA_CAN_BERR_COUNTER";
        break;
      case IFLA_CAN_DATA_BITTIMING:
        n = "IFLA_CAN_DATA_BITTIMING";
        break;
      default:
        break;
    }
  }
  return n.empty() ? fmt::format("attribute {}", type) : fmt::format("attribute {} ({})", type, n);
}

using Visit = std::function<expected<void, Error>(
    std::uint16_t type, std::span<const std::uint8_t> payload, std::size_t offset)>;

// Walks the attributes (struct nlattr: u16 nla_len, u16 nla_type, then the payload) of `bytes`,
// which start at `base` in the message. An attribute below 4 bytes or beyond its container is an
// error; the padding after the last one may be missing.
expected<void, Error> walk(std::span<const std::uint8_t> bytes, std::size_t base,
                           std::string_view level, const Visit& visit) {
  std::size_t at = 0;
  while (at + sizeof(nlattr) <= bytes.size()) {
    const auto len = load<std::uint16_t>(bytes, at);
    const auto type =
        static_cast<std::uint16_t>(load<std::uint16_t>(bytes, at + 2) & NLA_TYPE_MASK);
    if (len < sizeof(nlattr)) {
      return unexpected(
          fail(EINVAL, fmt::format("offset {}: {}: length {} below the header's {}", base + at,
                                   attr_name(level, type), len, sizeof(nlattr))));
    }
    if (len > bytes.size() - at) {
      return unexpected(
          fail(EINVAL, fmt::format("offset {}: {}: length {} beyond the {} bytes "
                                   "left in its container",
                                   base + at, attr_name(level, type), len, bytes.size() - at)));
    }
    if (auto ok = visit(type, bytes.subspan(at + sizeof(nlattr), len - sizeof(nlattr)), base + at);
        !ok) {
      return ok;
    }
    at += align(len);
  }
  if (at < bytes.size()) {
    return unexpected(fail(EINVAL, fmt::format("offset {}: {} trailing bytes, shorter than an "
                                               "attribute's header",
                                               base + at, bytes.size() - at)));
  }
  return {};
}

// An attribute shorter than the struct it carries: skipped, counted, named.
void skipped(LinkInfo& info, std::string_view level, std::uint16_t type, std::size_t offset,
             std::string_view why) {
  ++info.skipped;
  if (!info.skipped_detail.empty()) info.skipped_detail += "; ";
  info.skipped_detail += fmt::format("offset {}: {}: {}", offset, attr_name(level, type), why);
}

void skip(LinkInfo& info, std::string_view level, std::uint16_t type, std::size_t offset,
          std::size_t have, std::size_t need) {
  skipped(info, level, type, offset, fmt::format("{} bytes, {} needed", have, need));
}

std::string text_of(std::span<const std::uint8_t> payload) {
  std::size_t n = 0;
  while (n < payload.size() && payload[n] != 0) ++n;
  return {reinterpret_cast<const char*>(payload.data()), n};
}

expected<void, Error> parse_can_data(LinkInfo& info, std::span<const std::uint8_t> data,
                                     std::size_t base) {
  return walk(data, base, "can",
              [&](std::uint16_t type, std::span<const std::uint8_t> p,
                  std::size_t offset) -> expected<void, Error> {
                const auto need = [&](std::size_t n) {
                  if (p.size() >= n) return true;
                  skip(info, "can", type, offset, p.size(), n);
                  return false;
                };
                switch (type) {
                  case IFLA_CAN_BITTIMING:
                  case IFLA_CAN_DATA_BITTIMING: {
                    if (!need(sizeof(can_bittiming))) break;
                    const auto bt = load<can_bittiming>(p, 0);
                    if (type == IFLA_CAN_BITTIMING) {
                      if (bt.bitrate != 0) info.bitrate = bt.bitrate;
                      if (bt.sample_point != 0) info.sample_point = bt.sample_point;
                    } else if (bt.bitrate != 0) {
                      info.data_bitrate = bt.bitrate;
                    }
                    break;
                  }
                  case IFLA_CAN_STATE: {
                    if (!need(sizeof(std::uint32_t))) break;
                    const auto s = load<std::uint32_t>(p, 0);
                    if (s > CAN_STATE_SLEEPING) {
                      skipped(info, "can", type, offset,
                              fmt::format("state {} unknown (enum can_state ends at {})", s,
                                          static_cast<int>(CAN_STATE_SLEEPING)));
                      break;
                    }
                    info.state = static_cast<LinkControllerState>(s);
                    break;
                  }
                  case IFLA_CAN_BERR_COUNTER: {
                    if (!need(sizeof(can_berr_counter))) break;
                    const auto c = load<can_berr_counter>(p, 0);
                    info.tx_errors = c.txerr;
                    info.rx_errors = c.rxerr;
                    break;
                  }
                  case IFLA_CAN_RESTART_MS:
                    if (need(sizeof(std::uint32_t))) info.restart_ms = load<std::uint32_t>(p, 0);
                    break;
                  default:
                    break;  // clock, control mode, constants, termination: not read
                }
                return {};
              });
}

expected<void, Error> parse_linkinfo(LinkInfo& info, std::span<const std::uint8_t> bytes,
                                     std::size_t base) {
  // The kind first: IFLA_INFO_DATA means something only for a CAN device.
  std::span<const std::uint8_t> data;
  std::size_t data_at = 0;
  auto ok = walk(bytes, base, "linkinfo",
                 [&](std::uint16_t type, std::span<const std::uint8_t> p,
                     std::size_t offset) -> expected<void, Error> {
                   switch (type) {
                     case IFLA_INFO_KIND:
                       info.kind = text_of(p);
                       break;
                     case IFLA_INFO_DATA:
                       data = p;
                       data_at = offset + sizeof(nlattr);
                       break;
                     case IFLA_INFO_XSTATS: {
                       // Only a CAN device's are struct can_device_stats; checked below.
                       if (p.size() < sizeof(can_device_stats)) {
                         skip(info, "linkinfo", type, offset, p.size(), sizeof(can_device_stats));
                         break;
                       }
                       const auto s = load<can_device_stats>(p, 0);
                       info.device_stats =
                           LinkDeviceStats{s.bus_error, s.error_warning,    s.error_passive,
                                           s.bus_off,   s.arbitration_lost, s.restarts};
                       break;
                     }
                     default:
                       break;
                   }
                   return {};
                 });
  if (!ok) return ok;
  if (info.kind != "can") {
    info.device_stats.reset();  // another kind's statistics are another struct
    return {};
  }
  if (!data.empty()) return parse_can_data(info, data, data_at);
  return {};
}

// The first eight counters of struct rtnl_link_stats64 (u64) or rtnl_link_stats (u32): packets,
// bytes, errors, drops, each rx then tx. The 64-bit ones win whichever comes first.
void parse_counters(LinkInfo& info, std::uint16_t type, std::span<const std::uint8_t> p,
                    std::size_t offset, bool& stats64) {
  const bool wide = type == IFLA_STATS64;
  if (!wide && stats64) return;
  const std::size_t width = wide ? sizeof(std::uint64_t) : sizeof(std::uint32_t);
  if (p.size() < 8 * width) {
    skip(info, "link", type, offset, p.size(), 8 * width);
    return;
  }
  const auto at = [&](std::size_t i) -> std::uint64_t {
    return wide ? load<std::uint64_t>(p, i * width) : load<std::uint32_t>(p, i * width);
  };
  info.counters = LinkCounters{at(0), at(1), at(4), at(5), at(6), at(7)};
  stats64 = stats64 || wide;
}

}  // namespace

std::string_view to_string(LinkControllerState s) noexcept {
  switch (s) {
    case LinkControllerState::ErrorActive:
      return "error active";
    case LinkControllerState::ErrorWarning:
      return "error warning";
    case LinkControllerState::ErrorPassive:
      return "error passive";
    case LinkControllerState::BusOff:
      return "bus off";
    case LinkControllerState::Stopped:
      return "stopped";
    case LinkControllerState::Sleeping:
      return "sleeping";
  }
  return "?";
}

ControllerState controller_state(LinkControllerState s) noexcept {
  switch (s) {
    case LinkControllerState::ErrorActive:
      return ControllerState::ErrorActive;
    case LinkControllerState::ErrorWarning:
      return ControllerState::ErrorWarning;
    case LinkControllerState::ErrorPassive:
      return ControllerState::ErrorPassive;
    case LinkControllerState::BusOff:
      return ControllerState::BusOff;
    case LinkControllerState::Stopped:
    case LinkControllerState::Sleeping:
      break;
  }
  return ControllerState::Unknown;
}

bool LinkInfo::is_can() const noexcept {
  return kind == "can" || kind == "vcan" || kind == "vxcan";
}

expected<LinkInfo, Error> parse_link_message(std::span<const std::uint8_t> message) {
  if (message.size() < sizeof(nlmsghdr)) {
    return unexpected(fail(EINVAL, fmt::format("message of {} bytes, shorter than its {}-byte "
                                               "header (struct nlmsghdr)",
                                               message.size(), sizeof(nlmsghdr))));
  }
  const auto hdr = load<nlmsghdr>(message, 0);
  if (hdr.nlmsg_len < sizeof(nlmsghdr) || hdr.nlmsg_len > message.size()) {
    return unexpected(fail(EINVAL, fmt::format("nlmsg_len {} outside the {} bytes of the message "
                                               "(at least {})",
                                               hdr.nlmsg_len, message.size(), sizeof(nlmsghdr))));
  }
  const std::span<const std::uint8_t> msg = message.first(hdr.nlmsg_len);
  if (hdr.nlmsg_type == NLMSG_ERROR) {
    if (msg.size() < sizeof(nlmsghdr) + sizeof(int)) {
      return unexpected(fail(EINVAL, "NLMSG_ERROR without its error code"));
    }
    // A negative errno, or 0 for an acknowledgement (netlink(7)); anything else is bad input
    // (and INT_MIN has no negation).
    const int raw = load<int>(msg, sizeof(nlmsghdr));
    if (raw > 0 || raw < -4095) {
      return unexpected(fail(
          EINVAL, fmt::format("NLMSG_ERROR with error code {}, not a negative errno or 0", raw)));
    }
    const int err = -raw;
    return unexpected(
        fail(err, fmt::format("the kernel answered an error: {}",
                              err == 0 ? "none (an acknowledgement)" : std::strerror(err))));
  }
  if (hdr.nlmsg_type != RTM_NEWLINK) {
    return unexpected(fail(EINVAL, fmt::format("message type {} is not RTM_NEWLINK ({})",
                                               hdr.nlmsg_type, RTM_NEWLINK)));
  }
  const std::size_t attrs_at = align(sizeof(nlmsghdr)) + align(sizeof(ifinfomsg));
  if (msg.size() < align(sizeof(nlmsghdr)) + sizeof(ifinfomsg)) {
    return unexpected(
        fail(EINVAL, fmt::format("RTM_NEWLINK of {} bytes, shorter than its "
                                 "headers (nlmsghdr and ifinfomsg: {})",
                                 msg.size(), align(sizeof(nlmsghdr)) + sizeof(ifinfomsg))));
  }
  const auto ifi = load<ifinfomsg>(msg, align(sizeof(nlmsghdr)));
  LinkInfo info;
  bool stats64 = false;  // IFLA_STATS64 read: IFLA_STATS (32-bit) is not needed
  info.index = ifi.ifi_index;
  info.up = (ifi.ifi_flags & IFF_UP) != 0;
  if (msg.size() <= attrs_at) return info;
  auto ok = walk(msg.subspan(attrs_at), attrs_at, "link",
                 [&](std::uint16_t type, std::span<const std::uint8_t> p,
                     std::size_t offset) -> expected<void, Error> {
                   if (type == IFLA_IFNAME) info.name = text_of(p);
                   if (type == IFLA_LINKINFO) {
                     return parse_linkinfo(info, p, offset + sizeof(nlattr));
                   }
                   if (type == IFLA_STATS64 || type == IFLA_STATS) {
                     parse_counters(info, type, p, offset, stats64);
                   }
                   return {};
                 });
  if (!ok) return unexpected(ok.error());
  return info;
}

namespace {

// Closes a descriptor at scope exit.
struct Fd {
  int fd = -1;
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

expected<LinkInfo, Error> query_link(std::string_view interface) {
  const std::string name(interface);
  const auto named = [&](int code, std::string_view what) {
    return unexpected(fail(code, fmt::format("CAN interface {}: {}", name, what)));
  };
  if (name.empty() || name.size() >= IF_NAMESIZE) {
    return named(ENAMETOOLONG, fmt::format("a name must have 1 to {} characters", IF_NAMESIZE - 1));
  }
  const unsigned index = ::if_nametoindex(name.c_str());
  if (index == 0) return named(ENODEV, "no such interface");
  const Fd sock(::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE));
  if (sock.fd < 0) {
    const int e = errno;
    return named(e, fmt::format("netlink socket: {}", std::strerror(e)));
  }
  timeval tv{};
  tv.tv_sec = 1;
  static_cast<void>(::setsockopt(sock.fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv)));

  struct Request {
    nlmsghdr hdr;
    ifinfomsg ifi;
  } req{};
  req.hdr.nlmsg_len = sizeof(req);
  req.hdr.nlmsg_type = RTM_GETLINK;
  req.hdr.nlmsg_flags = NLM_F_REQUEST;
  req.hdr.nlmsg_seq = 1;
  req.ifi.ifi_family = AF_UNSPEC;
  req.ifi.ifi_index = static_cast<int>(index);
  sockaddr_nl kernel{};
  kernel.nl_family = AF_NETLINK;
  if (::sendto(sock.fd, &req, sizeof(req), 0, reinterpret_cast<const sockaddr*>(&kernel),
               sizeof(kernel)) < 0) {
    const int e = errno;
    return named(e, fmt::format("RTM_GETLINK: {}", std::strerror(e)));
  }
  std::vector<std::uint8_t> buffer(std::size_t{32} * 1024);
  const ssize_t n = ::recv(sock.fd, buffer.data(), buffer.size(), MSG_TRUNC);
  if (n < 0) {
    const int e = errno;
    return named(e, fmt::format("RTM_GETLINK answer: {}", std::strerror(e)));
  }
  if (static_cast<std::size_t>(n) > buffer.size()) {
    return named(EMSGSIZE,
                 fmt::format("RTM_GETLINK answer of {} bytes, more than {}", n, buffer.size()));
  }
  auto info =
      parse_link_message(std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(n)));
  if (!info) return named(info.error().code, info.error().message);
  if (!info->is_can()) {
    return named(EINVAL, fmt::format("not a CAN device (link kind: {})",
                                     info->kind.empty() ? "none" : info->kind));
  }
  return info;
}

}  // namespace vigil::can
