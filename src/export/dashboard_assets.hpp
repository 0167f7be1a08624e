#pragma once
// Private to the export module: the dashboard's files, embedded at build time by
// cmake/VigilEmbed.cmake from src/export/dashboard/ (and Chart.js from Debian's libjs-chart.js
// when the configure step found it; empty otherwise, and the page then shows tables only).
#include <string_view>

namespace vigil::exporter::detail {

extern const std::string_view kDashboardHtml;
extern const std::string_view kDashboardJs;
extern const std::string_view kDashboardCss;
extern const std::string_view kChartJs;  ///< empty when Chart.js was not found at configure time

}  // namespace vigil::exporter::detail
