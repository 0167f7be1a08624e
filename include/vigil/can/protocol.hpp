#pragma once
/// @file
/// What CAN supervision reads in the frames themselves, besides their timing: the bus load
/// (how many bits each frame occupies on the wire, as can-utils' `canbusload` counts them), the
/// controller state from SocketCAN error frames (Linux `include/uapi/linux/can/error.h`), and
/// CANopen (CiA 301) NMT, heartbeat, node guarding and emergency messages, DroneCAN NodeStatus.
///
/// The decoders are plain functions (constexpr where they can be); `ProtocolTracker` applies
/// them to a stream of `FrameRecord`s on the CAN supervisor's thread (the CAN aggregator owns
/// one), never on the sniffer's real-time path. Docs: docs/guide/can-protocols.md.
///
/// Frame length (ISO 11898-1:2015, clause 10.4, "Frame formats"): a Classical CAN data frame is
/// SOF (1), identifier (11), RTR (1), IDE (1), r0 (1), DLC (4), data (8 per byte), CRC sequence
/// (15), CRC delimiter (1), ACK slot (1), ACK delimiter (1), EOF (7), then the intermission (3):
/// 47 + 8n bits; the extended format adds SRR (1), IDE (1) and 18 identifier bits and has r1/r0:
/// 67 + 8n. Bit stuffing (clause 10.5) inserts a complementary bit after 5 equal bits from SOF to
/// the end of the CRC sequence. The three counting modes are canbusload's:
/// `Stuffing::None` (no stuff bit), `Stuffing::WorstCase` (55 + 10n, 80 + 10n) and
/// `Stuffing::Exact` (the frame's own bits, CRC-15 included). CAN FD frames use canbusload's
/// approximation (its canframelen.c): no stuffing 1 + id + (17 or 21 CRC bits) + 5 + 12 + 8n,
/// worst case x 5/4, and with BRS the bits of the data phase (BRS to CRC delimiter: 1 + 1 + 4 +
/// CRC + 8n, x 5/4 worst case) counted at the data bitrate. canbusload has no exact mode for
/// CAN FD; here `Exact` counts CAN FD frames as `WorstCase` and says how many it estimated.

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/sniffer_types.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

// ---------------------------------------------------------------------------------------------
// Bus load
// ---------------------------------------------------------------------------------------------

/// How stuff bits are counted (canbusload's modes: default worst case, `-e` exact, `-i` none).
enum class Stuffing : std::uint8_t {
  None,       ///< no stuff bit (canbusload -i)
  WorstCase,  ///< the most stuff bits a frame of that length can have (canbusload's default)
  Exact,      ///< the frame's own stuff bits, from its bits and CRC (canbusload -e)
};
inline constexpr std::size_t kStuffingModes = 3;
/// "none", "worst", "exact".
[[nodiscard]] std::string_view to_string(Stuffing s) noexcept;

/// The bits a frame occupies on the bus: `nominal` at the (arbitration) bitrate, `data` at the
/// CAN FD data bitrate (BRS frames only; 0 otherwise). Interframe space included.
struct FrameBits {
  std::uint32_t nominal = 0;
  std::uint32_t data = 0;
  [[nodiscard]] std::uint32_t total() const noexcept { return nominal + data; }
};

/// What the bit count needs of a frame. Data bytes past `data.size()` count as zero (exact
/// mode on CAN FD frames does not read them).
struct FrameShape {
  std::uint32_t id = 0;
  bool extended = false;
  bool rtr = false;
  bool fd = false;
  bool brs = false;
  std::uint8_t length = 0;  ///< DLC (Classical, remote) or data length (CAN FD), as `Frame`
  std::span<const std::uint8_t> data{};
};

/// CRC-15 of ISO 11898-1 (generator x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1, 0x4599,
/// initial value 0) over `bits` (one bit per element, 0 or 1, first bit first).
[[nodiscard]] std::uint16_t can_crc15(std::span<const std::uint8_t> bits) noexcept;

/// The unstuffed bits of a Classical CAN frame from SOF to the end of the CRC sequence, one per
/// element, into `out` (at least 118 elements); returns how many. Remote frames have no data
/// field; a DLC above 8 means 8 data bytes.
std::size_t classic_frame_bits(const FrameShape& f, std::span<std::uint8_t> out) noexcept;

/// Stuff bits ISO 11898-1 inserts in `bits` (after every 5 equal bits, the stuff bit itself
/// counting in the next run).
[[nodiscard]] std::uint32_t stuff_bits(std::span<const std::uint8_t> bits) noexcept;

/// A Classical CAN frame's bits from SOF to the end of the CRC sequence with its stuff bits:
/// `classic_frame_bits` + `stuff_bits`, computed on packed words with a table-driven CRC-15
/// (what `frame_bits` uses in `Stuffing::Exact`).
[[nodiscard]] std::uint32_t exact_classic_bits(const FrameShape& f) noexcept;

/// The bits frame `f` occupies on the bus in mode `s` (see the file comment). Error frames are
/// not frames on the wire: 0.
[[nodiscard]] FrameBits frame_bits(const FrameShape& f, Stuffing s) noexcept;
/// Same, from a `Frame`.
[[nodiscard]] FrameBits frame_bits(const Frame& f, Stuffing s) noexcept;

