#include "vigil/deploy/can_extension.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "vigil/deploy/system.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::deploy {

CanExtension::CanExtension(can::CanConfig config, supervisor::EventHub* events)
    : config_(std::move(config)), events_(events) {
  statistics_ = std::make_unique<can::CanAggregator>(
      registry_, can::CanAggregatorOptions{.protocol = config_.protocol_options()});
  // Its clock is the frames' (platform::now_ns, as the sniffers' callers and SocketCan stamp
  // them, even when supervision reads the TSC): the start of its cycles is the time node
  // silences are judged up to.
  supervisor_ = std::make_unique<can::CanDrainLoop>(
      registry_.ports(), *statistics_,
      supervisor::DrainOptions{
          .period_ns = 100 * kNanosPerMilli,
          .thread_name = "vigil-can-sup",
          .clock = Clock{[](const void*) noexcept { return platform::now_ns(); }, nullptr}});
  monitor_ = std::make_unique<can::CanMonitor>(config_);
  for (const can::BusConfig& b : config_.buses) {
    if (!b.bus || !b.interface) continue;
    can::LinkReading l;
    l.bus = *b.bus;
    l.interface = *b.interface;
    links_.push_back(std::move(l));
  }
  // CAN events leave at the CAN supervisor's pace: judged and published at the end of each of
  // its drains, on its thread (never on the sniffers' real-time side).
  statistics_->set_cycle_hook([this](const supervisor::DrainCycle& c) { on_can_cycle(c); });
}

CanExtension::~CanExtension() {
  // Its last drain calls the cycle hook, which needs the monitor: stop while it still exists.
  try {
    const std::lock_guard lock(step_mutex_);
    supervisor_->stop();
  } catch (...) {  // NOLINT(bugprone-empty-catch): out of memory in the last drain, nothing to say
  }
}

void CanExtension::on_can_cycle(const supervisor::DrainCycle& c) {
  // The regular drains' schedule, as the drain loop keeps it (one period after the latest
  // regular drain): a drain that starts close to it, or after it, is a regular one.
  const Nanos period = supervisor_->options().period_ns;
  if (c.time_ns >= regular_next_ - wake_margin(period)) regular_next_ = c.time_ns + period;
  // As add_reports: after a stop began, judged as of then (the bus went quiet with the system).
  const Nanos stopped = stopped_at_.load(std::memory_order_relaxed);
  const Nanos now = stopped != 0 ? stopped : platform::now_ns();
  const Nanos t0 = platform::now_ns();
  const can::CanReport r = monitor_->evaluate(*statistics_, now);
  publish_changes(r, now);
  publish_protocol_events(r);
  schedule_wake(r);
  // What judging at the drain's pace costs the CAN supervisor (its drain time excludes it).
  const Nanos took = platform::now_ns() - t0;
  judge_last_ns_.store(took, std::memory_order_relaxed);
  if (took > judge_max_ns_.load(std::memory_order_relaxed)) {
    judge_max_ns_.store(took, std::memory_order_relaxed);
  }
}

Nanos CanExtension::wake_margin(Nanos period) noexcept {
  return std::min<Nanos>(5 * kNanosPerMilli, period / 10);
}

namespace {

supervisor::EventKind link_event_kind(can::LinkControllerState s) {
  switch (s) {
    case can::LinkControllerState::ErrorWarning:
      return supervisor::EventKind::ErrorWarning;
    case can::LinkControllerState::ErrorPassive:
      return supervisor::EventKind::ErrorPassive;
    case can::LinkControllerState::BusOff:
      return supervisor::EventKind::BusOff;
    default:
      return supervisor::EventKind::ErrorActive;
  }
}

}  // namespace

void CanExtension::set_link_query(LinkQuery query) {
  const std::lock_guard lock(links_mutex_);
  link_query_ = std::move(query);
}

