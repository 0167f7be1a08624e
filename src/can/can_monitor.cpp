#include "vigil/can/can_monitor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
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

std::string plural(std::uint64_t n, std::string_view word) {
  return fmt::format("{} {}{}", n, word, n == 1 ? "" : "s");
}

std::string duration(Nanos ns) { return format_nanos(static_cast<double>(ns)); }

std::string id_text(const IdStats& s) {
  return s.extended ? fmt::format("{:08X}", s.id) : fmt::format("{:03X}", s.id);
}

// The node a request asks: the addressee of a frame "to the node", else the peer.
std::uint32_t asked_node(const IdStats& s) {
  return (s.flags & node_flags::kToNode) != 0 ? s.node : s.peer;
}

// The time up to which the frames of id key `s` have been seen: the tables were read then (the
// records were drained then, for a key the sniffer's table could not hold). Silence is measured
// up to it, never up to the monitor's clock: a frame handled after it may wait unread.
Nanos observed_for(const CanReport& r, const IdStats& s) {
  if (s.exact_count || r.snapshot.drained_ns < 0) return r.observed_ns;
  return std::min(r.observed_ns, r.snapshot.drained_ns);
}

// Where the ids of one (bus, node) are, and what the monitor learns from them.
struct NodeIds {
  std::vector<std::size_t> from;  // Rx data ids the node sent
  Nanos observed = -1;            // the earliest time up to which the ids below were seen
  Nanos last_from = -1;           // latest of them
  Nanos last_answer = -1;         // latest answer among them
  Nanos last_request = -1;        // latest request to the node (any direction)
  std::uint64_t requests = 0;     // frames of requests to the node
  std::uint64_t to_node = 0;      // frames addressed to it (Rx) or sent to it (Tx)
};

// Classifies every id key and learns the periods of the periodic ones (CanReport::ids).
void judge_ids(CanReport& r, const CanConfig& cfg) {
  const auto& ids = r.snapshot.ids;
  // Ids whose remote frames were seen: their data frames answer those requests.
  std::set<std::tuple<std::uint8_t, std::uint32_t, bool>> asked;
  for (const IdStats& s : ids) {
    if (s.rtr) asked.emplace(s.bus, s.id, s.extended);
  }
  r.ids.resize(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const IdStats& s = ids[i];
    IdVerdict& v = r.ids[i];
    if (s.direction == Direction::Rx) {
      v.silence_ns = std::max<Nanos>(0, observed_for(r, s) - s.last_ns);
    }
    if (s.error) {
      v.traffic = Traffic::Errors;
    } else if (s.node == kNoNode) {
      v.traffic = Traffic::Network;
    } else if (s.direction == Direction::Tx) {
      v.traffic = Traffic::Sent;
    } else if ((s.flags & node_flags::kToNode) != 0) {
      v.traffic = Traffic::ToNode;
    } else if ((s.flags & node_flags::kRequest) != 0) {
      v.traffic = Traffic::Requests;
    } else if ((s.flags & node_flags::kResponse) != 0 ||
               asked.contains({s.bus, s.id, s.extended})) {
      v.traffic = Traffic::OnRequest;
    } else if (const BusProtocolStats* b = r.snapshot.protocol.find_bus(s.bus);
               b != nullptr && event_driven(b->settings.protocol, s.id, s.extended)) {
      v.traffic = Traffic::Events;
    } else {
      const LearnRule& rule = cfg.thresholds_for(s.bus, s.node).learn;
      if (s.gap_ns.count < rule.min_gaps) {
        v.traffic = Traffic::Learning;
      } else {
        v.traffic = Traffic::Periodic;
        v.period_ns = stat_value(s.gap_ns, rule.percentile);
        const auto scaled = static_cast<Nanos>(rule.factor * static_cast<double>(v.period_ns));
        v.limit_ns = std::max(rule.floor_ns, scaled);
        v.overdue = v.silence_ns > v.limit_ns;
      }
    }
  }
}

