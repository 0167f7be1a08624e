#include "vigil/can/protocol.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

namespace vigil::can {

// ---------------------------------------------------------------------------------------------
// Bus load
// ---------------------------------------------------------------------------------------------

std::string_view to_string(Stuffing s) noexcept {
  switch (s) {
    case Stuffing::None:
      return "none";
    case Stuffing::WorstCase:
      return "worst";
    case Stuffing::Exact:
      return "exact";
  }
  return "?";
}

std::string_view to_string(LoadFigure f) noexcept {
  switch (f) {
    case LoadFigure::LastSecond:
      return "last_second";
    case LoadFigure::Avg1m:
      return "1min";
    case LoadFigure::Avg5m:
      return "5min";
    case LoadFigure::Avg15m:
      return "15min";
    case LoadFigure::Peak:
      return "peak";
    case LoadFigure::Mean:
      return "mean";
  }
  return "?";
}

double load_value(const BusLoad& l, LoadFigure f) noexcept {
  switch (f) {
    case LoadFigure::LastSecond:
      return l.last_second;
    case LoadFigure::Avg1m:
      return l.avg_1m;
    case LoadFigure::Avg5m:
      return l.avg_5m;
    case LoadFigure::Avg15m:
      return l.avg_15m;
    case LoadFigure::Peak:
      return l.peak;
    case LoadFigure::Mean:
      return l.mean;
  }
  return l.avg_1m;
}

std::uint16_t can_crc15(std::span<const std::uint8_t> bits) noexcept {
  // ISO 11898-1, clause 10.4.2.6: shift register, CRC_NXT = NXTBIT xor CRC_RG(14).
  std::uint16_t crc = 0;
  for (const std::uint8_t b : bits) {
    const bool next = ((b & 1U) != 0) != ((crc >> 14) & 1U);
    crc = static_cast<std::uint16_t>((crc << 1) & 0x7FFF);
    if (next) crc ^= 0x4599;
  }
  return crc;
}

namespace {

std::size_t data_bytes(const FrameShape& f) noexcept {
  if (f.rtr && !f.fd) return 0;  // a remote frame has no data field
  return f.fd ? std::min<std::size_t>(f.length, kMaxFdDataLength)
              : std::min<std::size_t>(f.length, kMaxClassicDataLength);
}

void put(std::span<std::uint8_t> out, std::size_t& n, std::uint32_t value, unsigned bits) {
  for (unsigned i = bits; i-- > 0;) out[n++] = static_cast<std::uint8_t>((value >> i) & 1U);
}

}  // namespace

std::size_t classic_frame_bits(const FrameShape& f, std::span<std::uint8_t> out) noexcept {
  if (out.size() < 118) return 0;
  std::size_t n = 0;
  out[n++] = 0;  // SOF (dominant)
  const std::uint32_t dlc = std::min<std::uint32_t>(f.length, kMaxDlc);
  if (f.extended) {
    put(out, n, (f.id >> 18) & 0x7FF, 11);  // base identifier
    out[n++] = 1;                           // SRR (recessive)
    out[n++] = 1;                           // IDE (recessive: extended)
    put(out, n, f.id & 0x3FFFF, 18);        // identifier extension
    out[n++] = f.rtr ? 1 : 0;               // RTR
    out[n++] = 0;                           // r1
    out[n++] = 0;                           // r0
  } else {
    put(out, n, f.id & 0x7FF, 11);
    out[n++] = f.rtr ? 1 : 0;  // RTR
    out[n++] = 0;              // IDE (dominant: standard)
    out[n++] = 0;              // r0
  }
  put(out, n, dlc, 4);
  const std::size_t bytes = data_bytes(f);
  for (std::size_t i = 0; i < bytes; ++i) {
    put(out, n, i < f.data.size() ? f.data[i] : 0U, 8);
  }
  const std::uint16_t crc = can_crc15(out.first(n));
  put(out, n, crc, 15);
  return n;
}

std::uint32_t stuff_bits(std::span<const std::uint8_t> bits) noexcept {
  std::uint32_t stuffed = 0;
  unsigned run = 0;
  std::uint8_t last = 2;
  for (const std::uint8_t b : bits) {
    if (b == last) {
      ++run;
    } else {
      last = b;
      run = 1;
    }
    if (run == 5) {
      // A complementary bit follows; it starts the next run.
      ++stuffed;
      last = static_cast<std::uint8_t>(b ^ 1U);
      run = 1;
    }
  }
  return stuffed;
}

namespace {

// CRC-15 one byte at a time (the bitwise register of `can_crc15` run 8 steps per table entry:
// feeding byte b MSB first into register r equals feeding 8 zeros into r ^ (b << 7)).
constexpr std::array<std::uint16_t, 256> make_crc15_table() {
  std::array<std::uint16_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    auto crc = static_cast<std::uint16_t>(i << 7);
    for (int k = 0; k < 8; ++k) {
      const bool top = ((crc >> 14) & 1U) != 0;
      crc = static_cast<std::uint16_t>((crc << 1) & 0x7FFF);
      if (top) crc ^= 0x4599;
    }
    t[i] = crc;
  }
  return t;
}
constexpr std::array<std::uint16_t, 256> kCrc15Table = make_crc15_table();

// Feeds the low `count` bits of `value` (most significant first) into the CRC register.
constexpr std::uint16_t crc15_bits(std::uint16_t crc, std::uint64_t value, unsigned count) {
  unsigned left = count;
  while (left % 8 != 0) {  // the odd bits one by one, the rest a byte at a time
    --left;
    const bool next = (((value >> left) & 1U) != 0) != (((crc >> 14) & 1U) != 0);
    crc = static_cast<std::uint16_t>((crc << 1) & 0x7FFF);
    if (next) crc ^= 0x4599;
  }
  while (left > 0) {
    left -= 8;
    const auto b = static_cast<unsigned>((value >> left) & 0xFFU);
    crc = static_cast<std::uint16_t>(((crc << 8) & 0x7FFF) ^ kCrc15Table[((crc >> 7) ^ b) & 0xFFU]);
  }
  return crc;
}

__extension__ using Bits128 = unsigned __int128;

// The highest set bit of `v`, or -1.
int highest_bit(Bits128 v) {
  const auto hi = static_cast<std::uint64_t>(v >> 64);
  if (hi != 0) return 127 - std::countl_zero(hi);
  const auto lo = static_cast<std::uint64_t>(v);
  return lo != 0 ? 63 - std::countl_zero(lo) : -1;
}

// Stuff bits ISO 11898-1 inserts in the `n` bits of `v` (n <= 128; the first bit is bit n - 1,
// the last bit 0). A run of L equal bits holds (L + carry) / 5 stuff bits, carry being 1 when
// the run just before it ended on a stuff bit (which has this run's value: L + carry of that run
// a multiple of 5). Only runs of 4 bits or more can hold one or pass a carry on, so only those
// are visited, found with masks (a frame has a few at most).
std::uint32_t packed_stuff_bits(Bits128 v, unsigned n) {
  if (n < 5) return 0;
  const Bits128 all = n >= 128 ? ~Bits128{0} : (Bits128{1} << n) - 1;
  // Bit i: stream bits i and i + 1 differ (a run boundary), for i < n - 1.
  const Bits128 bounds = (v ^ (v >> 1)) & (all >> 1);
  const Bits128 equal = ~bounds & (all >> 1);
  // Bit i: bits i to i + 3 are equal (a run of at least 4 covers them).
  Bits128 four = equal & (equal >> 1) & (equal >> 2);
  std::uint32_t stuffed = 0;
  int prev_bottom = -1;  // the previous long run's last bit
  unsigned prev_carry = 0;
  for (;;) {
    const int h = highest_bit(four);
    if (h < 0) break;
    const int top = h + 2 + 1;  // the highest `four` bit starts the run's top 4 bits
    const Bits128 below = h == 0 ? Bits128{0} : bounds & ((Bits128{1} << h) - 1);
    const int bottom = highest_bit(below) + 1;  // 0 when the run goes to the last bit
    const unsigned carry = prev_bottom == top + 1 ? prev_carry : 0;
    const unsigned eff = static_cast<unsigned>(top - bottom + 1) + carry;
    stuffed += eff / 5;
    prev_carry = eff % 5 == 0 ? 1 : 0;
    prev_bottom = bottom;
    four &= bottom == 0 ? Bits128{0} : (Bits128{1} << bottom) - 1;
  }
  return stuffed;
}

}  // namespace

