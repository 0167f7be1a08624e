// SAE J1939 in the protocol tracker: DM1 active and DM2 previously active trouble codes
// (J1939-73), single frame and reassembled by the transport protocol (J1939-21: BAM and
// connection mode, as a passive observer), address claims (J1939-81). Docs:
// docs/guide/can-protocols.md, "SAE J1939".
#include <fmt/format.h>

#include <algorithm>

#include "vigil/can/node_map.hpp"
#include "vigil/can/protocol.hpp"

namespace vigil::can {

namespace j1939 {

std::string_view to_string(Lamp l) noexcept {
  switch (l) {
    case Lamp::Off:
      return "off";
    case Lamp::On:
      return "on";
    case Lamp::Error:
      return "error";
    case Lamp::NotAvailable:
      return "n/a";
  }
  return "?";
}

std::string Lamps::describe() const {
  return fmt::format("MIL {}, red stop {}, amber warning {}, protect {}", to_string(mil),
                     to_string(red_stop), to_string(amber_warning), to_string(protect));
}

std::string_view fmi_name(std::uint8_t fmi) noexcept {
  switch (fmi) {
    case 0:
      return "data valid but above normal operational range - most severe level";
    case 1:
      return "data valid but below normal operational range - most severe level";
    case 2:
      return "data erratic, intermittent or incorrect";
    case 3:
      return "voltage above normal, or shorted to high source";
    case 4:
      return "voltage below normal, or shorted to low source";
    case 5:
      return "current below normal or open circuit";
    case 6:
      return "current above normal or grounded circuit";
    case 7:
      return "mechanical system not responding or out of adjustment";
    case 8:
      return "abnormal frequency or pulse width or period";
    case 9:
      return "abnormal update rate";
    case 10:
      return "abnormal rate of change";
    case 11:
      return "root cause not known";
    case 12:
      return "bad intelligent device or component";
    case 13:
      return "out of calibration";
    case 14:
      return "special instructions";
    case 15:
      return "data valid but above normal operating range - least severe level";
    case 16:
      return "data valid but above normal operating range - moderately severe level";
    case 17:
      return "data valid but below normal operating range - least severe level";
    case 18:
      return "data valid but below normal operating range - moderately severe level";
    case 19:
      return "received network data in error";
    case 20:
      return "data drifted high";
    case 21:
      return "data drifted low";
    case 31:
      return "condition exists";
    default:
      return "reserved";
  }
}

std::string Dtc::describe() const {
  std::string s = fmt::format("SPN {} FMI {} ({})", spn, fmi, fmi_name(fmi));
  if (occurrences == 127) {
    s += ", occurrence count n/a";
  } else {
    s += fmt::format(", {} occurrence{}", occurrences, occurrences == 1 ? "" : "s");
  }
  if (conversion_method) s += ", SPN conversion method 1 (decoded as version 4)";
  return s;
}

namespace {

// DM1 and DM2 share their layout (J1939-73): `what` names the message in errors.
std::optional<Dm1> decode_dtc_message(std::string_view what, std::span<const std::uint8_t> p,
                                      bool single_frame, std::string& error) {
  if (p.size() < 6) {
    error = fmt::format("{} of {} byte{} (at least 6: lamps and one DTC)", what, p.size(),
                        p.size() == 1 ? "" : "s");
    return std::nullopt;
  }
  if (!single_frame && (p.size() - 2) % 4 != 0) {
    error = fmt::format("{} of {} bytes (2 + 4 per DTC expected)", what, p.size());
    return std::nullopt;
  }
  if (single_frame && p.size() > 8) {
    error = fmt::format("{} frame of {} bytes (8 at most)", what, p.size());
    return std::nullopt;
  }
  Dm1 m;
  const auto lamp = [&](unsigned shift) { return static_cast<Lamp>((p[0] >> shift) & 0x3U); };
  m.lamps.mil = lamp(6);
  m.lamps.red_stop = lamp(4);
  m.lamps.amber_warning = lamp(2);
  m.lamps.protect = lamp(0);
  m.lamps.flash = p[1];
  // A single frame carries one DTC (bytes 3-6); bytes 7-8 are padding.
  const std::size_t count = single_frame ? 1 : (p.size() - 2) / 4;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint8_t* b = &p[2 + 4 * i];
    const bool zeros = b[0] == 0 && b[1] == 0 && b[2] == 0 && b[3] == 0;
    const bool ones = b[0] == 0xFF && b[1] == 0xFF && b[2] == 0xFF && b[3] == 0xFF;
    if (zeros || ones) continue;  // "no DTC"
    Dtc d;
    d.spn = static_cast<std::uint32_t>(b[0]) | static_cast<std::uint32_t>(b[1]) << 8 |
            static_cast<std::uint32_t>(b[2] >> 5) << 16;
    d.fmi = static_cast<std::uint8_t>(b[2] & 0x1FU);
    d.conversion_method = (b[3] & 0x80U) != 0;
    d.occurrences = static_cast<std::uint8_t>(b[3] & 0x7FU);
    const bool dup =
        std::any_of(m.dtcs.begin(), m.dtcs.end(), [&](const Dtc& o) { return o.same_code(d); });
    if (!dup) m.dtcs.push_back(d);
  }
  return m;
}

}  // namespace

std::optional<Dm1> decode_dm1(std::span<const std::uint8_t> p, bool single_frame,
                              std::string& error) {
  return decode_dtc_message("DM1", p, single_frame, error);
}

std::optional<Dm1> decode_dm2(std::span<const std::uint8_t> p, bool single_frame,
                              std::string& error) {
  return decode_dtc_message("DM2", p, single_frame, error);
}

Name decode_name(std::span<const std::uint8_t, 8> b) noexcept {
  std::uint64_t raw = 0;
  for (std::size_t i = 0; i < 8; ++i) raw |= static_cast<std::uint64_t>(b[i]) << (8 * i);
  Name n;
  n.raw = raw;
  n.identity = static_cast<std::uint32_t>(raw & 0x1FFFFFU);
  n.manufacturer = static_cast<std::uint16_t>((raw >> 21) & 0x7FFU);
  n.ecu_instance = static_cast<std::uint8_t>((raw >> 32) & 0x7U);
  n.function_instance = static_cast<std::uint8_t>((raw >> 35) & 0x1FU);
  n.function = static_cast<std::uint8_t>((raw >> 40) & 0xFFU);
  n.vehicle_system = static_cast<std::uint8_t>((raw >> 49) & 0x7FU);
  n.vehicle_system_instance = static_cast<std::uint8_t>((raw >> 56) & 0xFU);
  n.industry_group = static_cast<std::uint8_t>((raw >> 60) & 0x7U);
  n.arbitrary_address = (raw >> 63) != 0;
  return n;
}

std::string_view function_name(std::uint8_t function) noexcept {
  static constexpr std::array<std::string_view, 31> kNames{
      "engine",
      "auxiliary power unit",
      "electric propulsion control",
      "transmission",
      "battery pack monitor",
      "shift control",
      "power take-off (main or rear)",
      "axle - steering",
      "axle - drive",
      "brakes - system controller",
      "brakes - steer axle",
      "brakes - drive axle",
      "retarder - engine",
      "retarder - driveline",
      "cruise control",
      "fuel system",
      "steering controller",
      "suspension - steer axle",
      "suspension - drive axle",
      "instrument cluster",
      "trip recorder",
      "cab climate control",
      "aerodynamic control",
      "vehicle navigation",
      "vehicle security",
      "network interconnect ECU",
      "body controller",
      "power take-off (secondary or front)",
      "off vehicle gateway",
      "virtual terminal (in cab)",
      "management computer #1",
  };
  return function < kNames.size() ? kNames[function] : std::string_view{};
}

std::string_view industry_group_name(std::uint8_t group) noexcept {
  switch (group) {
    case 0:
      return "global";
    case 1:
      return "on-highway";
    case 2:
      return "agricultural and forestry";
    case 3:
      return "construction";
    case 4:
      return "marine";
    case 5:
      return "industrial";
    default:
      return {};
  }
}

std::string Name::label() const {
  const std::string_view f = function_name(function);
  std::string s = f.empty() ? fmt::format("function {}", function) : std::string(f);
  if (function_instance != 0) s += fmt::format(" #{}", function_instance);
  return s;
}

std::string Name::describe() const {
  const std::string_view ig = industry_group_name(industry_group);
  return fmt::format(
      "{}, function instance {}, ECU instance {}, manufacturer {}, identity {}, industry group "
      "{}{}, vehicle system {} instance {}{}",
      label(), function_instance, ecu_instance, manufacturer, identity, industry_group,
      ig.empty() ? std::string() : fmt::format(" ({})", ig), vehicle_system,
      vehicle_system_instance, arbitrary_address ? ", arbitrary address capable" : "");
}

}  // namespace j1939