NodeIds ids_of(const CanReport& r, std::optional<std::uint8_t> bus, std::uint32_t node) {
  NodeIds n;
  const auto& ids = r.snapshot.ids;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const IdStats& s = ids[i];
    if (s.error || (bus && s.bus != *bus)) continue;
    const IdVerdict& v = r.ids[i];
    const auto seen = [&] {
      const Nanos t = observed_for(r, s);
      n.observed = n.observed < 0 ? t : std::min(n.observed, t);
    };
    if (s.request() && asked_node(s) == node) {
      seen();
      n.last_request = std::max(n.last_request, s.last_ns);
      n.requests += s.frames;
    }
    if (s.node != node) continue;
    if (v.traffic == Traffic::ToNode || v.traffic == Traffic::Sent) n.to_node += s.frames;
    if (v.traffic == Traffic::Periodic || v.traffic == Traffic::Learning ||
        v.traffic == Traffic::OnRequest || v.traffic == Traffic::Requests ||
        v.traffic == Traffic::Events) {
      seen();
      n.from.push_back(i);
      n.last_from = std::max(n.last_from, s.last_ns);
      if (v.traffic == Traffic::OnRequest) n.last_answer = std::max(n.last_answer, s.last_ns);
    }
  }
  return n;
}

void not_responding(NodeReport& n, std::string message) {
  n.liveness = Liveness::NotResponding;
  n.status.merge(n.thresholds.not_responding_level, std::move(message));
}

void builtin_checks(NodeReport& n, const CanReport& r) {
  const NodeThresholds& t = n.thresholds;
  const NodeIds ids = ids_of(r, n.bus, n.node);
  n.to_node_frames = ids.to_node;
  const bool heard = ids.last_from >= 0;
  if (heard) n.silence_ns = std::max<Nanos>(0, ids.observed - ids.last_from);
  // A request is answered by a later answer of the node (a response, an RTR answer).
  const bool pending = ids.last_request >= 0 && ids.last_request > ids.last_answer;
  if (pending) n.unanswered_ns = std::max<Nanos>(0, ids.observed - ids.last_request);
  const bool unanswered = pending && n.unanswered_ns > t.answer_within_ns;

  if (!heard) {
    n.liveness = Liveness::NeverSeen;
    if (n.expected && t.never_seen_enabled) {
      if (ids.to_node > 0) {
        n.status.merge(t.never_seen_level,
                       fmt::format("not initialized: never answered ({} sent to it)",
                                   plural(ids.to_node, "frame")));
      } else {
        n.status.merge(t.never_seen_level, "not initialized: never seen");
      }
    } else if (unanswered) {
      n.status.merge(StatusLevel::Ok,
                     fmt::format("never answered {} to it", plural(ids.requests, "request")));
    }
  } else if (!t.not_responding_enabled) {
    n.liveness = Liveness::Responding;
  } else if (t.not_responding_after_ns) {
    n.silence_limit_ns = *t.not_responding_after_ns;
    n.liveness = Liveness::Responding;
    if (n.silence_ns > n.silence_limit_ns) {
      not_responding(n,
                     fmt::format("not responding: silent for {} (limit {})", duration(n.silence_ns),
                                 config::format_duration(n.silence_limit_ns)));
    }
  } else {
    // Learned: the largest limit of the node's periodic ids.
    std::size_t learning = 0;
    std::size_t answers = 0;  // ids on request or asking
    for (const std::size_t i : ids.from) {
      const IdVerdict& v = r.ids[i];
      if (v.traffic == Traffic::Learning) ++learning;
      if (v.traffic == Traffic::OnRequest || v.traffic == Traffic::Requests) ++answers;
      if (v.traffic == Traffic::Periodic && v.limit_ns > n.silence_limit_ns) {
        n.silence_limit_ns = v.limit_ns;
        n.limit_id = static_cast<std::ptrdiff_t>(i);
      }
    }
    n.limit_learned = n.limit_id >= 0;
    if (n.limit_learned) {
      n.liveness = Liveness::Responding;
      if (n.silence_ns > n.silence_limit_ns) {
        const IdStats& s = r.snapshot.ids[static_cast<std::size_t>(n.limit_id)];
        const IdVerdict& v = r.ids[static_cast<std::size_t>(n.limit_id)];
        const bool floor = v.limit_ns == t.learn.floor_ns;
        not_responding(
            n,
            fmt::format("not responding: silent for {} (limit {}, learned: {} x {} gap {} of {}{})",
                        duration(n.silence_ns), duration(n.silence_limit_ns),
                        fmt::format("{:g}", t.learn.factor), to_string(t.learn.percentile),
                        duration(v.period_ns), id_text(s), floor ? ", at the floor" : ""));
      }
    } else if (learning > 0) {
      n.liveness = Liveness::Learning;
      std::uint64_t most = 0;
      for (const std::size_t i : ids.from) {
        if (r.ids[i].traffic == Traffic::Learning) {
          most = std::max(most, r.snapshot.ids[i].gap_ns.count);
        }
      }
      n.status.merge(StatusLevel::Ok,
                     fmt::format("learning its period: {} of {} gaps", most, t.learn.min_gaps));
    } else if (answers > 0) {
      n.liveness = Liveness::OnRequest;  // it only answers (or asks): silence is no fault
    } else {
      n.liveness = Liveness::OnEvent;  // only protocol events (emergencies ...): likewise
    }
  }
  if (heard && unanswered) {
    const std::string what =
        fmt::format("request unanswered for {} (limit {})", duration(n.unanswered_ns),
                    config::format_duration(t.answer_within_ns));
    if (n.liveness == Liveness::Responding && t.not_responding_enabled) {
      n.status.merge(StatusLevel::Warn, "not answering: " + what);
    } else if (t.not_responding_enabled && n.liveness != Liveness::NotResponding) {
      not_responding(n, "not responding: " + what);
    }
  }
  check_limit(n.status, "read time", t.read_time, n.rx, true);
  check_limit(n.status, "write time", t.write_time, n.tx, true);
  check_limit(n.status, "rx gap", t.rx_gap, n.rx, false);
  check_limit(n.status, "tx gap", t.tx_gap, n.tx, false);
}

