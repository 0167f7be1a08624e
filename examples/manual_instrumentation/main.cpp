// manual_instrumentation: supervision for code that cannot change its base class.
//
// A vendor's control loop derives from the vendor's base and owns its thread. It keeps a
// vigil::Instrumentation as a member: init() once from its thread, then an UpdateGuard per
// cycle (pre on construction, post on destruction). The data is the same as Task<Derived>'s.
#include <cstdio>
#include <stdexcept>
#include <thread>

#include "vigil/vigil.hpp"

// Pretend this comes from a vendor SDK.
class VendorLoopBase {
 public:
  virtual ~VendorLoopBase() = default;
  virtual void cycle() = 0;
};

class Gripper : public VendorLoopBase {
 public:
  void run(int cycles) {
    sup_.init({.activity = "vendor-loop", .period_ns = 2 * vigil::kNanosPerMilli});
    vigil::Nanos release = vigil::platform::now_ns();
    for (int i = 0; i < cycles; ++i) {
      vigil::platform::sleep_until(release);
      {
        vigil::UpdateGuard guard(sup_, release);  // times this cycle against its release
        cycle();
      }
      release += 2 * vigil::kNanosPerMilli;
    }
    // Or, to catch and report exceptions with their type and message:
    sup_.run([] { throw std::runtime_error("gripper jammed"); }, release);
  }
  void cycle() override {
    volatile double force = 0;
    for (int i = 0; i < 1000; ++i) force = force + i * 1e-3;
  }

 private:
  vigil::Instrumentation sup_{"gripper"};
};

int main() {
  vigil::supervisor::ComponentAggregator aggregator;
  vigil::supervisor::TaskSupervisor supervisor(vigil::default_registry(), aggregator);
  vigil::Monitor monitor(aggregator);
  supervisor.start();

  std::thread t([] { Gripper().run(500); });
  t.join();
  supervisor.stop();

  const vigil::ReportSet reports = monitor.step();
  vigil::print_summary(stdout, reports);
  const auto* r = reports.find("gripper");
  return r != nullptr && r->counters.cycles == 501 && r->counters.exceptions == 1 ? 0 : 1;
}
