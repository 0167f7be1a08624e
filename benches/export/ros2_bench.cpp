// ROS 2 /diagnostics: what the ROS 2 output costs the monitor's thread per cycle.
//
// Times are the measuring thread's CPU time (the machine may be shared).
//  - ros2/publish: Ros2DiagnosticsOutput::publish() of one snapshot of N units: the mapping to a
//    DiagnosticArray (one status per report), Cyclone DDS's CDR serialisation and the write of
//    one sample of N statuses, against the floor of building the same document as JSON
//    (to_diagnostics_json, what GET /api/v1/diagnostics renders), in the same iteration.
//    Value = ms per cycle; ratio = publish / JSON.
//  - ros2/publish_remote: the same with a subscriber in another process on loopback (the
//    writer's thread then also packs and sends the sample's fragments).
// Every unit is a component with a full report (thread statistics, timing summaries).
#include <sys/wait.h>
#include <unistd.h>
#include <csignal>

#include <dds/dds.h>

#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "diagnostic_msgs/msg/dds_/DiagnosticArray_.h"
#include "support/bench_support.hpp"
#include "vigil/export/diagnostics.hpp"
#include "vigil/export/ros2_diagnostics.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::bench {
namespace {

// Loopback only, unicast discovery (loopback has no multicast in many containers).
const char* const kLoopback =
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/>"
    "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20"
    "</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
    "</Domain></CycloneDDS>";

int bench_domain() {
  std::random_device rd;
  return 200 + static_cast<int>(rd() % 30);
}

ReportSet make_reports(std::size_t n) {
  std::mt19937_64 rng(42);
  std::lognormal_distribution<double> exec(std::log(40'000.0), 0.3);
  ReportSet set;
  for (std::size_t i = 0; i < n; ++i) {
    supervisor::RunningStats s;
    for (int k = 0; k < 200; ++k) s.add(static_cast<Nanos>(exec(rng)));
    Report r;
    r.kind = ReportKind::Component;
    r.id = static_cast<std::uint32_t>(i + 1);
    r.name = "joint_" + std::to_string(i) + "_controller";
    r.activity = "control_" + std::to_string(i % 8);
    r.policy = r.requested_policy = SchedPolicy::Fifo;
    r.priority = 80;
    r.cpu = static_cast<int>(i % 4);
    r.tid = 1000 + static_cast<int>(i % 16);
    r.period_ns = kNanosPerMilli;
    r.state = TaskState::Running;
    r.counters.cycles = r.samples = 2000;
    r.counters.overruns = i % 7;
    r.execution_ns = s.summary();
    r.latency_ns = s.summary();
    if (i % 10 == 0) r.merge(StatusLevel::Warn, "near overrun: EWMA of total time 930us");
    set.components.push_back(std::move(r));
  }
  return set;
}

// A subscriber in a child process (forked before this process touches DDS): takes and drops
// every sample until killed.
pid_t start_remote_reader(int domain) {
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  // Not on the measuring thread's CPU: the child inherited its pinning.
  cpu_set_t all;
  CPU_ZERO(&all);
  for (int c = 0; c < CPU_SETSIZE; ++c) CPU_SET(c, &all);
  (void)sched_setaffinity(0, sizeof all, &all);
  const dds_entity_t d = dds_create_domain(static_cast<dds_domainid_t>(domain), kLoopback);
  const dds_entity_t pp =
      dds_create_participant(static_cast<dds_domainid_t>(domain), nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 10);
  const dds_entity_t t = dds_create_topic(pp, &diagnostic_msgs_msg_dds__DiagnosticArray__desc,
                                          "rt/diagnostics", q, nullptr);
  const dds_entity_t r = dds_create_reader(pp, t, q, nullptr);
  dds_delete_qos(q);
  if (d < 0 || r < 0) ::_exit(2);
  for (;;) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info[1];
    const dds_return_t n = dds_take(r, samples, info, 1, 1);
    if (n > 0) {
      (void)dds_return_loan(r, samples, n);
    } else {
      dds_sleepfor(DDS_MSECS(1));
    }
  }
}

void publish_units(benchmark::State& state, bool remote) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const int domain = bench_domain();
  const pid_t child = remote ? start_remote_reader(domain) : -1;
  exporter::Snapshot snap;
  snap.reports = make_reports(n);
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  exporter::OutputContext context{aggregator};
  exporter::Ros2DiagnosticsOutput out(
      {.domain_id = domain, .dds_config = kLoopback, .events = false});
  (void)out.start(context);
  if (!out.active()) {
    state.SkipWithError(("the ROS 2 output is not active: " + out.error()).c_str());
    if (child > 0) ::kill(child, SIGKILL);
    return;
  }
  if (remote) {  // wait until the reader matched (at most 10 s)
    for (int i = 0; i < 1000 && out.matched() == 0; ++i) dds_sleepfor(DDS_MSECS(10));
    if (out.matched() == 0) {
      state.SkipWithError("the remote reader did not match within 10 s");
      ::kill(child, SIGKILL);
      (void)::waitpid(child, nullptr, 0);
      return;
    }
  }
  std::vector<double> ours, floor, ratio;
  std::string json;
  const Nanos clock_cost = cpu_clock_cost();
  for (auto _ : state) {
    const Nanos w0 = platform::now_ns();
    const Nanos t0 = thread_cpu_ns();
    out.publish(snap);
    const Nanos t1 = thread_cpu_ns();
    const Nanos w1 = platform::now_ns();
    json = exporter::to_diagnostics_json(snap.reports, w1);
    const Nanos t2 = thread_cpu_ns();
    benchmark::DoNotOptimize(json.data());
    const Nanos a = std::max<Nanos>(t1 - t0 - clock_cost, 1);
    const Nanos b = std::max<Nanos>(t2 - t1 - clock_cost, 1);
    ours.push_back(static_cast<double>(a));
    floor.push_back(static_cast<double>(b));
    ratio.push_back(static_cast<double>(a) / static_cast<double>(b));
    state.SetIterationTime(static_cast<double>(w1 - w0) * 1e-9);
  }
  report_vs(state, "ms/cycle", median(ours) * 1e-6, median(floor) * 1e-6, median(ratio));
  state.counters["us_per_unit"] = median(ours) * 1e-3 / static_cast<double>(n);
  state.counters["json_MB"] = static_cast<double>(json.size()) * 1e-6;
  state.counters["published"] = static_cast<double>(out.published());
  out.stop(exporter::Snapshot{});
  if (child > 0) {
    ::kill(child, SIGKILL);
    (void)::waitpid(child, nullptr, 0);
  }
}

void publish_local(benchmark::State& state) { publish_units(state, false); }
void publish_remote(benchmark::State& state) { publish_units(state, true); }

}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::publish_local)
    ->Name("ros2/publish")
    ->ArgName("units")
    ->Arg(1'000)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(vigil::bench::publish_remote)
    ->Name("ros2/publish_remote")
    ->ArgName("units")
    ->Arg(1'000)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
