// The CAN monitor's report and the CAN log replay (`vigil can-stats`) as text and JSON.
#include "vigil/export/can_report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "vigil/export/json_writer.hpp"

namespace vigil::exporter {

using namespace vigil::can;  // NOLINT: the formatters name many CAN types

// ---------------------------------------------------------------------------------------------
// Text

namespace {

// Columns separated by two spaces, numbers right-aligned, the last column not padded.
class TextTable {
 public:
  TextTable(std::vector<std::string> header, std::vector<bool> right) : right_(std::move(right)) {
    rows_.push_back(std::move(header));
  }
  void add(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  [[nodiscard]] std::string str() const {
    std::vector<std::size_t> width(rows_.front().size(), 0);
    for (const auto& row : rows_) {
      for (std::size_t i = 0; i < row.size() && i < width.size(); ++i) {
        width[i] = std::max(width[i], row[i].size());
      }
    }
    std::string out;
    for (const auto& row : rows_) {
      std::string line;
      for (std::size_t i = 0; i < row.size(); ++i) {
        if (i > 0) line += "  ";
        const bool last = i + 1 == row.size();
        const std::size_t pad = width[i] - std::min(width[i], row[i].size());
        if (i < right_.size() && right_[i]) line.append(pad, ' ');
        line += row[i];
        if (!last && !(i < right_.size() && right_[i])) line.append(pad, ' ');
      }
      while (!line.empty() && line.back() == ' ') line.pop_back();
      out += line;
      out += '\n';
    }
    return out;
  }

 private:
  std::vector<bool> right_;
  std::vector<std::vector<std::string>> rows_;
};

std::string us(double ns) { return fmt::format("{:.3f}", ns / 1e3); }
std::string ms(double ns) { return fmt::format("{:.3f}", ns / 1e6); }
std::string us_or_dash(const StatsSummary& s, double ns) { return s.count == 0 ? "-" : us(ns); }
std::string ms_or_dash(const StatsSummary& s, double ns) { return s.count == 0 ? "-" : ms(ns); }

std::string messages_of(const Status& s) { return s.summary("; "); }

// "0CF00400" (extended, 8 digits) or "181" (standard, 3 digits), as candump writes ids.
std::string format_id(std::uint32_t id, bool extended) {
  return extended ? fmt::format("{:08X}", id) : fmt::format("{:03X}", id);
}

// An id's function for people, with the direction of a request or an answer and its peer.
std::string describe_function(NodeMapKind kind, const IdStats& s) {
  if (s.error) return "error class";
  std::string f = format_function(kind, s.function);
  if (s.rtr) return f + " (remote request)";
  if (kind == NodeMapKind::DroneCan && (s.flags & (node_flags::kRequest | node_flags::kResponse))) {
    f += s.request() ? " request" : " response";
    if (s.peer != kNoNode) f += fmt::format(" to {}", s.peer);
  }
  return f;
}

// "data", "RTR" or "error".
std::string kind_of(const IdStats& s) {
  if (s.error) return "error";
  return s.rtr ? "RTR" : "data";
}

// Bus `bus` for people: `bus_names[bus]` when there is one, else the number.
std::string bus_name(std::uint8_t bus, const std::vector<std::string>& bus_names) {
  if (bus < bus_names.size() && !bus_names[bus].empty()) return bus_names[bus];
  return fmt::format("{}", bus);
}

// The first lines: the verdict with the counts, the status's messages, the kinds of frames.
std::string report_heading(const CanReport& r) {
  std::string out;
  const SnifferTotals& t = r.snapshot.totals;
  std::size_t ids_count = 0;
  for (const IdStats& s : r.snapshot.ids) ids_count += s.error || s.rtr ? 0 : 1;
  const std::size_t learning = r.learning_count();
  out += fmt::format("CAN status: {} ({} frames, {} ids, {} nodes of which {} OK{}, node map {})\n",
                     to_string(r.status.level()), t.frames, ids_count, r.node_count(), r.ok_count(),
                     learning > 0 ? fmt::format(", {} learning", learning) : "",
                     to_string(r.node_map));
  for (const StatusMessage& m : r.status.messages()) {
    out += fmt::format("  {}: {}\n", to_string(m.level), m.text);
  }
  if (t.remote_frames > 0 || t.error_frames > 0) {
    out += fmt::format("  frames: {} data, {} remote (RTR), {} error\n",
                       t.accepted - std::min(t.accepted, t.remote_frames), t.remote_frames,
                       t.error_frames);
  }
  return out;
}

// The tables (this one, nodes and ids) have one unit per column family, named in the headers:
// counts, I/O times in us, gaps, silences, periods and limits in ms.
std::string summary_table(const CanReport& r) {
  TextTable summary({"CATEGORY", "DIR", "NODES", "FRAMES", "RTR", "RECORDS", "IO MEAN us",
                     "IO MIN us", "IO MAX us", "GAP MEAN ms", "GAP MIN ms", "GAP MAX ms"},
                    {false, false, true, true, true, true, true, true, true, true, true, true});
  for (const CategoryStats& c : r.snapshot.categories) {
    summary.add(
        {c.group ? "group " + c.name : c.name, std::string(to_string(c.direction)),
         fmt::format("{}", c.nodes), fmt::format("{}", c.frames),
         fmt::format("{}", c.remote_frames), fmt::format("{}", c.records),
         us_or_dash(c.io_ns, c.io_ns.mean), us_or_dash(c.io_ns, static_cast<double>(c.io_ns.min)),
         us_or_dash(c.io_ns, static_cast<double>(c.io_ns.max)), ms_or_dash(c.gap_ns, c.gap_ns.mean),
         ms_or_dash(c.gap_ns, static_cast<double>(c.gap_ns.min)),
         ms_or_dash(c.gap_ns, static_cast<double>(c.gap_ns.max))});
  }
  return summary.str();
}

// One row per direction a node was seen in (one row of dashes when never seen).
void add_node_rows(TextTable& nodes, const CanReport& r, const NodeReport& n,
                   const CanTextOptions& options) {
  const std::string status = n.liveness == Liveness::Learning && n.status.ok()
                                 ? std::string("LEARNING")
                                 : std::string(to_string(n.status.level()));
  const std::string bus = n.bus ? bus_name(*n.bus, options.bus_names) : "*";
  const std::string node = format_node(r.node_map, n.node);
  const std::string silence = n.silence_ns < 0 ? "-" : ms(static_cast<double>(n.silence_ns));
  const std::string limit = n.silence_limit_ns < 0 ? "-"
                                                   : ms(static_cast<double>(n.silence_limit_ns)) +
                                                         (n.limit_learned ? "" : "*");
  const std::string name = n.named ? n.name : "-";  // else the NODE column says it
  const std::string liveness(to_string(n.liveness));
  bool first = true;
  for (const auto* s : {&n.rx, &n.tx}) {
    if (!s->has_value()) continue;
    const NodeStats& x = **s;
    const bool rx = x.direction == Direction::Rx;
    nodes.add({status, bus, node, name, std::string(to_string(x.direction)),
               fmt::format("{}{}", x.frames, x.exact_count ? "" : "+"),
               fmt::format("{}", x.remote_frames), fmt::format("{}", x.records),
               fmt::format("{}", x.ids), ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.min)),
               ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.p50)),
               ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.max)), rx ? silence : "-",
               rx ? limit : "-", first ? liveness : "", first ? messages_of(n.status) : ""});
    first = false;
  }
  if (first) {
    nodes.add({status, bus, node, name, "-", "0", "0", "0", "0", "-", "-", "-", "-", limit,
               liveness, messages_of(n.status)});
  }
}