void CanExtension::read_links() {
  if (links_.empty()) return;
  const std::lock_guard lock(links_mutex_);
  for (can::LinkReading& l : links_) {
    // The state of the latest successful reading (-1: none), enum can_state's value.
    const int before = l.info && l.info->state ? static_cast<int>(*l.info->state) : -1;
    const std::string error_before = l.error;
    ++l.reads;
    l.read_ns = platform::now_ns();
    auto info = link_query_ ? link_query_(l.interface) : can::query_link(l.interface);
    if (!info) {
      ++l.failures;
      l.error = info.error().message;
      if (l.error != error_before) {  // said once per change: the bus's report says it each cycle
        std::fprintf(stderr, "vigil: can bus %u: controller state not read: %s\n", l.bus,
                     l.error.c_str());
      }
      continue;
    }
    l.error.clear();
    l.info = std::move(*info);
    const int after = l.info->state ? static_cast<int>(*l.info->state) : -1;
    // A change of the fault confinement state is an event, as an error frame's is; a first
    // reading only when it is not error active. Stopped and sleeping are the bus's WARN only.
    constexpr int kActive = static_cast<int>(can::LinkControllerState::ErrorActive);
    constexpr int kBusOff = static_cast<int>(can::LinkControllerState::BusOff);
    if (events_ != nullptr && after >= 0 && after <= kBusOff && after != before &&
        (before >= 0 || after != kActive)) {
      const auto state = static_cast<can::LinkControllerState>(after);
      supervisor::Event e;
      e.kind = link_event_kind(state);
      e.severity = state == can::LinkControllerState::BusOff ? supervisor::EventSeverity::Error
                   : state == can::LinkControllerState::ErrorPassive
                       ? supervisor::EventSeverity::Warn
                       : supervisor::EventSeverity::Info;
      e.component = fmt::format("can bus {}", l.bus);
      e.fault_ns = l.read_ns;  // read then (netlink gives no time of the change)
      e.detected_ns = platform::now_ns();
      e.detail = fmt::format(
          "{} (netlink): {} -> {}", l.interface,
          before >= 0 ? std::string(can::to_string(static_cast<can::LinkControllerState>(before)))
                      : std::string("unknown"),
          can::to_string(state));
      if (l.info->tx_errors && l.info->rx_errors) {
        e.detail +=
            fmt::format("; error counters tx {} rx {}", *l.info->tx_errors, *l.info->rx_errors);
      }
      events_->publish(std::move(e));
    }
  }
  // The interface's bitrate counts the load of a bus whose configuration gives none.
  std::vector<std::pair<std::uint8_t, std::pair<std::uint32_t, std::uint32_t>>> bitrates;
  for (const can::LinkReading& l : links_) {
    if (!l.info || !l.info->bitrate || config_.bus_config(l.bus).settings.bitrate != 0) continue;
    bitrates.emplace_back(l.bus, std::pair{*l.info->bitrate, l.info->data_bitrate.value_or(0)});
  }
  if (bitrates != link_bitrates_) {
    link_bitrates_ = bitrates;
    can::ProtocolOptions o = config_.protocol_options();
    for (const auto& [bus, rates] : bitrates) {
      can::BusSettings settings = config_.bus_config(bus).settings;
      settings.bitrate = rates.first;
      if (settings.data_bitrate == 0) settings.data_bitrate = rates.second;
      std::erase_if(o.buses, [bus = bus](const auto& e) { return e.first == bus; });
      o.buses.emplace_back(bus, settings);
    }
    statistics_->set_protocol_options(std::move(o));
  }
  monitor_->set_links(links_);
}

void CanExtension::schedule_wake(const can::CanReport& r) {
  // The earliest time a responding node's silence (or a request to it) passes its limit: one
  // more drain then judges it up to that time (strictly above the limit: +1 ns).
  Nanos next = std::numeric_limits<Nanos>::max();
  for (const can::NodeReport& n : r.nodes) {
    if (!n.is_node() || n.liveness != can::Liveness::Responding) continue;
    if (n.silence_ns >= 0 && n.silence_limit_ns >= 0) {
      next = std::min(next, r.observed_ns - n.silence_ns + n.silence_limit_ns + 1);
    }
    if (n.unanswered_ns >= 0 && n.thresholds.answer_within_ns >= 0) {
      next = std::min(next, r.observed_ns - n.unanswered_ns + n.thresholds.answer_within_ns + 1);
    }
  }
  // No extra drain for a limit that passes within the margin before the next regular drain:
  // that drain judges it (a healthy node sending every millisecond with a 100 ms limit would
  // otherwise double the drains). Later than the regular drain: that drain asks again.
  if (next >= regular_next_ - wake_margin(supervisor_->options().period_ns)) {
    next = std::numeric_limits<Nanos>::max();
  }
  // Never a busy loop: an observation that cannot pass the time asked for (a port that never
  // empties) gets one more drain per millisecond at most.
  const Nanos soonest = platform::now_ns() + kNanosPerMilli;
  if (next != std::numeric_limits<Nanos>::max()) next = std::max(next, soonest);
  statistics_->wake_at(next);
}

