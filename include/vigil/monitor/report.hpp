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
#include <utility>
#include <vector>

#include "vigil/monitor/status.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/running_stats.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::monitor {

/// What a report describes. The monitor makes the first three; everything a contributor adds (a
/// CAN node, a CAN group, a process...) is a `Unit`, whose kind the contributor names
/// (`Report::unit_kind`) and whose figures are its own `Field`s, under its own names.
enum class ReportKind : std::uint8_t {
  Component,   ///< a supervised component
  Supervisor,  ///< the supervisor thread itself ("vigil.supervisor")
  Monitor,     ///< the monitor itself ("vigil.monitor")
  Unit,        ///< a contributor's unit: `Report::unit_kind` says which
};

/// "component", "supervisor", "monitor", "unit".
[[nodiscard]] constexpr const char* to_string(ReportKind k) noexcept {
  switch (k) {
    case ReportKind::Component:
      return "component";
    case ReportKind::Supervisor:
      return "supervisor";
    case ReportKind::Monitor:
      return "monitor";
    case ReportKind::Unit:
      return "unit";
  }
  return "?";
}

/// One figure of a unit, under the name its contributor gives it ("frames_rx", "rx_gap"). Outputs
/// show a unit's fields by these names: a column each in the text summary, a member of the
/// report's "fields" object in JSON. Names are snake_case; a duration's name carries no unit
/// suffix (its type says it is nanoseconds).
struct Field {
  enum class Type : std::uint8_t {
    Count,         ///< `count`: a number of things (frames, nodes)
    Duration,      ///< `duration_ns`: one duration
    Distribution,  ///< `distribution`: statistics of durations (ns)
    Text,          ///< `text`: words ("learned")
  };
  std::string name;
  Type type = Type::Count;
  std::uint64_t count = 0;
  Nanos duration_ns = 0;
  StatsSummary distribution;
  std::string text;

  [[nodiscard]] static Field of_count(std::string field_name, std::uint64_t v) {
    Field f;
    f.name = std::move(field_name);
    f.count = v;
    return f;
  }
  [[nodiscard]] static Field of_duration(std::string field_name, Nanos ns) {
    Field f;
    f.name = std::move(field_name);
    f.type = Type::Duration;
    f.duration_ns = ns;
    return f;
  }
  [[nodiscard]] static Field of_distribution(std::string field_name, const StatsSummary& s) {
    Field f;
    f.name = std::move(field_name);
    f.type = Type::Distribution;
    f.distribution = s;
    return f;
  }
  [[nodiscard]] static Field of_text(std::string field_name, std::string words) {
    Field f;
    f.name = std::move(field_name);
    f.type = Type::Text;
    f.text = std::move(words);
    return f;
  }
};

/// "count", "duration", "distribution", "text".
[[nodiscard]] constexpr const char* to_string(Field::Type t) noexcept {
  switch (t) {
    case Field::Type::Count:
      return "count";
    case Field::Type::Duration:
      return "duration";
    case Field::Type::Distribution:
      return "distribution";
    case Field::Type::Text:
      return "text";
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
  Nanos period_ns =
      0;  ///< the configured period; 0 for non-periodic (measured: `measured_period_ns`)

  // --- state and counters ---
  TaskState state = TaskState::PreOperational;
  /// For reports whose state is not a lifecycle state (units, a component whose process ended):
  /// the state in words ("responding", "never seen", "process ended"), shown and exported
  /// instead of `state`.
  std::string state_label;
  task::Counters counters;    ///< cumulative, exact
  std::uint64_t samples = 0;  ///< cycle samples received (fewer than cycles when some dropped)
  Window window;              ///< counter deltas over the recent window

  // --- timing statistics (ns) ---
  StatsSummary execution_ns;        ///< on_update() alone
  StatsSummary total_ns;            ///< execution + supervision overhead
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

  // --- a unit's own figures (kind Unit) ---
  /// What the unit is, as its contributor names it ("can_node", "can_group"); empty for the
  /// monitor's own kinds.
  std::string unit_kind;
  std::vector<Field> fields;  ///< its figures, in the order its contributor added them
  /// The reports this one needs, by name: edges of the diagnosis graph its contributor knows (a
  /// CAN group its nodes, a health supervision its components; monitor/diagnosis.hpp).
  std::vector<std::string> depends_on;
  /// Set by the diagnosis graph when a failed dependency explains this report's status: the root
  /// causes it depends on (report names). Empty for a root cause, and for an OK report.
  std::vector<std::string> caused_by;

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
  /// Adds a unit's field. Contributors call it.
  void add_field(Field f) { fields.push_back(std::move(f)); }
  /// The field named `field_name`, if any (the first one).
  [[nodiscard]] const Field* field(std::string_view field_name) const noexcept;
  /// What the report describes in one word: `unit_kind` for a unit, else `to_string(kind)`.
  [[nodiscard]] std::string_view kind_name() const noexcept {
    return kind == ReportKind::Unit ? std::string_view(unit_kind) : to_string(kind);
  }
  /// A unit of kind `unit`.
  [[nodiscard]] bool is_unit(std::string_view unit) const noexcept {
    return kind == ReportKind::Unit && unit_kind == unit;
  }
};

/// The reports of one monitor cycle.
struct ReportSet {
  std::uint64_t cycle = 0;         ///< monitor cycles so far (0 before the first)
  Nanos time_ns = 0;               ///< monitor clock at the start of the cycle
  std::vector<Report> components;  ///< by registry id, then the supervisor, then the monitor
  /// The reports whose status (not OK) no failed dependency explains, in report order: what to
  /// act on first. Set by the diagnosis graph (monitor/diagnosis.hpp); empty when none ran.
  std::vector<std::string> root_causes;

  /// The report named `name`, or null.
  [[nodiscard]] const Report* find(std::string_view name) const noexcept;
  /// The worst status level among the reports (Ok when empty).
  [[nodiscard]] StatusLevel worst() const noexcept;
};

/// A duration for people: 3 significant digits and a unit ("950ns", "12.3us", "1.50ms", "2.00s").
/// Negative values get a '-'. Not RT-safe (allocates).
[[nodiscard]] std::string format_nanos(double ns);

/// A unit's field for people: "12", "1.50ms", "p50 1.00ms, p99 1.20ms, max 2.00ms (812
/// samples)", or its words. Not RT-safe (allocates).
[[nodiscard]] std::string format_field(const Field& f);

/// Fills the identity, counters and statistics of `r` from `s` (not the status, window, silence,
/// tasks_on_thread or thread fields, which the monitor computes).
void fill_report(Report& r, const supervisor::ComponentSnapshot& s);

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::Field;
using monitor::format_field;
using monitor::format_nanos;
using monitor::KeyValue;
using monitor::Report;
using monitor::ReportKind;
using monitor::ReportSet;
using monitor::to_string;
}  // namespace vigil