/// One direction (rx, tx, or both) of one bus, in one stuffing mode. Loads are percent of the
/// bitrate: nominal bits / bitrate + data-phase bits / data bitrate, per second; NaN when the
/// bitrate is not known. canbusload computes the same once a second, and its 1/5/15-minute
/// loads with the kernel's load-average damping (e^(-1/60), e^(-1/300), e^(-1/900) per second).
struct BusLoad {
  std::uint64_t frames = 0;            ///< frames counted since the start
  std::uint64_t bits = 0;              ///< their bits (nominal + data phase) since the start
  std::uint64_t last_second_bits = 0;  ///< bits in the latest complete second
  double last_second = 0;              ///< percent, the latest complete second
  double avg_1m = 0;                   ///< percent, exponential average over 1 minute
  double avg_5m = 0;
  double avg_15m = 0;
  double peak = 0;     ///< percent, the busiest complete second so far
  bool known = false;  ///< the bitrate is known: the percentages mean something
  double mean = 0;     ///< percent, bits / (bitrate x seconds observed): the whole history
};

/// Which figure of a `BusLoad` a threshold compares.
enum class LoadFigure : std::uint8_t { LastSecond, Avg1m, Avg5m, Avg15m, Peak, Mean };
/// "last_second", "1min", "5min", "15min", "peak", "mean".
[[nodiscard]] std::string_view to_string(LoadFigure f) noexcept;
/// The figure's value.
[[nodiscard]] double load_value(const BusLoad& l, LoadFigure f) noexcept;

// ---------------------------------------------------------------------------------------------
// Error frames (Linux include/uapi/linux/can/error.h)
// ---------------------------------------------------------------------------------------------

/// The error classes of a SocketCAN error frame (its id bits), in bit order.
namespace error_class {
inline constexpr std::uint32_t kTxTimeout = 0x001;  ///< TX timeout (by netdevice driver)
inline constexpr std::uint32_t kLostArb = 0x002;    ///< lost arbitration, data[0] the bit
inline constexpr std::uint32_t kCrtl = 0x004;       ///< controller problems, data[1]
inline constexpr std::uint32_t kProt = 0x008;       ///< protocol violation, data[2] type, [3] where
inline constexpr std::uint32_t kTrx = 0x010;        ///< transceiver status, data[4]
inline constexpr std::uint32_t kAck = 0x020;        ///< received no ACK on transmission
inline constexpr std::uint32_t kBusOff = 0x040;     ///< bus off
inline constexpr std::uint32_t kBusError = 0x080;   ///< bus error (may flood)
inline constexpr std::uint32_t kRestarted = 0x100;  ///< controller restarted
inline constexpr std::uint32_t kCnt = 0x200;        ///< TX / RX error counters in data[6] / [7]
inline constexpr std::size_t kCount = 10;
}  // namespace error_class

/// Name of error class bit `index` (0-9): "tx timeout", "lost arbitration", "controller",
/// "protocol", "transceiver", "no ack", "bus off", "bus error", "restarted", "error counters".
[[nodiscard]] std::string_view error_class_name(std::size_t index) noexcept;
/// Names of the controller status bits of data[1] ("rx overflow", "tx warning", "rx passive",
/// "active"...), joined with ", "; "unspecified" for 0.
[[nodiscard]] std::string controller_status_names(std::uint8_t data1);
/// Names of the protocol violation type bits of data[2] ("bit", "form", "stuff", ...).
[[nodiscard]] std::string protocol_type_names(std::uint8_t data2);
/// Name of a protocol violation location, data[3] ("CRC sequence", "ACK slot", ...); "location
/// 0xNN" for a value error.h does not define.
[[nodiscard]] std::string protocol_location_name(std::uint8_t data3);
/// Name of a transceiver status, data[4] ("CANH no wire", ...).
[[nodiscard]] std::string transceiver_name(std::uint8_t data4);

/// A CAN controller's fault confinement state (ISO 11898-1 clause 12.1.4).
enum class ControllerState : std::uint8_t {
  Unknown,       ///< no error frame said anything yet (presumed error active)
  ErrorActive,   ///< error counters below 96 (restarted, or recovered to active)
  ErrorWarning,  ///< an error counter reached 96
  ErrorPassive,  ///< an error counter above 127
  BusOff,        ///< the transmit error counter above 255: the controller left the bus
};
/// "unknown", "error active", "error warning", "error passive", "bus off".
[[nodiscard]] std::string_view to_string(ControllerState s) noexcept;

/// What the error frames of one bus said.
struct ControllerStats {
  ControllerState state = ControllerState::Unknown;
  Nanos state_since_ns = -1;  ///< the error frame that set it; -1 never
  std::uint64_t error_frames = 0;
  /// Error frames with each class bit (index = bit number, `error_class_name`).
  std::array<std::uint64_t, error_class::kCount> by_class{};
  std::uint64_t warnings = 0;      ///< entries into error warning
  std::uint64_t passives = 0;      ///< entries into error passive
  std::uint64_t bus_offs = 0;      ///< entries into bus off
  std::uint64_t restarts = 0;      ///< restarted (CAN_ERR_RESTARTED) or recovered to active
  std::uint64_t rx_overflows = 0;  ///< controller rx buffer overflows (CRTL)
  std::uint64_t tx_overflows = 0;  ///< controller tx buffer overflows (CRTL)
  /// Protocol violations by type bit (data[2]: bit, form, stuff, bit0, bit1, overload, active,
  /// tx) and by location (data[3], at most 32 distinct locations kept; more are counted in
  /// `other_locations`).
  std::array<std::uint64_t, 8> protocol_types{};
  std::vector<std::pair<std::uint8_t, std::uint64_t>> protocol_locations{};
  std::uint64_t other_locations = 0;
  std::optional<std::uint8_t> transceiver;  ///< latest transceiver status (data[4])
  std::optional<std::uint8_t> tx_errors;    ///< latest transmit error counter (data[6])
  std::optional<std::uint8_t> rx_errors;    ///< latest receive error counter (data[7])
  std::string last;                         ///< the latest error frame, decoded
  Nanos last_ns = -1;
};