expected<void, Error> CanExtension::start() {
  stopped_at_.store(0, std::memory_order_relaxed);
  const std::lock_guard lock(step_mutex_);
  return supervisor_->start();
}

void CanExtension::stopping() { stopped_at_.store(platform::now_ns(), std::memory_order_relaxed); }

void CanExtension::stop() {
  const std::lock_guard lock(step_mutex_);
  supervisor_->stop();
}

void CanExtension::contribute(exporter::Snapshot& snapshot) {
  add_reports(snapshot.reports, &snapshot.can_histograms, &snapshot.can_buses);
}

Report CanExtension::supervisor_report(const can::CanReport& r, bool running) const {
  const supervisor::DrainStats st = supervisor_->stats();
  Report s;
  s.kind = ReportKind::Supervisor;
  s.name = std::string(kCanSupervisorName);
  s.configured = true;
  s.activity = supervisor_->options().thread_name;
  s.period_ns = supervisor_->options().period_ns;
  s.state = running ? TaskState::Running : TaskState::Stopped;
  s.counters.cycles = st.cycles;
  s.samples = st.cycles;
  s.total_ns = st.drain_ns;
  s.port_high_water = st.max_occupancy;
  s.silence_ns = r.observer_lag_ns;  // how long ago the frames judged were read
  s.add("messages", std::to_string(st.messages));
  s.add("ports", std::to_string(st.ports));
  s.add("observer_lag", format_nanos(static_cast<double>(r.observer_lag_ns)));
  // Judging the nodes and publishing the CAN events at the end of each drain.
  s.add("judge_time",
        fmt::format(
            "last {}, max {}",
            format_nanos(static_cast<double>(judge_last_ns_.load(std::memory_order_relaxed))),
            format_nanos(static_cast<double>(judge_max_ns_.load(std::memory_order_relaxed)))));
  if (const std::uint64_t failed = statistics_->hook_failures(); failed > 0) {
    // The CAN events of those drains were not published (a custom check threw, out of memory).
    s.merge(StatusLevel::Warn,
            fmt::format("CAN events not judged at {} drain{}: the evaluation failed", failed,
                        failed == 1 ? "" : "s"));
  }
  const Nanos limit = monitor_->options().stale_after_ns;
  if (limit > 0 && r.observer_lag_ns > limit) {
    // Its own finding: the nodes are judged up to what it read, so none of them turns ERROR.
    s.merge(StatusLevel::Stale,
            fmt::format("not draining: CAN frames read up to {} ago (limit {}); CAN node "
                        "silences are judged up to then",
                        format_nanos(static_cast<double>(r.observer_lag_ns)),
                        format_nanos(static_cast<double>(limit))));
  }
  return s;
}

