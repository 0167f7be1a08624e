#pragma once
/// @file
/// `MonitorExporter`: connects a `Monitor` to the HTTP server and/or the node-exporter textfile
/// in one call, for a user's own program (and for a `deploy::System`'s `outputs`).
///
/// It subscribes to the monitor: after every monitor cycle, on the monitor's thread, it copies
/// the reports (plus those an `augment` function adds, e.g. a deployment's CAN nodes), reduces
/// the aggregator's histograms to Prometheus buckets, publishes the snapshot to the server and
/// rewrites the textfile. That costs the monitor thread a copy of the reports and a few
/// microseconds per component; HTTP clients never run on it and cannot delay it.
///
/// @code
/// vigil::ComponentAggregator aggregator;
/// vigil::Monitor monitor(aggregator);
/// auto http = vigil::exporter::serve_http(monitor, aggregator);   // 127.0.0.1:9479
/// if (!http) return fail(http.error().message);
/// monitor.start();
/// @endcode
///
/// Thread safety: construction and destruction from one control thread; the rest is
/// thread-safe. Not RT-safe.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::exporter {

/// What a `MonitorExporter` does.
struct ExportOptions {
  /// Serve HTTP with these options; none: no server.
  std::optional<HttpOptions> http;
  /// Rewrite this `.prom` file (atomically) after every monitor cycle; empty: none.
  std::filesystem::path textfile;
  /// Called on each cycle's copy of the reports before publication, to add or change reports
  /// (e.g. `[&system](ReportSet& r) { r = system.reports(); }` for a deploy::System's
  /// extensions). Runs on the monitor's thread.
  std::function<void(ReportSet&)> augment;
  /// Like `augment` (called after it), and also adds the gap histograms of the CAN reports it
  /// adds, matched by name (e.g. a deploy::System's CAN extension). Runs on the monitor's
  /// thread.
  std::function<void(ReportSet&, std::vector<CanHistograms>&)> augment_metrics;
  /// Serve the aggregator's events (`/api/v1/events`) and on-demand traces
  /// (`/api/v1/trace/<name>`) over HTTP, unless the HttpOptions name their own.
  bool events = true;
};

class MonitorExporter {
 public:
  /// Starts the server (if asked), subscribes to `monitor` and publishes its latest reports at
  /// once. `monitor` and `aggregator` (may be null: histograms then carry only count and sum)
  /// must outlive the exporter. Fails when the server cannot start (port taken...).
  static expected<std::unique_ptr<MonitorExporter>, Error> start(
      Monitor& monitor, const supervisor::ComponentAggregator* aggregator, ExportOptions options);

  /// Unsubscribes (waiting for a publication in progress), then stops the server. Must not run
  /// on the monitor's thread (e.g. from a subscriber).
  ~MonitorExporter();
  MonitorExporter(const MonitorExporter&) = delete;
  MonitorExporter& operator=(const MonitorExporter&) = delete;

  /// Publishes `reports` (and the gap buckets of its CAN reports, by name) now (e.g. the final
  /// reports after the system stopped, which a `System::step_monitor()` does not pass through
  /// `augment`). Any thread.
  void publish(const ReportSet& reports, std::vector<CanHistograms> can_histograms = {});

  /// The server, or null when HTTP was not asked for.
  [[nodiscard]] HttpServer* http() noexcept { return http_.get(); }
  /// The error of the latest textfile write; empty when it succeeded (or none is written).
  [[nodiscard]] std::string textfile_error() const;

 private:
  MonitorExporter(Monitor& monitor, const supervisor::ComponentAggregator* aggregator,
                  ExportOptions options);
  void on_cycle(const ReportSet& reports);

  struct Link {
    std::mutex mutex;
    MonitorExporter* self = nullptr;
  };

  Monitor& monitor_;
  const supervisor::ComponentAggregator* aggregator_;
  ExportOptions options_;
  std::unique_ptr<HttpServer> http_;
  std::shared_ptr<Link> link_;
  std::uint64_t subscription_ = 0;
  mutable std::mutex mutex_;  // serialises publications; guards textfile_error_
  std::string textfile_error_;
};

/// One call: serves `monitor`'s reports over HTTP with `options` (127.0.0.1:9479 by default).
[[nodiscard]] inline expected<std::unique_ptr<MonitorExporter>, Error> serve_http(
    Monitor& monitor, const supervisor::ComponentAggregator& aggregator, HttpOptions options = {}) {
  return MonitorExporter::start(monitor, &aggregator,
                                ExportOptions{.http = std::move(options),
                                              .textfile = {},
                                              .augment = {},
                                              .augment_metrics = {},
                                              .events = true});
}

}  // namespace vigil::exporter
