// The `can:` section through vigil::deploy_can: linking the target is all a program does (no
// registration call anywhere in this binary).
#include "vigil/deploy/can_extension.hpp"

#include <catch2/catch.hpp>
#include <thread>

#include "vigil/deploy/system.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

// Sends TPDO1 of nodes 1..3 every cycle (as read frames); node 3 stops after `quiet_after`.
class Bus : public Task<Bus> {
 public:
  explicit Bus(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        quiet_after_(c.parameters.optional<std::uint64_t>("quiet_after", 20)) {
    auto* ext = c.system->extension<CanExtension>();
    if (ext == nullptr) throw std::runtime_error("needs a can: section");
    sniffer_ = std::make_unique<can::Sniffer<64>>(
        ext->registry(), c.name, can::SnifferOptions{.node_map = can::NodeMap::canopen()});
  }
  void on_update() {
    ++cycle_;
    for (std::uint32_t node = 1; node <= 3; ++node) {
      if (node == 3 && cycle_ > quiet_after_) continue;
      const Nanos t = platform::now_ns();
      can::Frame f = can::Frame::classic(0x180 + node, {0x01});
      f.timestamp = t;
      sniffer_->on_read(f, t, t);
    }
  }

 private:
  std::uint64_t quiet_after_;
  std::uint64_t cycle_ = 0;
  std::unique_ptr<can::Sniffer<64>> sniffer_;
};

ComponentFactory& factory() {
  static ComponentFactory f;
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