void overall(CanReport& r, const CanMonitorOptions& options) {
  const SnifferTotals& t = r.snapshot.totals;
  if (options.stale_after_ns > 0 && r.observer_lag_ns > options.stale_after_ns) {
    // The observer's delay is its own finding: the nodes are judged up to what was observed.
    r.status.merge(StatusLevel::Stale,
                   fmt::format("CAN supervisor late: frames observed up to {} ago (limit {}); "
                               "node silences are judged up to then",
                               duration(r.observer_lag_ns), duration(options.stale_after_ns)));
  }
  if (t.frames == 0) {
    r.status.merge(StatusLevel::Warn, "no frames: nothing to judge");
  } else if (t.accepted == 0) {
    std::string why;
    if (t.error_frames > 0) why = fmt::format("{}", plural(t.error_frames, "error frame"));
    if (t.rejected > 0) {
      why += fmt::format("{}{} rejected by the filter", why.empty() ? "" : ", ", t.rejected);
    }
    r.status.merge(StatusLevel::Warn,
                   fmt::format("no valid frames: {} of {} seen ({})", "none", t.frames, why));
  }
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
  for (const BusReport& b : r.buses) {
    if (b.status.level() == StatusLevel::Ok) continue;
    r.status.merge(b.status.level(), fmt::format("bus {}: {}", b.bus, b.status.summary()));
  }
  if (const std::size_t learning = r.learning_count(); learning > 0) {
    r.status.merge(StatusLevel::Ok,
                   fmt::format("{} still learning {} period (not judged yet)",
                               plural(learning, "node"), learning == 1 ? "its" : "their"));
  }
  if (t.untracked_ids > 0) {
    r.status.merge(
        StatusLevel::Warn,
        fmt::format("{} not counted per id: more distinct ids than the sniffer's id "
                    "table holds ({} per sniffer)",
                    plural(t.untracked_ids, "frame"),
                    r.snapshot.sniffers.empty() ? 0 : r.snapshot.sniffers.front().max_ids));
  }
  if (t.untracked_nodes > 0) {
    r.status.merge(
        StatusLevel::Warn,
        fmt::format("{} not counted per node: more distinct nodes than the sniffer's "
                    "node table holds ({} per sniffer)",
                    plural(t.untracked_nodes, "frame"),
                    r.snapshot.sniffers.empty() ? 0 : r.snapshot.sniffers.front().max_nodes));
  }
  const std::uint64_t lost = r.snapshot.unaggregated_id_records -
                             std::min(r.snapshot.unaggregated_id_records, t.untracked_ids);
  if (lost > 0) {
    r.status.merge(StatusLevel::Warn,
                   fmt::format("{} not timed per id: the aggregator holds {} ids at most",
                               plural(lost, "record"), r.snapshot.max_ids));
  }
  if (t.error_frames > 0) {
    r.status.merge(StatusLevel::Warn, plural(t.error_frames, "error frame"));
  }
  if (t.dropped > 0) {
    r.status.merge(StatusLevel::Ok,
                   fmt::format("timing sampled: {} of {} dropped by full ports (counts are exact)",
                               plural(t.dropped, "record"), t.accepted + t.error_frames));
  }
}

}  // namespace

