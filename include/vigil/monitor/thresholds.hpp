#pragma once
/// @file
/// `Thresholds`: the limits the built-in checks apply to one component, with their defaults, and
/// `ThresholdSet`: defaults plus per-component overrides, as loaded from YAML.
///
/// Every field has a default (the values below) and a documented unit and range; the YAML keys
/// are the field names (docs/reference/thresholds.md lists them all). Durations are written with
/// units in YAML ("100ms"); fractions and rates are plain numbers in [0, 1].
///
/// The RT side never reads thresholds: only the monitor thread does, through an immutable
/// `std::shared_ptr<const ThresholdSet>` that a reload replaces as a whole.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>

#include "vigil/config/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::config {
class Node;
}  // namespace vigil::config

namespace vigil::monitor {

/// Initialization check: a component that has not sent its identity (TaskInfo) is not configured.
struct InitializationThresholds {
  bool enabled = true;
};

/// Exception check: an exception caught at a hook boundary is an Error.
struct ExceptionThresholds {
  bool enabled = true;
  /// true: Error as long as the component ever threw (until it leaves). false: Error while it is
  /// in Exception/FatalError or threw within the window, Warn "recovered" afterwards.
  bool sticky = true;
};

/// Overrun check.
struct OverrunThresholds {
  bool enabled = true;
  /// Warn "near overrun" when the EWMA of total time (user + supervision) is above this fraction
  /// of the period. Range [0, 1]; 0 disables this part. Periodic components only.
  double near_fraction = 0.9;
  /// Warn when overruns / cycles within the window is above this rate. Range [0, 1]; the default
  /// 0 warns on any overrun.
  double warn_rate = 0.0;
  /// Error when overruns / cycles within the window is above this rate. Range [0, 1],
  /// >= warn_rate.
  double error_rate = 0.1;
};

/// Starvation check: a Running component whose cycles stopped arriving is Stale "starved".
struct StarvationThresholds {
  bool enabled = true;
  /// Periodic components: Stale after `periods` × period without a cycle. Range [1, 1e6].
  double periods = 10.0;
  /// Lower bound of that limit, in ns: samples arrive when the supervisor drains (every 10 ms
  /// by default), so a limit below a few supervisor periods gives false alarms. Range [0, 1 h].
  Nanos min_silence_ns = 100 * kNanosPerMilli;
  /// Non-periodic components (triggered, manual without period): Stale after this long without
  /// a cycle; 0 (the default) never, since an event-driven component may rightly be idle.
  /// Range [0, 24 h].
  Nanos aperiodic_silence_ns = 0;
};

/// RealTime check: real-time losses (allocation, blocking, page faults, mode switches).
struct RealTimeThresholds {
  bool enabled = true;
  /// Warn when the losses within the window (all causes) are above this count.
  std::uint64_t warn_losses = 0;
  /// true: only components that run on a real-time policy (FIFO) are checked.
  bool fifo_only = true;
};

/// NotRealtime check: the component asked for FIFO and runs OTHER.
struct NotRealtimeThresholds {
  bool enabled = true;
};

/// Overhead check: supervision's share of the component's cycle time, judged only when the
/// overhead itself matters. A component whose on_update() takes 100 ns has a supervision share
/// near 50 % although supervision costs it nothing next to a 1 ms period: the two floors below
/// keep such a healthy component from warning.
struct OverheadThresholds {
  bool enabled = true;
  /// Warn when mean overhead / mean total time is above this share. Range [0, 1].
  double warn_share = 0.05;
  /// ... and the mean overhead is above this many ns (a few hundred ns is what supervision costs
  /// per measured cycle, cold caches included: docs/performance.md). Range [0, 1 s].
  Nanos min_overhead_ns = 1'000;
  /// ... and, for periodic components, above this fraction of the period (overhead that is not
  /// a tangible part of the cycle budget is not worth a warning). Range [0, 1]; 0 disables it.
  double min_period_share = 0.01;
};

/// Drops check: messages the component's port dropped (its supervisor did not keep up).
struct DropsThresholds {
  bool enabled = true;
  /// Warn when the drops within the window are above this count.
  std::uint64_t warn_drops = 0;
};

/// Every limit applied to one component. Aggregate with defaults: `Thresholds{}` is the default
/// configuration. Plain value; copy freely.
struct Thresholds {
  /// The "recent window" of the rate-based checks (overrun rates, losses, drops, exceptions):
  /// the deltas of the counters over at least this much monitor time, taken between monitor
  /// cycles. 0 (the default) means "since the previous monitor cycle". Range [0, 1 h].
  Nanos window_ns = 0;
  InitializationThresholds initialization;
  ExceptionThresholds exception;
  OverrunThresholds overrun;
  StarvationThresholds starvation;
  RealTimeThresholds realtime;
  NotRealtimeThresholds not_realtime;
  OverheadThresholds overhead;
  DropsThresholds drops;
  /// Numbers for custom checks (`custom: {max_temperature: 80}` in YAML), by key. The built-in
  /// checks ignore them.
  std::map<std::string, double, std::less<>> custom;

