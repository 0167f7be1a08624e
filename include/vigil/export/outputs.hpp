#pragma once
/// @file
/// The built-in outputs (vigil/export/output.hpp): the text summary, the JSON file, the HTTP
/// server, the node-exporter textfile, the event log and the flight-recorder traces. Each is
/// registered like any other output (`SupervisionService::add_output()`); the service's options
/// and a deployment's `outputs:` section register them for you.
///
/// Threads and RT-safety as `Output`: none of them touches a real-time thread.

#include <cstdio>
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
#include "vigil/export/output.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/export/trace_event.hpp"

namespace vigil::exporter {

/// Writes `reports` as JSON (docs/reference/json-schema.md) with `indent`, and a newline, to
/// `path`, checking every write, the flush and the close (a full disk shows only there). The one
/// JSON file writer of vigil: the service's JSON output, `vigil demo` and `vigil supervise` all
/// write through it. The error names the path and the reason. Not RT-safe.
expected<void, Error> write_json_file(const std::filesystem::path& path, const ReportSet& reports,
                                      int indent = 2);

/// The text summary (and, if asked, every report's detail view) on a FILE*.
struct TextOutputOptions {
  std::FILE* file = stdout;
  /// Also write the summary after every monitor cycle (a live console view), not only at stop.
  bool every_cycle = false;
  /// Write the detail views after the summary at stop.
  bool details_at_stop = false;
  ColorMode color = ColorMode::Auto;
};

class TextOutput final : public Output {
 public:
  explicit TextOutput(TextOutputOptions options) : options_(options) {}
  void publish(const Snapshot& snapshot) override;
  void stop(const Snapshot& final_snapshot) override;

 private:
  TextOutputOptions options_;
};

/// The final reports as a JSON file, written at stop (`write_json_file`). A file that cannot be
/// written is said on stderr and in `error()`, never thrown.
class JsonFileOutput final : public Output {
 public:
  JsonFileOutput(std::filesystem::path path, int indent)
      : path_(std::move(path)), indent_(indent) {}
  void stop(const Snapshot& final_snapshot) override;
  /// The error of the write at stop; empty when it succeeded (or before stop).
  [[nodiscard]] std::string error() const;

 private:
  std::filesystem::path path_;
  int indent_;
  mutable std::mutex mutex_;
  std::string error_;
};

/// The HTTP server (Prometheus `/metrics`, `/api/v1/reports`, events, traces, the dashboard;
/// docs/reference/http.md) publishing every snapshot. Unless the options name their own, it
/// serves the pipeline's events and its components' flight records on demand.
class HttpOutput final : public Output {
 public:
  explicit HttpOutput(HttpOptions options, bool serve_events = true)
      : options_(std::move(options)), serve_events_(serve_events) {}
  /// Starts the server: fails when it cannot (port taken, invalid options).
  expected<void, Error> start(OutputContext& context) override;
  void publish(const Snapshot& snapshot) override;
  /// Publishes the final snapshot, then stops the server.
  void stop(const Snapshot& final_snapshot) override;
  /// The server while the output runs (e.g. `server()->address().port` for `listen` port 0);
  /// null before start() and after stop(). Control thread.
  [[nodiscard]] HttpServer* server() noexcept { return server_.get(); }
  [[nodiscard]] const HttpOptions& options() const noexcept { return options_; }

 private:
  HttpOptions options_;
  bool serve_events_;
  std::unique_ptr<HttpServer> server_;
};

/// Rewrites a node-exporter textfile (`.prom`, docs/guide/fleet.md) atomically after every
/// monitor cycle and at stop.
class TextfileOutput final : public Output {
 public:
  explicit TextfileOutput(std::filesystem::path path) : path_(std::move(path)) {}
  void publish(const Snapshot& snapshot) override;
  void stop(const Snapshot& final_snapshot) override { publish(final_snapshot); }
  /// The error of the latest write; empty when it succeeded. Any thread.
  [[nodiscard]] std::string error() const;
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  mutable std::mutex mutex_;
  std::string error_;
};

/// Appends every event to a file as one JSON object per line (`EventLogWriter`), within
/// milliseconds of its detection: it subscribes to the event hub at start and waits at stop
/// until the events published so far are written.
class EventLogOutput final : public Output {
 public:
  explicit EventLogOutput(std::filesystem::path path) : path_(std::move(path)) {}
  expected<void, Error> start(OutputContext& context) override;
  void stop(const Snapshot& final_snapshot) override;
  /// Events written, and lost (the writer fell behind), so far; kept after stop.
  [[nodiscard]] std::uint64_t written() const;
  [[nodiscard]] std::uint64_t lost() const;
  /// The first write error (empty: none).
  [[nodiscard]] std::string error() const;
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  supervisor::EventHub* hub_ = nullptr;
  std::unique_ptr<EventLogWriter> writer_;
  mutable std::mutex mutex_;
  std::uint64_t written_ = 0;
  std::uint64_t lost_ = 0;
  std::string error_;
};

/// Writes the flight record frozen with every ERROR-raising event into a directory
/// (`TraceWriter`, open them in ui.perfetto.dev), within milliseconds of the event.
class TraceOutput final : public Output {
 public:
  explicit TraceOutput(TraceWriterOptions options) : options_(std::move(options)) {}
  expected<void, Error> start(OutputContext& context) override;
  void stop(const Snapshot& final_snapshot) override;
  /// The files written so far; kept after stop.
  [[nodiscard]] std::vector<std::filesystem::path> written() const;
  [[nodiscard]] const std::filesystem::path& directory() const noexcept {
    return options_.directory;
  }

 private:
  TraceWriterOptions options_;
  supervisor::EventHub* hub_ = nullptr;
  std::unique_ptr<TraceWriter> writer_;
  mutable std::mutex mutex_;
  std::vector<std::filesystem::path> written_;
};

/// An output made of functions (any may be empty): a report subscriber, a test's probe.
class CallbackOutput final : public Output {
 public:
  using Publish = std::function<void(const Snapshot&)>;
  /// `on_stop` empty: the final snapshot goes to `on_publish` too.
  explicit CallbackOutput(Publish on_publish, Publish on_stop = {})
      : on_publish_(std::move(on_publish)), on_stop_(std::move(on_stop)) {}
  void publish(const Snapshot& snapshot) override {
    if (on_publish_) on_publish_(snapshot);
  }
  void stop(const Snapshot& final_snapshot) override {
    if (on_stop_) {
      on_stop_(final_snapshot);
    } else if (on_publish_) {
      on_publish_(final_snapshot);
    }
  }

 private:
  Publish on_publish_;
  Publish on_stop_;
};

}  // namespace vigil::exporter