/// One error frame decoded to text ("controller: rx passive, tx passive; error counters tx 130
/// rx 0"). Only the bytes that exist are read.
[[nodiscard]] std::string describe_error_frame(std::uint32_t error_class,
                                               std::span<const std::uint8_t> data);

// ---------------------------------------------------------------------------------------------
// CANopen (CiA 301)
// ---------------------------------------------------------------------------------------------

namespace canopen {

/// The NMT state a heartbeat (or a node-guarding response) gives, CiA 301 clause 7.2.8.3.2.
enum class NmtState : std::uint8_t {
  Unknown = 0xFF,  ///< no heartbeat yet
  BootUp = 0x00,
  Stopped = 0x04,
  Operational = 0x05,
  PreOperational = 0x7F,
};
/// "boot-up", "stopped", "operational", "pre-operational", "unknown".
[[nodiscard]] std::string_view to_string(NmtState s) noexcept;
/// The state of byte `b` (toggle bit 7 cleared), or empty when CiA 301 defines none.
[[nodiscard]] std::optional<NmtState> nmt_state_of(std::uint8_t b) noexcept;

/// NMT command specifiers (CiA 301 clause 7.2.8.3.1), byte 0 of a frame on id 0x000.
[[nodiscard]] std::string_view nmt_command_name(std::uint8_t cs) noexcept;

/// The class of an emergency error code (CiA 301 clause 7.2.7.3.1, table 21): "error reset or
/// no error", "generic error", "current", "voltage", "temperature", "device hardware", "device
/// software", "additional modules", "monitoring", "external error", "additional functions",
/// "device specific", with the sub-class where CiA 301 names one ("communication: CAN overrun
/// (objects lost)", "communication: CAN in error passive mode", "communication: life guard or
/// heartbeat error", "communication: recovered from bus off", ...).
[[nodiscard]] std::string emergency_class(std::uint16_t code);
/// The set bits of an error register (object 0x1001): "generic", "current", "voltage",
/// "temperature", "communication", "device profile", "manufacturer".
[[nodiscard]] std::string error_register_names(std::uint8_t reg);

/// One emergency message, decoded.
struct Emergency {
  std::uint16_t code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
  std::uint8_t length = 0;  ///< bytes the frame had (8 expected)
  Nanos time_ns = 0;
  /// "0x8130 communication: life guard or heartbeat error, register 0x11 (generic,
  /// communication), manufacturer 00 00 00 00 00".
  [[nodiscard]] std::string describe() const;
};

/// What the CANopen decoder knows of one node.
struct NodeStats {
  std::uint8_t bus = 0;
  std::uint8_t node = 0;  ///< node-ID 1-127
  NmtState state = NmtState::Unknown;
  Nanos state_since_ns = -1;       ///< the heartbeat that set it
  Nanos last_heartbeat_ns = -1;    ///< latest heartbeat or guarding response
  Nanos operational_left_ns = -1;  ///< when it last left (or, never operational, first seen)
  bool ever_running = false;       ///< reported a state other than boot-up
  std::uint64_t heartbeats = 0;    ///< heartbeats (and guarding responses)
  std::uint64_t boot_ups = 0;
  std::uint64_t resets = 0;  ///< boot-ups of a node that was running
  Nanos last_reset_ns = -1;
  std::uint64_t state_changes = 0;
  std::uint64_t guard_requests = 0;   ///< remote frames to 0x700 + id
  std::uint64_t guard_responses = 0;  ///< answers to them
  std::uint64_t toggle_errors = 0;    ///< answers whose toggle bit did not alternate
  std::uint64_t emergencies = 0;
  std::optional<Emergency> last_emergency;
  /// Malformed payloads: an emergency shorter than 8 bytes, a heartbeat whose length is not 1
  /// or whose state byte CiA 301 does not define.
  std::uint64_t malformed_emergencies = 0;
  std::uint64_t malformed_heartbeats = 0;
  std::string last_malformed;  ///< what the latest was
};

}  // namespace canopen

// ---------------------------------------------------------------------------------------------
// DroneCAN (UAVCAN v0): uavcan.protocol.NodeStatus, data type ID 341
// ---------------------------------------------------------------------------------------------

