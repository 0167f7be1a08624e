#pragma once
/// @file
/// The deployment file: activities, components, supervision and outputs, in YAML
/// (docs/reference/deployment.md lists every key).
///
/// ```yaml
/// activities:
///   - {name: control, period: 1ms, policy: FIFO, priority: 80, cpu: 1}
///   - {name: planning, period: 100ms}                       # OTHER by default
/// components:
///   - {name: motor_left, type: robot.motor, activity: control, parameters: {gain: 2.0}}
///   - {name: planner, type: robot.planner, activity: planning, detectors: [allocation]}
/// supervision:
///   supervisor_period: 10ms
///   monitor_period: 1s
///   ewma_weight: 0.05
///   thresholds: {defaults: {overrun: {near_fraction: 0.9}}}   # or a file name
///   shared_memory: robot      # optional: supervised by `vigil supervise --name robot`
/// outputs: {json: final.json, http: {listen: 9479}, textfile: vigil.prom, ros2: {domain_id: 7}}
/// health:                         # checkpoints supervised (vigil/deploy/health_section.hpp)
///   deadline: [{name: plan_to_act, start: planner.plan_ready, end: motor_left.applied, max: 5ms}]
/// can: {node_map: canopen}        # a section of a registered extension
/// (vigil/deploy/extension.hpp)
/// ```
///
/// Loading checks everything it can before anything runs: unknown keys, types, ranges, unknown
/// component types (with a suggestion), references to undefined activities, duplicate names.
/// A top-level key that is none of the above is accepted only when an extension is registered
/// under its name; its content is validated by that extension when the System is built.
/// Not RT-safe.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/config/node.hpp"
#include "vigil/deploy/diagnosis_section.hpp"
#include "vigil/deploy/factory.hpp"
#include "vigil/deploy/health_section.hpp"
#include "vigil/deploy/reactions_section.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/monitor/thresholds.hpp"
#include "vigil/platform/tsc.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/running_stats.hpp"

