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
/// `read` and `write` make one system call each (recvmsg(2), write(2)) and allocate nothing: they
/// are how a CAN I/O component talks to SocketCAN on PREEMPT_RT; the sniffer calls around them
/// stay RT-safe. Opening and closing are not RT-safe.
///
/// A frame read carries its receive timestamp: by default the kernel's (SO_TIMESTAMPNS: when
/// the frame reached the socket), or the controller's where the driver gives one
/// (`RxTimestamp::Hardware`, SO_TIMESTAMPING), mapped onto vigil's clock by `StampMapper` from
/// the frames alone. A reader that gets to its frames late therefore neither delays them nor
/// squeezes their gaps, and the CAN monitor judges silence on the bus's time, not the reader's.

#include <algorithm>
#include <cstddef>
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

/// Where the time of a frame read comes from.
enum class RxTimestamp : std::uint8_t {
  Kernel,    ///< the kernel's receive timestamp (SO_TIMESTAMPNS): when it reached the socket
  Hardware,  ///< the controller's where the driver gives one (SO_TIMESTAMPING), else the kernel's
  Read,      ///< vigil's clock when the read returned (no timestamp asked of the kernel)
};

/// Options of a SocketCAN socket.
struct SocketCanOptions {
  std::uint8_t bus = 0;       ///< `Frame::bus` of the frames read
  bool fd = false;            ///< accept and send CAN FD frames (CAN_RAW_FD_FRAMES)
  bool receive_own = false;   ///< also read the frames this socket sent (CAN_RAW_RECV_OWN_MSGS)
  bool error_frames = false;  ///< read error frames (CAN_RAW_ERR_FILTER = all classes)
  Nanos read_timeout_ns = 0;  ///< > 0: `read` gives up after this long (SO_RCVTIMEO); 0: blocks
  RxTimestamp timestamp = RxTimestamp::Kernel;  ///< the time given to frames read
};

/**
 * Maps receive timestamps taken on another clock (the kernel's CLOCK_REALTIME, or a CAN
 * controller's) onto vigil's clock, from the frames alone: it reads no clock.
 *
 * A frame cannot have arrived after it was read, so `stamp - read` is at most the offset between
 * the clocks, and equals it for a frame read at once. The offset is taken as the largest
 * `stamp - read` over the frames of the current and the previous window (`kWindowNs` each): the
 * frame read soonest after it arrived. Hence a mapped time is never later than its read and
 * never earlier than the previous frame's; frames a late reader finds waiting keep their own
 * times and spacing; the offset follows a drift between the clocks (within the window: 100 ppm
 * is 0.2 ms) and a step forward at once. A step back of the source (a stamp more than
 * `kStepBackNs` below the previous one) starts the estimate over, as does a pause of two windows.
 * Until a frame is read soon after it arrived (the first ones may wait in a backlog), times are
 * late by at most that wait: never early.
 *
 * One per socket, used by its reading thread only. RT-safe: arithmetic only, noexcept.
 */
class StampMapper {
 public:
  static constexpr Nanos kWindowNs = kNanosPerSecond;
  static constexpr Nanos kStepBackNs = kNanosPerMilli;

  /// The time on vigil's clock of a frame stamped `stamp` (source clock) and read at `read_ns`
  /// (vigil's clock).
  [[nodiscard]] Nanos map(Nanos stamp, Nanos read_ns) noexcept {
    const Nanos d = stamp - read_ns;  // offset minus the frame's wait in the socket
    if (!started_ || stamp < last_stamp_ - kStepBackNs || read_ns - window_ns_ >= 2 * kWindowNs) {
      started_ = true;
      previous_ = d;
      current_ = d;
      window_ns_ = read_ns;
    } else if (read_ns - window_ns_ >= kWindowNs) {
      previous_ = current_;
      current_ = d;
      window_ns_ = read_ns;
    } else {
      current_ = std::max(current_, d);
    }
    last_stamp_ = stamp;
    // <= read_ns, since the offset is >= d; frames leave the socket in the order they came.
    last_ns_ = std::max(stamp - std::max(previous_, current_), last_ns_);
    return last_ns_;
  }

 private:
  bool started_ = false;
  Nanos previous_ = 0;    // largest stamp - read of the previous window
  Nanos current_ = 0;     // ... of the current one
  Nanos window_ns_ = 0;   // when the current window began (vigil's clock)
  Nanos last_stamp_ = 0;  // the previous frame's stamp (source clock)
  Nanos last_ns_ = 0;     // the previous result
};

namespace detail {
/// A receive timestamp as the kernel gives it.
struct RxStamp {
  Nanos ns = -1;          ///< on the stamping clock; -1: none
  bool hardware = false;  ///< the controller's clock (else the kernel's CLOCK_REALTIME)
};
/// The receive timestamp in a recvmsg(2) control buffer (a msghdr's msg_control, `size` bytes
/// of it used): with `hardware`, SCM_TIMESTAMPING's raw hardware stamp when it is not zero;
/// else SCM_TIMESTAMPING's software stamp or SCM_TIMESTAMPNS. RT-safe (no system call, no
/// allocation). Defined in src/can/socketcan.cpp.
[[nodiscard]] RxStamp receive_stamp(const void* control, std::size_t size, bool hardware) noexcept;
}  // namespace detail

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

  /// Reads one frame into `out`: its `timestamp` is its receive timestamp on vigil's clock
  /// (`SocketCanOptions::timestamp`; vigil's clock when the read returned if the kernel gave
  /// none, or with `RxTimestamp::Read`), never later than the read; `bus` is the options' bus.
  /// One recvmsg(2); allocation-free, noexcept.
  [[nodiscard]] IoStatus read(Frame& out) noexcept;
  /// Writes `f` (CAN FD frames need `options.fd`). One write(2); allocation-free, noexcept.
  [[nodiscard]] IoStatus write(const Frame& f) noexcept;

  /// `read`, timed into `sniffer.on_read(frame, begin, end, frame.timestamp)` when a frame was
  /// read: the frame's time is its receive timestamp, the read's time end - begin.
  template <class S>
  [[nodiscard]] IoStatus read(Frame& out, S& sniffer) noexcept {
    const Nanos begin = platform::now_ns();
    const IoStatus st = read(out);
    const Nanos end = platform::now_ns();
    if (st == IoStatus::Ok) sniffer.on_read(out, begin, end, out.timestamp);
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
  StampMapper software_stamps_;  // two clocks, two offsets: a driver may stamp only some frames
  StampMapper hardware_stamps_;
};

}  // namespace vigil::can