  /// `custom[key]` when present, else `fallback`.
  [[nodiscard]] double custom_value(std::string_view key, double fallback) const;
};

/// Defaults plus per-component overrides. A component's thresholds are the defaults with its
/// overrides applied key by key.
struct ThresholdSet {
  Thresholds defaults;
  /// Complete thresholds (defaults already applied) by component name.
  std::map<std::string, Thresholds, std::less<>> components;
  /// Where the set was loaded from ("" when built in code).
  std::string source;

  /// The thresholds of component `name`: its entry, or the defaults.
  [[nodiscard]] const Thresholds& for_component(std::string_view name) const;
};

/// Loads a threshold set from the root of a YAML document:
///
/// ```yaml
/// defaults:            # optional; each key optional (built-in defaults otherwise)
///   window: 0s
///   overrun: {near_fraction: 0.9, warn_rate: 0, error_rate: 0.1}
///   starvation: {periods: 10, min_silence: 100ms}
/// components:          # optional; overrides by component name, on top of `defaults`
///   motor:
///     overrun: {near_fraction: 0.8}
///     drops: {enabled: false}
/// ```
///
/// Unknown keys, wrong types and out-of-range values are errors located at file:line:col with
/// the dotted field (`components.motor.overrun.near_fraction`); every error of the document is
/// returned. Not RT-safe.
[[nodiscard]] expected<ThresholdSet, config::ConfigErrors> load_thresholds(
    const config::Node& root);

/// Reads one block of thresholds (the keys of `defaults:`, for a block embedded in another
/// document): each key present replaces the value of `base`, the others keep it. Errors are
/// recorded in `block`'s document (its `finish()` or `errors()` returns them); the returned
/// value is meaningful only when there is none. A missing or empty block returns `base`.
/// Not RT-safe.
[[nodiscard]] Thresholds read_thresholds(const config::Node& block, const Thresholds& base = {});

/// Reads and loads the YAML file at `path` (errors name the file as written). Not RT-safe.
[[nodiscard]] expected<ThresholdSet, config::ConfigErrors> load_thresholds_file(
    const std::filesystem::path& path);

/// Parses `text` (called `name` in errors) and loads it. Not RT-safe.
[[nodiscard]] expected<ThresholdSet, config::ConfigErrors> load_thresholds_string(
    std::string_view text, std::string name = "<string>");

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::DropsThresholds;
using monitor::ExceptionThresholds;
using monitor::InitializationThresholds;
using monitor::load_thresholds;
using monitor::load_thresholds_file;
using monitor::load_thresholds_string;
using monitor::NotRealtimeThresholds;
using monitor::OverheadThresholds;
using monitor::OverrunThresholds;
using monitor::read_thresholds;
using monitor::RealTimeThresholds;
using monitor::StarvationThresholds;
using monitor::Thresholds;
using monitor::ThresholdSet;
}  // namespace vigil
