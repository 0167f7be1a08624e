#pragma once
/// @file
/// The monitor's reports as JSON, with a documented, versioned schema
/// (docs/reference/json-schema.md). Version 1:
///
/// ```json
/// {"schema": 1, "generator": "vigil 0.1.0", "cycle": 12, "time_ns": 123456789,
///  "status": "WARN",
///  "components": [{"name": "motor", "kind": "component", "status": "WARN",
///                  "messages": ["near overrun: ..."], "state": "Running", "period_ns": 1000000,
///                  "counters": {"cycles": 1000, "overruns": 0, "missed_cycles": 0,
///                               "rt_losses": 0, "exceptions": 0, "dropped": 0, ...},
///                  "timing": {"execution_ns": {...}, "total_ns": {...}, ...}, ...}]}
/// ```
///
/// Within a schema version fields are only ever added; a field is never removed, renamed or
/// given another type without incrementing `schema`. Not RT-safe (allocates).

#include <string>

#include "vigil/export/json_writer.hpp"
#include "vigil/monitor/report.hpp"

namespace vigil::exporter {

/// The version written in the "schema" field.
inline constexpr int kJsonSchemaVersion = 2;

/// Options of the JSON export.
struct JsonOptions {
  /// 0: compact, one line; > 0: indented by this many spaces per level.
  int indent = 0;
};

/// The whole document for one monitor cycle.
[[nodiscard]] std::string to_json(const ReportSet& reports, const JsonOptions& options = {});

/// Writes one component object (an element of "components").
void write_json(JsonWriter& w, const Report& report);

/// Writes a statistics object: count, last, min, mean, ewma, max, p50, p90, p99, p999.
void write_json(JsonWriter& w, const StatsSummary& stats);

}  // namespace vigil::exporter

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exporter::JsonOptions;
using exporter::to_json;
}  // namespace vigil