std::string_view to_string(Liveness l) noexcept {
  switch (l) {
    case Liveness::NoNode:
      return "no node";
    case Liveness::NeverSeen:
      return "never seen";
    case Liveness::Learning:
      return "learning";
    case Liveness::OnRequest:
      return "on request";
    case Liveness::Responding:
      return "responding";
    case Liveness::NotResponding:
      return "not responding";
    case Liveness::OnEvent:
      return "on event";
  }
  return "?";
}

std::string_view to_string(Traffic t) noexcept {
  switch (t) {
    case Traffic::Periodic:
      return "periodic";
    case Traffic::Learning:
      return "learning";
    case Traffic::OnRequest:
      return "on request";
    case Traffic::Requests:
      return "requests";
    case Traffic::ToNode:
      return "to node";
    case Traffic::Network:
      return "network";
    case Traffic::Sent:
      return "sent";
    case Traffic::Errors:
      return "errors";
    case Traffic::Events:
      return "events";
  }
  return "?";
}

bool event_driven(BusProtocol p, std::uint32_t id, bool extended) noexcept {
  switch (p) {
    case BusProtocol::CanOpen:
      return !extended &&
             (id == 0x000 || (id >= 0x081 && id <= 0x0FF) || (id >= 0x581 && id <= 0x5FF) ||
              (id >= 0x601 && id <= 0x67F) || id == 0x7E4 || id == 0x7E5);
    case BusProtocol::J1939:
      if (!extended) return false;
      switch (decode_j1939(id).pgn) {
        case 0xEC00:  // TP.CM
        case 0xEB00:  // TP.DT
        case 0xC800:  // ETP.CM
        case 0xC700:  // ETP.DT
        case 0xEE00:  // address claimed
        case 0xEA00:  // request
        case 0xE800:  // acknowledgement
        case 0xFECB:  // DM2, sent on request
          return true;
        default:
          return false;
      }
    case BusProtocol::DroneCan:
      return extended && (id & 0x80U) != 0;
    default:
      return false;
  }
}

std::size_t CanReport::node_count() const noexcept {
  return static_cast<std::size_t>(
      std::count_if(nodes.begin(), nodes.end(), [](const NodeReport& n) { return n.is_node(); }));
}

std::size_t CanReport::ok_count() const noexcept {
  return static_cast<std::size_t>(
      std::count_if(nodes.begin(), nodes.end(), [](const NodeReport& n) {
        return n.is_node() && n.status.ok() && n.liveness != Liveness::Learning;
      }));
}

std::size_t CanReport::learning_count() const noexcept {
  return static_cast<std::size_t>(std::count_if(
      nodes.begin(), nodes.end(),
      [](const NodeReport& n) { return n.liveness == Liveness::Learning && n.status.ok(); }));
}

const NodeReport* CanReport::find(std::uint8_t bus, std::uint32_t node) const noexcept {
  for (const NodeReport& n : nodes) {
    if (n.bus && *n.bus == bus && n.node == node) return &n;
  }
  return nullptr;
}

const BusReport* CanReport::find_bus(std::uint8_t bus) const noexcept {
  for (const BusReport& b : buses) {
    if (b.bus == bus) return &b;
  }
  return nullptr;
}

const NodeReport* CanReport::find(std::string_view name) const noexcept {
  for (const NodeReport& n : nodes) {
    if (n.name == name) return &n;
  }
  return nullptr;
}

CanMonitor::CanMonitor(CanConfig config, CanMonitorOptions options)
    : options_(options), config_(std::make_shared<const CanConfig>(std::move(config))) {}

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