namespace {

// What a group's report is made of: the sum and worst of its nodes.
struct GroupTally {
  std::vector<std::string> members;  // its nodes' report names: what the group depends on
  std::uint64_t frames = 0;
  std::uint64_t nodes = 0;
  std::uint64_t responding = 0;
  Status status;
  std::set<std::uint8_t> buses;  // of its nodes: their controllers' state is the group's too
};

// A CAN node's report: its liveness, frames and gaps under CAN names.
Report node_report(const can::CanReport& r, const can::NodeReport& n) {
  Report rep;
  rep.kind = ReportKind::Unit;
  rep.unit_kind = std::string(can::kNodeUnit);
  rep.name = fmt::format("can{}/{}", n.bus ? std::to_string(*n.bus) : std::string("*"), n.name);
  rep.status = n.status;
  rep.state_label = std::string(can::to_string(n.liveness));
  rep.add_field(Field::of_count("frames_rx", n.rx ? n.rx->frames : 0));
  rep.add_field(Field::of_count("frames_tx", n.tx ? n.tx->frames : 0));
  if (n.rx) {
    rep.add_field(Field::of_distribution("rx_gap", n.rx->gap_ns));
    rep.add_field(Field::of_distribution("read_time", n.rx->io_ns));
  }
  if (n.tx) rep.add_field(Field::of_distribution("tx_gap", n.tx->gap_ns));
  if (n.silence_ns >= 0) rep.add_field(Field::of_duration("silence", n.silence_ns));
  if (n.silence_limit_ns >= 0) {
    rep.add_field(Field::of_duration("silence_limit", n.silence_limit_ns));
    rep.add_field(Field::of_text("limit", n.limit_learned ? "learned" : "configured"));
  }
  if (n.limit_id >= 0 && static_cast<std::size_t>(n.limit_id) < r.ids.size()) {
    const Nanos period = r.ids[static_cast<std::size_t>(n.limit_id)].period_ns;
    if (period >= 0) rep.add_field(Field::of_duration("period_learned", period));
  }
  if (n.canopen) {  // CiA 301: NMT state, resets, emergencies
    const can::canopen::NodeStats& co = *n.canopen;
    rep.add_field(Field::of_text("nmt_state", std::string(can::canopen::to_string(co.state))));
    rep.add_field(Field::of_count("heartbeats", co.heartbeats));
    rep.add_field(Field::of_count("resets", co.resets));
    rep.add_field(Field::of_count("emergencies", co.emergencies));
    if (co.last_emergency) {
      rep.add_field(Field::of_text("last_emergency", co.last_emergency->describe()));
    }
    if (co.guard_responses > 0) rep.add_field(Field::of_count("toggle_errors", co.toggle_errors));
    if (co.malformed_emergencies + co.malformed_heartbeats > 0) {
      rep.add_field(
          Field::of_count("malformed", co.malformed_emergencies + co.malformed_heartbeats));
    }
  }
  if (n.dronecan) {  // DroneCAN NodeStatus
    const can::dronecan::NodeStats& dc = *n.dronecan;
    rep.add_field(Field::of_text("health", std::string(can::dronecan::to_string(dc.health))));
    rep.add_field(Field::of_text("mode", can::dronecan::mode_name(dc.mode)));
    rep.add_field(Field::of_duration("uptime", Nanos{dc.uptime_s} * kNanosPerSecond));
    rep.add_field(Field::of_count("restarts", dc.restarts));
    if (dc.malformed > 0) rep.add_field(Field::of_count("malformed", dc.malformed));
  }
  if (n.j1939) {  // SAE J1939: DM1, DM2, address claim
    const can::j1939::NodeStats& j = *n.j1939;
    if (j.name) rep.add_field(Field::of_text("j1939_name", j.name->describe()));
    if (j.dm1s > 0) {
      rep.add_field(Field::of_count("active_dtcs", j.active.size()));
      std::string list;
      for (const can::j1939::Dtc& d : j.active) {
        if (!list.empty()) list += "; ";
        list += d.describe();
      }
      if (!list.empty()) rep.add_field(Field::of_text("dtcs", list));
      rep.add_field(Field::of_text("lamps", j.lamps.describe()));
    }
    if (j.dm2s > 0) {  // DM2: previously active codes, as of the latest one
      rep.add_field(Field::of_count("previously_active_dtcs", j.previously_active.size()));
      std::string list;
      for (const can::j1939::Dtc& d : j.previously_active) {
        if (!list.empty()) list += "; ";
        list += d.describe();
      }
      if (!list.empty()) rep.add_field(Field::of_text("previous_dtcs", list));
    }
    if (j.malformed > 0) rep.add_field(Field::of_count("malformed", j.malformed));
  }
  return rep;
}

// "12.3%", or "-" without a bitrate.
std::string percent_text(const can::BusLoad& l, double v) {
  return l.known ? fmt::format("{:.1f}%", v) : std::string("-");
}

// A CAN bus's report: its load (as canbusload), its controller's state from error frames.
Report bus_report(const can::BusReport& b) {
  Report rep;
  rep.kind = ReportKind::Unit;
  rep.unit_kind = std::string(can::kBusUnit);
  rep.name = fmt::format("can bus {}", b.bus);
  rep.status = b.status;
  const can::ControllerStats& c = b.stats.controller;
  const can::LinkInfo* live = b.link && b.link->info ? &*b.link->info : nullptr;
  if (live != nullptr && live->state) {
    rep.state_label = std::string(can::to_string(*live->state));  // the driver's, read live
  } else {
    rep.state_label = c.state == can::ControllerState::Unknown
                          ? std::string("no error frames")
                          : std::string(can::to_string(c.state));
  }
  const auto mode = static_cast<std::size_t>(b.config.load.stuffing);
  const can::BusLoad& all = b.stats.load[mode][2];
  rep.add_field(Field::of_count("frames", all.frames));
  rep.add_field(Field::of_count("bits_rx", b.stats.load[mode][0].bits));
  rep.add_field(Field::of_count("bits_tx", b.stats.load[mode][1].bits));
  rep.add_field(Field::of_count("bits_last_second", all.last_second_bits));
  if (all.known) {
    rep.add_field(Field::of_text("load_last_second", percent_text(all, all.last_second)));
    rep.add_field(Field::of_text("load_1m", percent_text(all, all.avg_1m)));
    rep.add_field(Field::of_text("load_5m", percent_text(all, all.avg_5m)));
    rep.add_field(Field::of_text("load_15m", percent_text(all, all.avg_15m)));
    rep.add_field(Field::of_text("load_peak", percent_text(all, all.peak)));
    rep.add_field(Field::of_text(
        "load_rx_1m", percent_text(b.stats.load[mode][0], b.stats.load[mode][0].avg_1m)));
    rep.add_field(Field::of_text(
        "load_tx_1m", percent_text(b.stats.load[mode][1], b.stats.load[mode][1].avg_1m)));
  }
  rep.add_field(Field::of_text("stuffing", std::string(can::to_string(b.config.load.stuffing))));
  if (b.config.settings.bitrate != 0) {
    rep.add_field(Field::of_count("bitrate", b.config.settings.bitrate));
    if (b.config.settings.data_bitrate != 0) {
      rep.add_field(Field::of_count("data_bitrate", b.config.settings.data_bitrate));
    }
    rep.add_field(Field::of_text("bitrate_source", b.bitrate_from_link ? "netlink" : "configured"));
  }
  if (b.link) {  // read live through netlink (vigil/can/can_link.hpp)
    rep.add_field(Field::of_text("interface", b.link->interface));
    rep.add_field(Field::of_count("link_reads", b.link->reads));
    rep.add_field(Field::of_count("link_read_failures", b.link->failures));
    if (!b.link->error.empty()) rep.add_field(Field::of_text("link_error", b.link->error));
    if (live != nullptr) {
      rep.add_field(Field::of_text("link_kind", live->kind));
      if (live->state) {
        rep.add_field(
            Field::of_text("controller_state", std::string(can::to_string(*live->state))));
        rep.add_field(
            Field::of_count("controller_state_code", static_cast<std::uint64_t>(*live->state)));
      }
      if (live->tx_errors)
        rep.add_field(Field::of_count("link_tx_error_counter", *live->tx_errors));
      if (live->rx_errors)
        rep.add_field(Field::of_count("link_rx_error_counter", *live->rx_errors));
      if (live->device_stats) {
        const can::LinkDeviceStats& d = *live->device_stats;
        rep.add_field(Field::of_count("link_bus_errors", d.bus_error));
        rep.add_field(Field::of_count("link_restarts", d.restarts));
        rep.add_field(Field::of_count("link_bus_offs", d.bus_off));
        rep.add_field(Field::of_count("link_error_passives", d.error_passive));
        rep.add_field(Field::of_count("link_error_warnings", d.error_warning));
        rep.add_field(Field::of_count("link_arbitration_lost", d.arbitration_lost));
      }
      if (live->restart_ms) rep.add_field(Field::of_count("restart_ms", *live->restart_ms));
      if (live->counters) {  // the interface's own counters (IFLA_STATS64)
        rep.add_field(Field::of_count("link_rx_frames", live->counters->rx_packets));
        rep.add_field(Field::of_count("link_tx_frames", live->counters->tx_packets));
        rep.add_field(Field::of_count("link_rx_errors", live->counters->rx_errors));
        rep.add_field(Field::of_count("link_tx_errors", live->counters->tx_errors));
        rep.add_field(Field::of_count("link_rx_dropped", live->counters->rx_dropped));
        rep.add_field(Field::of_count("link_tx_dropped", live->counters->tx_dropped));
      }
      if (live->skipped > 0) rep.add_field(Field::of_count("link_skipped", live->skipped));
    }
  }
  rep.add_field(Field::of_count("error_frames", c.error_frames));
  if (c.error_frames > 0) {
    rep.add_field(Field::of_count("error_passives", c.passives));
    rep.add_field(Field::of_count("bus_offs", c.bus_offs));
    rep.add_field(Field::of_count("restarts", c.restarts));
    rep.add_field(Field::of_count("protocol_errors", c.by_class[3]));
    rep.add_field(Field::of_count("no_ack", c.by_class[5]));
    rep.add_field(Field::of_count("lost_arbitration", c.by_class[1]));
    if (c.tx_errors) rep.add_field(Field::of_count("tx_error_counter", *c.tx_errors));
    if (c.rx_errors) rep.add_field(Field::of_count("rx_error_counter", *c.rx_errors));
    rep.add_field(Field::of_text("last_error", c.last));
  }
  return rep;
}

// A CAN group's report: the worst of its nodes, its frames, its nodes responding.
Report group_report(const std::string& name, GroupTally& t) {
  Report g;
  g.kind = ReportKind::Unit;
  g.unit_kind = std::string(can::kGroupUnit);
  g.name = "can group " + name;
  g.status = std::move(t.status);
  g.state_label = g.status.level() == StatusLevel::Ok ? "all responding" : "degraded";
  g.add_field(Field::of_count("frames", t.frames));
  g.add_field(Field::of_count("nodes", t.nodes));
  g.add_field(Field::of_count("responding", t.responding));
  g.depends_on = std::move(t.members);  // the diagnosis graph: a node explains its group
  return g;
}

}  // namespace

