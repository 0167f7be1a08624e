#pragma once
// Helpers shared by the CAN supervision tests: frames, draining a CAN registry's ports, and a
// pipeline (sniffer -> supervisor -> aggregator) stepped by hand with simulated time.
#include <memory>
#include <vector>

#include "vigil/can/can_statistics.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/sniffer.hpp"

namespace vigil::can::test {

/// Every record waiting in the registry's ports (as a supervisor would see them).
inline std::vector<FrameRecord> drain_records(CanRegistry& registry) {
  std::vector<std::shared_ptr<bus::RegistryEntry<CanMessage>>> entries;
  registry.ports().collect(entries);
  std::vector<FrameRecord> out;
  CanMessage buf[64];
  for (const auto& e : entries) {
    for (;;) {
      const std::size_t n = e->port->pop(buf, 64);
      if (n == 0) break;
      for (std::size_t i = 0; i < n; ++i) out.push_back(std::get<FrameRecord>(buf[i]));
    }
  }
  return out;
}

/// A classic frame with 11-bit `id` on `bus` at time `t`.
inline Frame frame(std::uint32_t id, Nanos t = 0, std::uint8_t bus = 0,
                   std::initializer_list<std::uint8_t> data = {0x01}) {
  Frame f = Frame::classic(id, data);
  f.bus = bus;
  f.timestamp = t;
  return f;
}

/// A sniffer of capacity N with its supervisor and aggregator, driven by hand.
///
/// The supervisor's clock is `clock_ns` (the frames' clock): the start of a cycle is the time up
/// to which the CAN monitor judges silences. It starts far in the future, so that a step means
/// "everything up to the monitor's `now` was read" (as a replay's report); set it, or step with
/// `step_at`, to model a supervisor that runs at a given time (late, for instance).
template <std::size_t N = 1024>
struct Pipeline {
  static constexpr Nanos kUpToDate = Nanos{1} << 62;

  CanRegistry registry;
  Sniffer<N> sniffer;
  CanAggregator aggregator;
  Nanos clock_ns = kUpToDate;
  CanDrainLoop supervisor;

  explicit Pipeline(SnifferOptions options = {}, CanAggregatorOptions agg = {})
      : sniffer(registry, "test-bus", options),
        aggregator(registry, agg),
        supervisor(registry.ports(), aggregator,
                   supervisor::DrainOptions{.clock = Clock{&read_clock, &clock_ns}}) {}

  /// Runs one supervisor cycle at time `t`.
  void step_at(Nanos t) {
    clock_ns = t;
    supervisor.step();
  }

  /// A read of `f` that took `io` ns and returned at f.timestamp.
  void read(const Frame& f, Nanos io = 0) { sniffer.on_read(f, f.timestamp - io, f.timestamp); }
  void write(const Frame& f, Nanos io = 0) { sniffer.on_write(f, f.timestamp - io, f.timestamp); }
  CanSnapshot step(std::span<const GroupSpec> groups = {}) {
    supervisor.step();
    return aggregator.snapshot(groups);
  }

 private:
  static Nanos read_clock(const void* t) noexcept { return *static_cast<const Nanos*>(t); }
};

}  // namespace vigil::can::test