namespace dronecan {

/// NodeStatus's data type ID.
inline constexpr std::uint16_t kNodeStatus = 341;

/// NodeStatus.health (2 bits).
enum class Health : std::uint8_t { Ok = 0, Warning = 1, Error = 2, Critical = 3, Unknown = 0xFF };
/// "OK", "WARNING", "ERROR", "CRITICAL", "unknown".
[[nodiscard]] std::string_view to_string(Health h) noexcept;
/// NodeStatus.mode (3 bits): "operational", "initialization", "maintenance", "software update",
/// "offline", or "mode N" for the values the standard reserves.
[[nodiscard]] std::string mode_name(std::uint8_t mode);

/// One NodeStatus payload (7 bytes: uptime_sec uint32, health uint2, mode uint3, sub_mode uint3,
/// vendor_specific_status_code uint16; little-endian, bit fields from the most significant bit
/// of their byte).
struct NodeStatus {
  std::uint32_t uptime_s = 0;
  Health health = Health::Ok;
  std::uint8_t mode = 0;
  std::uint8_t sub_mode = 0;
  std::uint16_t vendor_status = 0;
};
/// The NodeStatus in `payload`, or empty when it is shorter than 7 bytes.
[[nodiscard]] std::optional<NodeStatus> decode_node_status(
    std::span<const std::uint8_t> payload) noexcept;

/// What the DroneCAN decoder knows of one node.
struct NodeStats {
  std::uint8_t bus = 0;
  std::uint8_t node = 0;  ///< node ID 1-127
  Health health = Health::Unknown;
  std::uint8_t mode = 0;
  std::uint8_t sub_mode = 0;
  std::uint16_t vendor_status = 0;
  std::uint32_t uptime_s = 0;  ///< as of its latest NodeStatus
  Nanos last_status_ns = -1;
  std::uint64_t statuses = 0;  ///< NodeStatus messages
  std::uint64_t restarts = 0;  ///< its uptime went back
  Nanos last_restart_ns = -1;
  std::uint64_t malformed = 0;  ///< NodeStatus frames that are not a 7-byte single-frame transfer
  std::string last_malformed;
};

}  // namespace dronecan

// ---------------------------------------------------------------------------------------------
// SAE J1939: DM1 active and DM2 previously active trouble codes (J1939-73), transport protocol
// (J1939-21), address claim (J1939-81)
// ---------------------------------------------------------------------------------------------