std::uint32_t exact_classic_bits(const FrameShape& f) noexcept {
  // The frame from SOF to the end of the CRC sequence, as `classic_frame_bits` lays it out,
  // packed in one 128-bit value (at most 1 + 38 + 64 + 15 = 118 bits).
  const std::uint32_t dlc = std::min<std::uint32_t>(f.length, kMaxDlc);
  std::uint64_t head = 0;
  unsigned head_bits = 0;
  if (f.extended) {  // SOF, base id, SRR 1, IDE 1, extension, RTR, r1, r0, DLC
    head = (std::uint64_t{(f.id >> 18) & 0x7FFU} << 27) | (std::uint64_t{3} << 25) |
           (std::uint64_t{f.id & 0x3FFFFU} << 7) | (std::uint64_t{f.rtr ? 1U : 0U} << 6) | dlc;
    head_bits = 39;
  } else {  // SOF, id, RTR, IDE 0, r0, DLC
    head = (std::uint64_t{f.id & 0x7FFU} << 7) | (std::uint64_t{f.rtr ? 1U : 0U} << 6) | dlc;
    head_bits = 19;
  }
  // Leading zeros leave a zero register zero: the header fed as whole bytes (24 or 40 bits).
  std::uint16_t crc = crc15_bits(0, head, (head_bits + 7) & ~7U);
  const std::size_t bytes = data_bytes(f);
  std::uint64_t data = 0;
  for (std::size_t i = 0; i < bytes; ++i) {
    data = (data << 8) | (i < f.data.size() ? f.data[i] : 0U);
  }
  const auto data_bits = static_cast<unsigned>(bytes * 8);
  if (bytes > 0) crc = crc15_bits(crc, data, data_bits);
  Bits128 v = head;
  if (data_bits > 0) v = (v << data_bits) | data;
  v = (v << 15) | crc;
  const unsigned n = head_bits + data_bits + 15;
  return n + packed_stuff_bits(v, n);
}

FrameBits frame_bits(const FrameShape& f, Stuffing s) noexcept {
  const auto n = static_cast<std::uint32_t>(data_bytes(f));
  if (f.fd) {
    // canbusload's CAN FD approximation (can-utils canframelen.c, can_frame_length and
    // can_frame_dbitrate_length).
    const std::uint32_t crc = n >= 16 ? 21 : 17;
    const std::uint32_t total = 1 + (f.extended ? 29U : 11U) + crc + 5 + 12 + n * 8;
    const std::uint32_t data = f.brs ? 1 + 1 + 4 + crc + n * 8 : 0;
    if (s == Stuffing::None) return {total - data, data};
    const std::uint32_t wc_total = total * 5 / 4;
    const std::uint32_t wc_data = data * 5 / 4;
    return {wc_total - wc_data, wc_data};
  }
  switch (s) {
    case Stuffing::None:
      return {(f.extended ? 67U : 47U) + n * 8, 0};
    case Stuffing::WorstCase:
      return {(f.extended ? 80U : 55U) + n * 10, 0};
    case Stuffing::Exact:
      // + CRC delimiter, ACK slot, ACK delimiter (3), EOF (7), intermission (3).
      return {exact_classic_bits(f) + 13, 0};
  }
  return {};
}

FrameBits frame_bits(const Frame& f, Stuffing s) noexcept {
  if (f.error) return {};
  return frame_bits(FrameShape{.id = f.id,
                               .extended = f.extended,
                               .rtr = f.rtr,
                               .fd = f.fd,
                               .brs = f.brs,
                               .length = f.length,
                               .data = f.payload()},
                    s);
}

// ---------------------------------------------------------------------------------------------
// Error frames
// ---------------------------------------------------------------------------------------------

std::string_view error_class_name(std::size_t index) noexcept {
  constexpr std::array<std::string_view, error_class::kCount> kNames{
      "tx timeout", "lost arbitration", "controller", "protocol",  "transceiver",
      "no ack",     "bus off",          "bus error",  "restarted", "error counters"};
  return index < kNames.size() ? kNames[index] : "?";
}

namespace {

std::string bit_names(std::uint8_t v, const std::array<std::string_view, 8>& names) {
  if (v == 0) return "unspecified";
  std::string s;
  for (std::size_t i = 0; i < 8; ++i) {
    if ((v & (1U << i)) == 0) continue;
    if (!s.empty()) s += ", ";
    s += names[i];
  }
  return s;
}

}  // namespace

std::string controller_status_names(std::uint8_t data1) {
  return bit_names(data1, {"rx overflow", "tx overflow", "rx warning", "tx warning", "rx passive",
                           "tx passive", "active", "bit 7"});
}

