#pragma once
/// @file
/// `vigil::can::Frame`: one CAN frame (Classical CAN, CAN FD, remote or error frame) as vigil's
/// CAN supervision sees it, plus the DLC/length conversions of ISO 11898-1.
///
/// A `Frame` is trivially copyable and 80 bytes long whatever it carries, so that the real-time
/// side can copy it into fixed-size queues without allocating. Every member function is
/// constexpr, noexcept and RT-safe (no allocation, no system call, no lock).

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <span>
#include <string_view>
#include <type_traits>

#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// Whether a frame was received or sent by the node that logged it.
enum class Direction : std::uint8_t {
  Rx,  ///< received
  Tx,  ///< transmitted
};

/// "Rx" or "Tx". RT-safe: yes.
[[nodiscard]] constexpr std::string_view to_string(Direction d) noexcept {
  return d == Direction::Tx ? "Tx" : "Rx";
}

/// How an identifier is encoded on the bus.
enum class IdFormat : std::uint8_t {
  Standard,  ///< 11-bit identifier (CAN 2.0A)
  Extended,  ///< 29-bit identifier (CAN 2.0B)
};

/// The two flags a CAN FD frame carries besides its data.
struct FdFlags {
  bool brs = false;  ///< bit rate switch: the data phase ran at the data bit rate
  bool esi = false;  ///< error state indicator: the sender was error passive
};

inline constexpr std::uint32_t kMaxStandardId = 0x7FF;       ///< largest 11-bit identifier
inline constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;  ///< largest 29-bit identifier
inline constexpr std::size_t kMaxClassicDataLength = 8;      ///< data bytes of Classical CAN
inline constexpr std::size_t kMaxFdDataLength = 64;          ///< data bytes of CAN FD
inline constexpr std::uint8_t kMaxDlc = 15;                  ///< a DLC is 4 bits

/// Data length of a CAN FD frame with data length code `dlc` (0..8 -> 0..8, 9 -> 12, 10 -> 16,
/// 11 -> 20, 12 -> 24, 13 -> 32, 14 -> 48, 15 -> 64). Only the low 4 bits of `dlc` are used, as
/// a controller would. RT-safe: yes.
[[nodiscard]] constexpr std::uint8_t dlc_to_length(std::uint8_t dlc) noexcept {
  constexpr std::array<std::uint8_t, 16> kLength{0, 1,  2,  3,  4,  5,  6,  7,
                                                 8, 12, 16, 20, 24, 32, 48, 64};
  return kLength[dlc & 0x0F];
}

/// Smallest CAN FD data length code whose length holds `length` bytes (13 -> 10, i.e. 16 bytes);
/// lengths above 64 give 15. RT-safe: yes.
[[nodiscard]] constexpr std::uint8_t length_to_dlc(std::size_t length) noexcept {
  if (length <= 8) return static_cast<std::uint8_t>(length);
  if (length <= 12) return 9;
  if (length <= 16) return 10;
  if (length <= 20) return 11;
  if (length <= 24) return 12;
  if (length <= 32) return 13;
  if (length <= 48) return 14;
  return 15;
}

/// True when a CAN FD frame can carry exactly `length` data bytes (0..8, 12, 16, 20, 24, 32, 48,
/// 64). RT-safe: yes.
[[nodiscard]] constexpr bool is_fd_length(std::size_t length) noexcept {
  return length <= kMaxFdDataLength && dlc_to_length(length_to_dlc(length)) == length;
}