namespace j1939 {

inline constexpr std::uint32_t kPgnDm1 = 0xFECA;   ///< DM1, active DTCs (J1939-73)
inline constexpr std::uint32_t kPgnDm2 = 0xFECB;   ///< DM2, previously active DTCs (J1939-73)
inline constexpr std::uint32_t kPgnTpCm = 0xEC00;  ///< TP.CM (J1939-21)
inline constexpr std::uint32_t kPgnTpDt = 0xEB00;  ///< TP.DT (J1939-21)
inline constexpr std::uint32_t kPgnAddressClaimed = 0xEE00;  ///< address claimed (J1939-81)

/// TP.CM control bytes (J1939-21, transport protocol connection management).
inline constexpr std::uint8_t kTpRts = 16;
inline constexpr std::uint8_t kTpCts = 17;
inline constexpr std::uint8_t kTpEndOfMsgAck = 19;
inline constexpr std::uint8_t kTpBam = 32;
inline constexpr std::uint8_t kTpAbort = 255;
/// The largest message the transport protocol carries: 255 packets of 7 bytes.
inline constexpr std::size_t kTpMaxSize = 1785;

/// J1939-21 transport protocol timeouts, as a passive observer applies them: T1 (750 ms) after
/// a data packet when more are expected (and after a BAM), T2 (1250 ms) after a CTS for its
/// data, T3 (1250 ms) after an RTS (or the last data packet) for the CTS, T4 (1050 ms) after a
/// CTS that holds the connection open (0 packets) for the next CTS.
inline constexpr Nanos kT1 = Nanos{750} * 1'000'000;
inline constexpr Nanos kT2 = Nanos{1250} * 1'000'000;
inline constexpr Nanos kT3 = Nanos{1250} * 1'000'000;
inline constexpr Nanos kT4 = Nanos{1050} * 1'000'000;

/// A DM1 lamp (2 bits, J1939-73 DM1 byte 1): 00 off, 01 on, 10 error (so Detroit Diesel's DDEC VI
/// manual; other public descriptions say "reserved"; never counted as on), 11 not available.
enum class Lamp : std::uint8_t { Off = 0, On = 1, Error = 2, NotAvailable = 3 };
/// "off", "on", "error", "n/a".
[[nodiscard]] std::string_view to_string(Lamp l) noexcept;

/// The lamp status of a DM1 or DM2 (byte 1: bits 8-7 malfunction indicator lamp, 6-5 red stop
/// lamp, 4-3 amber warning lamp, 2-1 protect lamp; byte 2 their flash codes, in the same bit
/// pairs: 00 slow flash, 01 fast flash, 11 not flashing or not available).
struct Lamps {
  Lamp mil = Lamp::NotAvailable;            ///< malfunction indicator lamp (emissions)
  Lamp red_stop = Lamp::NotAvailable;       ///< red stop lamp
  Lamp amber_warning = Lamp::NotAvailable;  ///< amber warning lamp
  Lamp protect = Lamp::NotAvailable;        ///< protect lamp
  std::uint8_t flash = 0xFF;                ///< byte 2, the flash codes as sent
  [[nodiscard]] bool any_on() const noexcept {
    return mil == Lamp::On || red_stop == Lamp::On || amber_warning == Lamp::On ||
           protect == Lamp::On;
  }
  /// "MIL off, red stop on, amber warning off, protect n/a".
  [[nodiscard]] std::string describe() const;
  friend bool operator==(const Lamps&, const Lamps&) = default;
};

/// One diagnostic trouble code (J1939-73, 4 bytes: SPN bits 1-8, 9-16, then SPN bits 17-19 in
/// bits 8-6 with the FMI in bits 5-1, then the conversion method in bit 8 with the occurrence
/// count in bits 7-1). Decoded as conversion method version 4 (CM 0); the CM bit is kept.
struct Dtc {
  std::uint32_t spn = 0;           ///< suspect parameter number, 19 bits
  std::uint8_t fmi = 0;            ///< failure mode identifier, 5 bits
  std::uint8_t occurrences = 0;    ///< occurrence count, 7 bits (127: not available)
  bool conversion_method = false;  ///< the SPN conversion method bit (1: versions 1-3)
  /// "SPN 100 FMI 1 (data valid but below normal operational range - most severe level), 3
  /// occurrences".
  [[nodiscard]] std::string describe() const;
  [[nodiscard]] bool same_code(const Dtc& o) const noexcept { return spn == o.spn && fmi == o.fmi; }
  friend bool operator==(const Dtc&, const Dtc&) = default;
};

/// Name of a failure mode identifier (J1939-73 FMI table, 0-21 and 31; "reserved" otherwise).
[[nodiscard]] std::string_view fmi_name(std::uint8_t fmi) noexcept;

/// One DM1 message (or DM2: the same layout), decoded.
struct Dm1 {
  Lamps lamps;
  std::vector<Dtc> dtcs;  ///< the codes listed; empty: none ("no DTC" records are dropped)
};

/// Decodes a DM1 payload. `single_frame`: a message in one CAN frame (6-8 bytes: the lamps and
/// one DTC, the rest padding); otherwise a message reassembled by the transport protocol (2 + 4n
/// bytes exactly). A record of all zeros or all ones is "no DTC" (J1939-73). On a malformed
/// payload returns empty and says why in `error`.
[[nodiscard]] std::optional<Dm1> decode_dm1(std::span<const std::uint8_t> payload,
                                            bool single_frame, std::string& error);
/// Decodes a DM2 payload (previously active DTCs, J1939-73): the layout of DM1, the same rules;
/// its errors say "DM2".
[[nodiscard]] std::optional<Dm1> decode_dm2(std::span<const std::uint8_t> payload,
                                            bool single_frame, std::string& error);

/// A 64-bit NAME (J1939-81, address claimed message, little-endian): identity number (21
/// bits), manufacturer code (11), ECU instance (3), function instance (5), function (8), a
/// reserved bit, vehicle system (7), vehicle system instance (4), industry group (3),
/// arbitrary address capable (1).
struct Name {
  std::uint64_t raw = 0;
  std::uint32_t identity = 0;
  std::uint16_t manufacturer = 0;
  std::uint8_t ecu_instance = 0;
  std::uint8_t function_instance = 0;
  std::uint8_t function = 0;
  std::uint8_t vehicle_system = 0;
  std::uint8_t vehicle_system_instance = 0;
  std::uint8_t industry_group = 0;
  bool arbitrary_address = false;
  /// A short label for reports: the function's name ("engine", "brakes - system controller",
  /// or "function 130"), with "#<function instance>" when that is not 0.
  [[nodiscard]] std::string label() const;
  /// Every field: "engine, function instance 0, ECU instance 0, manufacturer 123, identity
  /// 4567, industry group 1 (on-highway), vehicle system 0 instance 0, arbitrary address
  /// capable".
  [[nodiscard]] std::string describe() const;
  friend bool operator==(const Name&, const Name&) = default;
};
/// The NAME of 8 address-claimed bytes (little-endian).
[[nodiscard]] Name decode_name(std::span<const std::uint8_t, 8> bytes) noexcept;
/// Name of a NAME function 0-30 (the first of the functions 0-127 that J1939 assigns whatever
/// the industry group; 128-255 depend on the industry group and vehicle system); others empty.
[[nodiscard]] std::string_view function_name(std::uint8_t function) noexcept;
/// Name of an industry group 0-5 ("global", "on-highway", "agricultural and forestry",
/// "construction", "marine", "industrial"); others empty.
[[nodiscard]] std::string_view industry_group_name(std::uint8_t group) noexcept;

/// What the J1939 decoder knows of one source address.
struct NodeStats {
  std::uint8_t bus = 0;
  std::uint8_t address = 0;  ///< source address
  std::optional<Name> name;  ///< from its latest address claim
  Nanos claimed_ns = -1;
  std::uint64_t claims = 0;  ///< address claimed messages
  std::uint64_t dm1s = 0;    ///< DM1 messages decoded
  Nanos last_dm1_ns = -1;
  Lamps lamps;                       ///< as of its latest DM1
  std::vector<Dtc> active;           ///< its active DTCs (latest DM1), at most `max_dtcs`
  std::uint64_t dtcs_untracked = 0;  ///< codes beyond `max_dtcs` (no events for them)
  std::uint64_t dtcs_appeared = 0;   ///< `dtc_active` events
  std::uint64_t dtcs_cleared = 0;    ///< `dtc_cleared` events
  std::uint64_t dm2s = 0;            ///< DM2 messages decoded (previously active DTCs)
  Nanos last_dm2_ns = -1;
  Lamps dm2_lamps;  ///< as of its latest DM2
  /// Its previously active DTCs (latest DM2), at most `max_dtcs`. No events: a DM2 usually
  /// answers a request, its list is a record of the past, not a change on the bus.
  std::vector<Dtc> previously_active;
  std::uint64_t previously_active_untracked = 0;  ///< codes of its latest DM2 beyond `max_dtcs`
  std::uint64_t tp_messages = 0;                  ///< transport protocol messages it completed
  std::uint64_t tp_aborts = 0;                    ///< its sessions ended by a connection abort
  std::uint64_t tp_timeouts = 0;                  ///< its sessions that timed out (also malformed)
  /// Malformed input: DM1 or DM2 of a wrong length, address claims not of 8 bytes, TP announcements
  /// that do not add up, data packets out of sequence or beyond the announced count, without a
  /// session, sessions that timed out or were replaced before they completed.
  std::uint64_t malformed = 0;
  std::string last_malformed;
};

}  // namespace j1939