std::string protocol_type_names(std::uint8_t data2) {
  return bit_names(
      data2, {"bit", "form", "stuff", "unable to send dominant bit", "unable to send recessive bit",
              "overload", "active error announcement", "on transmission"});
}

std::string protocol_location_name(std::uint8_t data3) {
  switch (data3) {
    case 0x00:
      return "unspecified";
    case 0x03:
      return "start of frame";
    case 0x02:
      return "ID bits 28-21 (SFF: 10-3)";
    case 0x06:
      return "ID bits 20-18 (SFF: 2-0)";
    case 0x04:
      return "substitute RTR (SFF: RTR)";
    case 0x05:
      return "identifier extension";
    case 0x07:
      return "ID bits 17-13";
    case 0x0F:
      return "ID bits 12-5";
    case 0x0E:
      return "ID bits 4-0";
    case 0x0C:
      return "RTR";
    case 0x0D:
      return "reserved bit 1";
    case 0x09:
      return "reserved bit 0";
    case 0x0B:
      return "data length code";
    case 0x0A:
      return "data section";
    case 0x08:
      return "CRC sequence";
    case 0x18:
      return "CRC delimiter";
    case 0x19:
      return "ACK slot";
    case 0x1B:
      return "ACK delimiter";
    case 0x1A:
      return "end of frame";
    case 0x12:
      return "intermission";
    default:
      return fmt::format("location 0x{:02X}", data3);
  }
}

std::string transceiver_name(std::uint8_t data4) {
  switch (data4) {
    case 0x00:
      return "unspecified";
    case 0x04:
      return "CANH no wire";
    case 0x05:
      return "CANH short to BAT";
    case 0x06:
      return "CANH short to VCC";
    case 0x07:
      return "CANH short to GND";
    case 0x40:
      return "CANL no wire";
    case 0x50:
      return "CANL short to BAT";
    case 0x60:
      return "CANL short to VCC";
    case 0x70:
      return "CANL short to GND";
    case 0x80:
      return "CANL short to CANH";
    default:
      return fmt::format("status 0x{:02X}", data4);
  }
}

std::string_view to_string(ControllerState s) noexcept {
  switch (s) {
    case ControllerState::Unknown:
      return "unknown";
    case ControllerState::ErrorActive:
      return "error active";
    case ControllerState::ErrorWarning:
      return "error warning";
    case ControllerState::ErrorPassive:
      return "error passive";
    case ControllerState::BusOff:
      return "bus off";
  }
  return "?";
}

std::string describe_error_frame(std::uint32_t cls, std::span<const std::uint8_t> data) {
  const auto byte = [&](std::size_t i) -> std::optional<std::uint8_t> {
    if (i < data.size()) return data[i];
    return std::nullopt;
  };
  std::string s;
  const auto add = [&](const std::string& part) {
    if (!s.empty()) s += "; ";
    s += part;
  };
  for (std::size_t i = 0; i < error_class::kCount; ++i) {
    const std::uint32_t bit = 1U << i;
    if ((cls & bit) == 0) continue;
    std::string part(error_class_name(i));
    if (bit == error_class::kLostArb && byte(0) && *byte(0) != 0) {
      part += fmt::format(" at bit {}", *byte(0));
    } else if (bit == error_class::kCrtl && byte(1)) {
      part += ": " + controller_status_names(*byte(1));
    } else if (bit == error_class::kProt) {
      if (byte(2)) part += ": " + protocol_type_names(*byte(2));
      if (byte(3)) part += " at " + protocol_location_name(*byte(3));
    } else if (bit == error_class::kTrx && byte(4)) {
      part += ": " + transceiver_name(*byte(4));
    } else if (bit == error_class::kCnt && byte(6) && byte(7)) {
      part += fmt::format(" tx {} rx {}", *byte(6), *byte(7));
    }
    add(part);
  }
  if ((cls & ~0x3FFU) != 0) add(fmt::format("unknown class bits 0x{:X}", cls & ~0x3FFU));
  if (s.empty()) s = "no class bit";
  return s;
}

// ---------------------------------------------------------------------------------------------
// CANopen
// ---------------------------------------------------------------------------------------------

namespace canopen {

std::string_view to_string(NmtState s) noexcept {
  switch (s) {
    case NmtState::Unknown:
      return "unknown";
    case NmtState::BootUp:
      return "boot-up";
    case NmtState::Stopped:
      return "stopped";
    case NmtState::Operational:
      return "operational";
    case NmtState::PreOperational:
      return "pre-operational";
  }
  return "?";
}

std::optional<NmtState> nmt_state_of(std::uint8_t b) noexcept {
  switch (b & 0x7FU) {
    case 0x00:
      return NmtState::BootUp;
    case 0x04:
      return NmtState::Stopped;
    case 0x05:
      return NmtState::Operational;
    case 0x7F:
      return NmtState::PreOperational;
    default:
      return std::nullopt;
  }
}

std::string_view nmt_command_name(std::uint8_t cs) noexcept {
  switch (cs) {
    case 0x01:
      return "start remote node";
    case 0x02:
      return "stop remote node";
    case 0x80:
      return "enter pre-operational";
    case 0x81:
      return "reset node";
    case 0x82:
      return "reset communication";
    default:
      return "unknown command";
  }
}

std::string emergency_class(std::uint16_t code) {
  switch (code) {  // the codes CiA 301 names one by one (table 21)
    case 0x8110:
      return "communication: CAN overrun (objects lost)";
    case 0x8120:
      return "communication: CAN in error passive mode";
    case 0x8130:
      return "communication: life guard error or heartbeat error";
    case 0x8140:
      return "communication: recovered from bus off";
    case 0x8150:
      return "communication: CAN-ID collision";
    case 0x8210:
      return "protocol error: PDO not processed due to length error";
    case 0x8220:
      return "protocol error: PDO length exceeded";
    case 0x8230:
      return "protocol error: DAM MPDO not processed, destination object not available";
    case 0x8240:
      return "protocol error: unexpected SYNC data length";
    case 0x8250:
      return "protocol error: RPDO timeout";
    default:
      break;
  }
  const unsigned hi = code >> 8;
  switch (hi) {
    case 0x21:
      return "current, device input side";
    case 0x22:
      return "current inside the device";
    case 0x23:
      return "current, device output side";
    case 0x31:
      return "voltage: mains";
    case 0x32:
      return "voltage inside the device";
    case 0x33:
      return "voltage: output";
    case 0x41:
      return "temperature: ambient";
    case 0x42:
      return "temperature: device";
    case 0x61:
      return "device software: internal";
    case 0x62:
      return "device software: user";
    case 0x63:
      return "device software: data set";
    case 0x81:
      return "monitoring: communication";
    case 0x82:
      return "monitoring: protocol error";
    case 0xF0:
      return "additional functions";
    case 0xFF:
      return "device specific";
    case 0x00:
      return "error reset or no error";
    case 0x10:
      return "generic error";
    default:
      break;
  }
  switch (code >> 12) {
    case 0x2:
      return "current";
    case 0x3:
      return "voltage";
    case 0x4:
      return "temperature";
    case 0x5:
      return "device hardware";
    case 0x6:
      return "device software";
    case 0x7:
      return "additional modules";
    case 0x8:
      return "monitoring";
    case 0x9:
      return "external error";
    default:
      return "not defined by CiA 301";
  }
}

std::string error_register_names(std::uint8_t reg) {
  if (reg == 0) return "none";
  constexpr std::array<std::string_view, 8> kNames{"generic",     "current",       "voltage",
                                                   "temperature", "communication", "device profile",
                                                   "bit 6",       "manufacturer"};
  std::string s;
  for (std::size_t i = 0; i < 8; ++i) {
    if ((reg & (1U << i)) == 0) continue;
    if (!s.empty()) s += ", ";
    s += kNames[i];
  }
  return s;
}

std::string Emergency::describe() const {
  std::string s = fmt::format("0x{:04X} {}, register 0x{:02X} ({})", code, emergency_class(code),
                              error_register, error_register_names(error_register));
  if (length >= 8) {
    s += fmt::format(", manufacturer {:02X} {:02X} {:02X} {:02X} {:02X}", manufacturer[0],
                     manufacturer[1], manufacturer[2], manufacturer[3], manufacturer[4]);
  } else {
    s += fmt::format(" (short: {} bytes of 8)", length);
  }
  return s;
}

}  // namespace canopen