void CanExtension::add_reports(ReportSet& reports, std::vector<exporter::CanHistograms>* histograms,
                               std::vector<exporter::CanBusLoads>* buses) {
  read_links();  // first: the step below and the evaluation judge the same readings
  bool running = false;
  {
    const std::lock_guard lock(step_mutex_);
    running = supervisor_->running();
    if (!running) supervisor_->step();
  }
  // After a stop, nodes are judged as of the moment the system began to stop: the bus went quiet
  // because the system stopped, not because a node failed. Either way a node's silence is judged
  // up to the time the CAN supervisor read the sniffers (CanMonitor): its own delay is reported
  // apart, in the CAN supervisor's report.
  const Nanos stopped = stopped_at_.load(std::memory_order_relaxed);
  const Nanos now = stopped != 0 ? stopped : platform::now_ns();
  // The events of this evaluation left already: the CAN supervisor's cycle hook publishes them
  // at the end of each drain (the step above included).
  const can::CanReport r = monitor_->evaluate(*statistics_, now);
  reports.components.push_back(supervisor_report(r, running));
  std::map<std::string, GroupTally> groups;
  std::map<std::pair<std::uint8_t, std::uint32_t>, std::string> names;  // of the nodes seen
  for (const auto& n : r.nodes) {
    if (!n.is_node()) continue;  // the frames of no node (SYNC, NMT...) are not judged
    Report rep = node_report(r, n);
    if (histograms != nullptr && n.bus) names.emplace(std::pair{*n.bus, n.node}, rep.name);
    const std::uint64_t frames = (n.rx ? n.rx->frames : 0) + (n.tx ? n.tx->frames : 0);
    for (const auto& g : n.groups) {
      GroupTally& t = groups[g];
      t.members.push_back(rep.name);
      t.frames += frames;
      ++t.nodes;
      if (n.liveness == can::Liveness::Responding) ++t.responding;
      if (n.bus) t.buses.insert(*n.bus);
      if (n.status.level() != StatusLevel::Ok) {
        t.status.merge(n.status.level(), fmt::format("{}: {}", n.name, n.status.summary()));
      }
    }
    reports.components.push_back(std::move(rep));
  }
  for (auto& [name, t] : groups) {
    // A controller error passive (WARN) or bus off (ERROR) is its nodes' groups' problem too.
    for (const std::uint8_t bus : t.buses) {
      const can::BusReport* b = r.find_bus(bus);
      if (b == nullptr) continue;
      const can::ControllerState st = b->controller_state;  // live (netlink) or error frames'
      if (st == can::ControllerState::BusOff) {
        t.status.merge(StatusLevel::Error, fmt::format("can bus {}: controller bus off", bus));
      } else if (st == can::ControllerState::ErrorPassive) {
        t.status.merge(StatusLevel::Warn, fmt::format("can bus {}: controller error passive", bus));
      }
    }
    reports.components.push_back(group_report(name, t));
  }
  for (const can::BusReport& b : r.buses) {
    reports.components.push_back(bus_report(b));
    if (buses != nullptr) {
      buses->push_back(exporter::CanBusLoads{.name = reports.components.back().name,
                                             .judged = b.config.load.stuffing,
                                             .load = b.stats.load});
    }
  }
  if (histograms == nullptr) return;
  // The buckets, from the aggregator's histograms: one more pass under its lock, right after
  // the snapshot the reports were judged on (a batch applied in between shows in the buckets,
  // not in the reports: the figures differ by at most one supervisor cycle's frames).
  std::map<std::string, exporter::CanHistograms> by_name;
  const auto group_specs = config_.group_specs();
  statistics_->visit_gap_distributions(group_specs, [&](const can::GapDistribution& d) {
    std::string name;
    bool group = false;
    if (d.group.empty()) {
      const auto it = names.find({d.bus, d.node});
      if (it == names.end()) return;  // the frames of no node
      name = it->second;
    } else {
      name = "can group " + std::string(d.group);
      group = true;
    }
    exporter::CanHistograms& h = by_name[name];
    h.name = name;
    h.group = group;
    (d.direction == can::Direction::Tx ? h.tx_gap : h.rx_gap) = exporter::reduce_to_buckets(d);
  });
  histograms->reserve(histograms->size() + by_name.size());
  for (auto& [name, h] : by_name) histograms->push_back(std::move(h));
}

