#pragma once
/// @file
/// The node-exporter textfile output: the Prometheus 0.0.4 exposition of a snapshot written to a
/// `.prom` file that node_exporter's textfile collector
/// (`--collector.textfile.directory`) serves with the host's metrics, for sites that collect
/// that way instead of scraping vigil.
///
/// The file is replaced atomically: the text goes to `<path>.tmp` in the same directory, which
/// is then renamed over `<path>`, so the collector never reads half a file. (The rename is
/// atomic against readers; it is not forced to disk, which a collector does not need.)
///
/// Not RT-safe (file I/O); any non-RT thread; one writer per path.

#include <filesystem>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/metrics_snapshot.hpp"

namespace vigil::exporter {

/// Writes `snapshot` to `path` atomically (see the file comment). Fails (naming the file and
/// the reason) when the directory does not exist or is not writable, or the rename fails; the
/// previous file is then left as it was.
expected<void, Error> write_textfile(const std::filesystem::path& path,
                                     const MetricsSnapshot& snapshot);

}  // namespace vigil::exporter
