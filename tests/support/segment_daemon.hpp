#pragma once
// The `vigil supervise` pipeline for tests and benchmarks: a SupervisionService draining the
// shared-memory segments of one supervisor name, stepped by hand or started, with its process
// events collected from the one event stream.
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vigil/expected.hpp"
#include "vigil/service/supervision_service.hpp"

namespace vigil::test {

struct DaemonOptions {
  std::string name = "vigil";
  Nanos period_ns = 10 * kNanosPerMilli;
  Nanos rescan_ns = kNanosPerSecond;
  bool watch_directory = true;
  bool reclaim = true;
  Nanos header_check_ns = 100 * kNanosPerMilli;
  MonitorOptions monitor{};  // read_thread_stats and clock are used
  supervisor::AggregatorOptions aggregator{};
};

class Daemon {
 public:
  static expected<std::unique_ptr<Daemon>, Error> create(const DaemonOptions& o) {
    service::SupervisionServiceOptions s;
    s.segments = service::SegmentSourceOptions{.name = o.name,
                                               .rescan_ns = o.rescan_ns,
                                               .watch_directory = o.watch_directory,
                                               .header_check_ns = o.header_check_ns,
                                               .reclaim = o.reclaim};
    if (auto ok = service::validate(*s.segments); !ok) return unexpected(ok.error());
    s.supervisor_period_ns = o.period_ns;
    s.monitor = o.monitor;
    s.monitor_period_ns = kNanosPerSecond;
    s.aggregator = o.aggregator;
    s.clock = o.monitor.clock;
    s.summary_file = nullptr;
    return std::unique_ptr<Daemon>(new Daemon(std::move(s)));
  }
  // One drain (no monitor cycle).
  std::size_t step() { return service_.segments()->step(); }
  // A monitor cycle (the source's contribution included) without a drain.
  ReportSet step_monitor() {
    (void)service_.monitor().step();
    return service_.reports();
  }
  // The reports as of now: a monitor cycle (as `vigil supervise` shows every second).
  ReportSet reports() { return step_monitor(); }
  expected<void, Error> start() { return service_.start(); }
  void stop() { (void)service_.stop(); }
  [[nodiscard]] std::vector<service::ProcessInfo> processes() {
    return service_.segments()->processes();
  }
  [[nodiscard]] service::SegmentSourceStats stats() { return service_.segments()->stats(); }
  supervisor::ComponentAggregator& aggregator() { return service_.aggregator(); }
  service::SupervisionService& service() { return service_; }
  // The events published so far, each taken once (call from the test's thread).
  std::vector<Event> take_events() {
    std::vector<Event> out = service_.events().since(seen_);
    if (!out.empty()) seen_ = out.back().seq;
    return out;
  }

 private:
  explicit Daemon(service::SupervisionServiceOptions o) : service_(std::move(o)) {}
  service::SupervisionService service_;
  std::uint64_t seen_ = 0;
};

}  // namespace vigil::test
