// The `can:` section through vigil::deploy_can: linking the target is all a program does (no
// registration call anywhere in this binary).
#include "vigil/deploy/can_extension.hpp"

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "vigil/deploy/system.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

// Sends TPDO1 of nodes 1..3 every cycle (as read frames); node 3 is quiet from cycle
// `quiet_after` + 1 to `back_after`.
class Bus : public Task<Bus> {
 public:
  explicit Bus(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        quiet_after_(c.parameters.optional<std::uint64_t>("quiet_after", 20)),
        back_after_(c.parameters.optional<std::uint64_t>("back_after", UINT64_MAX)) {
    auto* ext = c.system->extension<CanExtension>();
    if (ext == nullptr) throw std::runtime_error("needs a can: section");
    sniffer_ = std::make_unique<can::Sniffer<64>>(
        ext->registry(), c.name, can::SnifferOptions{.node_map = can::NodeMap::canopen()});
  }
  void on_update() {
    ++cycle_;
    for (std::uint32_t node = 1; node <= 3; ++node) {
      if (node == 3 && cycle_ > quiet_after_ && cycle_ <= back_after_) continue;
      const Nanos t = platform::now_ns();
      can::Frame f = can::Frame::classic(0x180 + node, {0x01});
      f.timestamp = t;
      sniffer_->on_read(f, t, t);
    }
  }

 private:
  std::uint64_t quiet_after_;
  std::uint64_t back_after_;
  std::uint64_t cycle_ = 0;
  std::unique_ptr<can::Sniffer<64>> sniffer_;
};

// A CANopen node 1: boot-up, then operational heartbeats every cycle; a boot-up again at cycle
// 40 (a reset), an emergency at cycle 50, then its controller goes bus off at cycle 60.
class CanOpenBus : public Task<CanOpenBus> {
 public:
  explicit CanOpenBus(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {
    auto* ext = c.system->extension<CanExtension>();
    if (ext == nullptr) throw std::runtime_error("needs a can: section");
    sniffer_ = std::make_unique<can::Sniffer<64>>(
        ext->registry(), c.name, can::SnifferOptions{.node_map = can::NodeMap::canopen()});
  }
  void on_update() {
    ++cycle_;
    const Nanos t = platform::now_ns();
    const auto read = [&](can::Frame f) {
      f.timestamp = t;
      sniffer_->on_read(f, t, t);
    };
    read(can::Frame::classic(
        0x701, {cycle_ == 1 || cycle_ == 40 ? std::uint8_t{0x00} : std::uint8_t{0x05}}));
    if (cycle_ == 50) read(can::Frame::classic(0x081, {0x30, 0x81, 0x11, 0, 0, 0, 0, 0}));
    if (cycle_ == 60) read(can::Frame::error_frame(can::error_class::kBusOff));
  }

 private:
  std::uint64_t cycle_ = 0;
  std::unique_ptr<can::Sniffer<64>> sniffer_;
};

// A J1939 engine (source address 0x00): EEC1 every cycle, its address claim at cycle 1, a DM1
// with SPN 100 FMI 1 and the amber warning lamp at cycle 20, a DM2 with SPN 190 FMI 2 (x7, a
// previously active code) at cycle 30, a DM1 without DTC at cycle 60.
class J1939Bus : public Task<J1939Bus> {
 public:
  explicit J1939Bus(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {
    auto* ext = c.system->extension<CanExtension>();
    if (ext == nullptr) throw std::runtime_error("needs a can: section");
    sniffer_ = std::make_unique<can::Sniffer<64>>(
        ext->registry(), c.name, can::SnifferOptions{.node_map = can::NodeMap::j1939()});
  }
  void on_update() {
    ++cycle_;
    const Nanos t = platform::now_ns();
    const auto read = [&](std::uint32_t id, std::initializer_list<std::uint8_t> d) {
      can::Frame f = can::Frame::classic(id, d, can::IdFormat::Extended);
      f.timestamp = t;
      sniffer_->on_read(f, t, t);
    };
    read(0x0CF00400, {0x70, 0x7D, 0x83, 0xC3, 0x12, 0x00, 0x0F, 0x84});
    // NAME: identity 1, manufacturer 0, function 0 (engine), industry group 1.
    if (cycle_ == 1) read(0x18EEFF00, {0x01, 0, 0, 0, 0, 0, 0, 0x10});
    if (cycle_ == 20) read(0x18FECA00, {0x04, 0xFF, 0x64, 0x00, 0x01, 0x03, 0xFF, 0xFF});
    if (cycle_ == 30) read(0x18FECB00, {0x00, 0xFF, 0xBE, 0x00, 0x02, 0x07, 0xFF, 0xFF});
    if (cycle_ == 60) read(0x18FECA00, {0x00, 0xFF, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF});
  }

 private:
  std::uint64_t cycle_ = 0;
  std::unique_ptr<can::Sniffer<64>> sniffer_;
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool j1939 = f.add<J1939Bus>("test.j1939_bus");
  (void)j1939;
  static const bool canopen = f.add<CanOpenBus>("test.canopen_bus");
  (void)canopen;
  static const bool once = f.add<Bus>("test.can_bus");
  (void)once;
  return f;
}

}  // namespace

TEST_CASE("Linking vigil::deploy_can is enough for a deployment's can: section", "[deploy][can]") {
  const auto names = registered_extensions();
  CHECK(std::find(names.begin(), names.end(), std::string(kCanSection)) != names.end());

  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.can_bus, activity: io, parameters: {quiet_after: 10}}]
supervision: {lock_memory: false, monitor_period: 50ms}
can:
  node_map: canopen
  defaults: {not_responding: {after: 100ms}}
  nodes: {drive_1: {node: 1, bus: 0}}
  groups: {arm: {nodes: [1, 2, 3], bus: 0}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  REQUIRE((*sys)->extension<CanExtension>() != nullptr);
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  (*sys)->stop();
  const ReportSet r = (*sys)->step_monitor();
  const Report* drive = r.find("can0/drive_1");
  REQUIRE(drive != nullptr);
  // A CAN node says what it is, with its figures under CAN names (not a component's).
  CHECK(drive->kind == ReportKind::Unit);
  CHECK(drive->kind_name() == "can_node");
  CHECK(drive->status.ok());
  CHECK(drive->state_label == "responding");
  CHECK(drive->counters.cycles == 0);
  const Field* frames_rx = drive->field("frames_rx");
  REQUIRE(frames_rx != nullptr);
  CHECK(frames_rx->type == Field::Type::Count);
  CHECK(frames_rx->count > 20);
  const Field* rx_gap = drive->field("rx_gap");
  REQUIRE(rx_gap != nullptr);
  CHECK(rx_gap->type == Field::Type::Distribution);
  CHECK(rx_gap->distribution.p50 > 0);
  REQUIRE(drive->field("read_time") != nullptr);
  REQUIRE(drive->field("silence_limit") != nullptr);
  CHECK(drive->field("silence_limit")->duration_ns == 100 * kNanosPerMilli);
  CHECK(drive->field("limit")->text == "configured");
  CHECK(drive->execution_ns.count == 0);
  const Report* quiet = r.find("can0/3");
  REQUIRE(quiet != nullptr);
  CHECK(quiet->status.level() == StatusLevel::Error);
  CHECK(quiet->state_label == "not responding");
  const Report* arm = r.find("can group arm");
  REQUIRE(arm != nullptr);
  CHECK(arm->status.level() == StatusLevel::Error);
  CHECK(arm->kind_name() == "can_group");
  CHECK(arm->state_label == "degraded");
  REQUIRE(arm->field("nodes") != nullptr);
  CHECK(arm->field("nodes")->count == 3);
  CHECK(arm->field("responding")->count < 3);
  CHECK(arm->field("frames")->count >= frames_rx->count);
  // The CAN supervisor reports itself: it drained on time (judged as of the stop).
  const Report* sup = r.find(kCanSupervisorName);
  REQUIRE(sup != nullptr);
  CHECK(sup->kind == ReportKind::Supervisor);
  CHECK(sup->status.ok());
  CHECK(sup->counters.cycles >= 3);
  CHECK(sup->silence_ns == 0);  // the last drain came after the stop began
  REQUIRE(sup->value("ports") != nullptr);
  CHECK(*sup->value("ports") == "1");  // the bus component's sniffer

  // The gap buckets of the same reports, matched by name (what /metrics serves).
  const auto snapshot = (*sys)->service().snapshot();  // the cycle of r, contributions included
  REQUIRE(snapshot->cycle == r.cycle);
  CHECK(snapshot->reports.find("can0/drive_1") != nullptr);
  const std::vector<exporter::CanHistograms>& histograms = snapshot->can_histograms;
  const auto find = [&](std::string_view name) -> const exporter::CanHistograms* {
    for (const auto& h : histograms) {
      if (h.name == name) return &h;
    }
    return nullptr;
  };
  const auto* h1 = find("can0/drive_1");
  REQUIRE(h1 != nullptr);
  CHECK_FALSE(h1->group);
  REQUIRE(h1->rx_gap);
  CHECK_FALSE(h1->tx_gap);  // nothing was sent to it
  CHECK(h1->rx_gap->count > 20);
  CHECK(h1->rx_gap->count < frames_rx->count);  // one gap fewer than frames (or more lost)
  // Gaps of about 5 ms (the activity's period): none under 1 ms, all under 1 s.
  CHECK(h1->rx_gap->cumulative[0] == 0);
  CHECK(exporter::kBucketBoundsNs[36] == kNanosPerSecond);
  CHECK(h1->rx_gap->cumulative[36] == h1->rx_gap->count);
  const auto* h3 = find("can0/3");
  REQUIRE(h3 != nullptr);
  const auto* h2 = find("can0/2");
  REQUIRE(h2 != nullptr);
  const auto* group = find("can group arm");
  REQUIRE(group != nullptr);
  CHECK(group->group);
  REQUIRE(group->rx_gap);
  CHECK(group->rx_gap->count == h1->rx_gap->count + h2->rx_gap->count + h3->rx_gap->count);
}

TEST_CASE("A bad can: section is refused at build time with file:line:col", "[deploy][can]") {
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.can_bus, activity: io}]
can: {node_map: canopn}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE_FALSE(sys.has_value());
  CHECK_THAT(config::to_string(sys.error()), Catch::StartsWith("can.yaml:4:17: can.node_map:"));
}