namespace dronecan {

std::string_view to_string(Health h) noexcept {
  switch (h) {
    case Health::Ok:
      return "OK";
    case Health::Warning:
      return "WARNING";
    case Health::Error:
      return "ERROR";
    case Health::Critical:
      return "CRITICAL";
    case Health::Unknown:
      return "unknown";
  }
  return "?";
}

std::string mode_name(std::uint8_t mode) {
  switch (mode) {
    case 0:
      return "operational";
    case 1:
      return "initialization";
    case 2:
      return "maintenance";
    case 3:
      return "software update";
    case 7:
      return "offline";
    default:
      return fmt::format("mode {}", mode);
  }
}

std::optional<NodeStatus> decode_node_status(std::span<const std::uint8_t> p) noexcept {
  if (p.size() < 7) return std::nullopt;
  NodeStatus s;
  s.uptime_s = static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
               static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
  s.health = static_cast<Health>((p[4] >> 6) & 0x3U);
  s.mode = static_cast<std::uint8_t>((p[4] >> 3) & 0x7U);
  s.sub_mode = static_cast<std::uint8_t>(p[4] & 0x7U);
  s.vendor_status = static_cast<std::uint16_t>(p[5] | (p[6] << 8));
  return s;
}

}  // namespace dronecan

// ---------------------------------------------------------------------------------------------
// The tracker
// ---------------------------------------------------------------------------------------------

std::string_view to_string(BusProtocol p) noexcept {
  switch (p) {
    case BusProtocol::Auto:
      return "auto";
    case BusProtocol::None:
      return "none";
    case BusProtocol::CanOpen:
      return "canopen";
    case BusProtocol::DroneCan:
      return "dronecan";
    case BusProtocol::J1939:
      return "j1939";
  }
  return "?";
}

std::string_view to_string(ProtocolEventKind k) noexcept {
  switch (k) {
    case ProtocolEventKind::NmtState:
      return "nmt_state";
    case ProtocolEventKind::NodeReset:
      return "node_reset";
    case ProtocolEventKind::Emergency:
      return "emergency";
    case ProtocolEventKind::NmtCommand:
      return "nmt_command";
    case ProtocolEventKind::ErrorWarning:
      return "error_warning";
    case ProtocolEventKind::ErrorPassive:
      return "error_passive";
    case ProtocolEventKind::BusOff:
      return "bus_off";
    case ProtocolEventKind::ErrorActive:
      return "error_active";
    case ProtocolEventKind::NodeHealth:
      return "node_health";
    case ProtocolEventKind::DtcActive:
      return "dtc_active";
    case ProtocolEventKind::DtcCleared:
      return "dtc_cleared";
    case ProtocolEventKind::AddressClaim:
      return "address_claim";
  }
  return "?";
}

BusSettings ProtocolOptions::settings(std::uint8_t bus, NodeMapKind map) const noexcept {
  BusSettings s = all_buses;
  for (const auto& [index, b] : buses) {
    if (index == bus) s = b;
  }
  if (s.protocol == BusProtocol::Auto) {
    s.protocol = map == NodeMapKind::CanOpen    ? BusProtocol::CanOpen
                 : map == NodeMapKind::DroneCan ? BusProtocol::DroneCan
                 : map == NodeMapKind::J1939    ? BusProtocol::J1939
                                                : BusProtocol::None;
  }
  return s;
}

bool ProtocolOptions::is_auto(std::uint8_t bus) const noexcept {
  BusProtocol p = all_buses.protocol;
  for (const auto& [index, b] : buses) {
    if (index == bus) p = b.protocol;
  }
  return p == BusProtocol::Auto;
}

BusProtocol detect_protocol_evidence(std::uint32_t id, bool extended, bool rtr,
                                     std::span<const std::uint8_t> data) noexcept {
  if (rtr) return BusProtocol::None;
  if (!extended) {
    // CiA 301 clause 7.2.8.3.2: heartbeat and boot-up on 0x700 + node-ID, one byte.
    if (id < 0x701 || id > 0x77F || data.size() != 1) return BusProtocol::None;
    const std::uint8_t state = data[0];
    const bool nmt_state = state == 0x00 || state == 0x04 || state == 0x05 || state == 0x7F;
    return nmt_state ? BusProtocol::CanOpen : BusProtocol::None;
  }
  // DroneCAN: a message frame (bit 7 clear) of NodeStatus from a node (not 0), single-frame.
  if ((id & 0x80U) == 0 && (id & 0x7FU) != 0 && ((id >> 8) & 0xFFFFU) == dronecan::kNodeStatus &&
      data.size() == 8 && (data[7] & 0xC0U) == 0xC0U) {
    return BusProtocol::DroneCan;
  }
  switch (decode_j1939(id).pgn) {
    case j1939::kPgnAddressClaimed:
    case 0xEA00:  // request
    case j1939::kPgnTpCm:
    case j1939::kPgnDm1:
    case 0xFECB:  // DM2
    case 0xF001:  // EBC1
    case 0xF003:  // EEC2
    case 0xF004:  // EEC1
    case 0xF005:  // ETC2
    case 0xFEE0:  // VD
    case 0xFEE5:  // HOURS
    case 0xFEE9:  // LFC
    case 0xFEEE:  // ET1
    case 0xFEEF:  // EFL/P1
    case 0xFEF1:  // CCVS
    case 0xFEF2:  // LFE
    case 0xFEF5:  // AMB
    case 0xFEF6:  // IC1
    case 0xFEFC:  // DD
      return BusProtocol::J1939;
    default:
      return BusProtocol::None;
  }
}

