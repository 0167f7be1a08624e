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
#include "vigil/export/exemplars.hpp"
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

/// Lines a live text view shows under its table (the latest events, the components' log).
class TextPanel {
 public:
  virtual ~TextPanel() = default;
  /// Appends the panel (a blank line, a title line, its lines) to `out`; nothing when empty.
  /// Any thread.
  virtual void append(std::string& out) const = 0;
};

/// The text summary (and, if asked, every report's detail view) on a FILE*.
struct TextOutputOptions {
  std::FILE* file = stdout;
  /// Also write the summary after every monitor cycle (a live console view), not only at stop.
  bool every_cycle = false;
  /// Write the detail views after the summary at stop.
  bool details_at_stop = false;
  ColorMode color = ColorMode::Auto;
  /// The live view's first line: "<title> — <seconds since start> s — worst: <level>"; empty:
  /// no such line.
  std::string title{};
  /// Redraw the live view in place (cursor home, clear): for a terminal.
  bool redraw = false;
  /// Shown under the table of every view, the final one included, in order (they must outlive
  /// the output: e.g. other outputs of the same service).
  std::vector<const TextPanel*> panels{};
  /// The line written before the final summary ("Stopped after 20.0 s. Final report:" when it
  /// is "Stopped"); empty: none.
  std::string final_title{};
};

class TextOutput final : public Output {
 public:
  explicit TextOutput(TextOutputOptions options) : options_(std::move(options)) {}
  expected<void, Error> start(OutputContext& context) override;
  void publish(const Snapshot& snapshot) override;
  void stop(const Snapshot& final_snapshot) override;
  /// Changes the final title (e.g. to "Interrupted" on Ctrl-C) before stop. Control thread.
  void set_final_title(std::string title) { options_.final_title = std::move(title); }

 private:
  TextOutputOptions options_;
  Nanos started_ns_ = 0;
};

/// Events as rate-limited lines for people (`supervisor::EventLineLimiter`: at most one per
/// component per second, folded counts never lost; lifecycle changes left out, the summary shows
/// the state): written to a FILE as each event arrives ("event: ..."), or kept, the latest
/// `lines`, for a live view's panel (`file` null).
class EventLineOutput final : public Output, public TextPanel {
 public:
  struct Options {
    std::FILE* file = stderr;  ///< null: keep the lines for the panel
    std::size_t lines = 6;     ///< lines kept for the panel
  };
  explicit EventLineOutput(Options options) : options_(options) {}
  expected<void, Error> start(OutputContext& context) override;
  void stop(const Snapshot& final_snapshot) override;
  /// "events (N lines; the last 6 here):" and the lines.
  void append(std::string& out) const override;

 private:
  void on_event(const Event& e);

  Options options_;
  supervisor::EventHub* hub_ = nullptr;
  std::uint64_t subscription_ = 0;
  supervisor::EventLineLimiter limiter_;
  mutable std::mutex mutex_;
  std::vector<std::string> lines_;  // the latest, oldest first
  std::uint64_t total_ = 0;
};

/// The final reports as a JSON file, written at stop (`write_json_file`). A file that cannot be
/// written is said on stderr and in `error()`, never thrown: at start, when the path cannot be
/// opened for writing then (supervision goes on, the write is tried again at stop), and at stop.
class JsonFileOutput final : public Output {
 public:
  JsonFileOutput(std::filesystem::path path, int indent)
      : path_(std::move(path)), indent_(indent) {}
  expected<void, Error> start(OutputContext& context) override;
  void stop(const Snapshot& final_snapshot) override;
  /// Whether the write at stop succeeded (false before stop).
  [[nodiscard]] bool written() const;
  /// The error of the write at stop; empty when it succeeded (or before stop).
  [[nodiscard]] std::string error() const;

 private:
  std::filesystem::path path_;
  int indent_;
  mutable std::mutex mutex_;
  std::string error_;
  bool written_ = false;
};

/// The HTTP server (Prometheus `/metrics`, `/api/v1/reports`, events, traces, the dashboard;
/// docs/reference/http.md) publishing every snapshot. Unless the options name their own, it
/// serves the pipeline's events, its components' flight records on demand and the records
/// frozen with events. Its OpenMetrics exposition carries exemplars (`ExemplarBook`): the worst
/// cycles and the latest overrun of each component, with the frozen record that holds them.
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
  // The OpenMetrics exemplars (worst cycles, overruns, their traces); publish() only.
  ExemplarBook exemplars_;
  supervisor::ComponentAggregator* aggregator_ = nullptr;  // from start() to stop()
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
