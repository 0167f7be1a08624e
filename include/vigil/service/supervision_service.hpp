#pragma once
/// @file
/// `SupervisionService`: the whole supervision pipeline of a program as one object. It owns the
/// component aggregator, the task supervisor's thread (draining every component's port), the
/// monitor (checks and reports, on its own thread or stepped), and the outputs that publish the
/// reports (a text summary, a JSON file, and any `ReportOutput` added).
///
/// ```cpp
/// int main() {
///   vigil::SupervisionService supervision;   // supervisor every 10 ms, monitor every 1 s
///   (void)supervision.start();
///   Motor motor;                             // a vigil::Task<Motor>: joins on construction
///   ...                                      // run the program's activities
///   supervision.stop();                      // last drain, last cycle, summary on stdout
/// }
/// ```
///
/// Components may be created before or after the service starts and may come and go while it
/// runs: the supervisor finds them in the registry (the process's default one unless the options
/// name another).
///
/// Extension points (where later features plug in):
///  - `subscribe()`: report subscribers, called with every cycle's reports (a robot's state
///    machine, an event log);
///  - `add_output()`: a `ReportOutput` started with the service, told about every cycle and
///    stopped with the final reports (the built-in text, JSON and HTTP/textfile outputs are
///    ones; `SupervisionServiceOptions::http` turns the HTTP exporter on);
///  - `add_contributor()`: code that adds its own reports to each set handed out (CAN nodes);
///  - `monitor()` / `aggregator()` / `supervisor()`: the parts, for custom checks and thresholds.
///
/// Threads: start(), stop(), step() and the add_* functions from one control thread. Subscribers
/// and outputs run on the monitor's thread (or step()'s or stop()'s caller), one cycle at a time;
/// contributors also run on any thread that calls reports(), so they must be thread-safe.
/// Nothing here is RT-safe.

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/export/http_service.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/default_registry.hpp"

namespace vigil::service {

/// Options of a SupervisionService: an aggregate with a sensible default for every field, so
/// `SupervisionService{}` is a working pipeline and a program names only what it changes:
/// `SupervisionService s({.monitor_period_ns = 500 * kNanosPerMilli, .json_file = "out.json"});`
struct SupervisionServiceOptions {
  /// The registry whose components are supervised; null: the process's `default_registry()`,
  /// which every Task<Derived> and Instrumentation joins unless told otherwise. Must outlive the
  /// service.
  ComponentRegistry* registry = nullptr;
  /// Period of the supervisor's thread, which drains every component's port. 10 ms: at 1 kHz a
  /// component queues about 10 messages per period.
  Nanos supervisor_period_ns = 10 * kNanosPerMilli;
  /// Period of the monitor's cycles (checks and reports). 1 s, the pace of a monitoring GUI.
  Nanos monitor_period_ns = kNanosPerSecond;
  /// Run the monitor on its own thread (true), or only when step() is called (false).
  bool monitor_thread = true;
  /// At stop(), run a last monitor cycle after the last drain and publish its reports (to the
  /// subscribers and the outputs). false: stop() publishes the latest cycle's reports as they are.
  bool final_cycle = true;
  /// Weight of the newest sample in every EWMA of the aggregator, in (0, 1].
  double ewma_weight = supervisor::kDefaultEwmaWeight;
  /// Where the text summary is written (print_summary) when the service stops; null: nowhere.
  std::FILE* summary_file = stdout;
  /// Also write the summary after every monitor cycle, not only at stop (a live console view).
  bool summary_every_cycle = false;
  /// Write every report's detail view after the summary at stop.
  bool details_at_stop = false;
  /// Colouring of the text output.
  ColorMode color = ColorMode::Auto;
  /// Write the final reports as JSON (docs/reference/json-schema.md) to this file at stop;
  /// empty: no file. A file that cannot be written is reported on stderr, never thrown.
  std::string json_file{};
  /// Indentation of the JSON file: 0 = one line.
  int json_indent = 2;
  /// Serve the reports over HTTP (Prometheus `/metrics`, `/api/v1/reports`, the dashboard;
  /// docs/reference/http.md) with these options, started by start(); none: no server. The
  /// default `exporter::HttpOptions{}` listens on 127.0.0.1:9479. A server that cannot start
  /// (port taken) makes start() fail.
  std::optional<exporter::HttpOptions> http{};
  /// Rewrite this node-exporter textfile (`.prom`) after every monitor cycle; empty: none.
  std::filesystem::path prom_textfile{};
  /// The monitor's options apart from its period (checks, thread stats, names). Its clock must
  /// be `clock` (the service sets both).
  MonitorOptions monitor{};
  /// The clock that stamps arrivals and times the monitor's windows.
  Clock clock = Clock::system();
};

/// Something that publishes reports: started with the service, told about each monitor cycle,
/// stopped with the final reports. The text summary and the JSON file are outputs; an HTTP
/// exporter would be one. Implementations must not call the service's start(), stop() or step().
class ReportOutput {
 public:
  virtual ~ReportOutput() = default;
  /// Called by SupervisionService::start() before the monitor's first cycle (e.g. to bind a
  /// socket). An error makes start() fail with it.
  virtual expected<void, Error> start() { return {}; }
  /// Called after every monitor cycle with its reports, on the monitor's thread (or step()'s
  /// caller). Keep it short: the next cycle waits for it.
  virtual void on_reports(const ReportSet& /*reports*/) {}
  /// Called once by SupervisionService::stop() with the final reports (after the last drain and
  /// the last monitor cycle), on stop()'s caller.
  virtual void stop(const ReportSet& /*final_reports*/) {}
};

class SupervisionService {
 public:
  /// A report subscriber: called with every cycle's reports and with the final ones at stop.
  using Subscriber = std::function<void(const ReportSet&)>;
  /// Adds reports of its own to a cycle's set before subscribers and outputs see it.
  using Contributor = std::function<void(ReportSet&)>;

