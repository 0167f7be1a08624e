#include "vigil/can/socketcan.hpp"

// The only place in vigil with SocketCAN and socket headers (STYLE rule 4).
#include <linux/can.h>
#include <linux/can/raw.h>
#include <linux/net_tstamp.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/uio.h>
#include <unistd.h>
#include <ctime>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

namespace vigil::can {

namespace {

Error errno_error(int code, std::string_view what) {
  return Error(code, fmt::format("{}: {}", what, std::strerror(code)));
}

// Frame -> the kernel's structs: a CAN FD frame goes as canfd_frame (CANFD_MTU bytes), any
// other as can_frame (CAN_MTU bytes).
void to_kernel(const Frame& f, canfd_frame& k) noexcept {
  std::memset(&k, 0, sizeof k);
  canid_t id = f.extended || f.error ? (f.id & CAN_EFF_MASK) : (f.id & CAN_SFF_MASK);
  if (f.extended) id |= CAN_EFF_FLAG;
  if (f.error) id |= CAN_ERR_FLAG;
  k.can_id = id;
  k.len = static_cast<__u8>(std::min<std::size_t>(f.length, CANFD_MAX_DLEN));
  k.flags = CANFD_FDF | (f.brs ? CANFD_BRS : 0) | (f.esi ? CANFD_ESI : 0);
  std::memcpy(k.data, f.data.data(), k.len);
}

void to_kernel(const Frame& f, can_frame& c) noexcept {
  std::memset(&c, 0, sizeof c);
  canid_t id = f.extended || f.error ? (f.id & CAN_EFF_MASK) : (f.id & CAN_SFF_MASK);
  if (f.extended) id |= CAN_EFF_FLAG;
  if (f.rtr) id |= CAN_RTR_FLAG;
  if (f.error) id |= CAN_ERR_FLAG;
  c.can_id = id;
  const std::uint8_t dlc = std::min<std::uint8_t>(f.length, kMaxDlc);
  c.len = std::min<std::uint8_t>(dlc, CAN_MAX_DLEN);
  if (dlc > CAN_MAX_DLEN) c.len8_dlc = dlc;
  if (!f.rtr) std::memcpy(c.data, f.data.data(), c.len);
}

void from_kernel(const canfd_frame& k, Frame& f) noexcept {
  f = Frame{};
  f.extended = (k.can_id & CAN_EFF_FLAG) != 0;
  f.error = (k.can_id & CAN_ERR_FLAG) != 0;
  f.id = (f.extended || f.error) ? (k.can_id & CAN_EFF_MASK) : (k.can_id & CAN_SFF_MASK);
  f.fd = true;
  f.brs = (k.flags & CANFD_BRS) != 0;
  f.esi = (k.flags & CANFD_ESI) != 0;
  f.length = static_cast<std::uint8_t>(std::min<std::size_t>(k.len, CANFD_MAX_DLEN));
  std::memcpy(f.data.data(), k.data, f.length);
}

void from_kernel(const can_frame& c, Frame& f) noexcept {
  f = Frame{};
  f.extended = (c.can_id & CAN_EFF_FLAG) != 0;
  f.error = (c.can_id & CAN_ERR_FLAG) != 0;
  f.id = (f.extended || f.error) ? (c.can_id & CAN_EFF_MASK) : (c.can_id & CAN_SFF_MASK);
  f.rtr = (c.can_id & CAN_RTR_FLAG) != 0;
  const std::uint8_t len = std::min<std::uint8_t>(c.len, CAN_MAX_DLEN);
  f.length = (len == CAN_MAX_DLEN && c.len8_dlc > CAN_MAX_DLEN && c.len8_dlc <= CAN_MAX_RAW_DLC)
                 ? c.len8_dlc
                 : len;
  if (!f.rtr) std::memcpy(f.data.data(), c.data, len);
}

Nanos to_nanos(const timespec& t) noexcept {
  return static_cast<Nanos>(t.tv_sec) * kNanosPerSecond + static_cast<Nanos>(t.tv_nsec);
}

// Room for SCM_TIMESTAMPING (three timespecs) and SCM_TIMESTAMPNS, whichever the kernel sends.
constexpr std::size_t kControlBytes =
    CMSG_SPACE(3 * sizeof(timespec)) + CMSG_SPACE(sizeof(timespec));

}  // namespace

namespace detail {

RxStamp receive_stamp(const void* control, std::size_t size, bool hardware) noexcept {
  // A msghdr over the buffer, only to walk it with the CMSG macros (which take a msghdr).
  msghdr msg{};
  msg.msg_control = const_cast<void*>(control);  // NOLINT(cppcoreguidelines-pro-type-const-cast)
  msg.msg_controllen = size;
  RxStamp software;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec t;
      std::memcpy(&t, CMSG_DATA(c), sizeof t);
      software.ns = to_nanos(t);
    } else if (c->cmsg_type == SCM_TIMESTAMPING && c->cmsg_len >= CMSG_LEN(3 * sizeof(timespec))) {
      // ts[0]: software (CLOCK_REALTIME), ts[1]: unused, ts[2]: raw hardware.
      timespec t[3];
      std::memcpy(t, CMSG_DATA(c), sizeof t);
      if (hardware && (t[2].tv_sec != 0 || t[2].tv_nsec != 0)) return {to_nanos(t[2]), true};
      if (t[0].tv_sec != 0 || t[0].tv_nsec != 0) software.ns = to_nanos(t[0]);
    }
  }
  return software;
}

}  // namespace detail

expected<void, Error> socketcan_available() {
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return unexpected(errno_error(errno, "socket(PF_CAN, SOCK_RAW, CAN_RAW)"));
  ::close(fd);
  return {};
}

