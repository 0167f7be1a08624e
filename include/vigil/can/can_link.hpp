#pragma once
/// @file
/// A CAN controller's live state as SocketCAN's driver gives it through rtnetlink (RTM_GETLINK):
/// its fault confinement state (error active, warning, passive, bus off, stopped), its error
/// counters (txerr, rxerr), its restarts, bus errors and state changes (`can_device_stats`), and
/// its bitrates (nominal and CAN FD data phase) — what `ip -details -statistics link show can0`
/// prints.
///
/// Two layers:
///  - `parse_link_message`: a pure function over the bytes of one RTM_NEWLINK message (no system
///    call): what the kernel's answer says, or an error naming the offset and the attribute for
///    truncated attributes, bad lengths, a link that is not a CAN device. Tested against
///    hand-built messages; fuzzed.
///  - `query_link`: one RTM_GETLINK request over a NETLINK_ROUTE socket for one interface, its
///    answer parsed by the above. Fails with a message naming the interface: no such interface,
///    not a CAN device (`lo`), no netlink.
///
/// The attributes read, from the kernel's UAPI headers:
///  - linux/rtnetlink.h: RTM_NEWLINK, struct ifinfomsg; linux/netlink.h: struct nlmsghdr,
///    struct nlattr, NLA_F_NESTED, NLMSG_ERROR;
///  - linux/if_link.h: IFLA_IFNAME, IFLA_STATS64 (else IFLA_STATS: the first eight counters,
///    packets, bytes, errors, drops), IFLA_LINKINFO { IFLA_INFO_KIND ("can", "vcan"),
///    IFLA_INFO_DATA, IFLA_INFO_XSTATS };
///  - linux/can/netlink.h: in IFLA_INFO_DATA, IFLA_CAN_BITTIMING (struct can_bittiming: bitrate,
///    sample point), IFLA_CAN_STATE (enum can_state, u32), IFLA_CAN_BERR_COUNTER (struct
///    can_berr_counter: u16 txerr, rxerr), IFLA_CAN_DATA_BITTIMING, IFLA_CAN_RESTART_MS; in
///    IFLA_INFO_XSTATS, struct can_device_stats (u32 bus_error, error_warning, error_passive,
///    bus_off, arbitration_lost, restarts).
/// A virtual CAN device (vcan) has no controller: its kind is "vcan" and none of the CAN
/// attributes; it reads as `is_can` with no state.
///
/// Not RT-safe (allocates; `query_link` makes system calls): the CAN extension reads the links
/// on the monitor's thread, never on a sniffer's.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "vigil/can/protocol.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// A CAN controller's state as the driver reports it (enum can_state of linux/can/netlink.h).
enum class LinkControllerState : std::uint8_t {
  ErrorActive = 0,   ///< CAN_STATE_ERROR_ACTIVE: error counters below 96
  ErrorWarning = 1,  ///< CAN_STATE_ERROR_WARNING: below 128
  ErrorPassive = 2,  ///< CAN_STATE_ERROR_PASSIVE: below 256
  BusOff = 3,        ///< CAN_STATE_BUS_OFF: 256 and above, the controller left the bus
  Stopped = 4,       ///< CAN_STATE_STOPPED: the interface is down
  Sleeping = 5,      ///< CAN_STATE_SLEEPING
};
/// "error active", "error warning", "error passive", "bus off", "stopped", "sleeping".
[[nodiscard]] std::string_view to_string(LinkControllerState s) noexcept;
/// The fault confinement state it is (`ControllerState`, as error frames give it); stopped and
/// sleeping have none (Unknown).
[[nodiscard]] ControllerState controller_state(LinkControllerState s) noexcept;

/// struct can_device_stats (linux/can/netlink.h): the driver's counts since the interface was
/// created.
struct LinkDeviceStats {
  std::uint32_t bus_error = 0;         ///< bus errors
  std::uint32_t error_warning = 0;     ///< changes to error warning state
  std::uint32_t error_passive = 0;     ///< changes to error passive state
  std::uint32_t bus_off = 0;           ///< changes to bus off state
  std::uint32_t arbitration_lost = 0;  ///< arbitration lost errors
  std::uint32_t restarts = 0;          ///< CAN controller re-starts
};