std::string nodes_table(const CanReport& r, const CanTextOptions& options) {
  TextTable nodes(
      {"STATUS", "BUS", "NODE", "NAME", "DIR", "FRAMES", "RTR", "RECORDS", "IDS", "GAP MIN ms",
       "GAP p50 ms", "GAP MAX ms", "SILENCE ms", "LIMIT ms", "LIVENESS", "MESSAGES"},
      {false, false, true, false, false, true, true, true, true, true, true, true, true, true,
       false, false});
  for (const NodeReport& n : r.nodes) add_node_rows(nodes, r, n, options);
  std::string out = nodes.str();
  if (std::any_of(r.nodes.begin(), r.nodes.end(), [](const NodeReport& n) {
        return n.silence_limit_ns >= 0 && !n.limit_learned;
      })) {
    out += "(* a configured limit; the others are learned from each node's traffic)\n";
  }
  return out;
}

std::string ids_table(const CanReport& r, const CanTextOptions& options) {
  TextTable ids(
      {"BUS", "ID", "NODE", "FUNCTION", "DIR", "FRAMES", "RECORDS", "GAP MIN ms", "GAP p50 ms",
       "GAP MAX ms", "GAP MEAN ms", "KIND", "PERIOD ms", "LIMIT ms", "SILENCE ms", "TRAFFIC"},
      {false, false, true, false, false, true, true, true, true, true, true, false, true, true,
       true, false});
  bool approximate = false;
  for (std::size_t i = 0; i < r.snapshot.ids.size(); ++i) {
    const IdStats& s = r.snapshot.ids[i];
    const IdVerdict v = i < r.ids.size() ? r.ids[i] : IdVerdict{};
    if (s.gap_ns.count > 0 && !s.gap_exact) approximate = true;
    const auto opt_ms = [](Nanos x) {
      return x < 0 ? std::string("-") : ms(static_cast<double>(x));
    };
    ids.add({bus_name(s.bus, options.bus_names), format_id(s.id, s.extended),
             format_node(r.node_map, s.node), describe_function(r.node_map, s),
             std::string(to_string(s.direction)),
             fmt::format("{}{}", s.frames, s.exact_count ? "" : "+"), fmt::format("{}", s.records),
             ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.min)),
             ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.p50)),
             ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.max)),
             ms_or_dash(s.gap_ns, s.gap_ns.mean), kind_of(s), opt_ms(v.period_ns),
             opt_ms(v.limit_ns), opt_ms(v.silence_ns),
             std::string(to_string(v.traffic)) + (v.overdue ? " (overdue)" : "")});
  }
  std::string out = ids.str();
  if (approximate) {
    out += "(gap percentiles are upper bounds within 3.1%; min, max and mean are exact)\n";
  }
  return out;
}

// "12.3" (percent), or "-" when the bitrate is not known.
std::string pct(const BusLoad& l, double v) {
  return l.known ? fmt::format("{:.1f}", v) : std::string("-");
}

std::string bitrate_text(const BusSettings& s) {
  if (s.bitrate == 0) return "-";
  const auto one = [](std::uint32_t b) {
    if (b % 1000000 == 0) return fmt::format("{}M", b / 1000000);
    if (b % 1000 == 0) return fmt::format("{}k", b / 1000);
    return fmt::format("{}", b);
  };
  std::string t = one(s.bitrate);
  if (s.data_bitrate != 0 && s.data_bitrate != s.bitrate) t += "/" + one(s.data_bitrate);
  return t;
}

// Bus load per bus, stuffing mode and direction (as canbusload), and the bus's verdict.
std::string buses_table(const CanReport& r, const CanTextOptions& options) {
  TextTable t(
      {"STATUS", "BUS", "BITRATE", "STUFFING", "DIR", "FRAMES", "BITS", "LAST %", "1MIN %",
       "5MIN %", "15MIN %", "PEAK %", "MEAN %", "MESSAGES"},
      {false, false, true, false, false, true, true, true, true, true, true, true, true, false});
  for (const BusReport& b : r.buses) {
    bool first = true;
    for (std::size_t m = 0; m < kStuffingModes; ++m) {
      for (std::size_t k = 0; k < 3; ++k) {
        const BusLoad& l = b.stats.load[m][k];
        if (k < 2 && (l.frames == 0 || b.stats.load[m][1 - k].frames == 0)) continue;
        t.add({first ? std::string(to_string(b.status.level())) : "",
               bus_name(b.bus, options.bus_names), bitrate_text(b.stats.settings),
               std::string(to_string(static_cast<Stuffing>(m))),
               k == 0 ? "Rx" : (k == 1 ? "Tx" : "all"), fmt::format("{}", l.frames),
               fmt::format("{}", l.bits), pct(l, l.last_second), pct(l, l.avg_1m), pct(l, l.avg_5m),
               pct(l, l.avg_15m), pct(l, l.peak), pct(l, l.mean),
               first ? messages_of(b.status) : ""});
        first = false;
      }
    }
  }
  std::string out = t.str();
  if (std::any_of(r.buses.begin(), r.buses.end(),
                  [](const BusReport& b) { return b.stats.settings.bitrate == 0; })) {
    out += "(- : no bitrate configured for the bus (buses.<bus>.bitrate): no percentage)\n";
  }
  if (std::any_of(r.buses.begin(), r.buses.end(),
                  [](const BusReport& b) { return b.stats.fd_estimated > 0; })) {
    out +=
        "(exact: CAN FD frames are counted with the worst case, as canbusload has no exact "
        "CAN FD count)\n";
  }
  return out;
}

