// Memory: what a supervised component, a port, a CAN sniffer and a CAN node cost in RAM.
//
// Measured as the growth of the heap in use (glibc's mallinfo2: bytes in allocated chunks,
// arenas and mmapped blocks together) between before and after adding N of them, divided by N.
// Under mlockall every allocated byte is resident and locked, so this is what each costs in
// locked RAM (without locking only the touched pages are resident; that is not measured here:
// from one repetition to the next the allocator reuses pages already resident). Thread stacks
// are not in these rows (activities share threads; a thread costs its stack:
// docs/design/memory.md).
//
// memory/supervised_component: N components (Task<Derived> with an empty on_update, its port of
//   256 messages in the registry, a ManualActivity) that each ran 10 cycles, then one supervisor
//   step (the aggregator's record) and one monitor step (the monitor's per-component state).
//   Counter `sizeof_bytes`: the same computed from sizeof of what is public: the port
//   (Port<Message, 256>), the aggregator record's four CompactRunningStats (user, latency,
//   period, overhead: 120 bytes each, plus one 256-byte chunk of histogram counters each for
//   these components' narrow distributions), its flight ring (1024 x 32 bytes) and its
//   ComponentSnapshot, the task and its activity; the measured value also has the rest of the
//   record (hot fields, the exact total), the allocator's rounding, the names, the registry
//   entry and the monitor's state. Counter `region_tail_bytes`: the part of the value that is
//   the last huge-page region's unused blocks (flight rings are carved from 2 MiB regions, 64
//   rings each, beyond the first 64 components), per component.
// memory/port: sizeof(Port<Message, N>) for the default capacity (computed, not measured).
// memory/can_sniffer: one Sniffer<1024> with default tables (1024 ids, 256 nodes), registered
//   with a CanAggregator.
// memory/can_node: N CANopen nodes, one TPDO each, received through that sniffer and
//   aggregated (one id slot and one node slot each).
#include <malloc.h>

#include <memory>
#include <string>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/bus/port.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/task.hpp"
#if __has_include("vigil/can/sniffer.hpp")
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/sniffer.hpp"
#define VIGIL_BENCH_HAVE_CAN 1
#endif