/// The interface's packet counters (IFLA_STATS64, struct rtnl_link_stats64 of linux/if_link.h;
/// IFLA_STATS, 32-bit, when the 64-bit ones are absent): for a CAN device, frames, and the errors
/// and drops its driver counted (bus errors, lost frames).
struct LinkCounters {
  std::uint64_t rx_packets = 0;
  std::uint64_t tx_packets = 0;
  std::uint64_t rx_errors = 0;
  std::uint64_t tx_errors = 0;
  std::uint64_t rx_dropped = 0;
  std::uint64_t tx_dropped = 0;
};

/// What one RTM_NEWLINK message says of a link.
struct LinkInfo {
  std::int32_t index = 0;  ///< ifi_index
  std::string name;        ///< IFLA_IFNAME ("" when absent)
  std::string kind;        ///< IFLA_INFO_KIND ("can", "vcan"; "" when the link has none)
  bool up = false;         ///< IFF_UP in ifi_flags
  std::optional<LinkControllerState> state;     ///< IFLA_CAN_STATE
  std::optional<std::uint16_t> tx_errors;       ///< IFLA_CAN_BERR_COUNTER txerr
  std::optional<std::uint16_t> rx_errors;       ///< IFLA_CAN_BERR_COUNTER rxerr
  std::optional<std::uint32_t> bitrate;         ///< IFLA_CAN_BITTIMING bitrate (bit/s; 0 omitted)
  std::optional<std::uint32_t> sample_point;    ///< ... sample point, tenths of a percent
  std::optional<std::uint32_t> data_bitrate;    ///< IFLA_CAN_DATA_BITTIMING bitrate (CAN FD)
  std::optional<std::uint32_t> restart_ms;      ///< IFLA_CAN_RESTART_MS (0: no auto restart)
  std::optional<LinkDeviceStats> device_stats;  ///< IFLA_INFO_XSTATS
  std::optional<LinkCounters> counters;         ///< IFLA_STATS64 (else IFLA_STATS)
  /// Attributes skipped because they were shorter than their type needs (each named in
  /// `skipped_detail`); the rest of the message is still read.
  std::uint32_t skipped = 0;
  std::string skipped_detail;

  /// A CAN device: kind "can" (a controller) or "vcan"/"vxcan" (virtual, no state).
  [[nodiscard]] bool is_can() const noexcept;
};

/// Parses one netlink message (struct nlmsghdr first) that must be an RTM_NEWLINK. Errors say
/// where ("offset 36: attribute 18 (IFLA_LINKINFO): length 200 beyond the message's 64 bytes"):
/// a message shorter than its header, an nlmsg_len beyond the bytes, another message type, an
/// NLMSG_ERROR (its errno), an attribute whose length is below 4 or beyond its container. An
/// attribute that is well formed but shorter than its C struct is skipped and counted
/// (`LinkInfo::skipped`). Never reads outside `message`. Pure: no system call, allocates only
/// the strings.
[[nodiscard]] expected<LinkInfo, Error> parse_link_message(std::span<const std::uint8_t> message);

/// Asks the kernel (RTM_GETLINK over NETLINK_ROUTE) for `interface`'s link and parses the
/// answer. Fails with a message naming the interface: ENODEV "no such interface", EINVAL "not a
/// CAN device (link kind: none)" for `lo` or an Ethernet port, the socket's errno otherwise, or
/// the parser's error. One socket per call, with a 1 s receive timeout. Not RT-safe.
[[nodiscard]] expected<LinkInfo, Error> query_link(std::string_view interface);

/// The latest reading of one bus's interface, as the CAN extension keeps it (monitor's pace).
struct LinkReading {
  std::uint8_t bus = 0;
  std::string interface;
  std::optional<LinkInfo> info;  ///< the latest successful reading
  std::string error;             ///< why the latest reading failed ("" when it succeeded)
  Nanos read_ns = -1;            ///< when it was read (platform::now_ns)
  std::uint64_t reads = 0;       ///< readings tried
  std::uint64_t failures = 0;    ///< of them, failed (`error` says the latest)
};

}  // namespace vigil::can