// The controllers' state from error frames, for buses that had any.
std::string controllers_table(const CanReport& r, const CanTextOptions& options) {
  TextTable t({"BUS", "STATE", "ERROR FRAMES", "WARNINGS", "PASSIVES", "BUS-OFFS", "RESTARTS",
               "PROTOCOL", "NO ACK", "LOST ARB", "TX ERR", "RX ERR", "LATEST"},
              {false, false, true, true, true, true, true, true, true, true, true, true, false});
  bool any = false;
  for (const BusReport& b : r.buses) {
    const ControllerStats& c = b.stats.controller;
    if (c.error_frames == 0) continue;
    any = true;
    const auto opt = [](const std::optional<std::uint8_t>& v) {
      return v ? fmt::format("{}", *v) : std::string("-");
    };
    t.add({bus_name(b.bus, options.bus_names), std::string(to_string(c.state)),
           fmt::format("{}", c.error_frames), fmt::format("{}", c.warnings),
           fmt::format("{}", c.passives), fmt::format("{}", c.bus_offs),
           fmt::format("{}", c.restarts), fmt::format("{}", c.by_class[3]),
           fmt::format("{}", c.by_class[5]), fmt::format("{}", c.by_class[1]), opt(c.tx_errors),
           opt(c.rx_errors), c.last});
  }
  return any ? t.str() : std::string();
}

// Every CANopen node the decoder saw.
std::string canopen_table(const CanReport& r, const CanTextOptions& options) {
  const auto& nodes = r.snapshot.protocol.canopen;
  if (nodes.empty()) return {};
  TextTable t({"BUS", "NODE", "NAME", "NMT", "HEARTBEATS", "BOOT-UPS", "RESETS", "EMCY", "GUARDING",
               "TOGGLE ERR", "MALFORMED", "LAST EMERGENCY"},
              {false, true, false, false, true, true, true, true, true, true, true, false});
  for (const canopen::NodeStats& n : nodes) {
    const NodeReport* rep = r.find(n.bus, n.node);
    t.add({bus_name(n.bus, options.bus_names), fmt::format("{}", n.node),
           rep != nullptr && rep->named ? rep->name : "-", std::string(to_string(n.state)),
           fmt::format("{}", n.heartbeats), fmt::format("{}", n.boot_ups),
           fmt::format("{}", n.resets), fmt::format("{}", n.emergencies),
           fmt::format("{}", n.guard_responses), fmt::format("{}", n.toggle_errors),
           fmt::format("{}", n.malformed_emergencies + n.malformed_heartbeats),
           n.last_emergency ? n.last_emergency->describe() : "-"});
  }
  return t.str();
}

// Every DroneCAN node whose NodeStatus was decoded.
std::string dronecan_table(const CanReport& r, const CanTextOptions& options) {
  const auto& nodes = r.snapshot.protocol.dronecan;
  if (nodes.empty()) return {};
  TextTable t({"BUS", "NODE", "NAME", "HEALTH", "MODE", "SUB", "UPTIME s", "VENDOR", "STATUSES",
               "RESTARTS", "MALFORMED"},
              {false, true, false, false, false, true, true, false, true, true, true});
  for (const dronecan::NodeStats& n : nodes) {
    const NodeReport* rep = r.find(n.bus, n.node);
    t.add({bus_name(n.bus, options.bus_names), fmt::format("{}", n.node),
           rep != nullptr && rep->named ? rep->name : "-",
           std::string(dronecan::to_string(n.health)), dronecan::mode_name(n.mode),
           fmt::format("{}", n.sub_mode), fmt::format("{}", n.uptime_s),
           fmt::format("0x{:04X}", n.vendor_status), fmt::format("{}", n.statuses),
           fmt::format("{}", n.restarts), fmt::format("{}", n.malformed)});
  }
  return t.str();
}

// "SPN 100 FMI 1 x3, SPN 110 FMI 0 x5 (+2 not kept)", or "-".
std::string dtc_list(const std::vector<j1939::Dtc>& codes, std::uint64_t untracked) {
  std::string dtcs;
  for (const j1939::Dtc& d : codes) {
    if (!dtcs.empty()) dtcs += ", ";
    dtcs += fmt::format("SPN {} FMI {} x{}", d.spn, d.fmi, d.occurrences);
  }
  if (untracked > 0) dtcs += fmt::format(" (+{} not kept)", untracked);
  return dtcs.empty() ? "-" : dtcs;
}

// Every J1939 node with a DM1, a DM2 or an address claim (or malformed J1939 input). The DM2
// columns only when some node sent a DM2.
std::string j1939_table(const CanReport& r, const CanTextOptions& options) {
  const auto& nodes = r.snapshot.protocol.j1939;
  if (nodes.empty()) return {};
  const bool dm2 =
      std::any_of(nodes.begin(), nodes.end(), [](const j1939::NodeStats& n) { return n.dm2s > 0; });
  std::vector<std::string> head{"BUS",         "SA",        "NAME",       "CLAIMED AS", "DM1",
                                "ACTIVE",      "APPEARED",  "CLEARED",    "LAMPS",      "TP MSGS",
                                "TP TIMEOUTS", "MALFORMED", "ACTIVE DTCS"};
  std::vector<bool> right{false, false, false, false, true, true, true,
                          true,  false, true,  true,  true, false};
  if (dm2) {
    head.insert(head.end(), {"DM2", "PREVIOUSLY ACTIVE DTCS"});
    right.insert(right.end(), {true, false});
  }
  TextTable t(head, right);
  for (const j1939::NodeStats& n : nodes) {
    const NodeReport* rep = r.find(n.bus, n.address);
    const std::string dtcs = dtc_list(n.active, n.dtcs_untracked);
    std::string lamps = "-";
    if (n.dm1s > 0) {
      const auto on = [](j1939::Lamp l) { return l == j1939::Lamp::On; };
      lamps.clear();
      if (on(n.lamps.mil)) lamps += "MIL ";
      if (on(n.lamps.red_stop)) lamps += "STOP ";
      if (on(n.lamps.amber_warning)) lamps += "AWL ";
      if (on(n.lamps.protect)) lamps += "PL ";
      lamps = lamps.empty() ? "off" : lamps.substr(0, lamps.size() - 1);
    }
    std::vector<std::string> row{
        bus_name(n.bus, options.bus_names),
        fmt::format("0x{:02X}", n.address),
        rep != nullptr && rep->named ? rep->name : "-",
        n.name ? n.name->label() +
                     fmt::format(" (mfr {}, id {})", n.name->manufacturer, n.name->identity)
               : "-",
        fmt::format("{}", n.dm1s),
        fmt::format("{}", n.active.size()),
        fmt::format("{}", n.dtcs_appeared),
        fmt::format("{}", n.dtcs_cleared),
        lamps,
        fmt::format("{}", n.tp_messages),
        fmt::format("{}", n.tp_timeouts),
        fmt::format("{}", n.malformed),
        dtcs};
    if (dm2) {
      row.push_back(fmt::format("{}", n.dm2s));
      row.push_back(n.dm2s > 0 ? dtc_list(n.previously_active, n.previously_active_untracked)
                               : "-");
    }
    t.add(row);
  }
  return t.str();
}