namespace vigil::bench {
namespace {

/// Bytes the allocator has handed out and not got back.
std::size_t heap_in_use() {
  const struct mallinfo2 mi = mallinfo2();
  return mi.uordblks + mi.hblkhd;
}

class Component : public Task<Component> {
 public:
  Component(std::string name, Registry<task::Message>& registry)
      : Task(std::move(name), {}, registry) {}
  void on_update() { empty_update(); }
};

struct Supervised {
  Supervised(std::string name, Registry<task::Message>& registry)
      : task(std::move(name), registry),
        activity(task, ManualConfig{.name = "memory", .period_ns = kNanosPerMilli}) {
    (void)task.configure();
    (void)activity.start();
  }
  Component task;
  ManualActivity activity;
};

void supervised_component(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  double per = 0;
  double tail = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Registry<task::Message> registry;
    supervisor::ComponentAggregator aggregator;
    supervisor::ComponentDrainLoop supervisor(registry, aggregator);
    MonitorOptions mo;
    mo.read_thread_stats = false;
    Monitor monitor(aggregator, mo);
    (void)supervisor.step();
    (void)monitor.step();
    std::vector<std::unique_ptr<Supervised>> components;
    components.reserve(n);
    const std::size_t heap0 = heap_in_use();
    state.ResumeTiming();
    for (std::size_t i = 0; i < n; ++i) {
      components.push_back(
          std::make_unique<Supervised>("component_" + std::to_string(i), registry));
      for (int k = 0; k < 10; ++k) (void)components.back()->activity.step();
    }
    (void)supervisor.step();
    (void)monitor.step();
    state.PauseTiming();
    // Flight rings on huge pages (RingPages::Auto, beyond the first 64) are in regions of their
    // own, outside malloc's count: added.
    per = static_cast<double>(heap_in_use() - heap0 + aggregator.ring_region_bytes()) /
          static_cast<double>(n);
    // Of which: the last region's blocks that no ring uses yet (a region is mapped whole, 64
    // rings at a time), spread over the components.
    const std::size_t ring_bytes =
        supervisor::FlightRecorderOptions{}.cycles * sizeof(supervisor::PackedCycle);
    tail = static_cast<double>(aggregator.ring_region_bytes() -
                               aggregator.rings_on_huge_pages() * ring_bytes) /
           static_cast<double>(n);
    components.clear();
    state.ResumeTiming();
  }
  report(state, "bytes/component", per);
  const double sizeof_bytes = static_cast<double>(
      sizeof(Port<task::Message, kDefaultPortCapacity>) +
      4 * (sizeof(supervisor::CompactRunningStats) + 256) +
      supervisor::FlightRecorderOptions{}.cycles * sizeof(supervisor::PackedCycle) +
      sizeof(supervisor::ComponentSnapshot) + sizeof(Supervised));
  state.counters["sizeof_bytes"] = sizeof_bytes;
  state.counters["region_tail_bytes"] = tail;
}

void port_size(benchmark::State& state) {
  for (auto _ : state) {
  }
  report(state, "bytes/port (sizeof)",
         static_cast<double>(sizeof(Port<task::Message, kDefaultPortCapacity>)));
  state.counters["message_bytes"] = static_cast<double>(sizeof(task::Message));
  state.counters["capacity"] = static_cast<double>(kDefaultPortCapacity);
}

#ifdef VIGIL_BENCH_HAVE_CAN
void can_sniffer(benchmark::State& state) {
  double per = 0;
  for (auto _ : state) {
    can::CanRegistry registry;
    can::CanAggregator aggregator(registry);
    can::CanDrainLoop supervisor(registry.ports(), aggregator);
    (void)supervisor.step();
    const std::size_t heap0 = heap_in_use();
    auto sniffer = std::make_unique<can::Sniffer<1024>>(registry, "bus0");
    (void)supervisor.step();
    per = static_cast<double>(heap_in_use() - heap0);
  }
  report(state, "bytes/sniffer", per);
  state.counters["port_sizeof_bytes"] = static_cast<double>(sizeof(Port<can::CanMessage, 1024>));
}

void can_node(benchmark::State& state) {
  const auto n = static_cast<std::uint32_t>(state.range(0));
  double per = 0;
  for (auto _ : state) {
    can::CanRegistry registry;
    can::CanAggregator aggregator(registry);
    can::CanDrainLoop supervisor(registry.ports(), aggregator);
    can::Sniffer<1024> sniffer(registry, "bus0", {.node_map = can::NodeMap::canopen()});
    (void)supervisor.step();
    const std::size_t heap0 = heap_in_use();
    Nanos t = platform::now_ns();
    for (int round = 0; round < 4; ++round) {  // several frames per node: gaps are measured
      for (std::uint32_t node = 1; node <= n; ++node) {
        t += 10'000;
        can::Frame f = can::Frame::classic(0x180 + node, {0x27, 0x06, 0x00, 0x10});
        f.timestamp = t;
        sniffer.on_read(f, t - 2'000, t);
      }
      (void)supervisor.step();
    }
    per = static_cast<double>(heap_in_use() - heap0) / n;
  }
  report(state, "bytes/node (rx, 1 id)", per);
}
#else
void can_sniffer(benchmark::State& state) {
  for (auto _ : state) {
  }
  state.SkipWithError("not available: the can module is not built");
}
void can_node(benchmark::State& state) { can_sniffer(state); }
#endif

}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::supervised_component)
    ->Name("memory/supervised_component")
    ->ArgNames({"components"})
    ->Arg(1'000)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(vigil::bench::port_size)->Name("memory/port")->Iterations(1);
BENCHMARK(vigil::bench::can_sniffer)->Name("memory/can_sniffer")->Iterations(1);
BENCHMARK(vigil::bench::can_node)
    ->Name("memory/can_node")
    ->ArgNames({"nodes"})
    ->Arg(100)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
