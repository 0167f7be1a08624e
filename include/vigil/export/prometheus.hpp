#pragma once
/// @file
/// The Prometheus exposition of a `MetricsSnapshot`: text format 0.0.4 (what Prometheus,
/// node_exporter's textfile collector and most tools read) and OpenMetrics 1.0 (what
/// Prometheus 2.x asks for first).
///
/// Every family has the `vigil_` prefix, base units (seconds, ratios), a HELP and a TYPE line
/// (and in OpenMetrics a UNIT line for `_seconds` families); counters end in `_total`; label
/// values are escaped (backslash, double quote, line feed) and invalid UTF-8 is replaced by
/// U+FFFD. Timing distributions are real histograms (`_bucket{le}` cumulative in seconds, `+Inf`
/// equal to `_count`, `_sum`; boundaries in vigil/export/buckets.hpp). The families are listed
/// in docs/reference/metrics.md.
///
/// Not RT-safe (allocates); any thread; the functions are pure.

#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/export/metrics_snapshot.hpp"

namespace vigil::exporter {

/// Which text format to write.
enum class ExpositionFormat : std::uint8_t {
  Prometheus,   ///< text format 0.0.4 (`text/plain; version=0.0.4`)
  OpenMetrics,  ///< OpenMetrics 1.0.0 (`application/openmetrics-text; version=1.0.0`)
};

/// The format an HTTP `Accept` header asks for: OpenMetrics when it names
/// `application/openmetrics-text` (with a q-value above 0), else the 0.0.4 text format.
[[nodiscard]] ExpositionFormat negotiate_format(std::string_view accept) noexcept;

/// The Content-Type of `format`, with version and charset.
[[nodiscard]] const char* content_type(ExpositionFormat format) noexcept;

/// Appends `value` escaped as a label value (without the quotes): `\` -> `\\`, `"` -> `\"`,
/// line feed -> `\n`; bytes that are not valid UTF-8 become U+FFFD.
void append_label_value(std::string& out, std::string_view value);

/// Appends `v` as an exposition number: integers exactly, others in the shortest form that
/// reads back to the same double, `+Inf`, `-Inf`, `NaN`.
void append_number(std::string& out, double v);

/// The whole exposition of `snapshot` in `format` (OpenMetrics ends with `# EOF`).
[[nodiscard]] std::string render_metrics(const MetricsSnapshot& snapshot, ExpositionFormat format);

/// Same, appending to `out` (reuse its capacity between calls).
void render_metrics(std::string& out, const MetricsSnapshot& snapshot, ExpositionFormat format);

}  // namespace vigil::exporter