TEST_CASE("A CAN node that stops and starts responding is an event, with its fault time",
          "[deploy][can][events]") {
  // Node 3 is quiet from about 50 ms to about 300 ms (cycles of 5 ms); its limit is 100 ms.
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.can_bus, activity: io,
              parameters: {quiet_after: 10, back_after: 60}}]
supervision: {lock_memory: false, monitor_period: 20ms}
can:
  node_map: canopen
  defaults: {not_responding: {after: 100ms}}
  nodes: {drive_1: {node: 1, bus: 0}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  std::mutex m;
  std::vector<Event> seen;
  const auto sub = (*sys)->service().events().subscribe([&](const Event& e) {
    if (e.kind != EventKind::NotResponding && e.kind != EventKind::Responding) return;
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  const Nanos start = platform::now_ns();
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  (*sys)->stop();
  (*sys)->service().events().flush();
  (*sys)->service().events().unsubscribe(sub);
  const std::lock_guard lock(m);
  REQUIRE(seen.size() == 2);  // one per change; none for the nodes that kept sending
  const Event& down = seen[0];
  CHECK(down.kind == EventKind::NotResponding);
  CHECK(down.severity == EventSeverity::Error);
  CHECK(down.component == "can0/3");
  CHECK(down.detail.find("not responding") != std::string::npos);
  // It failed when its silence passed the limit: 100 ms after its last frame.
  CHECK(down.fault_ns > start + 100 * kNanosPerMilli);
  CHECK(down.detected_ns >= down.fault_ns);
  const Event& up = seen[1];
  CHECK(up.kind == EventKind::Responding);
  CHECK(up.severity == EventSeverity::Info);
  CHECK(up.component == "can0/3");
  CHECK(up.fault_ns > down.fault_ns);  // its first frame again
  CHECK(up.detected_ns >= up.fault_ns);
  CHECK(std::string(to_string(up.kind)) == "responding");
  CHECK(std::string(to_string(down.kind)) == "not_responding");
}

TEST_CASE("CANopen resets, emergencies and a bus off are events, units show them",
          "[deploy][can][events]") {
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.canopen_bus, activity: io}]
supervision: {lock_memory: false, monitor_period: 20ms}
can:
  node_map: canopen
  buses: {all: {bitrate: 500k}}
  nodes: {drive_1: {node: 1, bus: 0}}
  groups: {arm: {nodes: [1], bus: 0}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  std::mutex m;
  std::vector<Event> seen;
  const auto sub = (*sys)->service().events().subscribe([&](const Event& e) {
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  (*sys)->stop();
  const ReportSet r = (*sys)->step_monitor();
  (*sys)->service().events().flush();
  (*sys)->service().events().unsubscribe(sub);
  const std::lock_guard lock(m);
  const auto find = [&](EventKind k) -> const Event* {
    for (const Event& e : seen) {
      if (e.kind == k) return &e;
    }
    return nullptr;
  };
  const Event* reset = find(EventKind::NodeReset);
  REQUIRE(reset != nullptr);
  CHECK(reset->component == "can0/drive_1");
  CHECK(reset->severity == EventSeverity::Warn);
  CHECK(reset->fault_ns > 0);
  CHECK(reset->detected_ns >= reset->fault_ns);
  const Event* emcy = find(EventKind::Emergency);
  REQUIRE(emcy != nullptr);
  CHECK(emcy->detail.find("0x8130") != std::string::npos);
  const Event* off = find(EventKind::BusOff);
  REQUIRE(off != nullptr);
  CHECK(off->component == "can bus 0");
  CHECK(off->severity == EventSeverity::Error);
  REQUIRE(find(EventKind::NmtState) != nullptr);

  const Report* bus0 = r.find("can bus 0");
  REQUIRE(bus0 != nullptr);
  CHECK(bus0->kind_name() == "can_bus");
  CHECK(bus0->state_label == "bus off");
  CHECK(bus0->status.level() == StatusLevel::Error);
  REQUIRE(bus0->field("load_1m") != nullptr);
  CHECK(bus0->field("bus_offs")->count == 1);
  const Report* drive = r.find("can0/drive_1");
  REQUIRE(drive != nullptr);
  CHECK(drive->field("nmt_state")->text == "operational");
  CHECK(drive->field("resets")->count == 1);
  REQUIRE(drive->field("last_emergency") != nullptr);
  CHECK(drive->status.level() == StatusLevel::Warn);  // its reset and its emergency
  const Report* arm = r.find("can group arm");
  REQUIRE(arm != nullptr);
  CHECK(arm->status.level() == StatusLevel::Error);  // its bus is off
}

TEST_CASE("J1939 trouble codes and address claims are events, the node named by its claim",
          "[deploy][can][events][j1939]") {
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.j1939_bus, activity: io}]
supervision: {lock_memory: false, monitor_period: 20ms}
can:
  node_map: j1939
  buses: {all: {bitrate: 250k}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  std::mutex m;
  std::vector<Event> seen;
  const auto sub = (*sys)->service().events().subscribe([&](const Event& e) {
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  (*sys)->stop();
  const ReportSet r = (*sys)->step_monitor();
  (*sys)->service().events().flush();
  (*sys)->service().events().unsubscribe(sub);
  const std::lock_guard lock(m);
  const auto find = [&](EventKind k) -> const Event* {
    for (const Event& e : seen) {
      if (e.kind == k) return &e;
    }
    return nullptr;
  };
  const Event* claim = find(EventKind::AddressClaim);
  REQUIRE(claim != nullptr);
  CHECK(claim->severity == EventSeverity::Info);
  CHECK(claim->detail.find("address 0x00 claimed by engine") != std::string::npos);
  const Event* active = find(EventKind::DtcActive);
  REQUIRE(active != nullptr);
  CHECK(active->component == "can0/engine (0x00)");
  CHECK(active->severity == EventSeverity::Warn);
  CHECK(active->fault_ns > 0);
  CHECK(active->detected_ns >= active->fault_ns);
  CHECK(active->detail.rfind("SPN 100 FMI 1", 0) == 0);
  const Event* cleared = find(EventKind::DtcCleared);
  REQUIRE(cleared != nullptr);
  CHECK(cleared->severity == EventSeverity::Info);
  CHECK(std::string(to_string(EventKind::DtcActive)) == "dtc_active");

  const Report* engine = r.find("can0/engine (0x00)");
  REQUIRE(engine != nullptr);
  CHECK(engine->field("active_dtcs")->count == 0);
  REQUIRE(engine->field("j1939_name") != nullptr);
  CHECK(engine->field("lamps")->text == "MIL off, red stop off, amber warning off, protect off");
  // The DM2's code, previously active: a field, no event.
  REQUIRE(engine->field("previously_active_dtcs") != nullptr);
  CHECK(engine->field("previously_active_dtcs")->count == 1);
  REQUIRE(engine->field("previous_dtcs") != nullptr);
  CHECK(engine->field("previous_dtcs")->text.rfind("SPN 190 FMI 2 (data erratic", 0) == 0);
  CHECK(std::count_if(seen.begin(), seen.end(),
                      [](const Event& e) { return e.kind == EventKind::DtcActive; }) == 1);
}

TEST_CASE("CAN events leave at the CAN supervisor's pace, not the monitor's",
          "[deploy][can][events]") {
  // A monitor cycle every 30 s: were CAN events published with the monitor's cycles, none would
  // come in this test. Node 3 is quiet from about 50 ms (limit 100 ms); node 1's emergency comes
  // at about 250 ms and its bus goes off at about 300 ms.
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}, {name: io2, period: 5ms}]
components:
  - {name: bus, type: test.can_bus, activity: io, parameters: {quiet_after: 10}}
  - {name: canopen, type: test.canopen_bus, activity: io2}
supervision: {lock_memory: false, monitor_period: 30s}
can:
  node_map: canopen
  defaults: {not_responding: {after: 100ms}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  std::mutex m;
  std::condition_variable cv;
  std::vector<Event> seen;
  const auto sub = (*sys)->service().events().subscribe([&](const Event& e) {
    const std::lock_guard lock(m);
    seen.push_back(e);
    cv.notify_all();
  });
  const auto find = [&](EventKind k) -> const Event* {
    for (const Event& e : seen) {
      if (e.kind == k) return &e;
    }
    return nullptr;
  };
  const Nanos start = platform::now_ns();
  REQUIRE((*sys)->start().has_value());
  Nanos arrived = -1;
  {
    std::unique_lock lock(m);
    // A tenth of the monitor period at most (a loaded test host may be slow: no tighter).
    cv.wait_for(lock, std::chrono::seconds(3), [&] {
      return find(EventKind::NotResponding) != nullptr && find(EventKind::Emergency) != nullptr &&
             find(EventKind::BusOff) != nullptr;
    });
    arrived = platform::now_ns();
  }
  const std::uint64_t monitor_cycles = (*sys)->service().snapshot()->cycle;
  (*sys)->stop();
  (*sys)->service().events().flush();
  (*sys)->service().events().unsubscribe(sub);
  const std::lock_guard lock(m);
  const Event* down = find(EventKind::NotResponding);
  REQUIRE(down != nullptr);
  CHECK(down->component == "can0/3");
  // Judged on the frames' clock: its last frame + the limit, never before.
  CHECK(down->fault_ns > start + 100 * kNanosPerMilli);
  CHECK(down->detected_ns >= down->fault_ns);
  // Well within the monitor's period: the CAN supervisor woke for the limit.
  CHECK(down->detected_ns - down->fault_ns < kNanosPerSecond);
  REQUIRE(find(EventKind::Emergency) != nullptr);
  CHECK(find(EventKind::Emergency)->component == "can0/1");
  REQUIRE(find(EventKind::BusOff) != nullptr);
  CHECK(find(EventKind::BusOff)->detected_ns - find(EventKind::BusOff)->fault_ns < kNanosPerSecond);
  CHECK(arrived - start < 3 * kNanosPerSecond);
  // No monitor cycle after the first (if any) came before the events.
  CHECK(monitor_cycles <= 1);
}

TEST_CASE("A bus whose interface is no CAN controller says so, and supervision goes on",
          "[deploy][can][link]") {
  // `lo` exists on every Linux host and is no CAN device: the netlink reading fails with a reason
  // naming it, the bus is WARN, the nodes are judged as ever.
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.can_bus, activity: io, parameters: {quiet_after: 1000000}}]
supervision: {lock_memory: false, monitor_period: 50ms}
can:
  node_map: canopen
  buses: {0: {interface: lo}}
  nodes: {drive_1: {node: 1, bus: 0}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  REQUIRE((*sys)->start().has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  (*sys)->stop();
  const ReportSet r = (*sys)->step_monitor();
  const Report* bus = r.find("can bus 0");
  REQUIRE(bus != nullptr);
  CHECK(bus->status.level() == StatusLevel::Warn);
  CHECK_THAT(bus->status.summary(),
             Catch::Contains("CAN interface lo: not a CAN device (link kind: none)"));
  REQUIRE(bus->field("interface") != nullptr);
  CHECK(bus->field("interface")->text == "lo");
  REQUIRE(bus->field("link_read_failures") != nullptr);
  CHECK(bus->field("link_read_failures")->count >= 1);
  CHECK(bus->field("link_read_failures")->count == bus->field("link_reads")->count);
  const Report* drive = r.find("can0/drive_1");
  REQUIRE(drive != nullptr);
  CHECK(drive->status.ok());
  CHECK(drive->state_label == "responding");
}

TEST_CASE("A bus's controller read through netlink: its state judged, its changes events",
          "[deploy][can][link][events]") {
  // The readings an RTM_GETLINK would give, replayed: error active at 250 kbit/s, then error
  // passive, then bus off.
  auto spec = load_deployment_string(R"(
activities: [{name: io, period: 5ms}]
components: [{name: bus, type: test.can_bus, activity: io, parameters: {quiet_after: 1000000}}]
supervision: {lock_memory: false, monitor_period: 20ms}
can:
  node_map: canopen
  buses: {0: {interface: fake0}}
  groups: {arm: {nodes: [1, 2, 3], bus: 0}}
)",
                                     "can.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  auto* ext = (*sys)->extension<CanExtension>();
  REQUIRE(ext != nullptr);
  std::atomic<int> reads{0};
  ext->set_link_query([&](std::string_view name) -> expected<can::LinkInfo, Error> {
    const int n = ++reads;
    can::LinkInfo i;
    i.name = std::string(name);
    i.kind = "can";
    i.up = true;
    i.bitrate = 250000;
    i.state = n <= 3   ? can::LinkControllerState::ErrorActive
              : n <= 6 ? can::LinkControllerState::ErrorPassive
                       : can::LinkControllerState::BusOff;
    i.tx_errors = static_cast<std::uint16_t>(n <= 3 ? 0 : n <= 6 ? 130 : 256);
    i.rx_errors = 0;
    return i;
  });
  std::mutex m;
  std::vector<Event> seen;
  const auto sub = (*sys)->service().events().subscribe([&](const Event& e) {
    if (e.component != "can bus 0") return;
    const std::lock_guard lock(m);
    seen.push_back(e);
  });
  REQUIRE((*sys)->start().has_value());
  for (int i = 0; i < 200 && reads.load() < 10; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  (*sys)->stop();
  const ReportSet r = (*sys)->step_monitor();
  (*sys)->service().events().flush();
  (*sys)->service().events().unsubscribe(sub);
  REQUIRE(reads.load() >= 7);
  {
    const std::lock_guard lock(m);
    REQUIRE(seen.size() == 2);  // the first reading is error active: no event
    CHECK(seen[0].kind == EventKind::ErrorPassive);
    CHECK(seen[0].severity == EventSeverity::Warn);
    CHECK(seen[0].detail ==
          "fake0 (netlink): error active -> error passive; error counters tx "
          "130 rx 0");
    CHECK(seen[1].kind == EventKind::BusOff);
    CHECK(seen[1].severity == EventSeverity::Error);
    CHECK(seen[1].detected_ns >= seen[1].fault_ns);
  }
  const Report* bus = r.find("can bus 0");
  REQUIRE(bus != nullptr);
  CHECK(bus->status.level() == StatusLevel::Error);
  CHECK(bus->state_label == "bus off");
  CHECK_THAT(bus->status.summary(), Catch::Contains("controller bus off (fake0, read live"));
  REQUIRE(bus->field("bitrate") != nullptr);
  CHECK(bus->field("bitrate")->count == 250000);
  CHECK(bus->field("bitrate_source")->text == "netlink");
  CHECK(bus->field("controller_state_code")->count == 3);
  CHECK(bus->field("link_tx_error_counter")->count == 256);
  // The load is counted with the interface's bitrate (none configured).
  REQUIRE(bus->field("load_1m") != nullptr);
  const Report* arm = r.find("can group arm");
  REQUIRE(arm != nullptr);
  CHECK(arm->status.level() == StatusLevel::Error);  // its nodes' bus is off
}