// ---------------------------------------------------------------------------------------------
// The tracker's J1939 part
// ---------------------------------------------------------------------------------------------

j1939::NodeStats* ProtocolTracker::j1939_node(std::uint8_t bus, std::uint8_t sa) {
  const auto key = std::pair{bus, sa};
  auto it = j1939_nodes_.find(key);
  if (it != j1939_nodes_.end()) return &it->second;
  if (j1939_nodes_.size() >= options_.max_nodes) {
    ++untracked_nodes_;
    return nullptr;
  }
  j1939::NodeStats& n = j1939_nodes_[key];
  n.bus = bus;
  n.address = sa;
  return &n;
}

void ProtocolTracker::j1939_malformed(std::uint8_t bus, std::uint8_t sa, std::string what) {
  j1939::NodeStats* n = j1939_node(bus, sa);
  if (n == nullptr) return;
  ++n->malformed;
  n->last_malformed = std::move(what);
}

void ProtocolTracker::on_j1939(const FrameRecord& r) {
  if (r.rtr) return;
  expire_sessions(r.time_ns);
  const J1939Id j = decode_j1939(r.id);
  const std::uint8_t sa = j.source;
  const std::size_t len = std::min<std::size_t>(r.length, r.data.size());
  switch (j.pgn) {
    case j1939::kPgnDm1:
      on_dm1(r.bus, sa, r.time_ns, r.direction, std::span<const std::uint8_t>(r.data.data(), len),
             true);
      break;
    case j1939::kPgnDm2:
      on_dm2(r.bus, sa, r.time_ns, std::span<const std::uint8_t>(r.data.data(), len), true);
      break;
    case j1939::kPgnTpCm:
      on_tp_cm(r, sa, j.destination);
      break;
    case j1939::kPgnTpDt:
      on_tp_dt(r, sa, j.destination);
      break;
    case j1939::kPgnAddressClaimed:
      on_address_claim(r, sa);
      break;
    default:
      break;
  }
}

