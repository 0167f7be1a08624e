#pragma once
/// @file
/// Deployment extensions: services that live with a `System` and are configured by a top-level
/// section of the deployment file (e.g. `can:`, handled by vigil::deploy_can). An extension
/// registers a maker under its section's name; the deployment loader accepts that section only
/// when a maker is registered for it, and `System::create` hands the section to that maker.
/// Nothing in the deploy module knows any section's name or content.
///
/// ```cpp
/// vigil::deploy::register_extension("lidar", [](const vigil::config::Node& section,
///                                               vigil::deploy::System&)
///     -> vigil::expected<std::unique_ptr<vigil::deploy::Extension>, vigil::config::ConfigErrors> {
///   auto ext = std::make_unique<Lidar>(section.required<std::string>("device"));
///   if (section.has_errors()) return vigil::unexpected(section.errors());
///   return ext;
/// });
/// ```
///
/// Registration is thread-safe and may happen at static initialisation. Not RT-safe.

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/config/node.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/output.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/service/contributor.hpp"

namespace vigil::deploy {

class System;

/// A service that lives with the system (e.g. CAN supervision), configured by a top-level
/// section of the deployment file. An extension is a contributor of the system's pipeline
/// (vigil/service/contributor.hpp): `contribute()` adds its units (e.g. one report per CAN node,
/// with its gap buckets) to every monitor cycle, once, on the monitor's thread. Its other
/// members are called from the thread that drives the System (`start`, `stopping`, `stop`).
class Extension : public service::Contributor {
 public:
  /// Called after the supervisor and monitor started, before any component is configured.
  /// A failure stops the system's start.
  virtual expected<void, Error> start() { return {}; }
  /// Called when the system begins to stop, before any component stops (e.g. to judge
  /// liveness as of that moment rather than after the shutdown's own delays).
  virtual void stopping() {}
  /// Called after the components stopped.
  virtual void stop() {}
  /// Adds the extension's units to a monitor cycle (default: none).
  void contribute(exporter::Snapshot& /*snapshot*/) override {}
  /// The names of the units it will report that a configuration may name (the `diagnosis:`
  /// section's units are checked against them when the system is built). Default: none.
  [[nodiscard]] virtual std::vector<std::string> unit_names() const { return {}; }
};

/// Makes an extension from its deployment section. Errors are the section's configuration
/// errors (file:line:col), as every schema loader reports them.
using ExtensionMaker = std::function<expected<std::unique_ptr<Extension>, config::ConfigErrors>(
    const config::Node& section, System& system)>;

/// Registers `maker` for the top-level section named `section` (replacing an earlier one).
/// Register before loading deployments that use the section. Thread-safe.
void register_extension(std::string section, ExtensionMaker maker);

/// The maker registered for `section`, or an empty function. Thread-safe.
[[nodiscard]] ExtensionMaker find_extension(std::string_view section);

/// The names of the registered sections, sorted. Thread-safe.
[[nodiscard]] std::vector<std::string> registered_extensions();

}  // namespace vigil::deploy
