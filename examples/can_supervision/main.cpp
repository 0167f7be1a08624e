// can_supervision: a simulated CAN I/O component whose every frame goes through a sniffer, a CAN
// supervisor at 10 Hz, and a CAN monitor with thresholds from a YAML file.
//
// The component runs at 1 kHz. Each cycle it sends SYNC and one RPDO1 to each of four CANopen
// drives (nodes 1-4), and reads their TPDO1 answers. After 1.5 s drive 4 stops answering. The
// sniffer's port holds only 64 records, far fewer than the 9000 frames a second: counts and
// liveness stay exact anyway. Prints the CAN report every second, and the last one as JSON with
// --json.
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/export/can_report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/task/task.hpp"

namespace can = vigil::can;

namespace {

// Busy for `ns` nanoseconds: what a driver call costs.
void spend(vigil::Nanos ns) {
  const vigil::Nanos end = vigil::platform::now_ns() + ns;
  while (vigil::platform::now_ns() < end) {
  }
}

// A simulated CAN controller: every RPDO1 written to a drive is answered with its TPDO1, except
// by a drive that has failed. Fixed capacity, no allocation after construction.
class SimulatedBus {
 public:
  void write(const can::Frame& f) {
    spend(8 * vigil::kNanosPerMicro);
    const std::uint32_t node = f.id & 0x7F;
    if ((f.id >> 7) == 4 && node != failed_ && count_ < answers_.size()) {  // RPDO1
      answers_[(head_ + count_++) % answers_.size()] =
          can::Frame::classic(0x180 + node, {0x27, 0x06, 0x00, 0x10});  // TPDO1: status word
    }
  }
  bool read(can::Frame& out) {
    spend(5 * vigil::kNanosPerMicro);
    if (count_ == 0) return false;
    out = answers_[head_];
    head_ = (head_ + 1) % answers_.size();
    --count_;
    return true;
  }
  void fail(std::uint32_t node) { failed_ = node; }

 private:
  std::array<can::Frame, 16> answers_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::uint32_t failed_ = 0;
};

// The CAN I/O component: a vigil task at 1 kHz that times every driver call into the sniffer.
class CanIo : public vigil::Task<CanIo> {
 public:
  CanIo(can::CanRegistry& registry, SimulatedBus& bus)
      : Task("can_io"),
        bus_(bus),
        sniffer_(registry, "can0", {.max_ids = 64, .node_map = can::NodeMap::canopen()}) {}

  void on_update() {
    send(can::Frame::classic(0x080, {}));  // SYNC
    for (std::uint32_t node = 1; node <= 4; ++node) {
      send(can::Frame::classic(0x200 + node, {0x0F, 0x00, 0x00, 0x10}));  // RPDO1: control word
    }
    can::Frame f;
    for (;;) {
      const vigil::Nanos t0 = vigil::platform::now_ns();
      const bool got = bus_.read(f);
      const vigil::Nanos t1 = vigil::platform::now_ns();
      if (!got) break;
      f.timestamp = t1;
      sniffer_.on_read(f, t0, t1);  // RT-safe: exact counts, timing to the port
    }
  }

  can::Sniffer<64>& sniffer() { return sniffer_; }

 private:
  void send(can::Frame f) {
    const vigil::Nanos t0 = vigil::platform::now_ns();
    bus_.write(f);
    const vigil::Nanos t1 = vigil::platform::now_ns();
    f.timestamp = t1;
    sniffer_.on_write(f, t0, t1);
  }

  SimulatedBus& bus_;
  can::Sniffer<64> sniffer_;
};

}  // namespace

int main(int argc, char** argv) {
  bool json = false;
  const char* config_path = VIGIL_CAN_EXAMPLE_CONFIG;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0) {
      json = true;
    } else {
      config_path = argv[i];
    }
  }
  auto config = can::load_can_config_file(config_path);
  if (!config) {
    std::fprintf(stderr, "%s\n", vigil::config::to_string(config.error()).c_str());
    return 1;
  }

  can::CanRegistry registry;
  SimulatedBus bus;
  CanIo io(registry, bus);
  if (auto ok = io.sniffer().set_filter(config->filter); !ok) {
    std::fprintf(stderr, "filter: %s\n", ok.error().message.c_str());
    return 1;
  }
  can::CanAggregator statistics(registry);
  can::CanDrainLoop supervisor(
      registry.ports(), statistics,
      {.period_ns = 100 * vigil::kNanosPerMilli, .thread_name = "can-supervisor"});
  can::CanMonitor monitor(*config);

  io.configure();
  vigil::PeriodicActivity activity(io, {.name = "can_io", .period_ns = vigil::kNanosPerMilli});
  if (auto ok = activity.start(); !ok) {
    std::fprintf(stderr, "cannot start: %s\n", ok.error().message.c_str());
    return 1;
  }
  if (auto ok = supervisor.start(); !ok) {
    std::fprintf(stderr, "cannot start the CAN supervisor: %s\n", ok.error().message.c_str());
    return 1;
  }

  const vigil::exporter::CanTextOptions text{.ids = false, .bus_names = {"can0"}};
  const auto print = [&](const char* when) {
    if (json) return;
    const can::CanReport r = monitor.evaluate(statistics, vigil::platform::now_ns());
    std::printf("--- %s\n%s\n", when, vigil::exporter::format_can_report(r, text).c_str());
  };
  using namespace std::chrono_literals;
  std::this_thread::sleep_for(1s);
  print("after 1 s: every drive responding, the gripper never seen");
  std::this_thread::sleep_for(500ms);
  bus.fail(4);  // drive 4 stops answering at 1.5 s
  std::this_thread::sleep_for(500ms);
  print("after 2 s: drive 4 silent for 0.5 s");
  std::this_thread::sleep_for(1s);

  // Judge the nodes as of when the bus stopped, not after the shutdown's own delay.
  const vigil::Nanos end = vigil::platform::now_ns();
  activity.stop();
  supervisor.stop();  // one last full drain
  const can::CanReport r = monitor.evaluate(statistics, end);
  if (json) {
    std::puts(vigil::exporter::can_report_json(r, 2, {"can0"}).c_str());
  } else {
    std::printf("--- after 3 s\n%s",
                vigil::exporter::format_can_report(r, {.bus_names = {"can0"}}).c_str());
  }
  return 0;
}