void ProtocolTracker::on_dm1(std::uint8_t bus, std::uint8_t sa, Nanos t, Direction d,
                             std::span<const std::uint8_t> payload, bool single_frame) {
  std::string error;
  const auto dm1 = j1939::decode_dm1(payload, single_frame, error);
  j1939::NodeStats* n = j1939_node(bus, sa);
  if (n == nullptr) return;
  if (!dm1) {
    ++n->malformed;
    n->last_malformed = std::move(error);
    return;
  }
  ++n->dm1s;
  n->last_dm1_ns = t;
  n->lamps = dm1->lamps;
  const std::uint8_t severity = dm1->lamps.red_stop == j1939::Lamp::On ? 2 : 1;
  const std::string lamps = dm1->lamps.describe();
  // Codes no longer listed: cleared.
  for (const j1939::Dtc& old : n->active) {
    const bool still = std::any_of(dm1->dtcs.begin(), dm1->dtcs.end(),
                                   [&](const j1939::Dtc& x) { return x.same_code(old); });
    if (still) continue;
    ++n->dtcs_cleared;
    emit(ProtocolEventKind::DtcCleared, 0, t, bus, sa, d,
         fmt::format("SPN {} FMI {} ({}) no longer active; lamps: {}", old.spn, old.fmi,
                     j1939::fmi_name(old.fmi), lamps));
  }
  std::vector<j1939::Dtc> next;
  next.reserve(std::min(dm1->dtcs.size(), options_.max_dtcs));
  std::uint64_t beyond = 0;
  for (const j1939::Dtc& x : dm1->dtcs) {
    if (next.size() >= options_.max_dtcs) {
      ++beyond;
      continue;
    }
    next.push_back(x);
    const bool known = std::any_of(n->active.begin(), n->active.end(),
                                   [&](const j1939::Dtc& o) { return o.same_code(x); });
    if (known) continue;
    ++n->dtcs_appeared;
    emit(ProtocolEventKind::DtcActive, severity, t, bus, sa, d,
         fmt::format("{}; lamps: {}", x.describe(), lamps));
  }
  n->dtcs_untracked += beyond;
  n->active = std::move(next);
}