// ---------------------------------------------------------------------------------------------
// The tracker
// ---------------------------------------------------------------------------------------------

/// Which protocol a bus (or a group of nodes) speaks.
enum class BusProtocol : std::uint8_t {
  /// The node mapping's: CANopen, DroneCAN or J1939 for those node maps; with any other
  /// mapping, the protocol recognised in the bus's traffic (`detect_protocol_evidence`), none
  /// until then.
  Auto,
  None,      ///< no protocol decoding
  CanOpen,   ///< CiA 301: NMT, heartbeat, node guarding, emergency
  DroneCan,  ///< DroneCAN NodeStatus (health, mode, uptime)
  J1939,     ///< SAE J1939: DM1 trouble codes (single and transport protocol), address claims
};
/// "auto", "none", "canopen", "dronecan", "j1939".
[[nodiscard]] std::string_view to_string(BusProtocol p) noexcept;

/// What the tracker is told about one bus.
struct BusSettings {
  std::uint32_t bitrate = 0;       ///< bit/s; 0 unknown (no load percentage)
  std::uint32_t data_bitrate = 0;  ///< CAN FD data phase bit/s; 0: the bitrate
  BusProtocol protocol = BusProtocol::Auto;
};

/// The tracker's configuration (built from a `CanConfig`: `CanConfig::protocol_options()`).
/// `BusProtocol::Auto` follows the node mapping of the sniffer a frame came from.
struct ProtocolOptions {
  BusSettings all_buses{};                                    ///< every bus without its own entry
  std::vector<std::pair<std::uint8_t, BusSettings>> buses{};  ///< per bus index
  /// CANopen node-IDs (bit n = node n) decoded on each bus besides the bus's own protocol
  /// (groups with `protocol: canopen`); index 256 holds the groups without a bus.
  std::vector<std::pair<std::uint16_t, std::array<std::uint64_t, 2>>> canopen_nodes{};
  /// Events kept for readers (oldest dropped and counted beyond it).
  std::size_t max_events = 1024;
  /// CANopen nodes tracked at most (more are counted in `untracked_nodes`); the same bound for
  /// DroneCAN and J1939 nodes.
  std::size_t max_nodes = 4096;
  /// J1939 transport protocol sessions open at once, over every bus (more are refused and
  /// counted as malformed for their source).
  std::size_t max_tp_sessions = 64;
  /// Active DTCs remembered per J1939 node (more are counted in `dtcs_untracked`), and
  /// previously active ones (DM2; more in `previously_active_untracked`).
  std::size_t max_dtcs = 64;

  /// The settings of bus `bus`, `Auto` resolved with node mapping `map` (to `None` when the
  /// mapping names no protocol: the tracker then recognises it from the traffic).
  [[nodiscard]] BusSettings settings(std::uint8_t bus, NodeMapKind map) const noexcept;
  /// Whether bus `bus` is configured `auto` (its own entry, else `all_buses`).
  [[nodiscard]] bool is_auto(std::uint8_t bus) const noexcept;
  /// Whether CANopen frames of node-ID `node` on bus `bus`, from a sniffer with node mapping
  /// `map`, are decoded (`node` 0: the bus's network messages, NMT commands, decoded when any
  /// node of the bus is).
  [[nodiscard]] bool canopen(std::uint8_t bus, std::uint32_t node, NodeMapKind map) const noexcept;
};

/// What a protocol event is about.
enum class ProtocolEventKind : std::uint8_t {
  NmtState,      ///< a CANopen node's NMT state changed (heartbeat)
  NodeReset,     ///< a node restarted: CANopen boot-up while running, DroneCAN uptime back
  Emergency,     ///< a CANopen emergency message
  NmtCommand,    ///< an NMT command seen on the bus
  ErrorWarning,  ///< the controller reached error warning
  ErrorPassive,  ///< the controller went error passive
  BusOff,        ///< the controller went bus off
  ErrorActive,   ///< the controller is error active again (restarted, recovered)
  NodeHealth,    ///< a DroneCAN node's NodeStatus health changed
  DtcActive,     ///< a J1939 DM1 trouble code became active
  DtcCleared,    ///< a J1939 DM1 trouble code is no longer active
  AddressClaim,  ///< a J1939 address claim: first, changed NAME, or cannot claim
};
/// "nmt_state", "node_reset", "emergency", "nmt_command", "error_warning", "error_passive",
/// "bus_off", "error_active", "node_health", "dtc_active", "dtc_cleared", "address_claim".
[[nodiscard]] std::string_view to_string(ProtocolEventKind k) noexcept;

