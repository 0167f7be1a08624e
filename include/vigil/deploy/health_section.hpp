#pragma once
/// @file
/// The `health:` section of a deployment file (or of the file `vigil supervise --health` reads):
/// health supervision's alive, deadline and logical supervisions in YAML, parsed into a
/// `health::HealthConfig` (docs/reference/deployment.md, "health", lists every key).
///
/// ```yaml
/// health:
///   alive:
///     - {name: telemetry_rate, checkpoint: telemetry, reference_cycle: 100ms, expected: 10,
///        min_margin: 2, max_margin: 2}
///   deadline:
///     - {name: sense_to_act, start: camera.frame, end: drive.command_sent, max: 2ms}
///   logical:
///     - name: drive_sequence
///       initial: [drive.read]
///       final: [drive.write]
///       transitions: [[drive.read, drive.compute], [drive.compute, drive.write]]
/// ```
///
/// A checkpoint is written `component.checkpoint` (`component` alone: its cycles), or
/// `{component: x, checkpoint: y}` when a name holds a dot. Every error names the file, line,
/// column and field. Not RT-safe.

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/config/node.hpp"
#include "vigil/health/config.hpp"

namespace vigil::deploy {

/// A parsed `health:` section: the configuration, and where each checkpoint it names was
/// written (for the checks that can only be made once the components have declared theirs).
struct HealthSpec {
  health::HealthConfig config;
  /// One checkpoint reference of the file and its node.
  struct Reference {
    health::CheckpointRef ref;
    config::Node node;
  };
  std::vector<Reference> references;
  /// True when the section names at least one supervision.
  [[nodiscard]] bool empty() const noexcept {
    return config.alive.empty() && config.deadline.empty() && config.logical.empty();
  }
};

/// Parses `node` (the `health:` mapping). Entities must be among `components` (the
/// deployment's, with a suggestion for a misspelt one); with none given (`vigil supervise`,
/// whose components come from other processes) any name is accepted. Errors are recorded on the
/// nodes (`node.has_errors()`); what it returns is then incomplete.
[[nodiscard]] HealthSpec parse_health(const config::Node& node,
                                      std::span<const std::string> components);

/// Checks every named checkpoint of `spec` on entity `component` against `declared`, the names
/// that component declares: an unknown one is an error at its node ("component 'drive' declares
/// no checkpoint 'comand_sent'; did you mean 'command_sent'?"). Returns the number of errors.
std::size_t check_declared(const HealthSpec& spec, std::string_view component,
                           std::span<const std::string> declared);

/// As check_declared, but returns the errors as "file:line:column: field: message" lines instead
/// of recording them (for checks made after loading, when the document's errors are no longer
/// read).
[[nodiscard]] std::vector<std::string> undeclared_checkpoints(
    const HealthSpec& spec, std::string_view component, std::span<const std::string> declared);

}  // namespace vigil::deploy
