#pragma once
/// @file
/// The `reactions:` section of a deployment file: what the pipeline does about faults
/// (service/reactions.hpp; every key in docs/reference/deployment.md, "reactions").
///
/// ```yaml
/// reactions:
///   dry_run: false                    # true: log what would be done, do nothing
///   policy: FIFO                      # the reaction thread (default OTHER)
///   priority: 30
///   rules:
///     - name: encoder_fault
///       on: {event: exception, component: encoder}
///       safe_state: true
///     - name: stop_right_arm
///       on: {unit: can0/drive_5, status: ERROR}
///       can:                          # through a CAN writer the program registered
///         - {writer: can_io, id: 0x000, data: [0x02, 0x06]}   # CANopen NMT stop, node 6
///       handlers: [notify_operator]   # registered with ComponentFactory::add_handler()
///       watchdog: false               # WATCHDOG=trigger to systemd
///       min_interval: 1s
/// ```
///
/// No shell command is ever run from a configuration file. Names are checked when the system
/// is built (units against the system's units, handlers and CAN writers against what the
/// program registered); every error names the file, line and column. Not RT-safe.

#include <string>
#include <vector>

#include "vigil/config/node.hpp"
#include "vigil/service/reactions.hpp"

namespace vigil::deploy {

/// A parsed `reactions:` section and where each name it uses was written.
struct ReactionsSpec {
  bool defined = false;
  bool dry_run = false;
  /// The reaction thread's scheduling (`policy`, `priority`).
  platform::SchedPolicy policy = platform::SchedPolicy::Other;
  int priority = 0;
  std::vector<service::Reaction> rules;
  /// Per rule, its node (for the errors found when the system is built).
  std::vector<config::Node> nodes;
};

/// Parses `node` (the `reactions:` mapping); errors are recorded on the nodes.
[[nodiscard]] ReactionsSpec parse_reactions(const config::Node& node);

}  // namespace vigil::deploy
