// Export: what serving /metrics costs with 1 to 1,000 components.
//
// Times are the measuring thread's CPU time (the machine may be shared).
//  - export/metrics: one render of the Prometheus 0.0.4 body (what a scrape costs the HTTP thread
//    the first time a snapshot is asked for; later scrapes of the same snapshot reuse it), against
//    the floor of the JSON report of the same reports (the exporter that existed before),
//    rendered in the same iteration. Value = ms per render; ratio = metrics / JSON.
//  - export/openmetrics: the same in OpenMetrics 1.0.
//  - export/publish: what the monitor's thread pays per cycle to publish: reducing four
//    histograms per component to Prometheus buckets and HttpServer::publish (copy of the
//    reports, history frame, swap). Value = us per component.
// Every component has a full report (thread statistics, four timing distributions of 2,000
// samples each), so the body has every family.
#include <random>
#include <string>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/export/buckets.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/prometheus.hpp"

namespace vigil::bench {
namespace {

struct World {
  explicit World(std::size_t n) {
    std::mt19937_64 rng(42);
    std::lognormal_distribution<double> exec(std::log(40'000.0), 0.3);
    std::lognormal_distribution<double> lat(std::log(8'000.0), 0.5);
    std::normal_distribution<double> per(1e6, 5e3);
    user.resize(n);
    latency.resize(n);
    period.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 2000; ++k) {
        user[i].add(static_cast<Nanos>(exec(rng)));
        latency[i].add(static_cast<Nanos>(lat(rng)));
        period[i].add(static_cast<Nanos>(per(rng)));
      }
      Report r;
      r.kind = ReportKind::Component;
      r.id = static_cast<std::uint32_t>(i + 1);
      r.name = "joint_" + std::to_string(i) + "_controller";
      r.configured = true;
      r.activity = "control_" + std::to_string(i % 8);
      r.policy = r.requested_policy = SchedPolicy::Fifo;
      r.priority = 80;
      r.cpu = static_cast<int>(i % 4);
      r.tid = 1000 + static_cast<int>(i % 16);
      r.tasks_on_thread = 4;
      r.period_ns = kNanosPerMilli;
      r.state = TaskState::Running;
      r.counters.cycles = r.samples = 2000;
      r.counters.overruns = i % 7;
      r.execution_ns = user[i].summary();
      r.total_ns = r.execution_ns;
      r.latency_ns = latency[i].summary();
      r.measured_period_ns = period[i].summary();
      r.silence_ns = 3 * kNanosPerMilli;
      r.port_capacity = 256;
      r.port_high_water = 12;
      r.thread = platform::ThreadStats{.tid = r.tid,
                                       .name = "control",
                                       .voluntary_switches = 10,
                                       .involuntary_switches = 3,
                                       .minor_faults = 1,
                                       .user_time_ns = 5'000'000'000};
      if (i % 10 == 0) r.merge(StatusLevel::Warn, "near overrun: EWMA of total time 930us");
      reports.components.push_back(std::move(r));
    }
    Report sup;
    sup.kind = ReportKind::Supervisor;
    sup.name = "vigil.supervisor";
    sup.add("messages", "123456789");
    sup.add("ports", std::to_string(n));
    reports.components.push_back(sup);
    Report mon;
    mon.kind = ReportKind::Monitor;
    mon.name = "vigil.monitor";
    mon.add("components", std::to_string(n));
    reports.components.push_back(mon);
    reports.cycle = 100;
    snapshot.reports = reports;
    snapshot.histograms = collect();
  }

  [[nodiscard]] std::vector<exporter::ComponentHistograms> collect() const {
    std::vector<exporter::ComponentHistograms> out;
    out.reserve(user.size());
    for (std::size_t i = 0; i < user.size(); ++i) {
      exporter::ComponentHistograms h;
      h.id = static_cast<std::uint32_t>(i + 1);
      h.name = reports.components[i].name;
      h.execution = exporter::reduce_to_buckets(user[i]);
      h.total = exporter::reduce_to_buckets(user[i], 150);
      h.latency = exporter::reduce_to_buckets(latency[i]);
      h.measured_period = exporter::reduce_to_buckets(period[i]);
      out.push_back(std::move(h));
    }
    return out;
  }

  std::vector<supervisor::RunningStats> user, latency, period;
  ReportSet reports;
  exporter::MetricsSnapshot snapshot;
};

void render(benchmark::State& state, exporter::ExpositionFormat format) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const World world(n);
  std::vector<double> ours, floor, ratio;
  std::string body, json;
  const Nanos clock_cost = cpu_clock_cost();
  for (auto _ : state) {
    body.clear();
    // Thread CPU time: on a shared machine, wall time would charge other processes to us.
    const Nanos w0 = platform::now_ns();
    const Nanos t0 = thread_cpu_ns();
    exporter::render_metrics(body, world.snapshot, format);
    const Nanos t1 = thread_cpu_ns();
    const Nanos w1 = platform::now_ns();
    json = to_json(world.reports);
    const Nanos t2 = thread_cpu_ns();
    benchmark::DoNotOptimize(body.data());
    benchmark::DoNotOptimize(json.data());
    const Nanos a = std::max<Nanos>(t1 - t0 - clock_cost, 1);
    const Nanos b = std::max<Nanos>(t2 - t1 - clock_cost, 1);
    ours.push_back(static_cast<double>(a));
    floor.push_back(static_cast<double>(b));
    ratio.push_back(static_cast<double>(a) / static_cast<double>(b));
    state.SetIterationTime(static_cast<double>(w1 - w0) * 1e-9);
  }
  report_vs(state, "ms/render", median(ours) * 1e-6, median(floor) * 1e-6, median(ratio));
  state.counters["body_MB"] = static_cast<double>(body.size()) * 1e-6;
  state.counters["json_MB"] = static_cast<double>(json.size()) * 1e-6;
  state.counters["us_per_component"] = median(ours) * 1e-3 / static_cast<double>(n);
}

void metrics(benchmark::State& state) { render(state, exporter::ExpositionFormat::Prometheus); }
void openmetrics(benchmark::State& state) {
  render(state, exporter::ExpositionFormat::OpenMetrics);
}

void publish(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const World world(n);
  exporter::HttpServer server;  // not started: publish() works without it
  std::vector<double> per;
  for (auto _ : state) {
    const Nanos w0 = platform::now_ns();
    const Nanos t0 = thread_cpu_ns();
    server.publish(world.reports, world.collect());
    const Nanos t1 = thread_cpu_ns();
    per.push_back(static_cast<double>(t1 - t0));
    state.SetIterationTime(static_cast<double>(platform::now_ns() - w0) * 1e-9);
  }
  report(state, "us/component", median(per) * 1e-3 / static_cast<double>(n));
  state.counters["publish_ms"] = median(per) * 1e-6;
}

}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::metrics)
    ->Name("export/metrics")
    ->ArgName("components")
    ->Arg(1)
    ->Arg(100)
    ->Arg(1'000)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(vigil::bench::openmetrics)
    ->Name("export/openmetrics")
    ->ArgName("components")
    ->Arg(1'000)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(vigil::bench::publish)
    ->Name("export/publish")
    ->ArgName("components")
    ->Arg(1'000)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
