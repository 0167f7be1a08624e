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
/// outputs: {json: final.json}
/// ```
///
/// Loading checks everything it can before anything runs: unknown keys, types, ranges, unknown
/// component types (with a suggestion), references to undefined activities, duplicate names.
/// Not RT-safe.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/config/node.hpp"
#include "vigil/deploy/factory.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/thresholds.hpp"

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
  config::Node parameters;  ///< undefined when absent
  config::Node node;        ///< the component's own entry, for errors
};

/// How the system supervises itself.
struct SupervisionSpec {
  Nanos supervisor_period_ns = 10 * kNanosPerMilli;
  Nanos monitor_period_ns = kNanosPerSecond;
  double ewma_weight = 0.05;
  /// Thresholds embedded in the deployment, or loaded from `thresholds_file` (watched and
  /// reloaded at run time when it changes).
  ThresholdSet thresholds;
  std::optional<std::filesystem::path> thresholds_file;
  /// mlockall + prefault at start.
  bool lock_memory = true;
  /// When set, the components' ports live in shared memory and `vigil supervise --name <this>`
  /// supervises them instead of this process (docs/guide/multi-process.md). Empty: in-process,
  /// unless the environment variable VIGIL_SUPERVISOR names a supervisor.
  std::string shared_memory;
};

/// Where the results go.
struct OutputSpec {
  std::optional<std::filesystem::path> json;  ///< final reports (the monitor's JSON schema)
};

/// A parsed, validated deployment.
struct DeploymentSpec {
  std::string name = "vigil";
  std::vector<ActivitySpec> activities;
  std::vector<ComponentSpec> components;
  SupervisionSpec supervision;
  OutputSpec outputs;
  /// Sections handled by extensions (e.g. `can:`), unparsed.
  config::Node can;
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
