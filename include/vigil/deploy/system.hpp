#pragma once
/// @file
/// `System`: a running deployment. It creates the registry, the supervision pipeline (a
/// `vigil::service::SupervisionService`: aggregator, supervisor, monitor), the activities and the
/// components of a DeploymentSpec, configures and starts everything in the right order, and stops
/// it in reverse; the user never orders anything by hand.
///
/// The system's pipeline is a `SupervisionService`: the deployment's outputs (`outputs.http`,
/// `outputs.textfile`) are outputs of that service and its extensions (e.g. CAN) are
/// contributors of it, run once per monitor cycle; the system keeps no exporter of its own.
///
/// Start order: the platform's real-time core (Xenomai Cobalt: libcobalt, unless the program
/// started it with vigil::platform::initialize(); nothing on Linux) -> the service (its outputs
/// first: a taken port fails start() here, before anything runs; then the supervisor and monitor
/// threads, so that nothing a component sends is missed)
/// -> process set-up for real time (memory locking, prefault) -> extensions -> every component
/// configured, in file order (all before any starts: a failure leaves nothing running) -> every
/// activity started, in file order of its components. Stop order: activities (reverse),
/// extensions, a last supervisor drain, the monitor, the outputs.
///
/// Not RT-safe; call from one control thread (on Cobalt: the main thread, unless the program
/// started Cobalt itself).

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/extension.hpp"
#include "vigil/error.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/ros2_diagnostics.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/monitor/threshold_file.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::deploy {

class System {
 public:
  /// Builds (does not start) everything `spec` describes. Errors: a component type that failed
  /// to build, parameters that failed validation (file:line:col), an extension that failed.
  static expected<std::unique_ptr<System>, config::ConfigErrors> create(
      DeploymentSpec spec, const ComponentFactory& factory = ComponentFactory::instance());

  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  /// Starts everything in order (see the file comment). On failure stops what was started and
  /// returns what failed (e.g. "outputs.http: HTTP server: cannot listen on 127.0.0.1:9479: the
  /// port is taken ...").
  expected<void, Error> start();
  /// Stops everything in reverse order: the outputs get the final monitor cycle, after a last
  /// drain. Idempotent.
  void stop();
  /// stop(), waiting at most `timeout_ns`: a component stuck in on_update never returns, and its
  /// activity's thread cannot be joined. False when the time passed: the stopping thread is then
  /// left blocked, and the caller must leave the process without destroying the system (the
  /// monitor, which stops after the activities, still runs: reports() is its latest view).
  [[nodiscard]] bool stop_within(Nanos timeout_ns);
  [[nodiscard]] bool running() const noexcept { return running_; }

  /// The latest monitor cycle's reports, the extensions' included. Any thread.
  [[nodiscard]] ReportSet reports() const;
  /// Runs one monitor cycle now (the extensions contribute to it) and returns its reports (e.g.
  /// final reports after stop()).
  ReportSet step_monitor();

  /// What start() did, one line per step (including downgrades such as SCHED_OTHER instead
  /// of FIFO).
  [[nodiscard]] const std::vector<std::string>& log() const noexcept { return log_; }
  [[nodiscard]] const platform::RealtimeSetupReport& realtime_setup() const noexcept {
    return rt_setup_;
  }

  [[nodiscard]] const DeploymentSpec& spec() const noexcept { return spec_; }
  [[nodiscard]] Registry<task::Message>& registry() noexcept { return registry_; }
  /// The supervision pipeline (aggregator, supervisor, monitor) the system owns, configured
  /// from the deployment's `supervision:` section. Start and stop it through the system.
  [[nodiscard]] service::SupervisionService& service() noexcept { return *service_; }
  [[nodiscard]] supervisor::ComponentAggregator& aggregator() noexcept {
    return service_->aggregator();
  }
  [[nodiscard]] supervisor::ComponentDrainLoop& supervisor() noexcept {
    return *service_->supervisor();
  }
  [[nodiscard]] Monitor& monitor() noexcept { return service_->monitor(); }
  /// The server of `outputs.http` while the system runs (e.g. `http()->address()` for the port
  /// chosen for `listen: 0`); null when the deployment has none or the system is stopped.
  /// Control thread.
  [[nodiscard]] exporter::HttpServer* http() noexcept { return service_->http(); }
  /// The latest textfile write error (kept after stop()); empty when every write succeeded
  /// or no textfile is written. Control thread.
  [[nodiscard]] std::string output_error() const;
  /// The output of `outputs.json` (the final reports, written at stop), or null. Its `error()`
  /// says why a write failed.
  [[nodiscard]] const exporter::JsonFileOutput* json_output() const noexcept { return json_; }
  /// The output of `outputs.ros2` (ROS 2 /diagnostics over DDS), or null. Its `active()` and
  /// `error()` say whether it publishes.
  [[nodiscard]] const exporter::Ros2DiagnosticsOutput* ros2_output() const noexcept {
    return ros2_;
  }
  /// The watched thresholds file (`supervision: {thresholds: FILE}`), or null when the
  /// thresholds are embedded. The monitor polls it at each cycle; `reload()` it to apply an edit
  /// at once.
  [[nodiscard]] ThresholdFile* thresholds_file() noexcept {
    return thresholds_file_ ? &*thresholds_file_ : nullptr;
  }
  /// The component named `name`, or null.
  [[nodiscard]] TaskCore* component(std::string_view name) const noexcept;
  /// The first extension of type E, or null.
  template <class E>
  [[nodiscard]] E* extension() const noexcept {
    for (const auto& e : extensions_) {
      if (auto* p = dynamic_cast<E*>(e.get())) return p;
    }
    return nullptr;
  }

 private:
  explicit System(DeploymentSpec spec);
  // `health:`: checks the checkpoints components declared when built, supervises the section.
  void supervise_health();
  // `diagnosis:`: checks the unit names it uses, sets the service's diagnosis graph.
  void configure_diagnosis();
  // `reactions:`: checks the units, handlers and CAN writers it names, adds the reactions.
  void configure_reactions(const ComponentFactory& factory);
  // Every unit name of this system: components, supervisions, extensions' units, the pipeline's.
  [[nodiscard]] std::vector<std::string> known_units() const;

  struct Slot {
    std::unique_ptr<TaskCore> task;
    std::unique_ptr<PeriodicActivity> activity;
    const ComponentSpec* spec = nullptr;
    /// Its checkpoints named in `health:` are checked when it has configured (it declared
    /// none when it was built).
    bool check_checkpoints_at_start = false;
  };

  DeploymentSpec spec_;
  Registry<task::Message> registry_;
  std::unique_ptr<service::SupervisionService> service_;  // after registry_: dies before it
  std::optional<ThresholdFile>
      thresholds_file_;  // after service_: detached before its monitor dies
  std::vector<std::unique_ptr<Extension>> extensions_;
  std::vector<Slot> slots_;
  exporter::TextfileOutput* textfile_ = nullptr;  // among the service's outputs
  exporter::JsonFileOutput* json_ = nullptr;
  exporter::Ros2DiagnosticsOutput* ros2_ = nullptr;
  std::vector<std::string> log_;
  platform::RealtimeSetupReport rt_setup_;
  bool running_ = false;
};

}  // namespace vigil::deploy
