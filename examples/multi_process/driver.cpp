// The driver process of examples/multi_process: a bus driver at 1 kHz and its diagnostics at
// 10 Hz, two threads. Like the controllers it is an ordinary vigil program; VIGIL_SUPERVISOR
// in its environment sends its components to the daemon.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "vigil/vigil.hpp"

namespace {

class BusDriver : public vigil::Task<BusDriver> {
 public:
  BusDriver() : Task("driver.bus") {}
  void on_update() {
    // Encode eight frames (stand-in for the real I/O).
    for (auto& f : frames_) f = (f * 1103515245U + 12345U) & 0x7FFFFFFFU;
  }

 private:
  unsigned frames_[8] = {1, 2, 3, 4, 5, 6, 7, 8};
};

class Diagnostics : public vigil::Task<Diagnostics> {
 public:
  Diagnostics() : Task("driver.diagnostics") {}
  void on_update() { ++checks_; }

 private:
  unsigned long checks_ = 0;
};

}  // namespace

int main() {
  vigil::platform::install_stop_signals();
  vigil::platform::setup_realtime_process({.request_zero_cpu_latency = false});
  BusDriver bus;
  Diagnostics diag;
  bus.configure();
  diag.configure();
  vigil::PeriodicActivity fast(bus, {.name = "bus",
                                     .period_ns = vigil::kNanosPerMilli,
                                     .policy = vigil::SchedPolicy::Fifo,
                                     .priority = 85});
  vigil::PeriodicActivity slow(diag,
                               {.name = "diagnostics", .period_ns = 100 * vigil::kNanosPerMilli});
  if (!fast.start() || !slow.start()) {
    std::fprintf(stderr, "driver: cannot start its activities\n");
    return 1;
  }
  std::printf("driver: pid %d, bus at 1 kHz, diagnostics at 10 Hz\n",
              static_cast<int>(vigil::platform::self_identity().pid));
  std::fflush(stdout);
  while (!vigil::platform::stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  fast.stop();
  slow.stop();
  std::printf("driver: stopped\n");
  return 0;
}