std::string event_node(const CanReport& r, const ProtocolEvent& e) {
  if (e.node == kNoNode) return "-";
  const NodeReport* rep = r.find(e.bus, e.node);
  if (rep != nullptr && rep->named) return fmt::format("{} ({})", e.node, rep->name);
  return fmt::format("{}", e.node);
}

std::string events_list(const CanReport& r, const CanTextOptions& options) {
  const ProtocolSnapshot& p = r.snapshot.protocol;
  if (p.events == 0) return {};
  std::string out = fmt::format("\nProtocol events ({}", p.events);
  if (p.events_dropped > 0) out += fmt::format(", the oldest {} no longer kept", p.events_dropped);
  const std::size_t n = p.recent_events.size();
  const std::size_t show =
      options.max_events < 0 ? n : std::min(n, static_cast<std::size_t>(options.max_events));
  if (show < n) out += fmt::format(", the latest {} shown", show);
  out += ")\n";
  TextTable t({"TIME s", "BUS", "NODE", "EVENT", "LEVEL", "DETAIL"},
              {true, false, false, false, false, false});
  for (std::size_t i = n - show; i < n; ++i) {
    const ProtocolEvent& e = p.recent_events[i];
    t.add({fmt::format("{:.6f}", static_cast<double>(e.time_ns) / 1e9),
           bus_name(e.bus, options.bus_names), event_node(r, e), std::string(to_string(e.kind)),
           e.severity == 2 ? "ERROR" : (e.severity == 1 ? "WARN" : "INFO"), e.detail});
  }
  return out + t.str();
}

}  // namespace