void ProtocolTracker::on_dm2(std::uint8_t bus, std::uint8_t sa, Nanos t,
                             std::span<const std::uint8_t> payload, bool single_frame) {
  std::string error;
  const auto dm2 = j1939::decode_dm2(payload, single_frame, error);
  j1939::NodeStats* n = j1939_node(bus, sa);
  if (n == nullptr) return;
  if (!dm2) {
    ++n->malformed;
    n->last_malformed = std::move(error);
    return;
  }
  // The latest DM2 replaces the list; no events (see NodeStats::previously_active).
  ++n->dm2s;
  n->last_dm2_ns = t;
  n->dm2_lamps = dm2->lamps;
  const std::size_t keep = std::min(dm2->dtcs.size(), options_.max_dtcs);
  n->previously_active.assign(dm2->dtcs.begin(),
                              dm2->dtcs.begin() + static_cast<std::ptrdiff_t>(keep));
  n->previously_active_untracked = dm2->dtcs.size() - keep;
}

void ProtocolTracker::on_address_claim(const FrameRecord& r, std::uint8_t sa) {
  const std::size_t len = std::min<std::size_t>(r.length, r.data.size());
  j1939::NodeStats* n = j1939_node(r.bus, sa);
  if (n == nullptr) return;
  if (len != 8) {
    ++n->malformed;
    n->last_malformed =
        fmt::format("address claim of {} byte{} (8 expected: the NAME)", len, len == 1 ? "" : "s");
    return;
  }
  const j1939::Name name = j1939::decode_name(std::span<const std::uint8_t, 8>(r.data));
  ++n->claims;
  const std::optional<j1939::Name> was = n->name;
  n->name = name;
  n->claimed_ns = r.time_ns;
  if (sa == 0xFE) {  // the null address: "cannot claim address" (J1939-81)
    if (was && *was == name) return;
    emit(ProtocolEventKind::AddressClaim, 1, r.time_ns, r.bus, sa, r.direction,
         fmt::format("cannot claim an address: {}", name.describe()));
    return;
  }
  if (!was) {
    emit(ProtocolEventKind::AddressClaim, 0, r.time_ns, r.bus, sa, r.direction,
         fmt::format("address 0x{:02X} claimed by {}", sa, name.describe()));
  } else if (!(*was == name)) {
    emit(ProtocolEventKind::AddressClaim, 1, r.time_ns, r.bus, sa, r.direction,
         fmt::format("address 0x{:02X} now claimed by {} (was {})", sa, name.describe(),
                     was->describe()));
  }
}

namespace {

std::uint32_t pgn_of(const std::array<std::uint8_t, 8>& d) {
  return static_cast<std::uint32_t>(d[5]) | static_cast<std::uint32_t>(d[6]) << 8 |
         static_cast<std::uint32_t>(d[7]) << 16;
}

}  // namespace

