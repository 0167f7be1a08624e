#pragma once
/// @file
/// A SocketCAN adapter: a Linux raw CAN socket (PF_CAN, SOCK_RAW, CAN_RAW) that reads and writes
/// `vigil::can::Frame`s, and can time each call into a `Sniffer`:
///
/// ```cpp
/// auto bus = vigil::can::SocketCan::open("can0", {.bus = 0});
/// if (!bus) return fail(bus.error().message);   // EAFNOSUPPORT: no SocketCAN in this kernel
/// vigil::can::Frame f;
/// if (bus->read(f, sniffer) == vigil::can::IoStatus::Ok) handle(f);   // sniffer.on_read(...)
/// bus->write(vigil::can::Frame::classic(0x601, {0x40, 0x00, 0x10, 0x00}), sniffer);
/// ```
///
/// This header includes no OS header (STYLE rule 4): the socket code is in src/can/socketcan.cpp.
/// `read` and `write` make one system call each (read(2), write(2)) and allocate nothing: they
/// are how a CAN I/O component talks to SocketCAN on PREEMPT_RT; the sniffer calls around them
/// stay RT-safe. Opening and closing are not RT-safe.

#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/can/frame.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// Whether this kernel offers SocketCAN: creates and closes a PF_CAN raw socket. Fails with the
/// socket's errno: EAFNOSUPPORT when the kernel has no PF_CAN (no `can` / `can_raw` module),
/// EPERM/EACCES when refused. Not RT-safe.
[[nodiscard]] expected<void, Error> socketcan_available();

/// Options of a SocketCAN socket.
struct SocketCanOptions {
  std::uint8_t bus = 0;       ///< `Frame::bus` of the frames read
  bool fd = false;            ///< accept and send CAN FD frames (CAN_RAW_FD_FRAMES)
  bool receive_own = false;   ///< also read the frames this socket sent (CAN_RAW_RECV_OWN_MSGS)
  bool error_frames = false;  ///< read error frames (CAN_RAW_ERR_FILTER = all classes)
  Nanos read_timeout_ns = 0;  ///< > 0: `read` gives up after this long (SO_RCVTIMEO); 0: blocks
};

/// Result of a read or write.
enum class IoStatus : std::uint8_t {
  Ok,       ///< one frame read or written
  Timeout,  ///< no frame within the read timeout (EAGAIN/EWOULDBLOCK), or the send queue is full
  Error,    ///< the call failed: see `last_error()`
};

/**
 * One raw CAN socket bound to an interface ("can0", "vcan0"). Move-only; closes on destruction.
 * One thread reads and one writes at a time (the socket itself allows more; a sniffer does not).
 */
class SocketCan {
 public:
  /// Opens a raw socket on `interface`. Fails with errno and a message naming the interface:
  /// EAFNOSUPPORT (no SocketCAN), ENODEV (no such interface), ENAMETOOLONG, ENOPROTOOPT (CAN FD
  /// asked of a kernel without it). Not RT-safe.
  [[nodiscard]] static expected<SocketCan, Error> open(std::string_view interface,
                                                       SocketCanOptions options = {});

  SocketCan(SocketCan&& other) noexcept;
  SocketCan& operator=(SocketCan&& other) noexcept;
  SocketCan(const SocketCan&) = delete;
  SocketCan& operator=(const SocketCan&) = delete;
  /// Closes the socket.
  ~SocketCan();

  /// Reads one frame into `out` (its `timestamp` = vigil's monotonic clock when read returned,
  /// `bus` = the options' bus). One read(2); allocation-free, noexcept.
  [[nodiscard]] IoStatus read(Frame& out) noexcept;
  /// Writes `f` (CAN FD frames need `options.fd`). One write(2); allocation-free, noexcept.
  [[nodiscard]] IoStatus write(const Frame& f) noexcept;

  /// `read`, timed into `sniffer.on_read(frame, begin, end)` when a frame was read.
  template <class S>
  [[nodiscard]] IoStatus read(Frame& out, S& sniffer) noexcept {
    const Nanos begin = platform::now_ns();
    const IoStatus st = read(out);
    const Nanos end = platform::now_ns();
    if (st == IoStatus::Ok) sniffer.on_read(out, begin, end);
    return st;
  }
  /// `write`, timed into `sniffer.on_write(frame, begin, end)` when the frame was written.
  template <class S>
  [[nodiscard]] IoStatus write(const Frame& f, S& sniffer) noexcept {
    const Nanos begin = platform::now_ns();
    const IoStatus st = write(f);
    const Nanos end = platform::now_ns();
    if (st == IoStatus::Ok) {
      Frame sent = f;
      sent.bus = options_.bus;
      sent.timestamp = end;
      sniffer.on_write(sent, begin, end);
    }
    return st;
  }

  /// errno of the last failed call (0 if none).
  [[nodiscard]] int last_error() const noexcept { return errno_; }
  /// The interface name.
  [[nodiscard]] const std::string& interface() const noexcept { return interface_; }
  /// The socket's file descriptor (for poll/select), -1 once moved from.
  [[nodiscard]] int native_handle() const noexcept { return fd_; }
  /// The options it was opened with.
  [[nodiscard]] const SocketCanOptions& options() const noexcept { return options_; }

 private:
  SocketCan(int fd, std::string interface, SocketCanOptions options) noexcept;
  int fd_ = -1;
  int errno_ = 0;
  std::string interface_;
  SocketCanOptions options_;
};

}  // namespace vigil::can