bool ProtocolOptions::canopen(std::uint8_t bus, std::uint32_t node,
                              NodeMapKind map) const noexcept {
  if (settings(bus, map).protocol == BusProtocol::CanOpen) return true;
  for (const auto& [index, bits] : canopen_nodes) {
    if (index != bus && index != 256) continue;
    if (node == 0) {
      if (bits[0] != 0 || bits[1] != 0) return true;
    } else if (node < 128 && (bits[node / 64] & (std::uint64_t{1} << (node % 64))) != 0) {
      return true;
    }
  }
  return false;
}

const BusProtocolStats* ProtocolSnapshot::find_bus(std::uint8_t bus) const noexcept {
  for (const auto& b : buses) {
    if (b.bus == bus) return &b;
  }
  return nullptr;
}

const dronecan::NodeStats* ProtocolSnapshot::find_dronecan(std::uint8_t bus,
                                                           std::uint32_t node) const noexcept {
  for (const auto& n : dronecan) {
    if (n.bus == bus && n.node == node) return &n;
  }
  return nullptr;
}

const j1939::NodeStats* ProtocolSnapshot::find_j1939(std::uint8_t bus,
                                                     std::uint32_t node) const noexcept {
  for (const auto& n : j1939) {
    if (n.bus == bus && n.address == node) return &n;
  }
  return nullptr;
}

const canopen::NodeStats* ProtocolSnapshot::find_canopen(std::uint8_t bus,
                                                         std::uint32_t node) const noexcept {
  for (const auto& n : canopen) {
    if (n.bus == bus && n.node == node) return &n;
  }
  return nullptr;
}

namespace {

// canbusload's damping per one-second sample: e^(-1/60), e^(-1/300), e^(-1/900) (it uses the
// 12-bit fixed-point values of the kernel's load average; these are exact).
const std::array<double, 3> kDamping{std::exp(-1.0 / 60), std::exp(-1.0 / 300),
                                     std::exp(-1.0 / 900)};

std::int64_t second_of(Nanos t) {
  const std::int64_t q = t / kNanosPerSecond;
  return (t % kNanosPerSecond < 0) ? q - 1 : q;
}

double percent(double nominal, double data, const BusSettings& s) {
  if (s.bitrate == 0) return 0;
  const double dbr = s.data_bitrate != 0 ? s.data_bitrate : s.bitrate;
  return 100.0 * (nominal / s.bitrate + data / dbr);
}

}  // namespace

ProtocolTracker::ProtocolTracker(ProtocolOptions options) : options_(std::move(options)) {}

void ProtocolTracker::set_options(ProtocolOptions options) {
  options_ = std::move(options);
  for (auto& [index, b] : buses_) resolve(b, index, b.map);
}

void ProtocolTracker::resolve(Bus& b, std::uint8_t index, NodeMapKind map) const {
  b.stats.settings = options_.settings(index, map);
  b.detecting = b.stats.settings.protocol == BusProtocol::None && options_.is_auto(index);
  // What the traffic said stays said while the bus is `auto` with no protocol of its own.
  if (b.detecting && b.detected != BusProtocol::None) b.stats.settings.protocol = b.detected;
  b.stats.detected = b.detecting && b.detected != BusProtocol::None;
}

ProtocolTracker::Bus& ProtocolTracker::bus(std::uint8_t index, NodeMapKind map) {
  auto [it, inserted] = buses_.try_emplace(index);
  Bus& b = it->second;
  if (inserted || b.map != map) {
    b.stats.bus = index;
    b.map = map;
    resolve(b, index, map);
  }
  return b;
}

void ProtocolTracker::detect(Bus& b, const FrameRecord& r) {
  const std::size_t len = r.rtr ? 0 : std::min<std::size_t>(r.length, r.data.size());
  const BusProtocol p = detect_protocol_evidence(r.id, r.extended, r.rtr,
                                                 std::span<const std::uint8_t>(r.data.data(), len));
  std::string from;
  switch (p) {
    case BusProtocol::CanOpen: {
      const std::uint32_t node = r.id & 0x7FU;
      std::uint64_t& word = b.heartbeat_seen[node / 64];
      const std::uint64_t bit = std::uint64_t{1} << (node % 64);
      if ((word & bit) == 0) {
        word |= bit;
        return;
      }
      from = fmt::format("CANopen heartbeats of node {} (0x{:03X})", node, r.id);
      break;
    }
    case BusProtocol::DroneCan:
      if (++b.dronecan_evidence < 2) return;
      from = "DroneCAN NodeStatus messages";
      break;
    case BusProtocol::J1939:
      if (++b.j1939_evidence < 2) return;
      from = fmt::format("J1939 parameter groups (PGN 0x{:04X})", decode_j1939(r.id).pgn);
      break;
    default:
      return;
  }
  b.detected = p;
  b.stats.settings.protocol = p;
  b.stats.detected = true;
  b.stats.detected_from = std::move(from);
  b.stats.detected_ns = r.time_ns;
}