void ProtocolTracker::on_tp_cm(const FrameRecord& r, std::uint8_t sa, std::uint8_t da) {
  const std::size_t len = std::min<std::size_t>(r.length, r.data.size());
  if (len != 8) {
    j1939_malformed(r.bus, sa, fmt::format("TP.CM of {} bytes (8 expected)", len));
    return;
  }
  const std::uint8_t control = r.data[0];
  const Nanos t = r.time_ns;
  const std::uint32_t pgn = pgn_of(r.data);
  switch (control) {
    case j1939::kTpBam:
    case j1939::kTpRts: {
      const bool bam = control == j1939::kTpBam;
      const char* what = bam ? "BAM" : "RTS";
      if (bam && da != 0xFF) {
        j1939_malformed(r.bus, sa, fmt::format("TP.CM_BAM to 0x{:02X} (global 0xFF expected)", da));
        return;
      }
      if (!bam && da == 0xFF) {
        j1939_malformed(r.bus, sa, "TP.CM_RTS to the global address");
        return;
      }
      const auto size = static_cast<std::uint16_t>(r.data[1] | (r.data[2] << 8));
      const std::uint8_t packets = r.data[3];
      if (size < 9 || size > j1939::kTpMaxSize || packets != (size + 6) / 7) {
        j1939_malformed(r.bus, sa,
                        fmt::format("TP.CM_{} of {} bytes in {} packets (9-1785 bytes, 7 a "
                                    "packet)",
                                    what, size, packets));
        return;
      }
      const TpKey key{r.bus, sa, da};
      auto it = tp_.find(key);
      if (it != tp_.end()) {
        if (!it->second.done) {
          j1939_malformed(
              r.bus, sa,
              fmt::format("TP.CM_{} for PGN 0x{:04X} while PGN 0x{:04X} was at packet "
                          "{} of {}: the earlier session is dropped",
                          what, pgn, it->second.pgn, it->second.next - 1, it->second.packets));
        }
        tp_.erase(it);
      }
      if (tp_.size() >= options_.max_tp_sessions) {
        j1939_malformed(r.bus, sa,
                        fmt::format("TP.CM_{} refused: {} transport sessions open (the bound)",
                                    what, tp_.size()));
        return;
      }
      TpSession s;
      s.bam = bam;
      s.pgn = pgn;
      s.size = size;
      s.packets = packets;
      s.keep = pgn == j1939::kPgnDm1 || pgn == j1939::kPgnDm2;
      if (s.keep) s.data.reserve(size);
      if (bam) {
        s.deadline = t + j1939::kT1;
        s.waiting = "T1: the first data packet";
      } else {
        s.deadline = t + j1939::kT3;
        s.waiting = "T3: a CTS";
      }
      tp_next_deadline_ = std::min(tp_next_deadline_, s.deadline);
      tp_.emplace(key, std::move(s));
      return;
    }
    case j1939::kTpCts: {
      // From the receiver (sa) to the originator (da).
      auto it = tp_.find(TpKey{r.bus, da, sa});
      if (it == tp_.end() || it->second.bam) return;  // not seen from its start
      TpSession& s = it->second;
      const std::uint8_t count = r.data[1];
      const std::uint8_t next = r.data[2];
      if (count == 0) {  // hold the connection open
        s.deadline = t + j1939::kT4;
        s.waiting = "T4: the next CTS";
      } else {
        if (next == 0 || next > s.packets || count > s.packets - next + 1) {
          j1939_malformed(r.bus, da,
                          fmt::format("TP.CM_CTS from 0x{:02X} for packets {}-{} of {}: the "
                                      "session is dropped",
                                      sa, next, next + count - 1, s.packets));
          tp_.erase(it);
          return;
        }
        if (s.keep && next < s.next) s.data.resize(static_cast<std::size_t>(next - 1) * 7);
        s.next = next;
        s.cts_end = static_cast<std::uint8_t>(next + count - 1);
        s.deadline = t + j1939::kT2;
        s.waiting = "T2: a data packet after the CTS";
      }
      tp_next_deadline_ = std::min(tp_next_deadline_, s.deadline);
      return;
    }
    case j1939::kTpEndOfMsgAck: {
      auto it = tp_.find(TpKey{r.bus, da, sa});
      if (it != tp_.end() && !it->second.bam) tp_.erase(it);
      return;
    }
    case j1939::kTpAbort: {
      // Either side may abort: the session is sa -> da or da -> sa.
      for (const TpKey& key : {TpKey{r.bus, sa, da}, TpKey{r.bus, da, sa}}) {
        auto it = tp_.find(key);
        if (it == tp_.end() || it->second.bam) continue;
        if (j1939::NodeStats* n = j1939_node(r.bus, std::get<1>(key)); n != nullptr) {
          ++n->tp_aborts;
        }
        tp_.erase(it);
      }
      return;
    }
    default:
      j1939_malformed(r.bus, sa,
                      fmt::format("TP.CM control byte {} (16, 17, 19, 32, 255 known)", control));
      return;
  }
}

