#pragma once
/// @file
/// The monitor's reports as text for people: a summary with one line per component, its status
/// coloured when the output is a terminal, and a detail view per component (key: value lines,
/// like the original's robot-monitor entries).
///
/// Summary columns: STATUS NAME STATE CYCLES USER(mean/p99) LAT(p99) OVERRUNS LOSSES MESSAGES.
///
/// Not RT-safe (allocates, and print_* write to a FILE).

#include <cstdint>
#include <cstdio>
#include <string>

#include "vigil/monitor/report.hpp"

namespace vigil::exporter {

/// When to colour the status with ANSI escapes.
enum class ColorMode : std::uint8_t {
  Auto,    ///< when the output is a terminal, NO_COLOR is unset and TERM is not "dumb"
  Always,  ///< always (e.g. for `less -R`)
  Never,   ///< never
};

/// Whether `mode` colours output written to `out` (Auto looks at the stream and environment).
[[nodiscard]] bool use_color(ColorMode mode, std::FILE* out);

/// The header line of the summary (no newline).
[[nodiscard]] std::string format_summary_header();
/// One summary line for `report` (no newline).
[[nodiscard]] std::string format_summary_line(const Report& report, bool color);
/// One line per root cause of `reports` (the diagnosis graph's, monitor/diagnosis.hpp):
/// "ROOT CAUSE ERROR can0/drive_5 (2 dependents): not responding..."; empty when none.
[[nodiscard]] std::string format_root_causes(const ReportSet& reports, bool color);
/// The root causes (and a blank line) when there are any, the header and one line per report,
/// each ending with a newline; a dependent report's messages start with "caused by <roots>".
[[nodiscard]] std::string format_summary(const ReportSet& reports, bool color);

/// The detail view of one report: a title line "name: STATUS", then indented key: value lines.
[[nodiscard]] std::string format_detail(const Report& report, bool color);
/// Every report's detail view, separated by blank lines.
[[nodiscard]] std::string format_details(const ReportSet& reports, bool color);

/// Writes format_summary to `out` (colour per `mode`).
void print_summary(std::FILE* out, const ReportSet& reports, ColorMode mode = ColorMode::Auto);
/// Writes format_details to `out` (colour per `mode`).
void print_details(std::FILE* out, const ReportSet& reports, ColorMode mode = ColorMode::Auto);

}  // namespace vigil::exporter

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exporter::ColorMode;
using exporter::format_detail;
using exporter::format_details;
using exporter::format_summary;
using exporter::format_summary_header;
using exporter::format_summary_line;
using exporter::print_details;
using exporter::print_summary;
using exporter::use_color;
}  // namespace vigil