std::vector<std::string> CanExtension::unit_names() const {
  std::vector<std::string> names;
  for (const auto& n : config_.nodes) {
    if (n.bus) names.push_back(fmt::format("can{}/{}", *n.bus, n.name));
  }
  for (const auto& g : config_.groups) names.push_back("can group " + g.members.name);
  return names;
}

void CanExtension::publish_changes(const can::CanReport& r, Nanos now) {
  if (events_ == nullptr) return;
  for (const auto& n : r.nodes) {
    if (!n.is_node() || !n.bus) continue;
    const bool silent = n.liveness == can::Liveness::NotResponding;
    const std::string name = fmt::format("can{}/{}", *n.bus, n.name);
    const auto it = not_responding_.find(name);
    const bool was = it != not_responding_.end() && it->second;
    if (silent == was) continue;
    not_responding_[name] = silent;
    supervisor::Event e;
    e.component = name;
    e.detected_ns = platform::now_ns();
    // The frames' time: the node's latest frame is `silence` before the observation.
    const Nanos last_frame = n.silence_ns >= 0 ? r.observed_ns - n.silence_ns : 0;
    if (silent) {
      e.kind = supervisor::EventKind::NotResponding;
      e.severity = supervisor::EventSeverity::Error;
      // It failed when its silence passed the limit (a request left unanswered: when seen).
      e.fault_ns = last_frame > 0 && n.silence_limit_ns >= 0 && n.silence_ns > n.silence_limit_ns
                       ? last_frame + n.silence_limit_ns
                       : r.observed_ns;
      e.detail = n.status.summary();
    } else {
      e.kind = supervisor::EventKind::Responding;
      e.severity = supervisor::EventSeverity::Info;
      e.fault_ns = last_frame > 0 ? last_frame : now;  // its first frame again, or about then
      e.detail = fmt::format("{} again", can::to_string(n.liveness));
    }
    events_->publish(std::move(e));
  }
}

