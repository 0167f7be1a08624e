// Wake-up latency of a vigil PeriodicActivity, printed in cyclictest's histogram format so that
// benches/latency.sh computes both tools' percentiles with the same code.
//
// A Task<Derived> runs on a PeriodicActivity (SCHED_FIFO, given priority, pinned CPU, given
// period, a thread of its own); each cycle's latency is start_ns - release_ns, the same numbers
// its CycleSample carries: when on_update() began minus the scheduled release. Memory is locked
// first (cyclictest -m), /dev/cpu_dma_latency is held at 0 (cyclictest's default), and a supervisor
// drains the component's port at its default period, as in a deployment, pinned to another CPU.
// Latencies are counted in 1 us buckets, truncated, as cyclictest -h does.
//
// usage: vigil_latency [-p prio] [-a cpu] [-i interval_us] [-D seconds] [-h max_us]
// stdout: "%06d %06llu" lines per bucket, then "# Total/Min/Avg/Max Latencies/Histogram
// Overflows" lines like cyclictest's; stderr: the policy obtained and the supervisor's view.
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <thread>
#include <vector>

#include "vigil/exec/periodic_activity.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#include "vigil/task/task.hpp"

namespace {

struct Options {
  int priority = 80;
  int cpu = 1;
  long interval_us = 1000;
  long duration_s = 30;
  long max_us = 1000;
};

class LatencyProbe : public vigil::Task<LatencyProbe> {
 public:
  explicit LatencyProbe(std::size_t buckets) : Task("latency_probe"), histogram_(buckets, 0) {}

  void on_update() {
    const vigil::CycleContext& c = cycle();
    const vigil::Nanos ns = c.start_ns - c.release_ns;
    const vigil::Nanos clamped = ns < 0 ? 0 : ns;
    const auto us = static_cast<std::size_t>(clamped / vigil::kNanosPerMicro);
    if (us < histogram_.size()) {
      ++histogram_[us];
    } else {
      ++overflows_;
    }
    ++count_;
    sum_us_ += us;
    min_ns_ = clamped < min_ns_ ? clamped : min_ns_;
    max_ns_ = clamped > max_ns_ ? clamped : max_ns_;
  }

  // Read after the activity stopped (its stop() is the hand-over).
  const std::vector<std::uint64_t>& histogram() const { return histogram_; }
  std::uint64_t overflows() const { return overflows_; }
  std::uint64_t count() const { return count_; }
  std::uint64_t sum_us() const { return sum_us_; }
  vigil::Nanos min_ns() const { return count_ == 0 ? 0 : min_ns_; }
  vigil::Nanos max_ns() const { return max_ns_; }