expected<SocketCan, Error> SocketCan::open(std::string_view interface, SocketCanOptions options) {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    return unexpected(Error(ENAMETOOLONG, fmt::format("CAN interface name '{}' must have 1 to {} "
                                                      "characters",
                                                      interface, IFNAMSIZ - 1)));
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return unexpected(errno_error(errno, "socket(PF_CAN, SOCK_RAW, CAN_RAW)"));
  const auto fail = [&](std::string_view what) {
    const int code = errno;
    ::close(fd);
    return unexpected(errno_error(code, fmt::format("{} on CAN interface '{}'", what, interface)));
  };

  ifreq ifr{};
  std::memcpy(ifr.ifr_name, interface.data(), interface.size());
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) < 0) return fail("SIOCGIFINDEX");

  const int on = 1;
  if (options.fd && ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
    return fail("setsockopt(CAN_RAW_FD_FRAMES)");
  }
  if (options.receive_own &&
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &on, sizeof on) < 0) {
    return fail("setsockopt(CAN_RAW_RECV_OWN_MSGS)");
  }
  if (options.error_frames) {
    const can_err_mask_t mask = CAN_ERR_MASK;
    if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) < 0) {
      return fail("setsockopt(CAN_RAW_ERR_FILTER)");
    }
  }
  if (options.read_timeout_ns > 0) {
    timeval tv{};
    tv.tv_sec = static_cast<time_t>(options.read_timeout_ns / kNanosPerSecond);
    tv.tv_usec = static_cast<suseconds_t>((options.read_timeout_ns % kNanosPerSecond) / 1000);
    if (tv.tv_sec == 0 && tv.tv_usec == 0) tv.tv_usec = 1;  // 0 would mean "block"
    if (::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv) < 0) {
      return fail("setsockopt(SO_RCVTIMEO)");
    }
  }
  if (options.timestamp == RxTimestamp::Kernel &&
      ::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0) {
    return fail("setsockopt(SO_TIMESTAMPNS)");
  }
  if (options.timestamp == RxTimestamp::Hardware) {
    // The software stamp too: it stands in for frames the controller did not stamp.
    const int flags = SOF_TIMESTAMPING_RX_HARDWARE | SOF_TIMESTAMPING_RAW_HARDWARE |
                      SOF_TIMESTAMPING_RX_SOFTWARE | SOF_TIMESTAMPING_SOFTWARE;
    if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPING, &flags, sizeof flags) < 0) {
      return fail("setsockopt(SO_TIMESTAMPING)");
    }
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) return fail("bind");
  return SocketCan(fd, std::string(interface), options);
}

SocketCan::SocketCan(int fd, std::string interface, SocketCanOptions options) noexcept
    : fd_(fd), interface_(std::move(interface)), options_(options) {}

SocketCan::SocketCan(SocketCan&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      errno_(other.errno_),
      interface_(std::move(other.interface_)),
      options_(other.options_),
      software_stamps_(other.software_stamps_),
      hardware_stamps_(other.hardware_stamps_) {}

SocketCan& SocketCan::operator=(SocketCan&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    errno_ = other.errno_;
    interface_ = std::move(other.interface_);
    options_ = other.options_;
    software_stamps_ = other.software_stamps_;
    hardware_stamps_ = other.hardware_stamps_;
  }
  return *this;
}

SocketCan::~SocketCan() {
  if (fd_ >= 0) ::close(fd_);
}

IoStatus SocketCan::read(Frame& out) noexcept {
  // Large enough for either struct; the kernel says which one by the size it returns.
  alignas(canfd_frame) unsigned char buffer[CANFD_MTU];
  alignas(cmsghdr) unsigned char control[kControlBytes];
  for (;;) {
    iovec iov{buffer, sizeof buffer};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    if (options_.timestamp != RxTimestamp::Read) {
      msg.msg_control = control;
      msg.msg_controllen = sizeof control;
    }
    const ssize_t n = ::recvmsg(fd_, &msg, 0);
    if (n == static_cast<ssize_t>(CAN_MTU) || n == static_cast<ssize_t>(CANFD_MTU)) {
      const Nanos read_ns = platform::now_ns();
      if (n == static_cast<ssize_t>(CANFD_MTU)) {
        canfd_frame k;
        std::memcpy(&k, buffer, sizeof k);
        from_kernel(k, out);
      } else {
        can_frame c;
        std::memcpy(&c, buffer, sizeof c);
        from_kernel(c, out);
      }
      out.bus = options_.bus;
      out.timestamp = read_ns;
      if (msg.msg_control != nullptr) {
        const detail::RxStamp s = detail::receive_stamp(
            control, msg.msg_controllen, options_.timestamp == RxTimestamp::Hardware);
        if (s.ns >= 0) {
          out.timestamp = (s.hardware ? hardware_stamps_ : software_stamps_).map(s.ns, read_ns);
        }
      }
      return IoStatus::Ok;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return IoStatus::Timeout;
    errno_ = n < 0 ? errno : EPROTO;  // a short read is not a frame
    return IoStatus::Error;
  }
}

IoStatus SocketCan::write(const Frame& f) noexcept {
  if (f.fd && !options_.fd) {
    errno_ = EINVAL;
    return IoStatus::Error;
  }
  canfd_frame k;
  can_frame c;
  const void* data = &c;
  std::size_t size = CAN_MTU;
  if (f.fd) {
    to_kernel(f, k);
    data = &k;
    size = CANFD_MTU;
  } else {
    to_kernel(f, c);
  }
  for (;;) {
    const ssize_t n = ::write(fd_, data, size);
    if (n == static_cast<ssize_t>(size)) return IoStatus::Ok;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
      return IoStatus::Timeout;
    }
    errno_ = n < 0 ? errno : EPROTO;
    return IoStatus::Error;
  }
}

}  // namespace vigil::can