namespace vigil::deploy {

/// One periodic activity (a thread, shared by equal activities unless told otherwise).
struct ActivitySpec {
  PeriodicConfig config;
};

/// One component.
struct ComponentSpec {
  std::string name;
  std::string type;
  std::string activity;
  SupervisionOptions supervision;
  /// `optional: true`: a refused start does not stop the system (it is said in the start log,
  /// and the component stays configured, not running).
  bool optional = false;
  config::Node parameters;  ///< undefined when absent
  config::Node node;        ///< the component's own entry, for errors
};

/// How the system supervises itself.
struct SupervisionSpec {
  Nanos supervisor_period_ns = 10 * kNanosPerMilli;
  Nanos monitor_period_ns = kNanosPerSecond;
  double ewma_weight = supervisor::kDefaultEwmaWeight;
  /// Thresholds embedded in the deployment, or loaded from `thresholds_file` (watched and
  /// reloaded at run time when it changes).
  ThresholdSet thresholds;
  std::optional<std::filesystem::path> thresholds_file;
  /// mlockall + prefault at start.
  bool lock_memory = true;
  /// `clock: monotonic | tsc`: the clock supervision reads in this process
  /// (platform::select_clock, vigil/platform/tsc.hpp); `tsc` falls back to `monotonic` with a
  /// line in the start log where the TSC cannot be used.
  platform::ClockSource clock = platform::ClockSource::Monotonic;
  /// Stacks of the supervisor's and the monitor's threads, in bytes (0: the system default).
  std::size_t supervisor_stack_bytes = platform::kDefaultStackBytes;
  std::size_t monitor_stack_bytes = platform::kDefaultStackBytes;
  /// When set, the components' ports live in shared memory and `vigil supervise --name <this>`
  /// supervises them instead of this process (docs/guide/multi-process.md). Empty: in-process,
  /// unless the environment variable VIGIL_SUPERVISOR names a supervisor.
  std::string shared_memory;
  /// `warmup`: the first cycles kept out of the statistics and windows (AggregatorOptions).
  Nanos warmup_ns = 100 * kNanosPerMilli;
  /// `watchdog: {enabled, periods, floor, aperiodic}`.
  supervisor::WatchdogOptions watchdog{};
  /// `events: {queue, auto_clear, state_changes}`.
  std::size_t event_queue = 1024;
  Nanos auto_clear_ns = 0;
  bool state_events = true;
  /// `flight_recorder: {cycles, min_interval, max_records}`.
  supervisor::FlightRecorderOptions recorder{};
};

/// `outputs.http`: serve the reports over HTTP while the system runs (docs/guide/http.md).
struct HttpOutputSpec {
  exporter::ListenAddress listen;  ///< `listen: "[ADDR:]PORT"` (127.0.0.1 without ADDR)
  unsigned threads = 3;            ///< `threads: 1..16`
  bool dashboard = true;           ///< `dashboard: false` serves no web page
  bool clear = false;              ///< `clear: true` enables POST /api/v1/clear
};

/// `outputs.ros2`: publish ROS 2 `/diagnostics` over DDS (docs/guide/ros2.md).
struct Ros2OutputSpec {
  std::optional<int> domain_id;  ///< `domain_id: 0..232`; absent: ROS_DOMAIN_ID, else 0
  std::string dds_config;        ///< `dds_config:` Cyclone DDS XML or file URIs; "": Cyclone's own
  bool events = true;            ///< `events: false` publishes at the monitor's pace only
  bool node = true;              ///< `node: false` announces no ROS 2 node (ros_discovery_info)
  std::string node_name = "vigil";   ///< `node_name:` the ROS 2 node of the writer
  std::string node_namespace = "/";  ///< `node_namespace:` its namespace
  std::string ros_distro;            ///< `ros_distro: humble|jazzy|...`; "": ROS_DISTRO, else jazzy
};

/// Where the results go.
struct OutputSpec {
  std::optional<std::filesystem::path> json;  ///< final reports (the monitor's JSON schema)
  std::optional<HttpOutputSpec> http;         ///< live HTTP endpoint
  /// node-exporter textfile (`.prom`), rewritten atomically after every monitor cycle.
  std::optional<std::filesystem::path> textfile;
  std::optional<Ros2OutputSpec> ros2;  ///< ROS 2 /diagnostics over DDS
};

/// A top-level section handled by an extension (e.g. `can:`), unparsed.
struct ExtensionSection {
  std::string name;   ///< the key, e.g. "can"
  config::Node node;  ///< its value
};

/// A parsed, validated deployment.
struct DeploymentSpec {
  std::string name = "vigil";
  std::vector<ActivitySpec> activities;
  std::vector<ComponentSpec> components;
  SupervisionSpec supervision;
  OutputSpec outputs;
  /// `health:`: alive, deadline and logical supervisions (vigil/deploy/health_section.hpp).
  HealthSpec health;
  /// `diagnosis:`: the diagnosis graph (vigil/deploy/diagnosis_section.hpp); the default graph
  /// when absent.
  DiagnosisSpec diagnosis;
  /// `reactions:`: what the pipeline does about faults (vigil/deploy/reactions_section.hpp).
  ReactionsSpec reactions;
  /// Sections handled by registered extensions (e.g. `can:`), in file order, unparsed.
  std::vector<ExtensionSection> extensions;
  /// The document (keeps the nodes valid; component parameters report into it).
  config::Node root;
};

/// Validates a deployment document. Component types are looked up in `factory`.
[[nodiscard]] expected<DeploymentSpec, config::ConfigErrors> parse_deployment(
    const config::Node& root, const ComponentFactory& factory = ComponentFactory::instance());

/// Loads and validates the deployment file at `path`.
[[nodiscard]] expected<DeploymentSpec, config::ConfigErrors> load_deployment_file(
    const std::filesystem::path& path,
    const ComponentFactory& factory = ComponentFactory::instance());

/// Loads and validates a deployment from `text` (named `name` in errors).
[[nodiscard]] expected<DeploymentSpec, config::ConfigErrors> load_deployment_string(
    std::string_view text, std::string name,
    const ComponentFactory& factory = ComponentFactory::instance());

}  // namespace vigil::deploy