 private:
  std::vector<std::uint64_t> histogram_;  // allocated before the thread starts
  std::uint64_t overflows_ = 0;
  std::uint64_t count_ = 0;
  std::uint64_t sum_us_ = 0;
  vigil::Nanos min_ns_ = std::numeric_limits<vigil::Nanos>::max();
  vigil::Nanos max_ns_ = 0;
};

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    auto value = [&] { return std::atol(argv[++i]); };
    if (std::strcmp(argv[i], "-p") == 0 && has_value) {
      o.priority = static_cast<int>(value());
    } else if (std::strcmp(argv[i], "-a") == 0 && has_value) {
      o.cpu = static_cast<int>(value());
    } else if (std::strcmp(argv[i], "-i") == 0 && has_value) {
      o.interval_us = value();
    } else if (std::strcmp(argv[i], "-D") == 0 && has_value) {
      o.duration_s = value();
    } else if (std::strcmp(argv[i], "-h") == 0 && has_value) {
      o.max_us = value();
    } else {
      std::fprintf(stderr,
                   "usage: %s [-p prio] [-a cpu] [-i interval_us] [-D seconds] [-h max_us]\n",
                   argv[0]);
      return false;
    }
  }
  return o.interval_us > 0 && o.duration_s > 0 && o.max_us > 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (!parse(argc, argv, o)) return 2;

  const auto setup = vigil::platform::setup_realtime_process();
  if (!setup.memory_locked) std::fprintf(stderr, "vigil_latency: memory NOT locked\n");
  // As cyclictest does by default: ask for a 0 us wake-up latency target (PM QoS) while we
  // measure, so that idle CPUs stay in shallow idle states (or poll, under haltpoll in a VM).
  // The request holds while the file stays open. Without it the comparison would measure the
  // idle states, not the wake-up path.
  const int qos = ::open("/dev/cpu_dma_latency", O_RDWR | O_CLOEXEC);
  const std::int32_t target_us = 0;
  const bool qos_set = qos >= 0 && ::write(qos, &target_us, sizeof(target_us)) == sizeof(target_us);
  std::fprintf(stderr, "vigil_latency: /dev/cpu_dma_latency = 0: %s\n",
               qos_set ? "held" : "not available (results include idle-state exits)");

  // The supervisor drains the component's port every 10 ms, as in a deployment, on a CPU other
  // than the measured one (what DrainLoop::start() does, plus the pinning it does not offer).
  vigil::supervisor::ComponentAggregator aggregator;
  vigil::supervisor::ComponentDrainLoop supervisor(vigil::default_registry(), aggregator);
  std::atomic<bool> quit{false};
  const int ncpu = vigil::platform::cpu_count();
  const int supervisor_cpu = ncpu > 1 ? (o.cpu + 1) % ncpu : -1;
  auto supervisor_thread =
      vigil::platform::Thread::spawn({.name = "vigil-supervisor", .cpu = supervisor_cpu}, [&] {
        const vigil::Nanos period = supervisor.options().period_ns;
        vigil::Nanos next = vigil::platform::now_ns();
        while (!quit.load(std::memory_order_acquire)) {
          (void)supervisor.step();
          next += period;
          vigil::platform::sleep_until(next);
        }
      });
  if (!supervisor_thread) {
    std::fprintf(stderr, "vigil_latency: supervisor: %s\n",
                 supervisor_thread.error().message.c_str());
    return 1;
  }

  LatencyProbe probe(static_cast<std::size_t>(o.max_us));
  vigil::PeriodicActivity activity(
      probe, vigil::PeriodicConfig{.name = "latency",
                                   .period_ns = o.interval_us * vigil::kNanosPerMicro,
                                   .policy = vigil::SchedPolicy::Fifo,
                                   .priority = o.priority,
                                   .cpu = o.cpu,
                                   .share_thread = false});
  if (!probe.configure()) return 1;
  if (auto r = activity.start(); !r) {
    std::fprintf(stderr, "vigil_latency: start: %s\n", r.error().message.c_str());
    return 1;
  }
  const auto& info = activity.info();
  std::fprintf(stderr, "vigil_latency: policy %s priority %d cpu %d%s\n",
               vigil::platform::to_string(info.policy), info.priority, info.cpu,
               info.realtime_refused ? " (FIFO refused: results are not real-time)" : "");

  std::this_thread::sleep_for(std::chrono::seconds(o.duration_s));
  activity.stop();
  quit.store(true, std::memory_order_release);
  supervisor_thread->join();
  (void)supervisor.step();

  if (qos >= 0) ::close(qos);

  const auto& h = probe.histogram();
  for (std::size_t i = 0; i < h.size(); ++i) {
    std::printf("%06zu %06llu\n", i, static_cast<unsigned long long>(h[i]));
  }
  const std::uint64_t n = probe.count();
  std::printf("# Total: %09llu\n", static_cast<unsigned long long>(n));
  std::printf("# Min Latencies: %05lld\n",
              static_cast<long long>(probe.min_ns() / vigil::kNanosPerMicro));
  std::printf("# Avg Latencies: %05llu\n",
              static_cast<unsigned long long>(n == 0 ? 0 : probe.sum_us() / n));
  std::printf("# Max Latencies: %05lld\n",
              static_cast<long long>(probe.max_ns() / vigil::kNanosPerMicro));
  std::printf("# Histogram Overflows: %05llu\n",
              static_cast<unsigned long long>(probe.overflows()));

  if (const auto s = aggregator.find("latency_probe")) {
    std::fprintf(
        stderr,
        "vigil_latency: supervisor saw %llu samples, latency p50 %lld ns, p99 %lld ns, "
        "max %lld ns; supervision overhead mean %.0f ns; dropped %llu\n",
        static_cast<unsigned long long>(s->samples), static_cast<long long>(s->latency_ns.p50),
        static_cast<long long>(s->latency_ns.p99), static_cast<long long>(s->latency_ns.max),
        s->overhead_ns.mean, static_cast<unsigned long long>(s->counters.dropped));
  }
  return 0;
}