/// One protocol event, on the frames' clock.
struct ProtocolEvent {
  std::uint64_t seq = 0;  ///< 1-based, per tracker
  ProtocolEventKind kind = ProtocolEventKind::NmtState;
  std::uint8_t severity = 0;  ///< 0 info, 1 warn, 2 error
  Nanos time_ns = 0;          ///< the frame's time
  std::uint8_t bus = 0;
  std::uint32_t node = kNoNode;  ///< the CANopen node-ID; `kNoNode` for the bus
  Direction direction = Direction::Rx;
  std::string detail;
};

/// One bus as the tracker sees it.
struct BusProtocolStats {
  std::uint8_t bus = 0;
  BusSettings settings{};  ///< as configured, `protocol` resolved
  /// `settings.protocol` was recognised from the traffic (`auto` with a node mapping that
  /// names no protocol); `detected_from` says by what, `detected_ns` when.
  bool detected = false;
  std::string detected_from;
  Nanos detected_ns = 0;
  /// [stuffing mode][0 rx, 1 tx, 2 both].
  std::array<std::array<BusLoad, 3>, kStuffingModes> load{};
  /// CAN FD frames counted in exact mode with the worst case (canbusload has no exact CAN FD).
  std::uint64_t fd_estimated = 0;
  Nanos first_ns = -1;       ///< first frame
  Nanos window_end_ns = -1;  ///< end of the latest complete second
  ControllerStats controller{};
  std::uint64_t nmt_commands = 0;
  std::uint64_t malformed_nmt = 0;  ///< NMT commands shorter than 2 bytes
};

/// Everything the tracker knows at one moment.
struct ProtocolSnapshot {
  std::vector<BusProtocolStats> buses;        ///< by bus index
  std::vector<canopen::NodeStats> canopen;    ///< by bus, node-ID
  std::vector<dronecan::NodeStats> dronecan;  ///< by bus, node ID
  std::vector<j1939::NodeStats> j1939;        ///< by bus, source address
  std::uint64_t tp_sessions_open = 0;         ///< J1939 transport sessions open now
  std::uint64_t untracked_nodes = 0;          ///< CANopen frames of nodes beyond `max_nodes`
  std::uint64_t events = 0;                   ///< events raised so far (the last seq)
  std::uint64_t events_dropped = 0;           ///< events dropped from the kept window
  std::vector<ProtocolEvent> recent_events;   ///< the kept events, oldest first

  [[nodiscard]] const BusProtocolStats* find_bus(std::uint8_t bus) const noexcept;
  [[nodiscard]] const canopen::NodeStats* find_canopen(std::uint8_t bus,
                                                       std::uint32_t node) const noexcept;
  [[nodiscard]] const dronecan::NodeStats* find_dronecan(std::uint8_t bus,
                                                         std::uint32_t node) const noexcept;
  [[nodiscard]] const j1939::NodeStats* find_j1939(std::uint8_t bus,
                                                   std::uint32_t node) const noexcept;
};

/// What one frame says of the protocol its bus speaks, for `BusProtocol::Auto` on a bus whose
/// node mapping names none: `CanOpen` for a CiA 301 heartbeat or boot-up (11-bit id 0x701 to
/// 0x77F, one data byte holding an NMT state: 0x00, 0x04, 0x05 or 0x7F); `DroneCan` for a
/// single-frame NodeStatus message (29-bit, data type 341, 8 bytes, the tail byte's start and
/// end bits set); `J1939` for a 29-bit frame of a parameter group only J1939 uses (address
/// claimed 0xEE00, request 0xEA00, TP.CM 0xEC00, DM1 0xFECA, DM2 0xFECB, EEC1 0xF004, EEC2
/// 0xF003, EBC1 0xF001, CCVS 0xFEF1, ET1 0xFEEE, EFL/P1 0xFEEF, IC1 0xFEF6, AMB 0xFEF5, LFE
/// 0xFEF2, HOURS 0xFEE5, LFC 0xFEE9, DD 0xFEFC, VD 0xFEE0, ETC2 0xF005); else `None`.
/// The tracker decides for a bus after two frames of the same protocol (for CANopen, two
/// from the same node-ID). Pure, O(1).
[[nodiscard]] BusProtocol detect_protocol_evidence(std::uint32_t id, bool extended, bool rtr,
                                                   std::span<const std::uint8_t> data) noexcept;

/**
 * Applies the decoders to the frames of a stream of `FrameRecord`s: bus load per second and
 * direction, controller state from error frames, CANopen state per node. Fed by the CAN
 * aggregator on the CAN supervisor's thread (and so, identically, by a replay); memory bounded
 * by `max_nodes` CANopen nodes, 256 buses and `max_events` events. Not thread-safe: the
 * aggregator's lock guards it. Not RT-safe.
 */
class ProtocolTracker {
 public:
  explicit ProtocolTracker(ProtocolOptions options = {});

  /// Replaces the configuration (bitrates, protocols); counts are kept.
  void set_options(ProtocolOptions options);
  [[nodiscard]] const ProtocolOptions& options() const noexcept { return options_; }

  /// Applies one record from a sniffer whose node mapping is `map`.
  void on(const FrameRecord& r, NodeMapKind map = NodeMapKind::Identity);
  /// Every record before `t` was applied: closes the seconds that end by then.
  void advance(Nanos t);