void ProtocolTracker::close_windows(Bus& b, std::int64_t upto) {
  if (!b.started || upto <= b.window) return;
  const BusSettings& s = b.stats.settings;
  const std::int64_t empty = upto - b.window - 1;  // whole seconds without a frame after it
  for (auto& mode : b.streams) {
    for (Stream& st : mode) {
      // The second that ends: one sample.
      for (std::size_t i = 0; i < 3; ++i) {
        st.ewma_nominal[i] = st.ewma_nominal[i] * kDamping[i] +
                             static_cast<double>(st.win_nominal) * (1 - kDamping[i]);
        st.ewma_data[i] =
            st.ewma_data[i] * kDamping[i] + static_cast<double>(st.win_data) * (1 - kDamping[i]);
      }
      st.peak = std::max(st.peak, percent(static_cast<double>(st.win_nominal),
                                          static_cast<double>(st.win_data), s));
      st.peak_bits = std::max(st.peak_bits, st.win_nominal + st.win_data);
      st.last_nominal = st.win_nominal;
      st.last_data = st.win_data;
      st.closed_nominal += st.win_nominal;
      st.closed_data += st.win_data;
      st.win_nominal = 0;
      st.win_data = 0;
      if (empty > 0) {
        // Seconds without a frame are samples of 0: the damping applied `empty` times.
        for (std::size_t i = 0; i < 3; ++i) {
          const double f = std::pow(kDamping[i], static_cast<double>(empty));
          st.ewma_nominal[i] *= f;
          st.ewma_data[i] *= f;
        }
        st.last_nominal = 0;
        st.last_data = 0;
      }
    }
  }
  b.seconds_closed += upto - b.window;
  b.window = upto;
  b.stats.window_end_ns = upto * kNanosPerSecond;
}

FrameBits ProtocolTracker::exact_bits(const FrameRecord& r, const FrameShape& shape) {
  // Periodic frames repeat their payloads: the exact count of the last frame of each (id,
  // format, length, data) that hashed to a slot is reused (the CRC and stuffing of a frame
  // cost about 60 ns; a hit, a few).
  std::uint64_t data = 0;
  std::memcpy(&data, r.data.data(), sizeof data);
  const auto shape_key = static_cast<std::uint16_t>(
      0x80U | (r.length & 0x1FU) | (r.extended ? 0x20U : 0U) | (r.rtr ? 0x40U : 0U));
  const std::uint64_t h = (data ^ (std::uint64_t{r.id} << 32 | shape_key)) * 0x9E3779B97F4A7C15ULL;
  ExactCacheEntry& e = exact_cache_[h >> (64 - 8)];
  if (e.shape != shape_key || e.id != r.id || e.data != data) {
    e.shape = shape_key;
    e.id = r.id;
    e.data = data;
    e.bits = frame_bits(shape, Stuffing::Exact).nominal;
  }
  return {e.bits, 0};
}

void ProtocolTracker::count_load(Bus& b, const FrameRecord& r) {
  const FrameShape shape{.id = r.id,
                         .extended = r.extended,
                         .rtr = r.rtr,
                         .fd = r.fd,
                         .brs = r.brs,
                         .length = r.length,
                         .data = std::span<const std::uint8_t>(r.data.data(), r.data.size())};
  const std::size_t dir = r.direction == Direction::Tx ? 1 : 0;
  for (std::size_t m = 0; m < kStuffingModes; ++m) {
    const auto mode = static_cast<Stuffing>(m);
    const FrameBits bits =
        mode == Stuffing::Exact && !r.fd ? exact_bits(r, shape) : frame_bits(shape, mode);
    for (const std::size_t k : {dir, std::size_t{2}}) {
      Stream& st = b.streams[m][k];
      ++st.frames;
      st.bits += bits.total();
      st.win_nominal += bits.nominal;
      st.win_data += bits.data;
    }
  }
  if (r.fd) ++b.stats.fd_estimated;
}

void ProtocolTracker::on(const FrameRecord& r, NodeMapKind map) {
  Bus& b = bus(r.bus, map);
  const std::int64_t w = second_of(r.time_ns);
  if (!b.started) {
    b.started = true;
    b.window = w;
    b.stats.first_ns = r.time_ns;
  } else if (w > b.window) {
    close_windows(b, w);
  }
  if (r.error) {
    on_error(b, r);
    return;
  }
  count_load(b, r);
  if (b.detecting && b.detected == BusProtocol::None) detect(b, r);
  if (!r.extended && (b.stats.settings.protocol == BusProtocol::CanOpen ||
                      options_.canopen(r.bus, r.id == 0 ? 0 : (r.id & 0x7FU), map))) {
    on_canopen(b, r);
  } else if (r.extended && b.stats.settings.protocol == BusProtocol::DroneCan) {
    on_dronecan(r);
  } else if (r.extended && b.stats.settings.protocol == BusProtocol::J1939) {
    on_j1939(r);
  }
}

void ProtocolTracker::advance(Nanos t) {
  const std::int64_t upto = second_of(t);
  for (auto& [index, b] : buses_) close_windows(b, upto);
  expire_sessions(t);
}

void ProtocolTracker::emit(ProtocolEventKind kind, std::uint8_t severity, Nanos t, std::uint8_t bus,
                           std::uint32_t node, Direction d, std::string detail) {
  ProtocolEvent e;
  e.seq = ++seq_;
  e.kind = kind;
  e.severity = severity;
  e.time_ns = t;
  e.bus = bus;
  e.node = node;
  e.direction = d;
  e.detail = std::move(detail);
  events_.push_back(std::move(e));
  while (events_.size() > std::max<std::size_t>(options_.max_events, 1)) {
    events_.pop_front();
    ++events_dropped_;
  }
}

