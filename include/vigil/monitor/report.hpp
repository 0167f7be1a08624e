#pragma once
/// @file
/// `Report`: what the monitor publishes about one component each cycle (identity, placement,
/// state, counters, timing statistics, the recent window, the thread's OS counters, the status
/// and its messages, and the key/values added by checks), and `ReportSet`, one monitor cycle's
/// reports. Plain values: copy them freely; exporters (text, JSON) read nothing else.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::monitor {

/// What a report describes.
enum class ReportKind : std::uint8_t {
  Component,   ///< a supervised component
  Supervisor,  ///< the supervisor itself ("vigil.supervisor")
  Monitor,     ///< the monitor itself ("vigil.monitor")
  CanNode,     ///< a CAN node, from a CAN monitor ("can0/drive_5")
  CanGroup,    ///< a group of CAN nodes ("can0/left_arm"), the worst of its nodes
};

/// "component", "supervisor", "monitor", "can_node", "can_group".
[[nodiscard]] constexpr const char* to_string(ReportKind k) noexcept {
  switch (k) {
    case ReportKind::Component:
      return "component";
    case ReportKind::Supervisor:
      return "supervisor";
    case ReportKind::Monitor:
      return "monitor";
    case ReportKind::CanNode:
      return "can_node";
    case ReportKind::CanGroup:
      return "can_group";
  }
  return "?";
}

/// One key/value added by a check, shown in the detail view and exported as a string.
struct KeyValue {
  std::string key;
  std::string value;

  friend bool operator==(const KeyValue&, const KeyValue&) = default;
};

/// The deltas of a component's cumulative counters over the recent window (see
/// `Thresholds::window_ns`): the `Counters` counted since the window's start (`Counters::since`).
/// On the first observation of a component the window starts when the component joined (the
/// counters' origin), and `first` is true.
struct Window : task::Counters {
  Nanos duration_ns = 0;  ///< monitor time covered (0 on the first observation)
  bool first = true;

  /// overruns / cycles in the window; 0 without cycles.
  [[nodiscard]] double overrun_rate() const noexcept {
    return cycles == 0 ? 0.0 : static_cast<double>(overruns) / static_cast<double>(cycles);
  }
};

/// The last exception of a component.
struct ExceptionInfo {
  std::uint64_t count = 0;  ///< exceptions so far
  std::string type;         ///< demangled type name
  std::string message;      ///< what(), as reported (truncated to 71 bytes)
  Hook hook = Hook::None;
  std::uint64_t cycle = 0;  ///< the component's cycle when it was thrown
};

/// Everything the monitor publishes about one component (or about the supervisor or itself).
struct Report {
  ReportKind kind = ReportKind::Component;
  std::uint32_t id = 0;  ///< the registry's id (0 for the supervisor and monitor entries)
  std::string name;
  bool alive = true;        ///< false once the component left (reported for a while)
  bool configured = false;  ///< its identity (TaskInfo) arrived

  // --- identity and placement (from TaskInfo) ---
  std::string activity;
  SchedPolicy requested_policy = SchedPolicy::Other;
  SchedPolicy policy = SchedPolicy::Other;
  bool realtime_refused = false;
  int priority = 0;
  int cpu = -1;  ///< pinned CPU, -1 for none
  int tid = 0;   ///< kernel thread id, 0 until the component runs on a thread
  /// Alive components the monitor saw on the same thread (same tid), this one included; 0 when
  /// the tid is unknown.
  unsigned tasks_on_thread = 0;
  Nanos period_ns = 0;  ///< configured period; 0 for non-periodic

  // --- state and counters ---
  TaskState state = TaskState::PreOperational;
  /// For reports that are not components (CAN nodes, groups): the state in words
  /// ("responding", "silent", "never seen"), shown and exported instead of `state`.
  std::string state_label;
  task::Counters counters;    ///< cumulative, exact
  std::uint64_t samples = 0;  ///< cycle samples received (fewer than cycles when some dropped)
  Window window;              ///< counter deltas over the recent window

  // --- timing statistics (ns) ---
  StatsSummary user_ns;             ///< on_update() alone
  StatsSummary total_ns;            ///< user + supervision overhead
  StatsSummary latency_ns;          ///< wake-up latency: start - scheduled release
  StatsSummary measured_period_ns;  ///< start-to-start of consecutive cycles
  StatsSummary overhead_ns;         ///< supervision's own time per cycle (sampled)
  double overhead_share = 0.0;      ///< mean overhead / mean total; 0 when unknown
  /// Monitor time since the latest cycle arrived (or since the component was seen entering
  /// Running, if later); -1 when not Running or not known.
  Nanos silence_ns = -1;
  std::size_t port_capacity = 0;
  std::size_t port_high_water = 0;  ///< highest port occupancy seen at a drain

  // --- warm-up, events, latch (vigil/supervisor/events.hpp) ---
  std::uint64_t warmup_cycles = 0;  ///< samples of the warm-up, kept out of the statistics
  task::Counters warmup;            ///< the counters when the warm-up ended (its overruns, ...)
  supervisor::LatchedFault latch;   ///< the latched fault, if `latch.active`
  Nanos deadline_ns = 0;            ///< the watchdog's limit (0: not watched)
  std::uint64_t deadline_misses = 0;
  std::uint64_t events = 0;  ///< events raised for it

  // --- exceptions ---
  bool has_exception = false;
  ExceptionInfo exception;

  /// The thread's OS counters (platform::read_thread_stats), when the thread is known and alive.
  std::optional<platform::ThreadStats> thread;

  // --- verdict ---
  Status status;
  std::vector<KeyValue> values;  ///< added by checks, in order

  /// Adds a key/value (shown in the detail view and exported). Checks call it.
  void add(std::string key, std::string value) {
    values.push_back(KeyValue{std::move(key), std::move(value)});
  }
  /// Merges a finding into `status` (see Status for the rule). Checks call it.
  void merge(StatusLevel level, std::string message = {}) {
    status.merge(level, std::move(message));
  }
  /// The value of `key` added by a check, if any (the first one).
  [[nodiscard]] const std::string* value(std::string_view key) const noexcept;
};

/// The reports of one monitor cycle.
struct ReportSet {
  std::uint64_t cycle = 0;         ///< monitor cycles so far (0 before the first)
  Nanos time_ns = 0;               ///< monitor clock at the start of the cycle
  std::vector<Report> components;  ///< by registry id, then the supervisor, then the monitor

  /// The report named `name`, or null.
  [[nodiscard]] const Report* find(std::string_view name) const noexcept;
  /// The worst status level among the reports (Ok when empty).
  [[nodiscard]] StatusLevel worst() const noexcept;
};

/// A duration for people: 3 significant digits and a unit ("950ns", "12.3us", "1.50ms", "2.00s").
/// Negative values get a '-'. Not RT-safe (allocates).
[[nodiscard]] std::string format_nanos(double ns);

/// Fills the identity, counters and statistics of `r` from `s` (not the status, window, silence,
/// tasks_on_thread or thread fields, which the monitor computes).
void fill_report(Report& r, const supervisor::ComponentSnapshot& s);

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::format_nanos;
using monitor::KeyValue;
using monitor::Report;
using monitor::ReportKind;
using monitor::ReportSet;
using monitor::to_string;
}  // namespace vigil