  /// Builds the pipeline (no thread yet) with the built-in outputs the options ask for. Not
  /// RT-safe.
  explicit SupervisionService(SupervisionServiceOptions options = {});
  /// Stops (as stop()) if running.
  ~SupervisionService();
  SupervisionService(const SupervisionService&) = delete;
  SupervisionService& operator=(const SupervisionService&) = delete;

  /// Starts the outputs, the supervisor's thread and (unless `monitor_thread` is false) the
  /// monitor's thread. On failure nothing is left running and the error says what failed. Fails
  /// when already running ("already running"); a stopped service may be started again.
  expected<void, Error> start();
  /// Stops the threads after a last full drain, runs a last monitor cycle, and hands its reports
  /// to the subscribers and to every output's stop() (the summary, the JSON file). Returns those
  /// final reports. Idempotent: a second call returns the same reports and publishes nothing.
  ReportSet stop();
  /// Whether start() succeeded and stop() was not called since.
  [[nodiscard]] bool running() const noexcept { return running_; }

  /// Runs one cycle now in the calling thread: drains the ports (when the supervisor's thread
  /// does not run) and runs the monitor; returns its reports (contributions included), which
  /// subscribers and outputs also get.
  ReportSet step();
  /// A copy of the latest cycle's reports, with the contributors' reports as of now. Any thread.
  [[nodiscard]] ReportSet reports() const;

  // --- extension points (call before start(), from the control thread) ---

  /// Adds a report subscriber; returns its id.
  std::uint64_t subscribe(Subscriber subscriber);
  /// Removes a subscriber; unknown ids are ignored.
  void unsubscribe(std::uint64_t id);
  /// Adds an output (started by start(), stopped by stop()). Returns it.
  ReportOutput& add_output(std::unique_ptr<ReportOutput> output);
  /// Adds a contributor of reports, run in the order added on every set handed out (to
  /// subscribers and outputs, and by step() and reports()).
  void add_contributor(Contributor contributor);

  // --- the parts ---

  [[nodiscard]] ComponentRegistry& registry() noexcept { return registry_; }
  [[nodiscard]] supervisor::ComponentAggregator& aggregator() noexcept { return aggregator_; }
  [[nodiscard]] supervisor::TaskSupervisor& supervisor() noexcept { return supervisor_; }
  /// The monitor: add checks, set or watch thresholds here.
  [[nodiscard]] Monitor& monitor() noexcept { return monitor_; }
  [[nodiscard]] const SupervisionServiceOptions& options() const noexcept { return options_; }
  /// The HTTP/textfile exporter while the service runs with `http` or `prom_textfile` set (its
  /// server: `exporter()->http()`); null otherwise.
  [[nodiscard]] exporter::MonitorExporter* exporter() noexcept { return exporter_; }

 private:
  void publish(const ReportSet& monitor_reports);
  ReportSet contribute(const ReportSet& monitor_reports) const;

  SupervisionServiceOptions options_;
  ComponentRegistry& registry_;
  supervisor::ComponentAggregator aggregator_;
  supervisor::TaskSupervisor supervisor_;
  Monitor monitor_;
  std::uint64_t monitor_subscription_ = 0;
  std::vector<std::unique_ptr<ReportOutput>> outputs_;
  std::vector<Contributor> contributors_;
  mutable std::mutex subscribers_mutex_;
  std::vector<std::pair<std::uint64_t, Subscriber>> subscribers_;
  std::uint64_t next_subscriber_ = 1;
  exporter::MonitorExporter* exporter_ = nullptr;  // owned by its output, while running
  ReportSet final_;
  bool running_ = false;
  bool stopped_ = false;
};

}  // namespace vigil::service

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using service::ReportOutput;
using service::SupervisionService;
using service::SupervisionServiceOptions;
}  // namespace vigil