/**
 * One CAN frame. Aggregate, trivially copyable, 80 bytes.
 *
 * `length` means what the wire carries: for Classical CAN (and remote frames) it is the DLC,
 * 0..15, of which at most 8 data bytes exist (DLC 9..15 is legal and still means 8 bytes); for
 * CAN FD it is the number of data bytes (one of 0..8, 12, 16, 20, 24, 32, 48, 64). For error
 * frames (SocketCAN's CAN_ERR_FLAG) `id` holds the error class bits and `data` the details.
 * Use `data_size()` / `payload()` to read the data bytes that exist; bytes past them are not
 * part of the frame and are ignored by `operator==`.
 *
 * @code
 * auto a = vigil::can::Frame::classic(0x123, {0x11, 0x22});
 * auto b = vigil::can::Frame::fd_frame(0x18FEF121, bytes, vigil::can::IdFormat::Extended,
 *                                      {.brs = true});
 * vigil::can::Frame c{.timestamp = t, .id = 0x7DF, .length = 8, .rtr = true};
 * @endcode
 */
struct Frame {
  Nanos timestamp = 0;        ///< ns; in logs since the Unix epoch (UTC), on a live bus monotonic
  std::uint32_t id = 0;       ///< identifier (11 or 29 bits); error class bits for error frames
  std::uint8_t bus = 0;       ///< bus index (the log's interface or channel, 0-based)
  std::uint8_t length = 0;    ///< DLC (Classical CAN, remote) or data length (CAN FD), see above
  bool extended : 1 = false;  ///< 29-bit identifier (CAN_EFF_FLAG)
  bool rtr : 1 = false;       ///< remote transmission request (Classical CAN only)
  bool error : 1 = false;     ///< error frame (CAN_ERR_FLAG): `id` is the error class
  bool fd : 1 = false;        ///< CAN FD frame
  bool brs : 1 = false;       ///< CAN FD bit rate switch
  bool esi : 1 = false;       ///< CAN FD error state indicator
  std::array<std::uint8_t, kMaxFdDataLength> data{};  ///< the first `data_size()` bytes are used

  /// A Classical CAN data frame with `bytes` as data; more than 8 bytes are cut to 8.
  /// RT-safe: yes.
  [[nodiscard]] static constexpr Frame classic(std::uint32_t id,
                                               std::span<const std::uint8_t> bytes,
                                               IdFormat format = IdFormat::Standard) noexcept {
    Frame f;
    f.id = id;
    f.extended = format == IdFormat::Extended;
    const std::size_t n = std::min(bytes.size(), kMaxClassicDataLength);
    std::copy_n(bytes.begin(), n, f.data.begin());
    f.length = static_cast<std::uint8_t>(n);
    return f;
  }
  /// Same, from a braced list: `Frame::classic(0x123, {0x11, 0x22})`. RT-safe: yes.
  [[nodiscard]] static constexpr Frame classic(std::uint32_t id,
                                               std::initializer_list<std::uint8_t> bytes,
                                               IdFormat format = IdFormat::Standard) noexcept {
    return classic(id, std::span<const std::uint8_t>(bytes.begin(), bytes.size()), format);
  }

  /// A CAN FD data frame (named `fd_frame` because `fd` is the flag). More than 64 bytes are cut
  /// to 64; a length that no DLC gives (e.g. 9) is padded with zero bytes to the next one (12),
  /// as a CAN FD controller does. RT-safe: yes.
  [[nodiscard]] static constexpr Frame fd_frame(std::uint32_t id,
                                                std::span<const std::uint8_t> bytes,
                                                IdFormat format = IdFormat::Standard,
                                                FdFlags flags = {}) noexcept {
    Frame f;
    f.id = id;
    f.extended = format == IdFormat::Extended;
    f.fd = true;
    f.brs = flags.brs;
    f.esi = flags.esi;
    const std::size_t n = std::min(bytes.size(), kMaxFdDataLength);
    std::copy_n(bytes.begin(), n, f.data.begin());
    f.length = dlc_to_length(length_to_dlc(n));
    return f;
  }
  /// Same, from a braced list. RT-safe: yes.
  [[nodiscard]] static constexpr Frame fd_frame(std::uint32_t id,
                                                std::initializer_list<std::uint8_t> bytes,
                                                IdFormat format = IdFormat::Standard,
                                                FdFlags flags = {}) noexcept {
    return fd_frame(id, std::span<const std::uint8_t>(bytes.begin(), bytes.size()), format, flags);
  }

