#include "vigil/export/log_report.hpp"

#include <string>

namespace vigil::exporter {

void add_log_lines(const log::LogService& logs, ReportSet& reports, std::size_t recent_lines) {
  for (Report& r : reports.components) {
    if (r.kind != ReportKind::Component) continue;
    const log::ComponentLogStats s = logs.stats(r.name);
    if (s.lines == 0 && s.suppressed == 0 && s.dropped == 0) continue;
    r.add("log.lines", std::to_string(s.lines));
    r.add("log.suppressed", std::to_string(s.suppressed));
    r.add("log.dropped", std::to_string(s.dropped));
    for (const log::Line& l : logs.recent(r.name, recent_lines)) {
      r.add("log", log::format_line(l, log::LineFormat{.component = false, .source = false}));
    }
  }
}

}  // namespace vigil::exporter
