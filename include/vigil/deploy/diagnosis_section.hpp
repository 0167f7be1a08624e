#pragma once
/// @file
/// The `diagnosis:` section of a deployment file: the diagnosis graph's configuration
/// (monitor/diagnosis.hpp; every key in docs/reference/deployment.md, "diagnosis").
///
/// ```yaml
/// diagnosis:
///   startup: 2s                                   # statuses shown OK until the system is up
///   hysteresis: {raise_after: 0s, clear_after: 3s}
///   units:
///     - {name: planner, depends_on: [can group right_arm], latch: true}
///   aggregates:
///     - {name: arms, op: and, members: [can group left_arm, can group right_arm]}
/// ```
///
/// Unit names are checked when the system is built, against the components, the health
/// supervisions ("supervision <name>"), the extensions' units (CAN nodes and groups), the
/// aggregates and the supervisor and monitor; every error names the file, line and column. Not
/// RT-safe.

#include <span>
#include <string>
#include <vector>

#include "vigil/config/node.hpp"
#include "vigil/monitor/diagnosis.hpp"

namespace vigil::deploy {

/// A parsed `diagnosis:` section and where each unit name it uses was written.
struct DiagnosisSpec {
  monitor::DiagnosisConfig config;
  bool defined = false;  ///< the section is present
  struct Reference {
    std::string name;
    config::Node node;
  };
  std::vector<Reference> references;  ///< every unit it names (units, members, dependencies)
};

/// Parses `node` (the `diagnosis:` mapping); errors are recorded on the nodes.
[[nodiscard]] DiagnosisSpec parse_diagnosis(const config::Node& node);

/// Records an error at each reference of `spec` to a name not in `known` (with a suggestion);
/// returns how many.
std::size_t check_unit_names(const DiagnosisSpec& spec, std::span<const std::string> known);

}  // namespace vigil::deploy
