#pragma once
/// @file
/// `SupervisionService`: the whole supervision pipeline as one object. It owns the source (the
/// thread draining every component's port), the component aggregator, the monitor (checks and
/// reports, on its own thread or stepped), the contributors and the outputs.
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
/// runs: the source finds them in the registry (the process's default one unless the options
/// name another).
///
/// The pipeline watches its own threads: the monitor reports a supervisor that stopped draining
/// (STALE, and a `thread_stalled` event), the supervisor a monitor that stopped cycling (a
/// `thread_stalled` event), the monitor a reaction handler stuck over its budget; /healthz and
/// systemd's keep-alive say so too (docs/guide/reactions.md, "Who watches the supervisor").
///
/// The one pipeline of vigil: a program's own components, a deployment's `deploy::System` and
/// the `vigil supervise` daemon are all this class (docs/design/modules.md, "One pipeline").
///
///   source ──> aggregator ──> monitor ──> contributors ──> outputs
///
///  - the **source** drains messages into the aggregator: this process's registry (default), or
///    other processes' shared-memory segments (`SupervisionServiceOptions::segments`);
///  - the **monitor** runs the checks once per monitor period and makes the cycle's reports;
///  - **contributors** (`add_contributor()`, vigil/service/contributor.hpp) add units of their
///    own to each cycle: CAN nodes, the processes of the segment source;
///  - **outputs** (`add_output()`, vigil/export/output.hpp) get one snapshot per cycle (the
///    reports, their buckets, the cycle's events) and the final one at stop: the text summary,
///    the JSON file, HTTP, the textfile, the event log, traces, and any output of a program's.
///  - events reach subscribers within milliseconds through `events()` (one event stream).
///
/// Threads: start(), stop(), step() and the add_* functions from one control thread. The
/// contributors and outputs run on the monitor's thread (or step()'s or stop()'s caller), one
/// cycle at a time. Nothing here is RT-safe.

#include <atomic>
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
#include "vigil/export/output.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/systemd_notify.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/monitor/diagnosis.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/service/contributor.hpp"
#include "vigil/service/reactions.hpp"
#include "vigil/service/segment_source.hpp"
#include "vigil/service/source.hpp"
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
  /// service. Not used with `segments`.
  ComponentRegistry* registry = nullptr;
  /// Drain the shared-memory segments of other processes (what `vigil supervise` does) instead
  /// of this process's registry; `segments->period_ns` is set from `supervisor_period_ns`.
  /// Invalid options (name, group) make start() fail.
  std::optional<SegmentSourceOptions> segments{};
  /// Period of the source's thread, which drains every component's port. 10 ms: at 1 kHz a
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
  /// Speak systemd's notify protocol (READY, STATUS, the watchdog's keep-alive, STOPPING;
  /// docs/guide/systemd.md) when the environment has `NOTIFY_SOCKET`, as under a `Type=notify`
  /// unit: the constructor then adds an `exporter::SystemdNotifyOutput`. Bad variables are
  /// warnings on stderr; supervision goes on. false: never.
  bool systemd_notify = true;
  /// The environment systemd's variables are read from; none (the default): the process's, read
  /// by the constructor. A program or a test names them here without changing the process's.
  std::optional<exporter::SystemdEnvironment> systemd_environment{};
  /// The monitor's options apart from its period (checks, thread stats, names, stack). Its clock
  /// must be `clock` (the service sets both).
  MonitorOptions monitor{};
  /// The aggregator's options apart from `ewma_weight` and `clock` (the service sets both from
  /// the fields above): warm-up, watchdog, flight recorder, event queue, auto-clear, state events.
  supervisor::AggregatorOptions aggregator{};
  /// The supervisor's options apart from its period (`supervisor_period_ns`): batch, thread
  /// name, stack size, its own clock.
  supervisor::DrainOptions supervisor{};
  /// The clock that stamps arrivals and times the monitor's windows.
  Clock clock = Clock::system();
};

class SupervisionService {
 public:
  /// Builds the pipeline (no thread yet) with the built-in outputs the options ask for. Not
  /// RT-safe.
  explicit SupervisionService(SupervisionServiceOptions options = {});
  /// Stops (as stop()) if running.
  ~SupervisionService();
  SupervisionService(const SupervisionService&) = delete;
  SupervisionService& operator=(const SupervisionService&) = delete;

  /// Starts the outputs, the source's thread and (unless `monitor_thread` is false) the
  /// monitor's thread. On failure nothing is left running and the error says what failed. Fails
  /// when already running ("already running"); a stopped service may be started again.
  expected<void, Error> start();
  /// Stops the threads after a last full drain, runs a last monitor cycle (its contributors
  /// included), and hands its snapshot to every output's stop() (the summary, the JSON file).
  /// Returns those final reports. Idempotent: a second call returns the same reports and
  /// publishes nothing.
  ReportSet stop();
  /// Whether start() succeeded and stop() was not called since.
  [[nodiscard]] bool running() const noexcept { return running_; }

  /// Runs one cycle now in the calling thread: drains (when the source's thread does not run),
  /// runs the monitor and the contributors, publishes the snapshot to the outputs; returns its
  /// reports.
  ReportSet step();
  /// The latest cycle's reports (contributions included, as the outputs got them; empty before
  /// the first cycle). Any thread: a copy, no contributor runs again.
  [[nodiscard]] ReportSet reports() const;
  /// The latest cycle's snapshot (never null: an empty one before the first cycle). Any thread.
  [[nodiscard]] std::shared_ptr<const exporter::Snapshot> snapshot() const;

  // --- the one way in and the one way out (call before start(), from the control thread) ---