  /// A copy of everything, with the percentages of the current bitrates.
  [[nodiscard]] ProtocolSnapshot snapshot() const;
  /// Events with seq > `after`, oldest first (those dropped from the window are missing).
  [[nodiscard]] std::vector<ProtocolEvent> events_after(std::uint64_t after) const;

 private:
  struct Stream {  // one direction (or both), one mode
    std::uint64_t frames = 0, bits = 0;
    std::uint64_t win_nominal = 0, win_data = 0;
    std::uint64_t last_nominal = 0, last_data = 0;
    std::uint64_t closed_nominal = 0, closed_data = 0;  // in the seconds closed
    double ewma_nominal[3] = {0, 0, 0};
    double ewma_data[3] = {0, 0, 0};
    double peak = 0;
    std::uint64_t peak_bits = 0;
  };
  struct Bus {
    BusProtocolStats stats;
    std::array<std::array<Stream, 3>, kStuffingModes> streams{};
    std::int64_t window = 0;  // the second being counted (frame time / 1 s)
    bool started = false;
    std::int64_t seconds_closed = 0;
    NodeMapKind map = NodeMapKind::Identity;  // of the latest record's sniffer
    // `auto` resolved to none: the traffic decides (`detect_protocol_evidence`).
    bool detecting = false;
    BusProtocol detected = BusProtocol::None;
    std::array<std::uint64_t, 2> heartbeat_seen{};  // CANopen node-IDs seen once
    std::uint8_t j1939_evidence = 0;
    std::uint8_t dronecan_evidence = 0;
  };
  struct CoNode {
    canopen::NodeStats stats;
    bool guard_pending = false;
    std::optional<bool> last_toggle;
  };

  Bus& bus(std::uint8_t index, NodeMapKind map);
  void resolve(Bus& b, std::uint8_t index, NodeMapKind map) const;
  void detect(Bus& b, const FrameRecord& r);
  void close_windows(Bus& b, std::int64_t upto);
  void count_load(Bus& b, const FrameRecord& r);
  struct ExactCacheEntry {
    std::uint64_t data = 0;
    std::uint32_t id = 0;
    std::uint32_t bits = 0;
    std::uint16_t shape = 0xFFFF;  // length, extended, rtr, a valid bit; 0xFFFF: empty
  };
  FrameBits exact_bits(const FrameRecord& r, const FrameShape& shape);
  std::array<ExactCacheEntry, 256> exact_cache_{};
  void on_error(Bus& b, const FrameRecord& r);
  void on_canopen(Bus& b, const FrameRecord& r);
  void on_dronecan(const FrameRecord& r);
  // J1939 (see protocol_j1939.cpp).
  struct TpSession {
    bool bam = false;
    bool done = false;  // every packet came; kept until T1 (BAM) or the ack (CM)
    bool keep = false;  // the data is kept (a PGN that is decoded)
    std::uint32_t pgn = 0;
    std::uint16_t size = 0;
    std::uint8_t packets = 0;
    std::uint8_t next = 1;     // the sequence number expected next
    std::uint8_t cts_end = 0;  // CM: the last packet the latest CTS allows (0: none yet)
    Nanos deadline = 0;
    const char* waiting = "";  // what the deadline waits for ("T1: data packet", ...)
    std::vector<std::uint8_t> data;
  };
  using TpKey = std::tuple<std::uint8_t, std::uint8_t, std::uint8_t>;  // bus, source, dest
  void on_j1939(const FrameRecord& r);
  void on_tp_cm(const FrameRecord& r, std::uint8_t sa, std::uint8_t da);
  void on_tp_dt(const FrameRecord& r, std::uint8_t sa, std::uint8_t da);
  void on_dm1(std::uint8_t bus, std::uint8_t sa, Nanos t, Direction d,
              std::span<const std::uint8_t> payload, bool single_frame);
  void on_dm2(std::uint8_t bus, std::uint8_t sa, Nanos t, std::span<const std::uint8_t> payload,
              bool single_frame);
  void on_address_claim(const FrameRecord& r, std::uint8_t sa);
  void expire_sessions(Nanos t);
  void j1939_malformed(std::uint8_t bus, std::uint8_t sa, std::string what);
  j1939::NodeStats* j1939_node(std::uint8_t bus, std::uint8_t sa);
  void emit(ProtocolEventKind kind, std::uint8_t severity, Nanos t, std::uint8_t bus,
            std::uint32_t node, Direction d, std::string detail);
  CoNode* co_node(std::uint8_t bus, std::uint32_t node);

  ProtocolOptions options_;
  std::map<std::uint8_t, Bus> buses_;
  std::map<std::pair<std::uint8_t, std::uint32_t>, CoNode> nodes_;
  std::map<std::pair<std::uint8_t, std::uint32_t>, dronecan::NodeStats> dc_nodes_;
  std::map<std::pair<std::uint8_t, std::uint8_t>, j1939::NodeStats> j1939_nodes_;
  std::map<TpKey, TpSession> tp_;
  Nanos tp_next_deadline_ = std::numeric_limits<Nanos>::max();
  std::uint64_t untracked_nodes_ = 0;
  std::deque<ProtocolEvent> events_;
  std::uint64_t seq_ = 0;
  std::uint64_t events_dropped_ = 0;
};

}  // namespace vigil::can
