#pragma once
/// @file
/// The diagnosis graph: from every report's status to the root causes. Each report of a monitor
/// cycle (components, CAN nodes and groups, health supervisions, any contributor's unit) is a
/// unit of the graph; `depends_on` edges say what a unit needs. A unit whose status (not OK) is
/// explained by a failed dependency is *dependent*, and names its root causes
/// (`Report::caused_by`); the others are the *root causes* (`ReportSet::root_causes`), named once
/// at the top of every output.
///
/// The edges come from the contributors (`Report::depends_on`: a CAN group needs its nodes, a
/// health supervision its components: the default graph, with no configuration) and from a
/// `DiagnosisConfig` (a deployment's `diagnosis:` section): more edges, *aggregates* that combine
/// units (and, or, k of n), and per unit a hysteresis (a status must hold for a time before it
/// is shown, and its end for another before it clears), start-up suppression and latching.
///
/// ```cpp
/// vigil::monitor::DiagnosisConfig d;
/// d.hysteresis = {.raise_after_ns = 0, .clear_after_ns = 3'000'000'000};  // every unit
/// d.aggregates.push_back({.name = "arms", .op = vigil::monitor::AggregateOp::KOfN, .k = 1,
///                         .members = {"can group left_arm", "can group right_arm"}});
/// service.set_diagnosis(d);   // applied to every cycle after the contributors
/// ```
///
/// Pure logic over a ReportSet; `DiagnosisGraph` keeps the per-unit state (hysteresis, latches)
/// from one cycle to the next. Not RT-safe, not thread-safe: the monitor's thread applies it.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/report.hpp"

namespace vigil::monitor {

/// How long a status must hold before it is shown. A worse status than the one shown is shown
/// once it has held `raise_after_ns` and `raise_after_cycles` monitor cycles (the cycle it first
/// appears in is the first); a better one once it has held `clear_after_ns` and
/// `clear_after_cycles`. 0: at once.
struct Hysteresis {
  Nanos raise_after_ns = 0;
  Nanos clear_after_ns = 0;
  std::uint32_t raise_after_cycles = 0;
  std::uint32_t clear_after_cycles = 0;
  friend bool operator==(const Hysteresis&, const Hysteresis&) = default;
};

/// What the configuration says about one unit (a report, by name).
struct DiagnosisUnit {
  std::string name{};
  /// More edges: the units this one needs (besides those its contributor declares).
  std::vector<std::string> depends_on{};
  /// Its own hysteresis (default: the configuration's).
  std::optional<Hysteresis> hysteresis{};
  /// An ERROR shown stays shown until `DiagnosisGraph::clear()` (the dashboard's or the API's
  /// clear, or a program's call).
  bool latch = false;
};

/// How an aggregate combines its members.
enum class AggregateOp : std::uint8_t {
  And,   ///< OK when every member is OK: its status is the worst member's
  Or,    ///< OK when one member is OK: its status is the best member's
  KOfN,  ///< OK when k members are OK: its status is the k-th best member's
};
/// "and", "or", "k_of_n".
[[nodiscard]] const char* to_string(AggregateOp op) noexcept;

/// A unit made of others: a report of kind `aggregate` added to every cycle.
struct Aggregate {
  std::string name{};
  AggregateOp op = AggregateOp::And;
  std::size_t k = 1;  ///< KOfN only: 1..members
  /// Its members (units by name). An absent member counts as STALE.
  std::vector<std::string> members{};
  /// What it needs besides its members (a failed member already explains it).
  std::vector<std::string> depends_on{};
  std::optional<Hysteresis> hysteresis{};
  bool latch = false;
};

/// The unit kind of an aggregate's report.
inline constexpr std::string_view kAggregateUnit = "aggregate";

/// The diagnosis graph's configuration.
struct DiagnosisConfig {
  /// Every unit's hysteresis unless its own says otherwise.
  Hysteresis hysteresis{};
  /// Start-up suppression: for this long after the first cycle, a status that is not OK is shown
  /// OK (its messages kept, marked as suppressed): the system is not up yet. 0: none.
  Nanos startup_ns = 0;
  std::vector<DiagnosisUnit> units{};
  std::vector<Aggregate> aggregates{};
  /// Use the edges the contributors declare (`Report::depends_on`). True by default.
  bool contributor_edges = true;
};

/// Checks `config`: a unit or aggregate named twice, an aggregate without members, a k outside
/// 1..members, a dependency on itself, a cycle among the configured edges (named with its path:
/// "a -> b -> a"). Not RT-safe.
[[nodiscard]] expected<void, Error> validate(const DiagnosisConfig& config);

/// Applies a DiagnosisConfig to every cycle's reports.
class DiagnosisGraph {
 public:
  /// Throws std::invalid_argument with validate()'s message for a bad configuration.
  explicit DiagnosisGraph(DiagnosisConfig config = {});

  /// Applies the graph to one cycle's `reports` at monitor time `now`: hysteresis, aggregates,
  /// start-up suppression and latches change the statuses shown; then every report gets its
  /// `caused_by` and the set its `root_causes`. Edges to names no report has are ignored.
  void apply(ReportSet& reports, Nanos now);

  /// Clears unit `name`'s latch ("" : every latch); returns how many were cleared.
  std::size_t clear(std::string_view name = {});

  [[nodiscard]] const DiagnosisConfig& config() const noexcept { return config_; }

 private:
  struct UnitState {
    StatusLevel shown = StatusLevel::Ok;
    StatusLevel pending = StatusLevel::Ok;
    Nanos pending_since = 0;
    std::uint32_t pending_cycles = 0;  // consecutive cycles `pending` has held, this one included
    std::vector<StatusMessage> last_messages;  // of the latest status not OK
    bool latched = false;
    std::vector<StatusMessage> latched_messages;
  };
  void filter(Report& r, const Hysteresis& h, bool latch, Nanos now);
  [[nodiscard]] Report aggregate(const Aggregate& a, const ReportSet& reports) const;

  DiagnosisConfig config_;
  std::map<std::string, const DiagnosisUnit*, std::less<>> units_;
  std::map<std::string, UnitState, std::less<>> state_;
  Nanos first_ = -1;
};

}  // namespace vigil::monitor
