#include "vigil/can/can_monitor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <utility>

#include "can/can_json.hpp"
#include "vigil/config/units.hpp"
#include "vigil/export/json_writer.hpp"
#include "vigil/monitor/report.hpp"

namespace vigil::can {

namespace {

// Thresholds of a node that may be on any bus (`bus` empty): group and node entries bound to a
// bus apply only when the bus is known.
NodeThresholds resolve(const CanConfig& c, std::optional<std::uint8_t> bus, std::uint32_t node) {
  if (bus) return c.thresholds_for(*bus, node);
  NodeThresholds t;
  c.defaults.apply_to(t);
  for (const GroupConfig& g : c.groups) {
    if (!g.members.bus && g.members.contains(0, node)) g.thresholds.apply_to(t);
  }
  for (const NodeConfig& n : c.nodes) {
    if (!n.bus && n.node == node) n.thresholds.apply_to(t);
  }
  return t;
}

void check_limit(Status& s, std::string_view what, const Limit& l,
                 const std::optional<NodeStats>& n, bool io) {
  if (!l.enabled() || !n) return;
  const StatsSummary& d = io ? n->io_ns : n->gap_ns;
  if (d.count == 0) return;
  const Nanos v = stat_value(d, l.stat);
  // Strictly above: a value equal to its limit passes (as every vigil threshold).
  if (l.error && v > *l.error) {
    s.merge(StatusLevel::Error,
            fmt::format("{} {} {} above {}", what, to_string(l.stat),
                        format_nanos(static_cast<double>(v)), config::format_duration(*l.error)));
  } else if (l.warn && v > *l.warn) {
    s.merge(StatusLevel::Warn,
            fmt::format("{} {} {} above {}", what, to_string(l.stat),
                        format_nanos(static_cast<double>(v)), config::format_duration(*l.warn)));
  }
}

void builtin_checks(NodeReport& n, Nanos now) {
  const NodeThresholds& t = n.thresholds;
  const bool received = n.rx && n.rx->frames > 0;
  if (n.expected && !received && t.never_seen_enabled) {
    if (n.tx && n.tx->frames > 0) {
      n.status.merge(
          t.never_seen_level,
          fmt::format("not initialized: never answered ({} frames sent to it)", n.tx->frames));
    } else {
      n.status.merge(t.never_seen_level, "not initialized: never seen");
    }
  }
  if (received) {
    n.silence_ns = std::max<Nanos>(0, now - n.rx->last_ns);
    if (t.not_responding_enabled && n.silence_ns > t.not_responding_after_ns) {
      n.status.merge(t.not_responding_level,
                     fmt::format("not responding: silent for {} (limit {})",
                                 format_nanos(static_cast<double>(n.silence_ns)),
                                 config::format_duration(t.not_responding_after_ns)));
    }
  }
  check_limit(n.status, "read time", t.read_time, n.rx, true);
  check_limit(n.status, "write time", t.write_time, n.tx, true);
  check_limit(n.status, "rx gap", t.rx_gap, n.rx, false);
  check_limit(n.status, "tx gap", t.tx_gap, n.tx, false);
}

std::string plural(std::uint64_t n, std::string_view word) {
  return fmt::format("{} {}{}", n, word, n == 1 ? "" : "s");
}

void overall(CanReport& r) {
  const SnifferTotals& t = r.snapshot.totals;
  for (const StatusLevel level : {StatusLevel::Stale, StatusLevel::Error, StatusLevel::Warn}) {
    std::vector<std::string> names;
    for (const NodeReport& n : r.nodes) {
      if (n.status.level() == level) names.push_back(n.name);
    }
    if (names.empty()) continue;
    std::string list;
    for (std::size_t i = 0; i < names.size() && i < 8; ++i) {
      if (i > 0) list += ", ";
      list += names[i];
    }
    if (names.size() > 8) list += ", ...";
    r.status.merge(level,
                   fmt::format("{} {}: {}", plural(names.size(), "node"), to_string(level), list));
  }
  if (t.untracked_ids > 0) {
    r.status.merge(StatusLevel::Warn,
                   fmt::format("{} not counted per id: the sniffer's id table is full",
                               plural(t.untracked_ids, "frame")));
  }
  if (t.untracked_nodes > 0) {
    r.status.merge(StatusLevel::Warn,
                   fmt::format("{} not counted per node: the sniffer's node table is full",
                               plural(t.untracked_nodes, "frame")));
  }
  if (t.error_frames > 0) {
    r.status.merge(StatusLevel::Warn, plural(t.error_frames, "error frame"));
  }
  if (t.dropped > 0) {
    r.status.merge(StatusLevel::Ok,
                   fmt::format("timing sampled: {} of {} dropped by full ports (counts are exact)",
                               plural(t.dropped, "record"), t.accepted));
  }
}

}  // namespace

const NodeReport* CanReport::find(std::uint8_t bus, std::uint32_t node) const noexcept {
  for (const NodeReport& n : nodes) {
    if (n.bus && *n.bus == bus && n.node == node) return &n;
  }
  return nullptr;
}

const NodeReport* CanReport::find(std::string_view name) const noexcept {
  for (const NodeReport& n : nodes) {
    if (n.name == name) return &n;
  }
  return nullptr;
}

CanMonitor::CanMonitor(CanConfig config)
    : config_(std::make_shared<const CanConfig>(std::move(config))) {}

void CanMonitor::set_config(CanConfig config) {
  set_config(std::make_shared<const CanConfig>(std::move(config)));
}

void CanMonitor::set_config(std::shared_ptr<const CanConfig> config) {
  if (!config) return;
  std::lock_guard lock(mutex_);
  config_ = std::move(config);
}

std::shared_ptr<const CanConfig> CanMonitor::config() const {
  std::lock_guard lock(mutex_);
  return config_;
}

void CanMonitor::add_check(std::string name, CanNodeCheck check) {
  if (!check) return;
  std::lock_guard lock(mutex_);
  checks_.emplace_back(std::move(name), std::move(check));
}

CanReport CanMonitor::evaluate(const CanAggregator& aggregator, Nanos now) const {
  const std::shared_ptr<const CanConfig> c = config();
  return evaluate(aggregator.snapshot(c->group_specs()), now);
}

CanReport CanMonitor::evaluate(CanSnapshot snapshot, Nanos now) const {
  std::shared_ptr<const CanConfig> cfg;
  std::vector<std::pair<std::string, CanNodeCheck>> checks;
  {
    std::lock_guard lock(mutex_);
    cfg = config_;
    checks = checks_;
  }
  CanReport r;
  r.time_ns = now;
  r.node_map = snapshot.sniffers.empty() ? cfg->node_map : snapshot.sniffers.front().node_map;
  r.snapshot = std::move(snapshot);

  std::map<std::pair<std::uint8_t, std::uint32_t>, NodeReport> seen;
  for (const NodeStats& s : r.snapshot.nodes) {
    NodeReport& n = seen[{s.bus, s.node}];
    n.bus = s.bus;
    n.node = s.node;
    (s.direction == Direction::Rx ? n.rx : n.tx) = s;
  }

  // Expected nodes: named ones, and the explicit members of groups.
  std::vector<std::pair<std::optional<std::uint8_t>, std::uint32_t>> expected;
  for (const NodeConfig& n : cfg->nodes) {
    if (n.expected) expected.emplace_back(n.bus, n.node);
  }
  for (const GroupConfig& g : cfg->groups) {
    if (!g.expected) continue;
    for (const std::uint32_t node : g.members.nodes) expected.emplace_back(g.members.bus, node);
  }
  std::vector<NodeReport> unseen;
  for (const auto& [bus, node] : expected) {
    if (bus) {
      NodeReport& n = seen[{*bus, node}];
      n.bus = *bus;
      n.node = node;
      n.expected = true;
      continue;
    }
    bool found = false;
    for (auto& [key, n] : seen) {
      if (key.second == node) {
        n.expected = true;
        found = true;
      }
    }
    const bool listed = std::any_of(unseen.begin(), unseen.end(),
                                    [&](const NodeReport& u) { return u.node == node; });
    if (!found && !listed) {
      NodeReport n;
      n.node = node;
      n.expected = true;
      unseen.push_back(std::move(n));
    }
  }

  for (auto& [key, n] : seen) r.nodes.push_back(std::move(n));
  for (NodeReport& n : unseen) r.nodes.push_back(std::move(n));
  for (NodeReport& n : r.nodes) {
    const NodeConfig* named = nullptr;
    if (n.bus) {
      named = cfg->find_node(*n.bus, n.node);
    } else {
      for (const NodeConfig& c : cfg->nodes) {
        if (!c.bus && c.node == n.node) {
          named = &c;
          break;
        }
      }
    }
    n.named = named != nullptr;
    n.name = named != nullptr ? named->name : format_node(r.node_map, n.node);
    for (const GroupConfig& g : cfg->groups) {
      const bool member = n.bus ? g.members.contains(*n.bus, n.node)
                                : !g.members.bus && g.members.contains(0, n.node);
      if (member) n.groups.push_back(g.members.name);
    }
    n.thresholds = resolve(*cfg, n.bus, n.node);
    builtin_checks(n, now);
  }
  for (const auto& [name, check] : checks) {
    for (NodeReport& n : r.nodes) {
      try {
        check(n, r, n.status);
      } catch (const std::exception& e) {
        n.status.merge(StatusLevel::Error, fmt::format("check {} failed: {}", name, e.what()));
      } catch (...) {
        n.status.merge(StatusLevel::Error, fmt::format("check {} failed", name));
      }
    }
  }
  overall(r);
  return r;
}

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

}  // namespace

