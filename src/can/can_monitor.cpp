#include "vigil/can/can_monitor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <utility>

#include "vigil/config/units.hpp"
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

}  // namespace vigil::can