  /// Adds an output (started by start(), published every cycle, stopped by stop()). Returns it.
  /// An output that is also a `Contributor` (the components' log, vigil/service/component_log.hpp)
  /// is registered as both.
  exporter::Output& add_output(std::unique_ptr<exporter::Output> output);
  /// Adds an output of type O built from `args`; returns it. Example:
  /// `auto& http = service.add_output<exporter::HttpOutput>(exporter::HttpOptions{});`
  template <class O, class... A>
  O& add_output(A&&... args) {
    return static_cast<O&>(add_output(std::make_unique<O>(std::forward<A>(args)...)));
  }
  /// Adds a contributor (owned by the service), run in the order added on every cycle.
  Contributor& add_contributor(std::unique_ptr<Contributor> contributor);
  /// Adds a contributor owned elsewhere (it must outlive the service or be stopped with it).
  void add_contributor(Contributor& contributor);

  /// The diagnosis graph applied to every cycle after the contributors (root causes, dependents,
  /// aggregates, hysteresis; vigil/monitor/diagnosis.hpp). Without a call the default graph runs:
  /// the edges the contributors declare, no hysteresis. Fails with validate()'s message. Any
  /// thread.
  expected<void, Error> set_diagnosis(monitor::DiagnosisConfig config);
  /// Clears latched units of the diagnosis graph ("": all); how many were cleared. Any thread.
  std::size_t clear_diagnosis(std::string_view name = {});
  /// What the pipeline does about faults (vigil/service/reactions.hpp): register handlers and
  /// CAN writers, add reactions before start(). Started and stopped with the service; status
  /// triggers see every cycle's reports after the diagnosis graph. With reactions, every cycle
  /// also has the reaction thread's unit (`vigil.reactions`).
  [[nodiscard]] Reactions& reactions() noexcept { return reactions_; }

  // --- the parts ---

  /// The events of the pipeline, within milliseconds of their detection (faults of components,
  /// processes and segments): subscribe here to act on one. The same hub as aggregator().events().
  [[nodiscard]] supervisor::EventHub& events() noexcept { return aggregator_.events(); }
  [[nodiscard]] ComponentRegistry& registry() noexcept { return registry_; }
  [[nodiscard]] supervisor::ComponentAggregator& aggregator() noexcept { return aggregator_; }
  /// The source (a RegistrySource, or a SegmentSource with `segments`).
  [[nodiscard]] Source& source() noexcept { return *source_; }
  /// The in-process supervisor (the registry source's), or null with `segments`.
  [[nodiscard]] supervisor::ComponentDrainLoop* supervisor() noexcept;
  /// The segment source with `segments` (its processes, its statistics), or null.
  [[nodiscard]] SegmentSource* segments() noexcept;
  /// The monitor: add checks, set or watch thresholds here.
  [[nodiscard]] Monitor& monitor() noexcept { return monitor_; }
  [[nodiscard]] const SupervisionServiceOptions& options() const noexcept { return options_; }
  /// The HTTP server while the service runs with `http` set; null otherwise.
  [[nodiscard]] exporter::HttpServer* http() noexcept;
  /// The systemd notify output when `systemd_notify` found `NOTIFY_SOCKET` (e.g. to
  /// `trigger_watchdog()`); null otherwise.
  [[nodiscard]] exporter::SystemdNotifyOutput* systemd() noexcept { return systemd_; }

 private:
  void on_cycle(const ReportSet& monitor_reports);
  // The supervisor's side of the cross-check (its thread, each drain): a monitor that stopped
  // cycling raises `thread_stalled`. The monitor's side is in on_cycle().
  void watch_monitor(Nanos now);
  void watch_threads(const ReportSet& reports);
  void stop_outputs(const exporter::Snapshot& final_snapshot, std::size_t count);

  SupervisionServiceOptions options_;
  ComponentRegistry& registry_;
  supervisor::ComponentAggregator aggregator_;
  std::unique_ptr<Source> source_;
  Monitor monitor_;
  std::uint64_t monitor_subscription_ = 0;
  std::uint64_t histogram_hook_ = 0;
  std::vector<std::unique_ptr<exporter::Output>> outputs_;
  std::vector<std::unique_ptr<Contributor>> owned_contributors_;
  std::vector<Contributor*> contributors_;
  exporter::HttpOutput* http_ = nullptr;              // among outputs_, when options_.http
  exporter::SystemdNotifyOutput* systemd_ = nullptr;  // among outputs_, under systemd
  // Cycle state, on the monitor's thread (or step()'s or stop()'s caller): the buckets read at
  // the start of the cycle, the last event handed out, whether outputs get the cycle.
  std::vector<exporter::ComponentHistograms> cycle_histograms_;
  std::uint64_t last_event_seq_ = 0;
  std::atomic<bool> publishing_{false};  // set by the control thread, read by the monitor's
  std::mutex diagnosis_mutex_;  // guards diagnosis_: the monitor's thread and set/clear callers
  monitor::DiagnosisGraph diagnosis_;
  Reactions reactions_;
  // The cross-check of the pipeline's threads: when the monitor's latest cycle ended (its
  // clock), and which threads were last reported stalled (set on the watching thread).
  std::atomic<Nanos> monitor_heartbeat_{0};
  std::atomic<bool> monitor_stalled_{false};
  std::vector<std::string> stalled_;  // the monitor's thread: units reported stalled
  mutable std::mutex latest_mutex_;   // guards latest_: held for a pointer copy
  std::shared_ptr<const exporter::Snapshot> latest_;
  ReportSet final_;
  bool running_ = false;
};

}  // namespace vigil::service

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using service::SupervisionService;
using service::SupervisionServiceOptions;
}  // namespace vigil