namespace detail {

std::string format_id(std::uint32_t id, bool extended) {
  return extended ? fmt::format("{:08X}", id) : fmt::format("{:03X}", id);
}

std::string bus_name(std::uint8_t bus, const std::vector<std::string>& bus_names) {
  if (bus < bus_names.size() && !bus_names[bus].empty()) return bus_names[bus];
  return fmt::format("{}", bus);
}

}  // namespace detail

std::string format_can_report(const CanReport& r, const CanTextOptions& options) {
  std::string out;
  const SnifferTotals& t = r.snapshot.totals;
  std::size_t ok = 0;
  for (const NodeReport& n : r.nodes) ok += n.status.ok() ? 1 : 0;
  out += fmt::format("CAN status: {} ({} frames, {} ids, {} nodes of which {} OK, node map {})\n",
                     to_string(r.status.level()), t.frames, r.snapshot.ids.size(), r.nodes.size(),
                     ok, to_string(r.node_map));
  for (const StatusMessage& m : r.status.messages()) {
    out += fmt::format("  {}: {}\n", to_string(m.level), m.text);
  }

  out += "\nSummary\n";
  TextTable summary({"CATEGORY", "DIR", "NODES", "FRAMES", "RECORDS", "IO MEAN us", "IO MIN us",
                     "IO MAX us", "GAP MEAN us", "GAP MIN us", "GAP MAX us"},
                    {false, false, true, true, true, true, true, true, true, true, true});
  for (const CategoryStats& c : r.snapshot.categories) {
    summary.add(
        {c.group ? "group " + c.name : c.name, std::string(to_string(c.direction)),
         fmt::format("{}", c.nodes), fmt::format("{}", c.frames), fmt::format("{}", c.records),
         us_or_dash(c.io_ns, c.io_ns.mean), us_or_dash(c.io_ns, static_cast<double>(c.io_ns.min)),
         us_or_dash(c.io_ns, static_cast<double>(c.io_ns.max)), us_or_dash(c.gap_ns, c.gap_ns.mean),
         us_or_dash(c.gap_ns, static_cast<double>(c.gap_ns.min)),
         us_or_dash(c.gap_ns, static_cast<double>(c.gap_ns.max))});
  }
  out += summary.str();

  out += "\nNodes\n";
  TextTable nodes(
      {"STATUS", "BUS", "NODE", "NAME", "DIR", "FRAMES", "RECORDS", "IDS", "GAP MIN ms",
       "GAP p50 ms", "GAP MAX ms", "SILENCE ms", "MESSAGES"},
      {false, false, true, false, false, true, true, true, true, true, true, true, false});
  for (const NodeReport& n : r.nodes) {
    const std::string bus = n.bus ? detail::bus_name(*n.bus, options.bus_names) : "*";
    const std::string node = format_node(r.node_map, n.node);
    const std::string silence = n.silence_ns < 0 ? "-" : ms(static_cast<double>(n.silence_ns));
    const std::string name = n.named ? n.name : "-";  // else the NODE column says it
    bool first = true;
    for (const auto* s : {&n.rx, &n.tx}) {
      if (!s->has_value()) continue;
      const NodeStats& x = **s;
      nodes.add({std::string(to_string(n.status.level())), bus, node, name,
                 std::string(to_string(x.direction)),
                 fmt::format("{}{}", x.frames, x.exact_count ? "" : "+"),
                 fmt::format("{}", x.records), fmt::format("{}", x.ids),
                 ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.min)),
                 ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.p50)),
                 ms_or_dash(x.gap_ns, static_cast<double>(x.gap_ns.max)),
                 x.direction == Direction::Rx ? silence : "-", first ? messages_of(n.status) : ""});
      first = false;
    }
    if (first) {
      nodes.add({std::string(to_string(n.status.level())), bus, node, name, "-", "0", "0", "0", "-",
                 "-", "-", "-", messages_of(n.status)});
    }
  }
  out += nodes.str();

  if (options.ids) {
    out += "\nIds\n";
    TextTable ids({"BUS", "ID", "NODE", "FUNCTION", "DIR", "FRAMES", "RECORDS", "GAP MIN ms",
                   "GAP p50 ms", "GAP MAX ms", "GAP MEAN ms"},
                  {false, false, true, false, false, true, true, true, true, true, true});
    bool approximate = false;
    for (const IdStats& s : r.snapshot.ids) {
      if (s.gap_ns.count > 0 && !s.gap_exact) approximate = true;
      ids.add({detail::bus_name(s.bus, options.bus_names), detail::format_id(s.id, s.extended),
               format_node(r.node_map, s.node), format_function(r.node_map, s.function),
               std::string(to_string(s.direction)),
               fmt::format("{}{}", s.frames, s.exact_count ? "" : "+"),
               fmt::format("{}", s.records),
               ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.min)),
               ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.p50)),
               ms_or_dash(s.gap_ns, static_cast<double>(s.gap_ns.max)),
               ms_or_dash(s.gap_ns, s.gap_ns.mean)});
    }
    out += ids.str();
    if (approximate) {
      out += "(gap percentiles are upper bounds within 3.1%; min, max and mean are exact)\n";
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// JSON

namespace {

void write_summary(JsonWriter& w, const StatsSummary& s) {
  w.begin_object();
  w.field("count", s.count).field("min", s.min).field("max", s.max).field("mean", s.mean);
  w.field("ewma", s.ewma).field("last", s.last);
  w.field("p50", s.p50).field("p90", s.p90).field("p99", s.p99).field("p999", s.p999);
  w.end_object();
}

void write_status(JsonWriter& w, const Status& s) {
  w.field("status", to_string(s.level()));
  w.key("messages").begin_array();
  for (const StatusMessage& m : s.messages()) {
    w.begin_object().field("level", to_string(m.level)).field("text", m.text).end_object();
  }
  w.end_array();
}

void write_totals(JsonWriter& w, const SnifferTotals& t) {
  w.begin_object();
  w.field("frames", t.frames).field("rx", t.rx).field("tx", t.tx);
  w.field("error_frames", t.error_frames).field("rejected", t.rejected);
  w.field("accepted", t.accepted).field("untracked_ids", t.untracked_ids);
  w.field("untracked_nodes", t.untracked_nodes).field("dropped", t.dropped);
  w.field("filter_changes", t.filter_changes);
  w.end_object();
}

void write_node_stats(JsonWriter& w, const NodeStats& s) {
  w.begin_object();
  w.field("frames", s.frames).field("exact_count", s.exact_count).field("records", s.records);
  w.field("ids", s.ids).field("first_ns", s.first_ns).field("last_ns", s.last_ns);
  w.key("io_ns");
  write_summary(w, s.io_ns);
  w.key("gap_ns");
  write_summary(w, s.gap_ns);
  w.field("gap_exact", s.gap_exact);
  w.end_object();
}

void write_us(JsonWriter& w, const StatsSummary& s) {
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

}  // namespace

namespace detail {

void write_report_members(JsonWriter& w, const CanReport& r,
                          const std::vector<std::string>& bus_names) {
  w.field("time_ns", r.time_ns);
  w.field("node_map", to_string(r.node_map));
  write_status(w, r.status);
  w.field("records", r.snapshot.records);
  w.key("totals");
  write_totals(w, r.snapshot.totals);

  w.key("summary").begin_array();
  for (const CategoryStats& c : r.snapshot.categories) {
    w.begin_object();
    w.field("category", c.name).field("group", c.group).field("direction", to_string(c.direction));
    w.field("nodes", c.nodes).field("frames", c.frames).field("records", c.records);
    w.key("io_us");
    write_us(w, c.io_ns);
    w.key("gap_us");
    write_us(w, c.gap_ns);
    w.end_object();
  }
  w.end_array();

  w.key("nodes").begin_array();
  for (const NodeReport& n : r.nodes) {
    w.begin_object();
    if (n.bus) {
      w.field("bus", *n.bus).field("bus_name", bus_name(*n.bus, bus_names));
    } else {
      w.key("bus").null().key("bus_name").null();
    }
    w.field("node", n.node).field("name", n.name).field("named", n.named);
    w.field("expected", n.expected);
    w.key("groups").begin_array();
    for (const std::string& g : n.groups) w.value(g);
    w.end_array();
    write_status(w, n.status);
    if (n.silence_ns >= 0) {
      w.field("silence_ns", n.silence_ns);
    } else {
      w.key("silence_ns").null();
    }
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
  w.end_array();

  w.key("ids").begin_array();
  for (const IdStats& s : r.snapshot.ids) {
    w.begin_object();
    w.field("bus", s.bus).field("bus_name", bus_name(s.bus, bus_names));
    w.field("id", format_id(s.id, s.extended)).field("id_value", s.id);
    w.field("extended", s.extended).field("direction", to_string(s.direction));
    w.field("node", s.node).field("function", s.function);
    w.field("frames", s.frames).field("exact_count", s.exact_count).field("records", s.records);
    w.field("first_ns", s.first_ns).field("last_ns", s.last_ns);
    w.key("io_ns");
    write_summary(w, s.io_ns);
    w.key("gap_ns");
    write_summary(w, s.gap_ns);
    w.field("gap_exact", s.gap_exact);
    w.end_object();
  }
  w.end_array();

  w.key("sniffers").begin_array();
  for (const SnifferInfo& s : r.snapshot.sniffers) {
    w.begin_object();
    w.field("port_id", s.port_id).field("name", s.name).field("alive", s.alive);
    w.field("node_map", to_string(s.node_map)).field("filter", s.filter);
    w.field("ids", s.ids).field("max_ids", s.max_ids).field("nodes", s.nodes);
    w.field("max_nodes", s.max_nodes).field("port_capacity", s.port_capacity);
    w.key("totals");
    write_totals(w, s.totals);
    w.end_object();
  }
  w.end_array();
}

}  // namespace detail

std::string can_report_json(const CanReport& report, int indent,
                            const std::vector<std::string>& bus_names) {
  JsonWriter w(indent);
  w.begin_object();
  w.field("schema", 1);
  detail::write_report_members(w, report, bus_names);
  w.end_object();
  return w.take();
}

}  // namespace vigil::can
