#include "vigil/can/can_config.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <utility>

#include "vigil/config/load.hpp"
#include "vigil/config/node.hpp"
#include "vigil/config/units.hpp"

namespace vigil::can {

namespace cfg = vigil::config;

std::string_view to_string(LimitStat s) noexcept {
  switch (s) {
    case LimitStat::Last:
      return "last";
    case LimitStat::Mean:
      return "mean";
    case LimitStat::Ewma:
      return "ewma";
    case LimitStat::Max:
      return "max";
    case LimitStat::P50:
      return "p50";
    case LimitStat::P90:
      return "p90";
    case LimitStat::P99:
      return "p99";
    case LimitStat::P999:
      return "p999";
  }
  return "?";
}

Nanos stat_value(const StatsSummary& s, LimitStat stat) noexcept {
  switch (stat) {
    case LimitStat::Last:
      return s.last;
    case LimitStat::Mean:
      return static_cast<Nanos>(std::llround(s.mean));
    case LimitStat::Ewma:
      return static_cast<Nanos>(std::llround(s.ewma));
    case LimitStat::Max:
      return s.max;
    case LimitStat::P50:
      return s.p50;
    case LimitStat::P90:
      return s.p90;
    case LimitStat::P99:
      return s.p99;
    case LimitStat::P999:
      return s.p999;
  }
  return s.max;
}

void LimitOverride::apply_to(Limit& l) const {
  if (enabled && !*enabled) {
    l.warn.reset();
    l.error.reset();
  }
  if (warn) l.warn = warn;
  if (error) l.error = error;
  if (stat) l.stat = *stat;
}

void ThresholdOverrides::apply_to(NodeThresholds& t) const {
  if (never_seen_enabled) t.never_seen_enabled = *never_seen_enabled;
  if (never_seen_level) t.never_seen_level = *never_seen_level;
  if (not_responding_enabled) t.not_responding_enabled = *not_responding_enabled;
  if (not_responding_after_ns) t.not_responding_after_ns = *not_responding_after_ns;
  if (learn_percentile) t.learn.percentile = *learn_percentile;
  if (learn_factor) t.learn.factor = *learn_factor;
  if (learn_floor_ns) t.learn.floor_ns = *learn_floor_ns;
  if (learn_min_gaps) t.learn.min_gaps = *learn_min_gaps;
  if (answer_within_ns) t.answer_within_ns = *answer_within_ns;
  if (not_responding_level) t.not_responding_level = *not_responding_level;
  if (canopen_heartbeat_ns) t.canopen_heartbeat_ns = *canopen_heartbeat_ns;
  if (canopen_not_operational_after_ns) {
    t.canopen_not_operational_after_ns = *canopen_not_operational_after_ns;
  }
  if (canopen_reset_window_ns) t.canopen_reset_window_ns = *canopen_reset_window_ns;
  if (canopen_emergency_level) t.canopen_emergency_level = *canopen_emergency_level;
  if (j1939_dtc_level) t.j1939_dtc_level = *j1939_dtc_level;
  if (j1939_lamp_level) t.j1939_lamp_level = *j1939_lamp_level;
  if (j1939_stop_lamp_level) t.j1939_stop_lamp_level = *j1939_stop_lamp_level;
  read_time.apply_to(t.read_time);
  write_time.apply_to(t.write_time);
  rx_gap.apply_to(t.rx_gap);
  tx_gap.apply_to(t.tx_gap);
}

NodeThresholds CanConfig::thresholds_for(std::uint8_t bus, std::uint32_t node) const {
  NodeThresholds t;
  defaults.apply_to(t);
  for (const GroupConfig& g : groups) {
    if (g.members.contains(bus, node)) g.thresholds.apply_to(t);
  }
  for (const NodeConfig& n : nodes) {
    if (n.node == node && (!n.bus || *n.bus == bus)) n.thresholds.apply_to(t);
  }
  return t;
}

std::vector<GroupSpec> CanConfig::group_specs() const {
  std::vector<GroupSpec> v;
  v.reserve(groups.size());
  for (const GroupConfig& g : groups) v.push_back(g.members);
  return v;
}

const NodeConfig* CanConfig::find_node(std::uint8_t bus, std::uint32_t node) const noexcept {
  // A bus-specific entry wins over an any-bus one.
  const NodeConfig* any = nullptr;
  for (const NodeConfig& n : nodes) {
    if (n.node != node) continue;
    if (n.bus && *n.bus == bus) return &n;
    if (!n.bus && any == nullptr) any = &n;
  }
  return any;
}

ResolvedBus CanConfig::bus_config(std::uint8_t bus) const {
  ResolvedBus r;
  const auto apply = [&](const BusConfig& b) {
    if (b.bitrate) r.settings.bitrate = *b.bitrate;
    if (b.data_bitrate) r.settings.data_bitrate = *b.data_bitrate;
    if (b.protocol) r.settings.protocol = *b.protocol;
    if (b.load_warn) r.load.warn = b.load_warn;
    if (b.load_error) r.load.error = b.load_error;
    if (b.load_stuffing) r.load.stuffing = *b.load_stuffing;
    if (b.load_figure) r.load.figure = *b.load_figure;
  };
  for (const BusConfig& b : buses) {
    if (!b.bus) apply(b);
  }
  for (const BusConfig& b : buses) {
    if (b.bus && *b.bus == bus) apply(b);
  }
  return r;
}

ProtocolOptions CanConfig::protocol_options() const {
  ProtocolOptions o;
  for (const BusConfig& b : buses) {
    if (!b.bus) continue;
    if (std::none_of(o.buses.begin(), o.buses.end(),
                     [&](const auto& e) { return e.first == *b.bus; })) {
      o.buses.emplace_back(*b.bus, bus_config(*b.bus).settings);
    }
  }
  // `all` alone is what a bus without an entry gets.
  ResolvedBus all;
  for (const BusConfig& b : buses) {
    if (b.bus) continue;
    if (b.bitrate) all.settings.bitrate = *b.bitrate;
    if (b.data_bitrate) all.settings.data_bitrate = *b.data_bitrate;
    if (b.protocol) all.settings.protocol = *b.protocol;
  }
  o.all_buses = all.settings;
  for (const GroupConfig& g : groups) {
    if (g.protocol != BusProtocol::CanOpen) continue;
    const std::uint16_t index = g.members.bus ? *g.members.bus : 256;
    auto it = std::find_if(o.canopen_nodes.begin(), o.canopen_nodes.end(),
                           [&](const auto& e) { return e.first == index; });
    if (it == o.canopen_nodes.end()) {
      o.canopen_nodes.emplace_back(index, std::array<std::uint64_t, 2>{});
      it = std::prev(o.canopen_nodes.end());
    }
    for (std::uint32_t n = 1; n < 128; ++n) {
      if (g.members.contains(g.members.bus.value_or(0), n)) {
        it->second[n / 64] |= std::uint64_t{1} << (n % 64);
      }
    }
  }
  return o;
}

namespace {

constexpr std::array<cfg::EnumName<BusProtocol>, 5> kProtocols{{
    {"auto", BusProtocol::Auto},
    {"none", BusProtocol::None},
    {"canopen", BusProtocol::CanOpen},
    {"dronecan", BusProtocol::DroneCan},
    {"j1939", BusProtocol::J1939},
}};

constexpr std::array<cfg::EnumName<Stuffing>, 3> kStuffings{{
    {"none", Stuffing::None},
    {"worst", Stuffing::WorstCase},
    {"exact", Stuffing::Exact},
}};

constexpr std::array<cfg::EnumName<LoadFigure>, 6> kFigures{{
    {"last_second", LoadFigure::LastSecond},
    {"1min", LoadFigure::Avg1m},
    {"5min", LoadFigure::Avg5m},
    {"15min", LoadFigure::Avg15m},
    {"peak", LoadFigure::Peak},
    {"mean", LoadFigure::Mean},
}};

// A bitrate: an integer (bit/s) or one with a k or M suffix ("500k", "1M", "2.5M").
std::optional<std::uint32_t> bitrate_of(const cfg::Node& n) {
  if (!n.is_scalar()) {
    n.error("expected a bitrate such as 500000, '500k' or '1M'");
    return std::nullopt;
  }
  const std::string text = n.get<std::string>();
  double scale = 1;
  std::string digits = text;
  if (!digits.empty() && (digits.back() == 'k' || digits.back() == 'K')) {
    scale = 1e3;
    digits.pop_back();
  } else if (!digits.empty() && digits.back() == 'M') {
    scale = 1e6;
    digits.pop_back();
  }
  char* end = nullptr;
  const double v = digits.empty() ? -1 : std::strtod(digits.c_str(), &end);
  if (digits.empty() || end == nullptr || *end != '\0' || !(v > 0)) {
    n.error(fmt::format("expected a bitrate such as 500000, '500k' or '1M', got '{}'", text));
    return std::nullopt;
  }
  const double bps = v * scale;
  if (bps < 1000 || bps > 100e6 || bps != std::floor(bps)) {
    n.error(fmt::format("must be a whole number of bit/s between 1000 and 100M, got '{}'", text));
    return std::nullopt;
  }
  return static_cast<std::uint32_t>(bps);
}

BusConfig load_bus(const cfg::Node& n, std::optional<std::uint8_t> bus) {
  BusConfig b;
  b.bus = bus;
  n.reject_unknown_keys({"bitrate", "data_bitrate", "protocol", "load", "interface"});
  if (n.has("interface")) {
    // A Linux interface name (IFNAMSIZ 16, with its NUL): the controller's state is read live.
    const auto name_ok = [](const std::string& v) -> std::optional<std::string> {
      if (v.empty() || v.size() > 15) return "must be an interface name of 1 to 15 characters";
      if (v.find_first_of("/ \t:") != std::string::npos) {
        return fmt::format("'{}' is no interface name (no '/', ':' or blank)", v);
      }
      return std::nullopt;
    };
    if (!bus) {
      n["interface"].error("belongs to one bus (buses: {0: {interface: can0}}), not to all");
    } else {
      b.interface = n.required<std::string>("interface", name_ok);
    }
  }
  if (n.has("bitrate")) b.bitrate = bitrate_of(n["bitrate"]);
  if (n.has("data_bitrate")) b.data_bitrate = bitrate_of(n["data_bitrate"]);
  if (n.has("protocol")) b.protocol = n.required_enum("protocol", kProtocols);
  if (const cfg::Node l = n["load"]; l.defined()) {
    l.reject_unknown_keys({"warn", "error", "stuffing", "figure"});
    const auto pct = cfg::in_range(0.0, 1000.0);
    if (l.has("warn")) b.load_warn = l.required<double>("warn", pct);
    if (l.has("error")) b.load_error = l.required<double>("error", pct);
    if (l.has("stuffing")) b.load_stuffing = l.required_enum("stuffing", kStuffings);
    if (l.has("figure")) b.load_figure = l.required_enum("figure", kFigures);
    if (b.load_warn && b.load_error && *b.load_warn > *b.load_error) {
      l["warn"].error(fmt::format("must not be above error ({})", *b.load_error));
    }
  }
  return b;
}

constexpr std::array<cfg::EnumName<NodeMapKind>, 4> kNodeMaps{{
    {"identity", NodeMapKind::Identity},
    {"canopen", NodeMapKind::CanOpen},
    {"j1939", NodeMapKind::J1939},
    {"dronecan", NodeMapKind::DroneCan},
}};

constexpr std::array<cfg::EnumName<StatusLevel>, 3> kLevels{{
    {"OK", StatusLevel::Ok},
    {"WARN", StatusLevel::Warn},
    {"ERROR", StatusLevel::Error},
}};

constexpr std::array<cfg::EnumName<LimitStat>, 8> kStats{{
    {"last", LimitStat::Last},
    {"mean", LimitStat::Mean},
    {"ewma", LimitStat::Ewma},
    {"max", LimitStat::Max},
    {"p50", LimitStat::P50},
    {"p90", LimitStat::P90},
    {"p99", LimitStat::P99},
    {"p999", LimitStat::P999},
}};

constexpr std::array<cfg::EnumName<Direction>, 2> kDirections{{
    {"rx", Direction::Rx},
    {"tx", Direction::Tx},
}};

enum class Format : std::uint8_t { Standard, Extended };
constexpr std::array<cfg::EnumName<Format>, 2> kFormats{{
    {"standard", Format::Standard},
    {"extended", Format::Extended},
}};

// Check: at most `max`, written in hex ("must be at most 0x1FFFFFFF").
auto at_most_hex(std::uint32_t max) {
  return [max](std::uint32_t v) -> std::optional<std::string> {
    if (v <= max) return std::nullopt;
    return fmt::format("must be at most 0x{:X}", max);
  };
}

// One integer, or a sequence of them, each checked.
template <class C>
std::vector<std::uint32_t> u32_list(const cfg::Node& n, const C& check) {
  std::vector<std::uint32_t> out;
  if (n.is_sequence()) {
    for (const cfg::Node& e : n.elements()) out.push_back(e.get<std::uint32_t>(check));
  } else {
    out.push_back(n.get<std::uint32_t>(check));
  }
  return out;
}

// `[lo, hi]`, each checked, lo <= hi.
template <class C>
std::optional<std::pair<std::uint32_t, std::uint32_t>> u32_range(const cfg::Node& n,
                                                                 const C& check) {
  if (!n.is_sequence()) {
    if (n.defined()) n.error("expected a sequence [lo, hi]");
    return std::nullopt;
  }
  const std::vector<cfg::Node> items = n.elements();
  if (items.size() != 2) {
    n.error(fmt::format("expected two values [lo, hi], got {}", items.size()));
    return std::nullopt;
  }
  const auto lo = items[0].get<std::uint32_t>(check);
  const auto hi = items[1].get<std::uint32_t>(check);
  if (lo > hi) {
    items[0].error(fmt::format("lo (0x{:X}) must not be above hi (0x{:X})", lo, hi));
    return std::nullopt;
  }
  return std::make_pair(lo, hi);
}

std::vector<std::uint8_t> bus_list(const cfg::Node& n) {
  std::vector<std::uint8_t> out;
  const auto check = cfg::in_range<unsigned>(0, 255);
  if (n.is_sequence()) {
    for (const cfg::Node& e : n.elements())
      out.push_back(static_cast<std::uint8_t>(e.get<unsigned>(check)));
  } else {
    out.push_back(static_cast<std::uint8_t>(n.get<unsigned>(check)));
  }
  return out;
}

FilterExpr payload_condition(const cfg::Node& n) {
  n.reject_unknown_keys({"byte", "value", "mask"});
  const auto index = n.required<unsigned>("byte", cfg::in_range<unsigned>(0, 63));
  const auto value = n.required<unsigned>("value", cfg::in_range<unsigned>(0, 255));
  const auto mask = n.optional<unsigned>("mask", 0xFF, cfg::in_range<unsigned>(0, 255));
  return match::payload_byte(index, value, mask);
}

LimitOverride load_limit(const cfg::Node& n) {
  LimitOverride l;
  if (!n.defined()) return l;
  n.reject_unknown_keys({"enabled", "warn", "error", "stat"});
  if (n.has("enabled")) l.enabled = n.required<bool>("enabled");
  if (n.has("warn")) l.warn = n.required_duration("warn");
  if (n.has("error")) l.error = n.required_duration("error");
  if (n.has("stat")) l.stat = n.required_enum("stat", kStats);
  if (l.warn && l.error && *l.warn > *l.error) {
    n["warn"].error(fmt::format("must not be above error ({})", cfg::format_duration(*l.error)));
  }
  return l;
}

}  // namespace

FilterExpr load_filter(const cfg::Node& n) {
  if (!n.defined() || n.is_null()) return match::accept_all();
  if (!n.is_mapping()) {
    n.error("expected a mapping of conditions");
    return match::accept_all();
  }
  n.reject_unknown_keys({"all", "any", "not", "bus", "ids", "id_range", "id_mask", "nodes",
                         "node_range", "functions", "format", "direction", "fd", "remote",
                         "payload"});
  std::vector<FilterExpr> parts;
  // Conditions in file order, so that the compiled program follows what the user wrote.
  for (const auto& [key, value] : n.entries()) {
    if (key == "all" || key == "any") {
      std::vector<FilterExpr> children;
      if (!value.is_sequence() && !value.is_null()) {
        value.error("expected a sequence of filters");
        continue;
      }
      for (const cfg::Node& e : value.elements()) children.push_back(load_filter(e));
      parts.push_back(key == "all" ? match::all_of(std::move(children))
                                   : match::any_of(std::move(children)));
    } else if (key == "not") {
      parts.push_back(!load_filter(value));
    } else if (key == "bus") {
      parts.push_back(match::bus(bus_list(value)));
    } else if (key == "ids") {
      parts.push_back(match::ids(u32_list(value, at_most_hex(kMaxExtendedId))));
    } else if (key == "id_range") {
      if (auto r = u32_range(value, at_most_hex(kMaxExtendedId))) {
        parts.push_back(match::id_range(r->first, r->second));
      }
    } else if (key == "id_mask") {
      value.reject_unknown_keys({"id", "mask"});
      const auto id = value.required<std::uint32_t>("id", at_most_hex(kMaxExtendedId));
      const auto mask = value.required<std::uint32_t>("mask", at_most_hex(kMaxExtendedId));
      parts.push_back(match::id_mask(id, mask));
    } else if (key == "nodes") {
      parts.push_back(match::nodes(u32_list(value, at_most_hex(0xFFFFFFFFU))));
    } else if (key == "node_range") {
      if (auto r = u32_range(value, at_most_hex(0xFFFFFFFFU))) {
        parts.push_back(match::node_range(r->first, r->second));
      }
    } else if (key == "functions") {
      parts.push_back(match::functions(u32_list(value, at_most_hex(0xFFFFFFFFU))));
    } else if (key == "format") {
      parts.push_back(value.get_enum(kFormats) == Format::Extended ? match::extended()
                                                                   : match::standard());
    } else if (key == "direction") {
      parts.push_back(match::direction(value.get_enum(kDirections)));
    } else if (key == "fd") {
      parts.push_back(value.get<bool>() ? match::fd() : !match::fd());
    } else if (key == "remote") {
      parts.push_back(value.get<bool>() ? match::remote() : !match::remote());
    } else if (key == "payload") {
      if (value.is_sequence()) {
        for (const cfg::Node& e : value.elements()) parts.push_back(payload_condition(e));
      } else {
        parts.push_back(payload_condition(value));
      }
    }
  }
  if (parts.empty()) return match::accept_all();
  if (parts.size() == 1) return parts.front();
  return match::all_of(std::move(parts));
}

ThresholdOverrides load_thresholds(const cfg::Node& n) {
  ThresholdOverrides t;
  if (!n.defined()) return t;
  n.reject_unknown_keys({"never_seen", "not_responding", "read_time", "write_time", "rx_gap",
                         "tx_gap", "canopen", "j1939"});
  if (const cfg::Node j = n["j1939"]; j.defined()) {
    j.reject_unknown_keys({"dtc_level", "lamp_level", "stop_lamp_level"});
    if (j.has("dtc_level")) t.j1939_dtc_level = j.required_enum("dtc_level", kLevels);
    if (j.has("lamp_level")) t.j1939_lamp_level = j.required_enum("lamp_level", kLevels);
    if (j.has("stop_lamp_level")) {
      t.j1939_stop_lamp_level = j.required_enum("stop_lamp_level", kLevels);
    }
  }
  if (const cfg::Node co = n["canopen"]; co.defined()) {
    co.reject_unknown_keys(
        {"heartbeat", "not_operational_after", "reset_window", "emergency_level"});
    if (const cfg::Node hb = co["heartbeat"]; hb.defined()) {
      if (hb.is_scalar() && hb.get<std::string>() == "learned") {
        t.canopen_heartbeat_ns = std::optional<Nanos>{};
      } else {
        t.canopen_heartbeat_ns =
            std::optional<Nanos>{co.required_duration("heartbeat", cfg::positive())};
      }
    }
    if (const cfg::Node no = co["not_operational_after"]; no.defined()) {
      if (no.is_scalar() && no.get<std::string>() == "never") {
        t.canopen_not_operational_after_ns = std::optional<Nanos>{};
      } else {
        t.canopen_not_operational_after_ns =
            std::optional<Nanos>{co.required_duration("not_operational_after", cfg::positive())};
      }
    }
    if (co.has("reset_window")) {
      t.canopen_reset_window_ns = co.required_duration("reset_window", cfg::non_negative());
    }
    if (co.has("emergency_level")) {
      t.canopen_emergency_level = co.required_enum("emergency_level", kLevels);
    }
  }
  if (const cfg::Node ns = n["never_seen"]; ns.defined()) {
    ns.reject_unknown_keys({"enabled", "level"});
    if (ns.has("enabled")) t.never_seen_enabled = ns.required<bool>("enabled");
    if (ns.has("level")) t.never_seen_level = ns.required_enum("level", kLevels);
  }
  if (const cfg::Node nr = n["not_responding"]; nr.defined()) {
    nr.reject_unknown_keys({"enabled", "after", "level", "percentile", "factor", "floor",
                            "min_gaps", "answer_within"});
    if (nr.has("enabled")) t.not_responding_enabled = nr.required<bool>("enabled");
    if (const cfg::Node after = nr["after"]; after.defined()) {
      const std::string text = after.is_scalar() ? after.get<std::string>() : std::string();
      if (text == "learned") {
        t.not_responding_after_ns = std::optional<Nanos>{};
      } else if (after.is_scalar() && !cfg::parse_duration(text).has_value() &&
                 !std::isdigit(static_cast<unsigned char>(text.empty() ? ' ' : text[0]))) {
        after.error(
            fmt::format("expected a duration such as '100ms', or 'learned', got '{}'", text));
      } else {
        t.not_responding_after_ns =
            std::optional<Nanos>{nr.required_duration("after", cfg::positive())};
      }
    }
    if (nr.has("percentile")) t.learn_percentile = nr.required_enum("percentile", kStats);
    if (nr.has("factor")) t.learn_factor = nr.required<double>("factor", cfg::in_range(1.0, 100.0));
    if (nr.has("floor")) t.learn_floor_ns = nr.required_duration("floor", cfg::non_negative());
    if (nr.has("min_gaps")) {
      t.learn_min_gaps =
          nr.required<std::uint32_t>("min_gaps", cfg::in_range<std::uint32_t>(1, 1000000));
    }
    if (nr.has("answer_within")) {
      t.answer_within_ns = nr.required_duration("answer_within", cfg::positive());
    }
    if (nr.has("level")) t.not_responding_level = nr.required_enum("level", kLevels);
  }
  t.read_time = load_limit(n["read_time"]);
  t.write_time = load_limit(n["write_time"]);
  t.rx_gap = load_limit(n["rx_gap"]);
  t.tx_gap = load_limit(n["tx_gap"]);
  return t;
}

CanConfig load_can_config(const cfg::Node& root) {
  CanConfig c;
  root.reject_unknown_keys({"node_map", "filter", "defaults", "nodes", "groups", "buses"});
  c.node_map = root.optional_enum("node_map", NodeMapKind::Identity, kNodeMaps);
  c.filter = load_filter(root["filter"]);
  // Compile now, so that a filter the sniffer would refuse fails the load, not the reload. Its
  // operands were checked above, with their positions; this catches what remains (nesting).
  if (!root.has_errors()) {
    if (auto compiled = Filter::compile(c.filter); !compiled) {
      root["filter"].error(compiled.error().message);
    }
  }
  c.defaults = load_thresholds(root["defaults"]);

  const auto bus_check = cfg::in_range<unsigned>(0, 255);
  for (const auto& [name, n] : root["nodes"].entries()) {
    n.reject_unknown_keys({"node", "bus", "expected", "thresholds"});
    NodeConfig nc;
    nc.name = name;
    nc.node = n.required<std::uint32_t>("node");
    if (n.has("bus")) nc.bus = static_cast<std::uint8_t>(n.required<unsigned>("bus", bus_check));
    nc.expected = n.optional("expected", true);
    nc.thresholds = load_thresholds(n["thresholds"]);
    c.nodes.push_back(std::move(nc));
  }
  for (const auto& [name, g] : root["groups"].entries()) {
    g.reject_unknown_keys({"nodes", "node_range", "bus", "expected", "thresholds", "protocol"});
    GroupConfig gc;
    gc.members.name = name;
    if (g.has("nodes")) gc.members.nodes = u32_list(g["nodes"], at_most_hex(0xFFFFFFFFU));
    if (g.has("node_range")) {
      if (auto r = u32_range(g["node_range"], at_most_hex(0xFFFFFFFFU))) {
        gc.members.node_ranges.push_back(*r);
      }
    }
    if (!g.has("nodes") && !g.has("node_range") && g.is_mapping()) {
      g.error("a group needs 'nodes' or 'node_range'");
    }
    if (g.has("bus")) {
      gc.members.bus = static_cast<std::uint8_t>(g.required<unsigned>("bus", bus_check));
    }
    gc.expected = g.optional("expected", true);
    gc.thresholds = load_thresholds(g["thresholds"]);
    if (g.has("protocol")) {
      gc.protocol = g.required_enum("protocol", kProtocols);
      if (gc.protocol == BusProtocol::DroneCan || gc.protocol == BusProtocol::J1939) {
        // DroneCAN and J1939 are a bus's protocol (`buses:`), not a group's.
        g["protocol"].error(
            fmt::format("a group's protocol is canopen, none or auto, got '{}' "
                        "(set it on the bus: buses: {{0: {{protocol: {}}}}})",
                        to_string(gc.protocol), to_string(gc.protocol)));
      }
    }
    c.groups.push_back(std::move(gc));
  }
  for (const auto& [key, b] : root["buses"].entries()) {
    std::optional<std::uint8_t> bus;
    if (key != "all") {
      char* end = nullptr;
      const long v = std::strtol(key.c_str(), &end, 0);
      if (key.empty() || end == nullptr || *end != '\0' || v < 0 || v > 255) {
        b.error(fmt::format("'{}': a bus is 'all' or a bus index 0-255", key));
        continue;
      }
      bus = static_cast<std::uint8_t>(v);
    }
    c.buses.push_back(load_bus(b, bus));
  }
  return c;
}

expected<CanConfig, cfg::ConfigErrors> load_can_config_file(const std::filesystem::path& path) {
  return cfg::load_file(path, [](const cfg::Node& root) { return load_can_config(root); });
}

expected<CanConfig, cfg::ConfigErrors> load_can_config_string(std::string_view text,
                                                              std::string name) {
  return cfg::load_string(text, std::move(name),
                          [](const cfg::Node& root) { return load_can_config(root); });
}

}  // namespace vigil::can
