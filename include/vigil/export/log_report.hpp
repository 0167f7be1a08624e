#pragma once
/// @file
/// The components' log lines in the reports: what the JSON and detail outputs show of them.

#include <cstddef>

#include "vigil/log/service.hpp"
#include "vigil/monitor/report.hpp"

namespace vigil::exporter {

/// Adds to each component report of `reports` that logged: "log.lines", "log.suppressed",
/// "log.dropped", and its last `recent_lines` lines, each as a value "log". The JSON and detail
/// outputs show them. Thread-safe (reads `logs` through its thread-safe accessors); not RT-safe.
void add_log_lines(const log::LogService& logs, ReportSet& reports, std::size_t recent_lines = 5);

}  // namespace vigil::exporter