void CanMonitor::set_links(std::vector<LinkReading> links) {
  std::lock_guard lock(mutex_);
  links_ = std::move(links);
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

namespace {

// Nodes by (bus, node).
using NodesByKey = std::map<std::pair<std::uint8_t, std::uint32_t>, NodeReport>;

// The snapshot's nodes, with their statistics in each direction.
NodesByKey seen_nodes(const CanSnapshot& snapshot) {
  NodesByKey seen;
  for (const NodeStats& s : snapshot.nodes) {
    NodeReport& n = seen[{s.bus, s.node}];
    n.bus = s.bus;
    n.node = s.node;
    (s.direction == Direction::Rx ? n.rx : n.tx) = s;
  }
  return seen;
}

// Marks the nodes `cfg` expects (named ones, and the explicit members of groups) in `seen`: one
// on a given bus is added there when not seen; one on any bus marks every node of its number,
// and is returned when there is none.
std::vector<NodeReport> mark_expected(const CanConfig& cfg, NodesByKey& seen) {
  std::vector<std::pair<std::optional<std::uint8_t>, std::uint32_t>> expected;
  for (const NodeConfig& n : cfg.nodes) {
    if (n.expected) expected.emplace_back(n.bus, n.node);
  }
  for (const GroupConfig& g : cfg.groups) {
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
  return unseen;
}

// A node's name (configured, or as the node map writes it), groups and thresholds.
void configure(NodeReport& n, const CanConfig& cfg, NodeMapKind node_map) {
  const NodeConfig* named = nullptr;
  if (n.bus) {
    named = cfg.find_node(*n.bus, n.node);
  } else {
    for (const NodeConfig& c : cfg.nodes) {
      if (!c.bus && c.node == n.node) {
        named = &c;
        break;
      }
    }
  }
  n.named = named != nullptr;
  n.name = named != nullptr ? named->name : format_node(node_map, n.node);
  for (const GroupConfig& g : cfg.groups) {
    const bool member = n.bus ? g.members.contains(*n.bus, n.node)
                              : !g.members.bus && g.members.contains(0, n.node);
    if (member) n.groups.push_back(g.members.name);
  }
  n.thresholds = resolve(cfg, n.bus, n.node);
}

// CANopen (CiA 301): resets, emergencies, time outside operational, heartbeat consumer,
// node-guarding toggle bit, malformed payloads.
void canopen_checks(NodeReport& n, const CanReport& r) {
  if (r.node_map != NodeMapKind::CanOpen || !n.bus || n.node == 0 || n.node > 127) return;
  const canopen::NodeStats* co = r.snapshot.protocol.find_canopen(*n.bus, n.node);
  if (co == nullptr) return;
  n.canopen = *co;
  const NodeThresholds& t = n.thresholds;
  const Nanos at = r.observed_ns;
  if (co->resets > 0 && t.canopen_reset_window_ns > 0 &&
      at - co->last_reset_ns <= t.canopen_reset_window_ns) {
    n.status.merge(StatusLevel::Warn,
                   fmt::format("node reset: boot-up of a running node {} ago ({} reset{} so far)",
                               duration(std::max<Nanos>(0, at - co->last_reset_ns)), co->resets,
                               co->resets == 1 ? "" : "s"));
  }
  if (co->last_emergency && co->last_emergency->code != 0) {
    n.status.merge(t.canopen_emergency_level,
                   fmt::format("emergency {}", co->last_emergency->describe()));
  }
  if (t.canopen_not_operational_after_ns && co->state != canopen::NmtState::Operational &&
      co->state != canopen::NmtState::Unknown && co->operational_left_ns >= 0) {
    const Nanos out = at - co->operational_left_ns;
    if (out > *t.canopen_not_operational_after_ns) {
      n.status.merge(
          StatusLevel::Warn,
          fmt::format("not operational: {} for {} (limit {})", canopen::to_string(co->state),
                      duration(out), config::format_duration(*t.canopen_not_operational_after_ns)));
    }
  }
  if (t.canopen_heartbeat_ns && co->last_heartbeat_ns >= 0 && t.not_responding_enabled) {
    const Nanos since = at - co->last_heartbeat_ns;
    if (since > *t.canopen_heartbeat_ns) {
      n.status.merge(t.not_responding_level,
                     fmt::format("heartbeat lost: none for {} (consumer time {})", duration(since),
                                 config::format_duration(*t.canopen_heartbeat_ns)));
    }
  }
  if (co->toggle_errors > 0) {
    n.status.merge(StatusLevel::Warn,
                   fmt::format("node guarding: toggle bit did not alternate in {} of {} "
                               "responses",
                               co->toggle_errors, co->guard_responses));
  }
  if (co->malformed_emergencies + co->malformed_heartbeats > 0) {
    n.status.merge(
        StatusLevel::Ok,
        fmt::format("malformed CANopen payloads: {} emergenc{}, {} heartbeat{} "
                    "(latest: {})",
                    co->malformed_emergencies, co->malformed_emergencies == 1 ? "y" : "ies",
                    co->malformed_heartbeats, co->malformed_heartbeats == 1 ? "" : "s",
                    co->last_malformed));
  }
}

// DroneCAN NodeStatus: health WARNING is WARN, ERROR and CRITICAL are ERROR; a restart (uptime
// went back) WARN for `canopen_reset_window_ns`.
void dronecan_checks(NodeReport& n, const CanReport& r) {
  if (r.node_map != NodeMapKind::DroneCan || !n.bus || n.node == 0 || n.node > 127) return;
  const dronecan::NodeStats* dc = r.snapshot.protocol.find_dronecan(*n.bus, n.node);
  if (dc == nullptr) return;
  n.dronecan = *dc;
  const Nanos at = r.observed_ns;
  if (dc->statuses > 0 && dc->health != dronecan::Health::Ok) {
    const StatusLevel level =
        dc->health == dronecan::Health::Warning ? StatusLevel::Warn : StatusLevel::Error;
    n.status.merge(level, fmt::format("NodeStatus health {} (mode {}, vendor status 0x{:04X})",
                                      dronecan::to_string(dc->health),
                                      dronecan::mode_name(dc->mode), dc->vendor_status));
  }
  const Nanos window = n.thresholds.canopen_reset_window_ns;
  if (dc->restarts > 0 && window > 0 && at - dc->last_restart_ns <= window) {
    n.status.merge(StatusLevel::Warn,
                   fmt::format("node restart: its uptime went back {} ago ({} restart{} so far)",
                               duration(std::max<Nanos>(0, at - dc->last_restart_ns)), dc->restarts,
                               dc->restarts == 1 ? "" : "s"));
  }
  if (dc->malformed > 0) {
    n.status.merge(StatusLevel::Ok, fmt::format("malformed NodeStatus: {} (latest: {})",
                                                dc->malformed, dc->last_malformed));
  }
}

// Every bus the protocol tracker saw: its load against its thresholds, its controller state.
// SAE J1939: an active DTC is `j1939_dtc_level`, a lamp on `j1939_lamp_level` (MIL, amber
// warning, protect) or `j1939_stop_lamp_level` (red stop); an address claim names the node.
void j1939_checks(NodeReport& n, const CanReport& r) {
  if (r.node_map != NodeMapKind::J1939 || !n.bus || n.node > 0xFF) return;
  const j1939::NodeStats* j = r.snapshot.protocol.find_j1939(*n.bus, n.node);
  if (j == nullptr) return;
  n.j1939 = *j;
  const NodeThresholds& t = n.thresholds;
  if (j->name && !n.named) n.name = fmt::format("{} ({})", j->name->label(), n.name);
  if (j->address == 0xFE && j->claims > 0) {
    n.status.merge(StatusLevel::Warn,
                   fmt::format("cannot claim an address: {}", j->name ? j->name->describe() : "?"));
  }
  if (!j->active.empty()) {
    std::string list;
    for (std::size_t i = 0; i < j->active.size() && i < 4; ++i) {
      if (!list.empty()) list += "; ";
      list += fmt::format("SPN {} FMI {}", j->active[i].spn, j->active[i].fmi);
    }
    if (j->active.size() > 4) list += "; ...";
    n.status.merge(t.j1939_dtc_level, fmt::format("{} active DTC{} (DM1): {}", j->active.size(),
                                                  j->active.size() == 1 ? "" : "s", list));
  }
  const j1939::Lamps& l = j->lamps;
  if (j->dm1s > 0 && l.red_stop == j1939::Lamp::On) {
    n.status.merge(t.j1939_stop_lamp_level,
                   fmt::format("red stop lamp on (DM1: {})", l.describe()));
  }
  if (j->dm1s > 0 && (l.mil == j1939::Lamp::On || l.amber_warning == j1939::Lamp::On ||
                      l.protect == j1939::Lamp::On)) {
    n.status.merge(t.j1939_lamp_level, fmt::format("lamp on (DM1: {})", l.describe()));
  }
  if (j->malformed > 0) {
    n.status.merge(StatusLevel::Ok, fmt::format("malformed J1939 input: {} (latest: {})",
                                                j->malformed, j->last_malformed));
  }
}

// The controller's state, judged alike wherever it comes from (the error frames, or netlink):
// bus off ERROR, error passive WARN, error warning an OK message. `how` says since when or what
// was read.
void judge_controller(Status& s, ControllerState state, const std::string& how) {
  if (state == ControllerState::BusOff) {
    s.merge(StatusLevel::Error, fmt::format("controller bus off {}", how));
  } else if (state == ControllerState::ErrorPassive) {
    s.merge(StatusLevel::Warn, fmt::format("controller error passive {}", how));
  } else if (state == ControllerState::ErrorWarning) {
    s.merge(StatusLevel::Ok, fmt::format("controller error warning {}", how));
  }
}

// What netlink read of the bus's interface: the state and the counters, or why it failed.
void judge_link(BusReport& b) {
  const LinkReading& l = *b.link;
  if (!l.info) {
    b.status.merge(StatusLevel::Warn,
                   fmt::format("controller state not read live: {}",
                               l.error.empty() ? std::string("no reading yet") : l.error));
    return;
  }
  const LinkInfo& i = *l.info;
  if (!l.error.empty()) {
    b.status.merge(
        StatusLevel::Warn,
        fmt::format("controller state of {} not read at the latest try: {}", l.interface, l.error));
  }
  if (i.skipped > 0) {
    b.status.merge(StatusLevel::Ok,
                   fmt::format("netlink reading of {}: {} attribute{} skipped ({})", l.interface,
                               i.skipped, i.skipped == 1 ? "" : "s", i.skipped_detail));
  }
  if (!i.state) return;  // a virtual CAN device: no controller
  b.live_state = true;
  b.controller_state = controller_state(*i.state);
  std::string how = fmt::format("({}, read live", l.interface);
  if (i.tx_errors && i.rx_errors) {
    how += fmt::format("; error counters tx {} rx {}", *i.tx_errors, *i.rx_errors);
  }
  if (i.device_stats) {
    how += fmt::format("; {} bus-off{}, {} restart{}", i.device_stats->bus_off,
                       i.device_stats->bus_off == 1 ? "" : "s", i.device_stats->restarts,
                       i.device_stats->restarts == 1 ? "" : "s");
  }
  how += ")";
  if (*i.state == LinkControllerState::Stopped || *i.state == LinkControllerState::Sleeping) {
    b.status.merge(StatusLevel::Warn,
                   fmt::format("controller {} ({}: interface {})", to_string(*i.state), l.interface,
                               i.up ? "up" : "down"));
    return;
  }
  judge_controller(b.status, b.controller_state, how);
}

// Every bus the protocol tracker saw or whose interface is read: its load against its
// thresholds, its controller state.
void judge_buses(CanReport& r, const CanConfig& cfg, const std::vector<LinkReading>& links) {
  std::vector<BusProtocolStats> buses = r.snapshot.protocol.buses;
  for (const LinkReading& l : links) {
    const bool known = std::any_of(buses.begin(), buses.end(),
                                   [&](const BusProtocolStats& b) { return b.bus == l.bus; });
    if (!known) {
      BusProtocolStats b;
      b.bus = l.bus;
      buses.push_back(std::move(b));
    }
  }
  std::sort(buses.begin(), buses.end(),
            [](const BusProtocolStats& a, const BusProtocolStats& b) { return a.bus < b.bus; });
  for (const BusProtocolStats& s : buses) {
    BusReport b;
    b.bus = s.bus;
    b.config = cfg.bus_config(s.bus);
    b.stats = s;
    for (const LinkReading& l : links) {
      if (l.bus == s.bus) b.link = l;
    }
    const LinkInfo* info = b.link && b.link->info ? &*b.link->info : nullptr;
    // The configured bitrate wins; the interface's is used without one (the extension gives it
    // to the protocol tracker, which counts the load).
    if (info != nullptr && info->bitrate) {
      if (b.config.settings.bitrate == 0) {
        b.config.settings.bitrate = *info->bitrate;
        if (info->data_bitrate && b.config.settings.data_bitrate == 0) {
          b.config.settings.data_bitrate = *info->data_bitrate;
        }
        b.bitrate_from_link = true;
      } else if (b.config.settings.bitrate != *info->bitrate) {
        b.status.merge(StatusLevel::Warn,
                       fmt::format("configured bitrate {} differs from {}'s {} (the configured "
                                   "one is used for the load)",
                                   b.config.settings.bitrate, b.link->interface, *info->bitrate));
      }
    }
    const LoadLimit& l = b.config.load;
    const BusLoad& load = s.load[static_cast<std::size_t>(l.stuffing)][2];
    b.judged_load = load.known ? load_value(load, l.figure) : std::nan("");
    if (!load.known) {
      if ((l.warn || l.error) && b.config.settings.bitrate == 0) {
        b.status.merge(StatusLevel::Warn,
                       "load thresholds set but no bitrate: configure buses.<bus>.bitrate");
      }
    } else {
      const auto above = [&](StatusLevel level, double limit) {
        b.status.merge(level,
                       fmt::format("bus load {:.1f}% ({}, {} stuffing) above {:g}%", b.judged_load,
                                   to_string(l.figure), to_string(l.stuffing), limit));
      };
      if (l.error && b.judged_load > *l.error) {
        above(StatusLevel::Error, *l.error);
      } else if (l.warn && b.judged_load > *l.warn) {
        above(StatusLevel::Warn, *l.warn);
      }
    }
    if (b.link) judge_link(b);
    if (!b.live_state) {
      // The error frames' state: the latest one that said something.
      const ControllerStats& c = s.controller;
      b.controller_state = c.state;
      const std::string since = c.state_since_ns >= 0
                                    ? duration(std::max<Nanos>(0, r.observed_ns - c.state_since_ns))
                                    : std::string("?");
      judge_controller(
          b.status, c.state,
          c.state == ControllerState::BusOff
              ? fmt::format("for {} ({} bus-off{})", since, c.bus_offs, c.bus_offs == 1 ? "" : "s")
              : fmt::format("for {}", since));
    }
    r.buses.push_back(std::move(b));
  }
}

// The checks added with add_check, each on every node; one that throws is the node's error.
void custom_checks(const std::vector<std::pair<std::string, CanNodeCheck>>& checks, CanReport& r) {
  for (const auto& [name, check] : checks) {
    for (NodeReport& n : r.nodes) {
      if (!n.is_node()) continue;
      try {
        check(n, r, n.status);
      } catch (const std::exception& e) {
        n.status.merge(StatusLevel::Error, fmt::format("check {} failed: {}", name, e.what()));
      } catch (...) {
        n.status.merge(StatusLevel::Error, fmt::format("check {} failed", name));
      }
    }
  }
}

}  // namespace

CanReport CanMonitor::evaluate(CanSnapshot snapshot, Nanos now) const {
  std::shared_ptr<const CanConfig> cfg;
  std::vector<std::pair<std::string, CanNodeCheck>> checks;
  std::vector<LinkReading> links;
  {
    std::lock_guard lock(mutex_);
    cfg = config_;
    checks = checks_;
    links = links_;
  }
  CanReport r;
  r.time_ns = now;
  // Silence is judged up to the time the sniffers' tables were read, and no later than `now`:
  // a late CAN supervisor makes silences shorter, never longer (see the file comment).
  r.observed_ns = snapshot.observed_ns < 0 ? now : std::min(now, snapshot.observed_ns);
  r.observer_lag_ns = now - r.observed_ns;
  r.node_map = snapshot.sniffers.empty() ? cfg->node_map : snapshot.sniffers.front().node_map;
  r.snapshot = std::move(snapshot);
  judge_ids(r, *cfg);

  NodesByKey seen = seen_nodes(r.snapshot);
  std::vector<NodeReport> unseen = mark_expected(*cfg, seen);
  for (auto& [key, n] : seen) r.nodes.push_back(std::move(n));
  for (NodeReport& n : unseen) r.nodes.push_back(std::move(n));
  for (NodeReport& n : r.nodes) {
    if (n.node == kNoNode) {
      n.liveness = Liveness::NoNode;
      n.name = "(no node)";
      continue;
    }
    configure(n, *cfg, r.node_map);
    builtin_checks(n, r);
    canopen_checks(n, r);
    dronecan_checks(n, r);
    j1939_checks(n, r);
  }
  judge_buses(r, *cfg, links);
  custom_checks(checks, r);
  overall(r, options_);
  return r;
}

}  // namespace vigil::can