  /// A remote frame (RTR) requesting `dlc` bytes (0..15, higher values are cut to 15).
  /// RT-safe: yes.
  [[nodiscard]] static constexpr Frame remote(std::uint32_t id, std::uint8_t dlc = 0,
                                              IdFormat format = IdFormat::Standard) noexcept {
    Frame f;
    f.id = id;
    f.extended = format == IdFormat::Extended;
    f.rtr = true;
    f.length = std::min(dlc, kMaxDlc);
    return f;
  }

  /// An error frame with SocketCAN error class bits `error_class` (CAN_ERR_* of
  /// <linux/can/error.h>, at most 29 bits) and up to 8 detail bytes. RT-safe: yes.
  [[nodiscard]] static constexpr Frame error_frame(
      std::uint32_t error_class, std::initializer_list<std::uint8_t> bytes = {}) noexcept {
    Frame f = classic(error_class & kMaxExtendedId,
                      std::span<const std::uint8_t>(bytes.begin(), bytes.size()));
    f.error = true;
    return f;
  }

  /// Number of data bytes the frame carries: 0 for remote frames, min(length, 64) for CAN FD,
  /// min(length, 8) otherwise. RT-safe: yes.
  [[nodiscard]] constexpr std::size_t data_size() const noexcept {
    if (rtr && !fd) return 0;
    return std::min<std::size_t>(length, fd ? kMaxFdDataLength : kMaxClassicDataLength);
  }

  /// The data bytes that exist (`data_size()` of them). RT-safe: yes.
  [[nodiscard]] constexpr std::span<const std::uint8_t> payload() const noexcept {
    return {data.data(), data_size()};
  }

  /// The 4-bit data length code on the wire: `length` (at most 15) for Classical CAN and remote
  /// frames, `length_to_dlc(length)` for CAN FD. RT-safe: yes.
  [[nodiscard]] constexpr std::uint8_t dlc() const noexcept {
    return fd ? length_to_dlc(length) : std::min(length, kMaxDlc);
  }

  /**
   * True when the frame could exist on a bus: the id fits its format (11 or 29 bits; error
   * classes 29 bits), a Classical CAN DLC is at most 15, a CAN FD length is one a DLC gives,
   * CAN FD frames are not remote or error frames, and BRS/ESI are only set on CAN FD frames.
   * RT-safe: yes.
   */
  [[nodiscard]] constexpr bool valid() const noexcept {
    if (error) {
      if (id > kMaxExtendedId || rtr || fd || brs || esi) return false;
      return length <= kMaxClassicDataLength;
    }
    if (id > (extended ? kMaxExtendedId : kMaxStandardId)) return false;
    if (fd) return !rtr && is_fd_length(length);
    return !brs && !esi && length <= kMaxDlc;
  }

  /// Two frames are equal when every field is equal and their `data_size()` data bytes are;
  /// unused bytes of `data` are not compared. RT-safe: yes.
  friend constexpr bool operator==(const Frame& a, const Frame& b) noexcept {
    if (a.timestamp != b.timestamp || a.id != b.id || a.bus != b.bus || a.length != b.length ||
        a.extended != b.extended || a.rtr != b.rtr || a.error != b.error || a.fd != b.fd ||
        a.brs != b.brs || a.esi != b.esi) {
      return false;
    }
    const std::size_t n = a.data_size();
    return std::equal(a.data.begin(), a.data.begin() + static_cast<std::ptrdiff_t>(n),
                      b.data.begin());
  }
};

static_assert(std::is_trivially_copyable_v<Frame>, "Frame must be trivially copyable");
static_assert(std::is_aggregate_v<Frame>, "Frame must stay an aggregate");
static_assert(sizeof(Frame) == 80, "Frame has a fixed size of 80 bytes: keep the layout packed");
static_assert(alignof(Frame) == alignof(Nanos));

}  // namespace vigil::can