std::string format_can_report(const CanReport& r, const CanTextOptions& options) {
  std::string out = report_heading(r);
  out += "\nSummary\n";
  out += summary_table(r);
  out += "\nNodes\n";
  out += nodes_table(r, options);
  if (!r.buses.empty()) {
    out += "\nBuses\n";
    out += buses_table(r, options);
  }
  if (const std::string c = controllers_table(r, options); !c.empty()) {
    out += "\nControllers (error frames)\n" + c;
  }
  if (const std::string c = canopen_table(r, options); !c.empty()) out += "\nCANopen\n" + c;
  if (const std::string c = dronecan_table(r, options); !c.empty()) out += "\nDroneCAN\n" + c;
  if (const std::string c = j1939_table(r, options); !c.empty()) out += "\nJ1939\n" + c;
  out += events_list(r, options);
  if (options.ids) {
    out += "\nIds\n";
    out += ids_table(r, options);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// JSON

namespace {

void write_summary(exporter::JsonWriter& w, const StatsSummary& s) {
  w.begin_object();
  w.field("count", s.count).field("min", s.min).field("max", s.max).field("mean", s.mean);
  w.field("ewma", s.ewma).field("last", s.last);
  w.field("p50", s.p50).field("p90", s.p90).field("p99", s.p99).field("p999", s.p999);
  w.end_object();
}

void write_status(exporter::JsonWriter& w, const Status& s) {
  w.field("status", to_string(s.level()));
  w.key("messages").begin_array();
  for (const StatusMessage& m : s.messages()) {
    w.begin_object().field("level", to_string(m.level)).field("text", m.text).end_object();
  }
  w.end_array();
}

void write_totals(exporter::JsonWriter& w, const SnifferTotals& t) {
  w.begin_object();
  w.field("frames", t.frames).field("rx", t.rx).field("tx", t.tx);
  w.field("error_frames", t.error_frames).field("remote_frames", t.remote_frames);
  w.field("rejected", t.rejected);
  w.field("accepted", t.accepted).field("untracked_ids", t.untracked_ids);
  w.field("untracked_nodes", t.untracked_nodes).field("dropped", t.dropped);
  w.field("filter_changes", t.filter_changes);
  w.end_object();
}

void write_node_stats(exporter::JsonWriter& w, const NodeStats& s) {
  w.begin_object();
  w.field("frames", s.frames).field("remote_frames", s.remote_frames);
  w.field("exact_count", s.exact_count).field("records", s.records);
  w.field("ids", s.ids).field("first_ns", s.first_ns).field("last_ns", s.last_ns);
  w.key("io_ns");
  write_summary(w, s.io_ns);
  w.key("gap_ns");
  write_summary(w, s.gap_ns);
  w.field("gap_exact", s.gap_exact);
  w.end_object();
}

// `key: ns`, or `key: null` for a negative value (none).
void optional_ns(exporter::JsonWriter& w, std::string_view key, Nanos ns) {
  if (ns < 0) {
    w.key(key).null();
  } else {
    w.field(key, ns);
  }
}

void write_us(exporter::JsonWriter& w, const StatsSummary& s) {
  w.begin_object();
  if (s.count == 0) {
    w.key("mean").null().key("min").null().key("max").null();
  } else {
    w.field("mean", s.mean / 1e3);
    w.field("min", static_cast<double>(s.min) / 1e3);
    w.field("max", static_cast<double>(s.max) / 1e3);
  }
  w.end_object();
}

void write_limits(exporter::JsonWriter& w, const CanSnapshot& s) {
  w.begin_object();
  w.field("max_ids", s.max_ids).field("max_nodes", s.max_nodes);
  w.field("unaggregated_id_records", s.unaggregated_id_records);
  w.field("unaggregated_node_records", s.unaggregated_node_records);
  w.end_object();
}

void write_category(exporter::JsonWriter& w, const CategoryStats& c) {
  w.begin_object();
  w.field("category", c.name).field("group", c.group).field("direction", to_string(c.direction));
  w.field("nodes", c.nodes).field("frames", c.frames).field("remote_frames", c.remote_frames);
  w.field("records", c.records);
  w.key("io_us");
  write_us(w, c.io_ns);
  w.key("gap_us");
  write_us(w, c.gap_ns);
  w.end_object();
}

void write_node(exporter::JsonWriter& w, const CanReport& r, const NodeReport& n,
                const std::vector<std::string>& bus_names) {
  w.begin_object();
  if (n.bus) {
    w.field("bus", *n.bus).field("bus_name", bus_name(*n.bus, bus_names));
  } else {
    w.key("bus").null().key("bus_name").null();
  }
  if (n.is_node()) {
    w.field("node", n.node);
  } else {
    w.key("node").null();
  }
  w.field("name", n.name).field("named", n.named);
  w.field("expected", n.expected).field("liveness", to_string(n.liveness));
  w.key("groups").begin_array();
  for (const std::string& g : n.groups) w.value(g);
  w.end_array();
  write_status(w, n.status);
  optional_ns(w, "silence_ns", n.silence_ns);
  optional_ns(w, "silence_limit_ns", n.silence_limit_ns);
  if (n.silence_limit_ns < 0) {
    w.key("limit").null();
  } else {
    w.field("limit", n.limit_learned ? "learned" : "configured");
  }
  if (n.limit_id >= 0) {
    const IdStats& s = r.snapshot.ids[static_cast<std::size_t>(n.limit_id)];
    w.field("limit_id", format_id(s.id, s.extended));
  } else {
    w.key("limit_id").null();
  }
  w.field("to_node_frames", n.to_node_frames);
  optional_ns(w, "unanswered_ns", n.unanswered_ns);
  w.key("rx");
  if (n.rx) {
    write_node_stats(w, *n.rx);
  } else {
    w.null();
  }
  w.key("tx");
  if (n.tx) {
    write_node_stats(w, *n.tx);
  } else {
    w.null();
  }
  w.end_object();
}

// The id `s` with its verdict `v`.
void write_id(exporter::JsonWriter& w, NodeMapKind node_map, const IdStats& s, const IdVerdict& v,
              const std::vector<std::string>& bus_names) {
  w.begin_object();
  w.field("bus", s.bus).field("bus_name", bus_name(s.bus, bus_names));
  w.field("id", format_id(s.id, s.extended)).field("id_value", s.id);
  w.field("extended", s.extended).field("kind", kind_of(s));
  w.field("direction", to_string(s.direction));
  if (s.node == kNoNode) {
    w.key("node").null();
  } else {
    w.field("node", s.node);
  }
  w.field("function", s.function);
  w.field("function_name", describe_function(node_map, s));
  if (s.peer == kNoNode) {
    w.key("peer").null();
  } else {
    w.field("peer", s.peer);
  }
  w.field("to_node", (s.flags & node_flags::kToNode) != 0);
  w.field("request", s.request()).field("response", (s.flags & node_flags::kResponse) != 0);
  w.field("traffic", to_string(v.traffic));
  optional_ns(w, "period_ns", v.period_ns);
  optional_ns(w, "silence_limit_ns", v.limit_ns);
  optional_ns(w, "silence_ns", v.silence_ns);
  w.field("overdue", v.overdue);
  w.field("frames", s.frames).field("exact_count", s.exact_count).field("records", s.records);
  w.field("first_ns", s.first_ns).field("last_ns", s.last_ns);
  w.key("io_ns");
  write_summary(w, s.io_ns);
  w.key("gap_ns");
  write_summary(w, s.gap_ns);
  w.field("gap_exact", s.gap_exact);
  w.end_object();
}

void write_sniffer(exporter::JsonWriter& w, const SnifferInfo& s) {
  w.begin_object();
  w.field("port_id", s.port_id).field("name", s.name).field("alive", s.alive);
  w.field("node_map", to_string(s.node_map)).field("filter", s.filter);
  w.field("ids", s.ids).field("max_ids", s.max_ids).field("nodes", s.nodes);
  w.field("max_nodes", s.max_nodes).field("port_capacity", s.port_capacity);
  w.key("totals");
  write_totals(w, s.totals);
  w.end_object();
}

void write_load(exporter::JsonWriter& w, const BusLoad& l) {
  w.begin_object();
  w.field("frames", l.frames).field("bits", l.bits).field("last_second_bits", l.last_second_bits);
  const auto p = [&](std::string_view k, double v) {
    w.key(k);
    if (l.known) {
      w.value(v);
    } else {
      w.null();
    }
  };
  p("last_second", l.last_second);
  p("avg_1m", l.avg_1m);
  p("avg_5m", l.avg_5m);
  p("avg_15m", l.avg_15m);
  p("peak", l.peak);
  p("mean", l.mean);
  w.end_object();
}

void write_bus(exporter::JsonWriter& w, const BusReport& b,
               const std::vector<std::string>& bus_names) {
  const BusProtocolStats& s = b.stats;
  w.begin_object();
  w.field("bus", b.bus).field("bus_name", bus_name(b.bus, bus_names));
  write_status(w, b.status);
  w.key("bitrate");
  if (s.settings.bitrate != 0) {
    w.value(s.settings.bitrate);
  } else {
    w.null();
  }
  w.key("data_bitrate");
  if (s.settings.data_bitrate != 0) {
    w.value(s.settings.data_bitrate);
  } else {
    w.null();
  }
  w.field("protocol", to_string(s.settings.protocol));
  w.field("protocol_detected", s.detected);
  if (s.detected) w.field("protocol_detected_from", s.detected_from);
  w.key("judged").begin_object();
  w.field("stuffing", to_string(b.config.load.stuffing))
      .field("figure", to_string(b.config.load.figure));
  w.key("load");
  if (std::isnan(b.judged_load)) {
    w.null();
  } else {
    w.value(b.judged_load);
  }
  w.key("warn");
  if (b.config.load.warn) {
    w.value(*b.config.load.warn);
  } else {
    w.null();
  }
  w.key("error");
  if (b.config.load.error) {
    w.value(*b.config.load.error);
  } else {
    w.null();
  }
  w.end_object();
  w.key("load").begin_object();
  for (std::size_t m = 0; m < kStuffingModes; ++m) {
    w.key(to_string(static_cast<Stuffing>(m))).begin_object();
    w.key("rx");
    write_load(w, s.load[m][0]);
    w.key("tx");
    write_load(w, s.load[m][1]);
    w.key("all");
    write_load(w, s.load[m][2]);
    w.end_object();
  }
  w.end_object();
  w.field("fd_estimated", s.fd_estimated);
  optional_ns(w, "window_end_ns", s.window_end_ns);
  const ControllerStats& c = s.controller;
  w.key("controller").begin_object();
  w.field("state", to_string(c.state));
  optional_ns(w, "state_since_ns", c.state_since_ns);
  w.field("error_frames", c.error_frames);
  w.key("by_class").begin_object();
  for (std::size_t i = 0; i < error_class::kCount; ++i) {
    w.field(error_class_name(i), c.by_class[i]);
  }
  w.end_object();
  w.field("warnings", c.warnings).field("passives", c.passives).field("bus_offs", c.bus_offs);
  w.field("restarts", c.restarts).field("rx_overflows", c.rx_overflows);
  w.field("tx_overflows", c.tx_overflows);
  w.key("protocol_types").begin_object();
  constexpr std::array<std::string_view, 8> kTypes{"bit",  "form",     "stuff",  "bit0",
                                                   "bit1", "overload", "active", "tx"};
  for (std::size_t i = 0; i < 8; ++i) w.field(kTypes[i], c.protocol_types[i]);
  w.end_object();
  w.key("protocol_locations").begin_array();
  for (const auto& [loc, n] : c.protocol_locations) {
    w.begin_object().field("location", protocol_location_name(loc)).field("count", n);
    w.end_object();
  }
  w.end_array();
  w.key("transceiver");
  if (c.transceiver) {
    w.value(transceiver_name(*c.transceiver));
  } else {
    w.null();
  }
  w.key("tx_errors");
  if (c.tx_errors) {
    w.value(*c.tx_errors);
  } else {
    w.null();
  }
  w.key("rx_errors");
  if (c.rx_errors) {
    w.value(*c.rx_errors);
  } else {
    w.null();
  }
  w.field("latest", c.last);
  w.end_object();
  w.field("nmt_commands", s.nmt_commands).field("malformed_nmt", s.malformed_nmt);
  w.end_object();
}

void write_emergency(exporter::JsonWriter& w, const canopen::Emergency& e) {
  w.begin_object();
  w.field("code", fmt::format("0x{:04X}", e.code)).field("class", canopen::emergency_class(e.code));
  w.field("error_register", e.error_register)
      .field("error_register_bits", canopen::error_register_names(e.error_register));
  w.field("manufacturer",
          fmt::format("{:02X} {:02X} {:02X} {:02X} {:02X}", e.manufacturer[0], e.manufacturer[1],
                      e.manufacturer[2], e.manufacturer[3], e.manufacturer[4]));
  w.field("length", e.length).field("time_ns", e.time_ns).field("text", e.describe());
  w.end_object();
}

// A protocol table's node: its bus (index and name), its number, and its configured name or null.
void write_node_identity(exporter::JsonWriter& w, const CanReport& r, std::uint8_t bus,
                         std::uint32_t node, const std::vector<std::string>& bus_names) {
  w.field("bus", bus).field("bus_name", bus_name(bus, bus_names)).field("node", node);
  const NodeReport* rep = r.find(bus, node);
  w.key("name");
  if (rep != nullptr && rep->named) {
    w.value(rep->name);
  } else {
    w.null();
  }
}

void write_canopen(exporter::JsonWriter& w, const CanReport& r, const canopen::NodeStats& n,
                   const std::vector<std::string>& bus_names) {
  w.begin_object();
  write_node_identity(w, r, n.bus, n.node, bus_names);
  w.field("nmt_state", to_string(n.state));
  optional_ns(w, "state_since_ns", n.state_since_ns);
  optional_ns(w, "last_heartbeat_ns", n.last_heartbeat_ns);
  optional_ns(w, "not_operational_since_ns", n.operational_left_ns);
  w.field("heartbeats", n.heartbeats).field("boot_ups", n.boot_ups).field("resets", n.resets);
  optional_ns(w, "last_reset_ns", n.last_reset_ns);
  w.field("state_changes", n.state_changes);
  w.field("guard_requests", n.guard_requests).field("guard_responses", n.guard_responses);
  w.field("toggle_errors", n.toggle_errors).field("emergencies", n.emergencies);
  w.key("last_emergency");
  if (n.last_emergency) {
    write_emergency(w, *n.last_emergency);
  } else {
    w.null();
  }
  w.field("malformed_emergencies", n.malformed_emergencies);
  w.field("malformed_heartbeats", n.malformed_heartbeats);
  w.field("last_malformed", n.last_malformed);
  w.end_object();
}

void write_dronecan(exporter::JsonWriter& w, const CanReport& r, const dronecan::NodeStats& n,
                    const std::vector<std::string>& bus_names) {
  w.begin_object();
  write_node_identity(w, r, n.bus, n.node, bus_names);
  w.field("health", dronecan::to_string(n.health)).field("mode", dronecan::mode_name(n.mode));
  w.field("sub_mode", n.sub_mode).field("vendor_status", n.vendor_status);
  w.field("uptime_s", n.uptime_s);
  optional_ns(w, "last_status_ns", n.last_status_ns);
  w.field("statuses", n.statuses).field("restarts", n.restarts);
  optional_ns(w, "last_restart_ns", n.last_restart_ns);
  w.field("malformed", n.malformed).field("last_malformed", n.last_malformed);
  w.end_object();
}

void write_dtc(exporter::JsonWriter& w, const j1939::Dtc& d) {
  w.begin_object();
  w.field("spn", d.spn).field("fmi", d.fmi).field("fmi_name", j1939::fmi_name(d.fmi));
  w.field("occurrences", d.occurrences).field("conversion_method", d.conversion_method);
  w.end_object();
}

void write_j1939(exporter::JsonWriter& w, const CanReport& r, const j1939::NodeStats& n,
                 const std::vector<std::string>& bus_names) {
  w.begin_object();
  write_node_identity(w, r, n.bus, n.address, bus_names);
  w.key("claimed_name");
  if (n.name) {
    const j1939::Name& m = *n.name;
    w.begin_object();
    w.field("raw", fmt::format("0x{:016X}", m.raw)).field("label", m.label());
    w.field("identity", m.identity).field("manufacturer", m.manufacturer);
    w.field("ecu_instance", m.ecu_instance).field("function_instance", m.function_instance);
    w.field("function", m.function).field("vehicle_system", m.vehicle_system);
    w.field("vehicle_system_instance", m.vehicle_system_instance);
    w.field("industry_group", m.industry_group);
    w.field("arbitrary_address_capable", m.arbitrary_address);
    w.end_object();
  } else {
    w.null();
  }
  optional_ns(w, "claimed_ns", n.claimed_ns);
  w.field("claims", n.claims).field("dm1s", n.dm1s);
  optional_ns(w, "last_dm1_ns", n.last_dm1_ns);
  w.key("lamps");
  if (n.dm1s > 0) {
    w.begin_object();
    w.field("mil", j1939::to_string(n.lamps.mil));
    w.field("red_stop", j1939::to_string(n.lamps.red_stop));
    w.field("amber_warning", j1939::to_string(n.lamps.amber_warning));
    w.field("protect", j1939::to_string(n.lamps.protect));
    w.field("flash", n.lamps.flash);
    w.end_object();
  } else {
    w.null();
  }
  w.key("active_dtcs").begin_array();
  for (const j1939::Dtc& d : n.active) write_dtc(w, d);
  w.end_array();
  w.field("dtcs_untracked", n.dtcs_untracked);
  w.field("dtcs_appeared", n.dtcs_appeared).field("dtcs_cleared", n.dtcs_cleared);
  w.field("dm2s", n.dm2s);
  optional_ns(w, "last_dm2_ns", n.last_dm2_ns);
  w.key("previously_active_dtcs").begin_array();
  for (const j1939::Dtc& d : n.previously_active) write_dtc(w, d);
  w.end_array();
  w.field("previously_active_untracked", n.previously_active_untracked);
  w.field("tp_messages", n.tp_messages).field("tp_aborts", n.tp_aborts);
  w.field("tp_timeouts", n.tp_timeouts);
  w.field("malformed", n.malformed).field("last_malformed", n.last_malformed);
  w.end_object();
}

void write_event(exporter::JsonWriter& w, const ProtocolEvent& e,
                 const std::vector<std::string>& bus_names) {
  w.begin_object();
  w.field("seq", e.seq).field("kind", to_string(e.kind));
  w.field("severity", e.severity == 2 ? "error" : (e.severity == 1 ? "warn" : "info"));
  w.field("time_ns", e.time_ns).field("bus", e.bus).field("bus_name", bus_name(e.bus, bus_names));
  w.key("node");
  if (e.node == kNoNode) {
    w.null();
  } else {
    w.value(e.node);
  }
  w.field("direction", to_string(e.direction)).field("detail", e.detail);
  w.end_object();
}

}  // namespace

void write_can_report_members(exporter::JsonWriter& w, const CanReport& r,
                              const std::vector<std::string>& bus_names) {
  w.field("time_ns", r.time_ns);
  w.field("node_map", to_string(r.node_map));
  write_status(w, r.status);
  w.field("records", r.snapshot.records);
  w.field("node_count", r.node_count()).field("ok_count", r.ok_count());
  w.field("learning_count", r.learning_count());
  w.key("totals");
  write_totals(w, r.snapshot.totals);
  w.key("limits");
  write_limits(w, r.snapshot);
  w.key("summary").begin_array();
  for (const CategoryStats& c : r.snapshot.categories) write_category(w, c);
  w.end_array();
  w.key("nodes").begin_array();
  for (const NodeReport& n : r.nodes) write_node(w, r, n, bus_names);
  w.end_array();
  w.key("ids").begin_array();
  for (std::size_t i = 0; i < r.snapshot.ids.size(); ++i) {
    write_id(w, r.node_map, r.snapshot.ids[i], i < r.ids.size() ? r.ids[i] : IdVerdict{},
             bus_names);
  }
  w.end_array();
  w.key("sniffers").begin_array();
  for (const SnifferInfo& s : r.snapshot.sniffers) write_sniffer(w, s);
  w.end_array();
  // What the frames said (vigil/can/protocol.hpp): bus load, controllers, CANopen, events.
  w.key("bus_reports").begin_array();
  for (const BusReport& b : r.buses) write_bus(w, b, bus_names);
  w.end_array();
  w.key("canopen").begin_array();
  for (const canopen::NodeStats& n : r.snapshot.protocol.canopen) {
    write_canopen(w, r, n, bus_names);
  }
  w.end_array();
  w.key("dronecan").begin_array();
  for (const dronecan::NodeStats& n : r.snapshot.protocol.dronecan) {
    write_dronecan(w, r, n, bus_names);
  }
  w.end_array();
  w.key("j1939").begin_array();
  for (const j1939::NodeStats& n : r.snapshot.protocol.j1939) write_j1939(w, r, n, bus_names);
  w.end_array();
  const ProtocolSnapshot& p = r.snapshot.protocol;
  w.key("protocol").begin_object();
  w.field("error_records", r.snapshot.error_records);
  w.field("events", p.events).field("events_dropped", p.events_dropped);
  w.field("untracked_canopen_nodes", p.untracked_nodes);
  std::uint64_t resets = 0;
  std::uint64_t emergencies = 0;
  for (const canopen::NodeStats& n : p.canopen) {
    resets += n.resets;
    emergencies += n.emergencies;
  }
  for (const dronecan::NodeStats& n : p.dronecan) resets += n.restarts;
  w.field("resets", resets).field("emergencies", emergencies);
  std::uint64_t active_dtcs = 0;
  std::uint64_t dtcs_appeared = 0;
  std::uint64_t claims = 0;
  std::uint64_t previously_active = 0;
  for (const j1939::NodeStats& n : p.j1939) {
    active_dtcs += n.active.size();
    dtcs_appeared += n.dtcs_appeared;
    previously_active += n.previously_active.size();
    if (n.name) ++claims;
  }
  w.field("j1939_nodes", p.j1939.size()).field("active_dtcs", active_dtcs);
  w.field("previously_active_dtcs", previously_active);
  w.field("dtcs_appeared", dtcs_appeared).field("address_claims", claims);
  w.field("tp_sessions_open", p.tp_sessions_open);
  w.key("recent_events").begin_array();
  for (const ProtocolEvent& e : p.recent_events) write_event(w, e, bus_names);
  w.end_array();
  w.end_object();
}

std::string can_report_json(const CanReport& report, int indent,
                            const std::vector<std::string>& bus_names) {
  exporter::JsonWriter w(indent);
  w.begin_object();
  w.field("schema", 1);
  write_can_report_members(w, report, bus_names);
  w.end_object();
  return w.take();
}

// ---------------------------------------------------------------------------------------------
// CAN log replay (vigil can-stats)

namespace {

// A log timestamp as candump writes it: seconds with 6 decimals (9 when not whole µs).
std::string timestamp_text(Nanos t) {
  const Nanos s = t / kNanosPerSecond;
  const Nanos ns = t % kNanosPerSecond;
  if (ns % 1000 == 0) return fmt::format("{}.{:06}", s, ns / 1000);
  return fmt::format("{}.{:09}", s, ns);
}

}  // namespace

std::string format_replay_warnings(const LogReplay& replay, std::string_view prefix,
                                   std::size_t max_per_file) {
  std::string out;
  for (const ReplayFile& f : replay.files()) {
    if (f.malformed == 0) continue;
    out += fmt::format("{}warning: {}: {} malformed line{} skipped\n", prefix, f.path.string(),
                       f.malformed, f.malformed == 1 ? "" : "s");
    for (std::size_t i = 0; i < f.errors.size() && i < max_per_file; ++i) {
      out += "  " + f.errors[i].to_string() + '\n';
    }
  }
  return out;
}

std::string format_can_replay(const LogReplay& replay, const CanReport& report,
                              const CanReplayTextOptions& options) {
  std::string out;
  const Nanos duration = replay.last_ns() - replay.first_ns();
  out += fmt::format("vigil can-stats: {} file{}, {} frames, {} to {} ({:.6f} s)\n",
                     replay.files().size(), replay.files().size() == 1 ? "" : "s", replay.frames(),
                     timestamp_text(replay.first_ns()), timestamp_text(replay.last_ns()),
                     static_cast<double>(duration) / 1e9);
  for (const ReplayFile& f : replay.files()) {
    out += fmt::format("  {}: {}, {} frames", f.path.string(), to_string(f.format), f.frames);
    if (f.malformed > 0) out += fmt::format(", {} malformed lines skipped", f.malformed);
    if (f.skipped > 0) out += fmt::format(", {} status records", f.skipped);
    out += '\n';
  }
  std::string buses;
  for (std::size_t i = 0; i < replay.bus_names().size(); ++i) {
    if (i > 0) buses += ", ";
    buses += fmt::format("{} = {}", i, replay.bus_names()[i]);
  }
  if (!buses.empty()) out += "  buses: " + buses + '\n';
  if (!options.config.empty()) out += "  config: " + options.config + '\n';
  const ProtocolSnapshot& p = report.snapshot.protocol;
  // Protocols recognised from the traffic (`protocol: auto` with a mapping that names none).
  for (const BusProtocolStats& b : p.buses) {
    if (!b.detected) continue;
    out += fmt::format("  protocol: {} {}, recognised from {} ({:.6f})\n",
                       bus_name(b.bus, replay.bus_names()), to_string(b.settings.protocol),
                       b.detected_from, static_cast<double>(b.detected_ns) / 1e9);
  }
  // The findings in one line: resets, emergencies, controller faults, bus load.
  std::uint64_t resets = 0;
  std::uint64_t emergencies = 0;
  for (const canopen::NodeStats& n : p.canopen) {
    resets += n.resets;
    emergencies += n.emergencies;
  }
  std::uint64_t passives = 0;
  std::uint64_t bus_offs = 0;
  std::string loads;
  for (const BusReport& b : report.buses) {
    passives += b.stats.controller.passives;
    bus_offs += b.stats.controller.bus_offs;
    const BusLoad& l = b.stats.load[static_cast<std::size_t>(b.config.load.stuffing)][2];
    if (!loads.empty()) loads += ", ";
    loads += l.known ? fmt::format("{} mean {:.1f}% peak {:.1f}%",
                                   bus_name(b.bus, replay.bus_names()), l.mean, l.peak)
                     : fmt::format("{} {} bits (no bitrate)", bus_name(b.bus, replay.bus_names()),
                                   l.bits);
  }
  std::string dronecan;
  if (!p.dronecan.empty()) {
    std::uint64_t restarts = 0;
    std::size_t unhealthy = 0;
    for (const dronecan::NodeStats& n : p.dronecan) {
      restarts += n.restarts;
      if (n.health != dronecan::Health::Ok) ++unhealthy;
    }
    dronecan = fmt::format("{} DroneCAN node{} ({} not OK, {} restart{}), ", p.dronecan.size(),
                           p.dronecan.size() == 1 ? "" : "s", unhealthy, restarts,
                           restarts == 1 ? "" : "s");
  }
  std::string j1939_text;
  if (!p.j1939.empty()) {
    std::size_t active = 0;
    std::uint64_t appeared = 0;
    std::size_t claimed = 0;
    std::size_t with_dm1 = 0;
    std::size_t with_dm2 = 0;
    std::size_t previous = 0;
    for (const j1939::NodeStats& n : p.j1939) {
      active += n.active.size();
      appeared += n.dtcs_appeared;
      previous += n.previously_active.size();
      if (n.name) ++claimed;
      if (n.dm1s > 0) ++with_dm1;
      if (n.dm2s > 0) ++with_dm2;
    }
    const std::string dm2_text = with_dm2 == 0
                                     ? std::string()
                                     : fmt::format("{} previously active (DM2 from {} node{}), ",
                                                   previous, with_dm2, with_dm2 == 1 ? "" : "s");
    j1939_text = fmt::format(
        "J1939: {} node{} with DM1, {} active DTC{} ({} appeared), {}{} address "
        "claim{}, ",
        with_dm1, with_dm1 == 1 ? "" : "s", active, active == 1 ? "" : "s", appeared, dm2_text,
        claimed, claimed == 1 ? "" : "s");
  }
  out += fmt::format(
      "  findings: {} CANopen node{}, {} reset{}, {} emergenc{}, {}{}{} error passive, {} bus "
      "off; load ({} stuffing): {}\n",
      p.canopen.size(), p.canopen.size() == 1 ? "" : "s", resets, resets == 1 ? "" : "s",
      emergencies, emergencies == 1 ? "y" : "ies", dronecan, j1939_text, passives, bus_offs,
      report.buses.empty() ? "exact" : to_string(report.buses.front().config.load.stuffing),
      loads.empty() ? "-" : loads);
  out += '\n';
  out += format_can_report(report,
                           {.ids = options.ids, .bus_names = replay.bus_names(), .max_events = -1});
  return out;
}

std::string can_replay_json(const LogReplay& replay, const CanReport& report, int indent) {
  exporter::JsonWriter w(indent);
  w.begin_object();
  w.field("schema", 1).field("tool", "vigil can-stats");
  w.key("files").begin_array();
  for (const ReplayFile& f : replay.files()) {
    w.begin_object();
    w.field("path", f.path.string()).field("format", to_string(f.format));
    w.field("frames", f.frames).field("malformed", f.malformed).field("skipped", f.skipped);
    w.end_object();
  }
  w.end_array();
  w.key("buses").begin_array();
  for (const std::string& b : replay.bus_names()) w.value(b);
  w.end_array();
  w.field("frames", replay.frames());
  w.field("first_timestamp_ns", replay.first_ns()).field("last_timestamp_ns", replay.last_ns());
  w.field("duration_ns", replay.last_ns() - replay.first_ns());
  write_can_report_members(w, report, replay.bus_names());
  w.end_object();
  return w.take();
}

}  // namespace vigil::exporter
