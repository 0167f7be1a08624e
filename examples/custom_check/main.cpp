// custom_check: a check of your own next to the built-in ones: one class, one registration line.
//
// A 1 kHz component runs for 2 s under the supervisor and the monitor; the custom check warns
// when its wake-up latency p99 exceeds a threshold read from the same YAML file as the built-in
// thresholds (`custom: {max_latency_p99_us: ...}`). Prints the summary, the component's detail
// view, and with --json the JSON report.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "vigil/exec/periodic_activity.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/monitor/threshold_file.hpp"
#include "vigil/task/task.hpp"

// The custom check. Any class with name() and run() satisfies vigil::Check.
class LatencyCheck {
 public:
  [[nodiscard]] std::string_view name() const { return "latency"; }

  void run(const vigil::CheckInput& in, vigil::Report& out) const {
    const vigil::StatsSummary& latency = in.component.latency_ns;
    if (latency.count == 0) return;  // no cycle yet: nothing to judge
    const double limit_ns = in.thresholds.custom_value("max_latency_p99_us", 200.0) * 1e3;
    out.add("latency_p99_limit", vigil::format_nanos(limit_ns));
    if (static_cast<double>(latency.p99) > limit_ns) {
      out.merge(vigil::StatusLevel::Warn,
                "late wake-ups: latency p99 " +
                    vigil::format_nanos(static_cast<double>(latency.p99)) + " above " +
                    vigil::format_nanos(limit_ns));
    }
  }
};

// A component: about 100 us of work per cycle.
class Controller : public vigil::Task<Controller> {
 public:
  Controller() : Task("controller") {}
  void on_update() {
    const vigil::Nanos end = vigil::platform::now_ns() + 100 * vigil::kNanosPerMicro;
    while (vigil::platform::now_ns() < end) {
    }
  }
};

int main(int argc, char** argv) {
  using namespace std::chrono_literals;
  bool json = false;
  const char* thresholds = nullptr;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0) {
      json = true;
    } else {
      thresholds = argv[i];
    }
  }

  vigil::supervisor::ComponentAggregator aggregator;
  vigil::supervisor::TaskSupervisor supervisor(vigil::default_registry(), aggregator);
  vigil::Monitor monitor(aggregator, {.period_ns = 500 * vigil::kNanosPerMilli});
  monitor.set_supervisor(&supervisor);
  monitor.add_check<LatencyCheck>();         // the registration line
  std::optional<vigil::ThresholdFile> file;  // watched: reloaded at each monitor cycle
  if (thresholds != nullptr) {
    auto opened = vigil::ThresholdFile::open(thresholds);
    if (!opened) {
      std::fprintf(stderr, "%s\n", vigil::config::to_string(opened.error()).c_str());
      return 1;
    }
    file.emplace(std::move(*opened));
    file->attach(monitor);
  }

  Controller controller;
  controller.configure();
  vigil::PeriodicActivity activity(controller,
                                   {.name = "control", .period_ns = vigil::kNanosPerMilli});
  if (auto ok = activity.start(); !ok) {
    std::fprintf(stderr, "cannot start: %s\n", ok.error().message.c_str());
    return 1;
  }
  (void)supervisor.start();
  (void)monitor.start();
  std::this_thread::sleep_for(2s);
  monitor.stop();
  activity.stop();
  supervisor.stop();

  const vigil::ReportSet reports = monitor.step();
  if (json) {
    std::fputs(vigil::to_json(reports, {.indent = 2}).c_str(), stdout);
    return 0;
  }
  vigil::print_summary(stdout, reports);
  std::printf("\n%s", vigil::format_detail(*reports.find("controller"),
                                           vigil::use_color(vigil::ColorMode::Auto, stdout))
                          .c_str());
  return 0;
}