void ProtocolTracker::on_error(Bus& b, const FrameRecord& r) {
  ControllerStats& c = b.stats.controller;
  const std::uint32_t cls = r.id;
  const std::span<const std::uint8_t> data(r.data.data(),
                                           std::min<std::size_t>(r.length, r.data.size()));
  ++c.error_frames;
  for (std::size_t i = 0; i < error_class::kCount; ++i) {
    if ((cls & (1U << i)) != 0) ++c.by_class[i];
  }
  c.last = describe_error_frame(cls, data);
  c.last_ns = r.time_ns;
  std::optional<ControllerState> next;
  if ((cls & error_class::kCrtl) != 0 && data.size() > 1) {
    const std::uint8_t d1 = data[1];
    if ((d1 & 0x01U) != 0) ++c.rx_overflows;
    if ((d1 & 0x02U) != 0) ++c.tx_overflows;
    if ((d1 & 0x30U) != 0) {
      next = ControllerState::ErrorPassive;
    } else if ((d1 & 0x0CU) != 0) {
      next = ControllerState::ErrorWarning;
    } else if ((d1 & 0x40U) != 0) {
      next = ControllerState::ErrorActive;
    }
  }
  if ((cls & error_class::kProt) != 0) {
    if (data.size() > 2) {
      for (std::size_t i = 0; i < 8; ++i) {
        if ((data[2] & (1U << i)) != 0) ++c.protocol_types[i];
      }
    }
    if (data.size() > 3) {
      auto it = std::find_if(c.protocol_locations.begin(), c.protocol_locations.end(),
                             [&](const auto& p) { return p.first == data[3]; });
      if (it != c.protocol_locations.end()) {
        ++it->second;
      } else if (c.protocol_locations.size() < 32) {
        c.protocol_locations.emplace_back(data[3], 1);
      } else {
        ++c.other_locations;
      }
    }
  }
  if ((cls & error_class::kTrx) != 0 && data.size() > 4) c.transceiver = data[4];
  if ((cls & error_class::kCnt) != 0 && data.size() > 7) {
    c.tx_errors = data[6];
    c.rx_errors = data[7];
  }
  if ((cls & error_class::kRestarted) != 0) {
    ++c.restarts;
    next = ControllerState::ErrorActive;
  }
  if ((cls & error_class::kBusOff) != 0) next = ControllerState::BusOff;
  if (!next || *next == c.state) return;
  const ControllerState was = c.state;
  c.state = *next;
  c.state_since_ns = r.time_ns;
  const std::string detail = fmt::format("{} -> {}: {}", to_string(was), to_string(*next), c.last);
  switch (*next) {
    case ControllerState::BusOff:
      ++c.bus_offs;
      emit(ProtocolEventKind::BusOff, 2, r.time_ns, r.bus, kNoNode, r.direction, detail);
      break;
    case ControllerState::ErrorPassive:
      ++c.passives;
      emit(ProtocolEventKind::ErrorPassive, 1, r.time_ns, r.bus, kNoNode, r.direction, detail);
      break;
    case ControllerState::ErrorWarning:
      ++c.warnings;
      emit(ProtocolEventKind::ErrorWarning, 0, r.time_ns, r.bus, kNoNode, r.direction, detail);
      break;
    case ControllerState::ErrorActive:
      if (was != ControllerState::Unknown) {
        emit(ProtocolEventKind::ErrorActive, 0, r.time_ns, r.bus, kNoNode, r.direction, detail);
      }
      break;
    case ControllerState::Unknown:
      break;
  }
}

ProtocolTracker::CoNode* ProtocolTracker::co_node(std::uint8_t bus, std::uint32_t node) {
  const auto key = std::pair{bus, node};
  auto it = nodes_.find(key);
  if (it != nodes_.end()) return &it->second;
  if (nodes_.size() >= options_.max_nodes) {
    ++untracked_nodes_;
    return nullptr;
  }
  CoNode& n = nodes_[key];
  n.stats.bus = bus;
  n.stats.node = static_cast<std::uint8_t>(node);
  return &n;
}

void ProtocolTracker::on_canopen(Bus& b, const FrameRecord& r) {
  const std::uint32_t id = r.id;
  const std::size_t len = r.rtr ? 0 : std::min<std::size_t>(r.length, 8);
  const Nanos t = r.time_ns;
  if (id == 0x000) {  // NMT command (CiA 301 clause 7.2.8.3.1): [command specifier, node-ID]
    if (r.rtr) return;
    if (len < 2) {
      ++b.stats.malformed_nmt;
      return;
    }
    ++b.stats.nmt_commands;
    const std::uint8_t cs = r.data[0];
    const std::uint8_t target = r.data[1];
    emit(ProtocolEventKind::NmtCommand, cs == 0x81 || cs == 0x82 ? 1 : 0, t, r.bus,
         target == 0 ? kNoNode : target, r.direction,
         fmt::format("{} (0x{:02X}) to {}", canopen::nmt_command_name(cs), cs,
                     target == 0 ? std::string("all nodes") : fmt::format("node {}", target)));
    return;
  }
  const std::uint32_t node = id & 0x7FU;
  if (node == 0) return;
  if (id >= 0x081 && id <= 0x0FF) {  // EMCY (clause 7.2.7)
    if (r.rtr) return;
    CoNode* n = co_node(r.bus, node);
    if (n == nullptr) return;
    canopen::NodeStats& s = n->stats;
    if (len < 8) {
      ++s.malformed_emergencies;
      s.last_malformed =
          fmt::format("emergency of {} byte{} (8 expected)", len, len == 1 ? "" : "s");
      if (len < 2) return;  // not even an error code
    }
    canopen::Emergency e;
    e.code = static_cast<std::uint16_t>(r.data[0] | (r.data[1] << 8));
    e.error_register = len > 2 ? r.data[2] : 0;
    for (std::size_t i = 0; i < 5; ++i) e.manufacturer[i] = 3 + i < len ? r.data[3 + i] : 0;
    e.length = static_cast<std::uint8_t>(len);
    e.time_ns = t;
    ++s.emergencies;
    s.last_emergency = e;
    emit(ProtocolEventKind::Emergency, e.code == 0 ? 0 : 1, t, r.bus, node, r.direction,
         e.describe());
    return;
  }
  if (id < 0x701 || id > 0x77F) return;
  // NMT error control (clause 7.2.8.3.2): heartbeat, boot-up, node guarding.
  CoNode* n = co_node(r.bus, node);
  if (n == nullptr) return;
  canopen::NodeStats& s = n->stats;
  if (r.rtr) {
    ++s.guard_requests;
    n->guard_pending = true;
    return;
  }
  if (len == 0) {
    ++s.malformed_heartbeats;
    s.last_malformed = "heartbeat without a state byte";
    return;
  }
  const std::uint8_t byte = r.data[0];
  const auto state = canopen::nmt_state_of(byte);
  if (len != 1) {
    ++s.malformed_heartbeats;
    s.last_malformed = fmt::format("heartbeat of {} bytes (1 expected)", len);
  }
  if (!state) {
    ++s.malformed_heartbeats;
    s.last_malformed =
        fmt::format("heartbeat state byte 0x{:02X} (CiA 301 defines 0x00, 0x04, 0x05, 0x7F)", byte);
    return;
  }
  if (n->guard_pending) {
    // A node-guarding response: bit 7 toggles from one response to the next.
    n->guard_pending = false;
    ++s.guard_responses;
    const bool toggle = (byte & 0x80U) != 0;
    if (n->last_toggle && *n->last_toggle == toggle) ++s.toggle_errors;
    n->last_toggle = toggle;
  }
  ++s.heartbeats;
  s.last_heartbeat_ns = t;
  const canopen::NmtState was = s.state;
  if (*state == canopen::NmtState::BootUp) {
    ++s.boot_ups;
    n->last_toggle.reset();  // guarding starts over after a reset
    if (s.ever_running) {
      ++s.resets;
      s.last_reset_ns = t;
      s.state = *state;
      s.state_since_ns = t;
      ++s.state_changes;
      s.ever_running = false;
      if (s.operational_left_ns < 0) s.operational_left_ns = t;
      emit(ProtocolEventKind::NodeReset, 1, t, r.bus, node, r.direction,
           fmt::format("boot-up while {}: node reset ({} so far)", canopen::to_string(was),
                       s.resets));
      return;
    }
  } else {
    s.ever_running = true;
  }
  if (*state == was) return;
  s.state = *state;
  s.state_since_ns = t;
  ++s.state_changes;
  if (*state == canopen::NmtState::Operational) {
    s.operational_left_ns = -1;
  } else if (was == canopen::NmtState::Operational || s.operational_left_ns < 0) {
    s.operational_left_ns = t;
  }
  emit(ProtocolEventKind::NmtState, was == canopen::NmtState::Operational ? 1 : 0, t, r.bus, node,
       r.direction, fmt::format("{} -> {}", canopen::to_string(was), canopen::to_string(*state)));
}