void ProtocolTracker::on_tp_dt(const FrameRecord& r, std::uint8_t sa, std::uint8_t da) {
  const std::size_t len = std::min<std::size_t>(r.length, r.data.size());
  if (len != 8) {
    j1939_malformed(r.bus, sa, fmt::format("TP.DT of {} bytes (8 expected)", len));
    return;
  }
  const std::uint8_t seq = r.data[0];
  auto it = tp_.find(TpKey{r.bus, sa, da});
  if (it == tp_.end()) {
    j1939_malformed(
        r.bus, sa,
        fmt::format("TP.DT packet {} to 0x{:02X} without an announced session", seq, da));
    return;
  }
  TpSession& s = it->second;
  const Nanos t = r.time_ns;
  if (s.done) {
    j1939_malformed(r.bus, sa,
                    fmt::format("TP.DT packet {} for PGN 0x{:04X}: more packets than the {} "
                                "announced",
                                seq, s.pgn, s.packets));
    return;
  }
  const bool beyond_cts = !s.bam && (s.cts_end == 0 || seq > s.cts_end);
  if (seq != s.next || beyond_cts) {
    j1939_malformed(
        r.bus, sa,
        seq > s.packets
            ? fmt::format("TP.DT packet {} for PGN 0x{:04X}: more packets than the {} announced",
                          seq, s.pgn, s.packets)
        : beyond_cts
            ? fmt::format("TP.DT packet {} for PGN 0x{:04X} not cleared by a CTS", seq, s.pgn)
            : fmt::format("TP.DT sequence gap for PGN 0x{:04X}: packet {}, {} expected; "
                          "the session is dropped",
                          s.pgn, seq, s.next));
    tp_.erase(it);
    return;
  }
  if (s.keep) {
    const std::size_t room = s.size - s.data.size();
    const std::size_t take = std::min<std::size_t>(7, room);
    s.data.insert(s.data.end(), r.data.begin() + 1, r.data.begin() + 1 + take);
  }
  if (seq < s.packets) {
    ++s.next;
    if (!s.bam && seq == s.cts_end) {
      s.deadline = t + j1939::kT3;
      s.waiting = "T3: the next CTS";
    } else {
      s.deadline = t + j1939::kT1;
      s.waiting = "T1: the next data packet";
    }
    tp_next_deadline_ = std::min(tp_next_deadline_, s.deadline);
    return;
  }
  // The last packet: the message is complete.
  j1939::NodeStats* n = j1939_node(r.bus, sa);
  if (n != nullptr) ++n->tp_messages;
  if (s.keep) {  // DM1 or DM2
    const std::vector<std::uint8_t> data = std::move(s.data);
    const std::uint32_t pgn = s.pgn;
    s.data.clear();
    s.done = true;
    s.deadline = t + (s.bam ? j1939::kT1 : j1939::kT3);  // kept to see packets beyond the count
    s.waiting = "";
    tp_next_deadline_ = std::min(tp_next_deadline_, s.deadline);
    if (pgn == j1939::kPgnDm1) {
      on_dm1(r.bus, sa, t, r.direction, data, false);
    } else {
      on_dm2(r.bus, sa, t, data, false);
    }
    return;
  }
  s.done = true;
  s.deadline = t + (s.bam ? j1939::kT1 : j1939::kT3);
  s.waiting = "";
  tp_next_deadline_ = std::min(tp_next_deadline_, s.deadline);
}

void ProtocolTracker::expire_sessions(Nanos t) {
  if (t <= tp_next_deadline_) return;
  Nanos next = std::numeric_limits<Nanos>::max();
  for (auto it = tp_.begin(); it != tp_.end();) {
    const TpSession& s = it->second;
    if (t <= s.deadline) {
      next = std::min(next, s.deadline);
      ++it;
      continue;
    }
    if (!s.done) {
      if (j1939::NodeStats* n = j1939_node(std::get<0>(it->first), std::get<1>(it->first));
          n != nullptr) {
        ++n->tp_timeouts;
        ++n->malformed;
        n->last_malformed = fmt::format(
            "TP {} session for PGN 0x{:04X} timed out at packet {} of {} (waiting for {})",
            s.bam ? "BAM" : "RTS/CTS", s.pgn, s.next - 1, s.packets, s.waiting);
      }
    }
    it = tp_.erase(it);
  }
  tp_next_deadline_ = next;
}

}  // namespace vigil::can
