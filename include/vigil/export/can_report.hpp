#pragma once
/// @file
/// CAN supervision for people and programs: the CAN monitor's report (`can::CanReport`) and a CAN
/// log replay (`vigil can-stats`) as text tables and JSON (schema in
/// docs/guide/can-supervision.md).
///
/// Not RT-safe (allocates). Any non-RT thread; the functions keep no state.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/can_monitor.hpp"
#include "vigil/can/replay.hpp"
#include "vigil/export/json_writer.hpp"

namespace vigil::exporter {

/// Options of the text form of a CAN report.
struct CanTextOptions {
  bool ids = true;                       ///< append the per-id table
  std::vector<std::string> bus_names{};  ///< name of bus i (e.g. candump's interfaces); else i
  /// Protocol events listed (the latest ones; -1: every one kept).
  std::ptrdiff_t max_events = 20;
};

/// The report for people: status line, summary table, node table, optionally the id table.
/// Ends with a newline.
[[nodiscard]] std::string format_can_report(const can::CanReport& report,
                                            const CanTextOptions& options = {});

/// The report as one JSON object (schema 1); `indent` as `JsonWriter`. `bus_names` names buses
/// as in the text form.
[[nodiscard]] std::string can_report_json(const can::CanReport& report, int indent = 0,
                                          const std::vector<std::string>& bus_names = {});

/// Writes the report's members (time, status, totals, summary, nodes, ids, sniffers) into the
/// object `w` has open, so that a tool can add its own members around them.
void write_can_report_members(exporter::JsonWriter& w, const can::CanReport& report,
                              const std::vector<std::string>& bus_names);

/// Options of the text form of a replay.
struct CanReplayTextOptions {
  bool ids = true;     ///< append the per-id table
  std::string config;  ///< the configuration file to name in the header ("" for none)
};

/// A replay's header (files, frames, time span, buses) followed by `format_can_report`.
[[nodiscard]] std::string format_can_replay(const can::LogReplay& replay,
                                            const can::CanReport& report,
                                            const CanReplayTextOptions& options = {});

/// A replay as one JSON object: `tool`, `files`, `buses`, `frames`, timestamps, then the
/// report's members (`write_can_report_members`).
[[nodiscard]] std::string can_replay_json(const can::LogReplay& replay,
                                          const can::CanReport& report, int indent = 2);

/// The malformed lines of each file read by `replay`: "PREFIXwarning: FILE: N malformed lines
/// skipped", then its first `max_per_file` errors as "  file:line:col: message"; one per line,
/// empty when there were none.
[[nodiscard]] std::string format_replay_warnings(const can::LogReplay& replay,
                                                 std::string_view prefix = "",
                                                 std::size_t max_per_file = 10);

}  // namespace vigil::exporter