void ProtocolTracker::on_dronecan(const FrameRecord& r) {
  // DroneCAN "CAN bus transport layer": a message frame (bit 7 clear) of NodeStatus (type ID in
  // bits 8-23) from a node (source in bits 0-6, not 0). NodeStatus (7 bytes) always travels in
  // a single-frame transfer: its tail byte (the last) has the start and end bits (7, 6) set.
  if (r.rtr || (r.id & 0x80U) != 0) return;
  const std::uint32_t node = r.id & 0x7FU;
  if (node == 0 || ((r.id >> 8) & 0xFFFFU) != dronecan::kNodeStatus) return;
  const auto key = std::pair{r.bus, node};
  auto it = dc_nodes_.find(key);
  if (it == dc_nodes_.end()) {
    if (dc_nodes_.size() >= options_.max_nodes) {
      ++untracked_nodes_;
      return;
    }
    it = dc_nodes_.emplace(key, dronecan::NodeStats{}).first;
    it->second.bus = r.bus;
    it->second.node = static_cast<std::uint8_t>(node);
  }
  dronecan::NodeStats& s = it->second;
  const std::size_t len = std::min<std::size_t>(r.length, 8);
  const bool single = len >= 1 && (r.data[len - 1] & 0xC0U) == 0xC0U;
  if (len != 8 || !single) {
    ++s.malformed;
    s.last_malformed =
        len != 8 ? fmt::format("NodeStatus frame of {} bytes (7 and a tail byte expected)", len)
                 : std::string("NodeStatus frame that is not a single-frame transfer");
    return;
  }
  const auto st = dronecan::decode_node_status(std::span<const std::uint8_t>(r.data.data(), 7));
  if (!st) return;
  const Nanos t = r.time_ns;
  if (s.statuses > 0 && st->uptime_s < s.uptime_s) {
    ++s.restarts;
    s.last_restart_ns = t;
    emit(ProtocolEventKind::NodeReset, 1, t, r.bus, node, r.direction,
         fmt::format("uptime went back from {} s to {} s: node restart ({} so far)", s.uptime_s,
                     st->uptime_s, s.restarts));
  }
  const dronecan::Health was = s.health;
  ++s.statuses;
  s.last_status_ns = t;
  s.uptime_s = st->uptime_s;
  s.health = st->health;
  s.mode = st->mode;
  s.sub_mode = st->sub_mode;
  s.vendor_status = st->vendor_status;
  // A change of health, and a first status that is not OK.
  const bool first_ok = was == dronecan::Health::Unknown && st->health == dronecan::Health::Ok;
  if (st->health != was && !first_ok) {
    const std::uint8_t severity = st->health == dronecan::Health::Ok        ? 0
                                  : st->health == dronecan::Health::Warning ? 1
                                                                            : 2;
    emit(ProtocolEventKind::NodeHealth, severity, t, r.bus, node, r.direction,
         fmt::format("health {} -> {} (mode {})", dronecan::to_string(was),
                     dronecan::to_string(st->health), dronecan::mode_name(st->mode)));
  }
}

ProtocolSnapshot ProtocolTracker::snapshot() const {
  ProtocolSnapshot out;
  out.buses.reserve(buses_.size());
  for (const auto& [index, b] : buses_) {
    BusProtocolStats s = b.stats;
    const BusSettings& set = s.settings;
    for (std::size_t m = 0; m < kStuffingModes; ++m) {
      for (std::size_t k = 0; k < 3; ++k) {
        const Stream& st = b.streams[m][k];
        BusLoad& l = s.load[m][k];
        l.frames = st.frames;
        l.bits = st.bits;
        l.last_second_bits = st.last_nominal + st.last_data;
        l.known = set.bitrate != 0;
        if (!l.known) continue;
        l.last_second =
            percent(static_cast<double>(st.last_nominal), static_cast<double>(st.last_data), set);
        l.avg_1m = percent(st.ewma_nominal[0], st.ewma_data[0], set);
        l.avg_5m = percent(st.ewma_nominal[1], st.ewma_data[1], set);
        l.avg_15m = percent(st.ewma_nominal[2], st.ewma_data[2], set);
        l.peak = st.peak > 0 ? st.peak : percent(static_cast<double>(st.peak_bits), 0, set);
        // The whole history: its bits over the seconds closed (the second under way excluded).
        if (b.seconds_closed > 0) {
          l.mean = percent(static_cast<double>(st.closed_nominal),
                           static_cast<double>(st.closed_data), set) /
                   static_cast<double>(b.seconds_closed);
        }
      }
    }
    out.buses.push_back(std::move(s));
  }
  out.canopen.reserve(nodes_.size());
  for (const auto& [key, n] : nodes_) out.canopen.push_back(n.stats);
  out.dronecan.reserve(dc_nodes_.size());
  for (const auto& [key, n] : dc_nodes_) out.dronecan.push_back(n);
  out.j1939.reserve(j1939_nodes_.size());
  for (const auto& [key, n] : j1939_nodes_) out.j1939.push_back(n);
  out.tp_sessions_open = tp_.size();
  out.untracked_nodes = untracked_nodes_;
  out.events = seq_;
  out.events_dropped = events_dropped_;
  out.recent_events.assign(events_.begin(), events_.end());
  return out;
}

std::vector<ProtocolEvent> ProtocolTracker::events_after(std::uint64_t after) const {
  std::vector<ProtocolEvent> out;
  for (const ProtocolEvent& e : events_) {
    if (e.seq > after) out.push_back(e);
  }
  return out;
}

}  // namespace vigil::can