void CanExtension::publish_protocol_events(const can::CanReport& r) {
  const std::vector<can::ProtocolEvent> events = statistics_->protocol_events_after(protocol_seq_);
  if (events.empty()) return;
  protocol_seq_ = events.back().seq;
  if (events_ == nullptr) return;
  const Nanos detected = platform::now_ns();
  for (const can::ProtocolEvent& pe : events) {
    supervisor::Event e;
    switch (pe.kind) {
      case can::ProtocolEventKind::NmtState:
        e.kind = supervisor::EventKind::NmtState;
        break;
      case can::ProtocolEventKind::NodeReset:
        e.kind = supervisor::EventKind::NodeReset;
        break;
      case can::ProtocolEventKind::Emergency:
        e.kind = supervisor::EventKind::Emergency;
        break;
      case can::ProtocolEventKind::NmtCommand:
        e.kind = supervisor::EventKind::NmtCommand;
        break;
      case can::ProtocolEventKind::ErrorWarning:
        e.kind = supervisor::EventKind::ErrorWarning;
        break;
      case can::ProtocolEventKind::ErrorPassive:
        e.kind = supervisor::EventKind::ErrorPassive;
        break;
      case can::ProtocolEventKind::BusOff:
        e.kind = supervisor::EventKind::BusOff;
        break;
      case can::ProtocolEventKind::ErrorActive:
        e.kind = supervisor::EventKind::ErrorActive;
        break;
      case can::ProtocolEventKind::NodeHealth:
        e.kind = supervisor::EventKind::NodeHealth;
        break;
      case can::ProtocolEventKind::DtcActive:
        e.kind = supervisor::EventKind::DtcActive;
        break;
      case can::ProtocolEventKind::DtcCleared:
        e.kind = supervisor::EventKind::DtcCleared;
        break;
      case can::ProtocolEventKind::AddressClaim:
        e.kind = supervisor::EventKind::AddressClaim;
        break;
    }
    e.severity = pe.severity == 2   ? supervisor::EventSeverity::Error
                 : pe.severity == 1 ? supervisor::EventSeverity::Warn
                                    : supervisor::EventSeverity::Info;
    // A node's events name it as its report does; an NMT command names its target node.
    const bool bus_event = pe.node == can::kNoNode || pe.kind == can::ProtocolEventKind::NmtCommand;
    if (bus_event) {
      e.component = fmt::format("can bus {}", pe.bus);
    } else {
      const can::NodeReport* n = r.find(pe.bus, pe.node);
      const can::NodeConfig* named = config_.find_node(pe.bus, pe.node);
      e.component = fmt::format("can{}/{}", pe.bus,
                                n != nullptr       ? n->name
                                : named != nullptr ? named->name
                                                   : can::format_node(r.node_map, pe.node));
    }
    e.fault_ns = pe.time_ns;  // the frame's time, on the frames' clock
    e.detected_ns = detected;
    e.detail = pe.detail;
    events_->publish(std::move(e));
  }
}

void register_can_extension() {
  static const bool once = [] {
    register_extension(
        std::string(kCanSection),
        [](const config::Node& section,
           System& system) -> expected<std::unique_ptr<Extension>, config::ConfigErrors> {
          can::CanConfig cfg = can::load_can_config(section);
          if (section.has_errors()) return vigil::unexpected(section.errors());
          return std::make_unique<CanExtension>(std::move(cfg), &system.service().events());
        });
    return true;
  }();
  (void)once;
}

}  // namespace vigil::deploy
