#pragma once
/// @file
/// Events and flight records for people and tools:
///  - `trace_event_json`: a `FlightRecord` as Chrome/Perfetto trace-event JSON (open it in
///    https://ui.perfetto.dev or chrome://tracing; docs/guide/events.md shows how to read it);
///  - `TraceWriter`: writes the record frozen with every ERROR-raising event into a directory,
///    and any component's recorder on demand;
///  - `EventLogWriter`: appends every event to a file as one JSON object per line.
///
/// Both writers are event subscribers (vigil/supervisor/events.hpp): they run on their own
/// dispatcher thread and never delay the supervisor. Not RT-safe.

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::exporter {

/// The record as trace-event JSON (the "JSON Object Format"): one process per component
/// ("vigil: <name>"), one thread (its activity), an `X` (complete) event per cycle with `ts` and
/// `dur` in microseconds (fractional: nanosecond precision) and the cycle's numbers in `args`,
/// counter tracks "latency_us" and "execution_us", an instant (`i`) marker on the faulting cycle
/// (or at the deadline that passed), markers where cycles are missing, and the event in
/// `otherData`. Timestamps are the monotonic clock in microseconds.
[[nodiscard]] std::string trace_event_json(const supervisor::FlightRecord& record);

/// An event as one JSON object on one line (no newline): seq, kind, severity, component,
/// component_id, cycle, fault_ns, detected_ns, latency_ns, count, latched, traced, detail
/// (strings escaped and UTF-8-repaired by `append_json_string`). Not RT-safe (allocates).
[[nodiscard]] std::string event_json(const Event& e);

/// Options of a `TraceWriter`.
struct TraceWriterOptions {
  std::filesystem::path directory;  ///< created if missing
  /// Where the writer says what it wrote or failed to write (empty: nothing is said).
  std::function<void(const std::string&)> log;
};

/// Writes frozen flight records as `<directory>/<component>-<seq>.trace.json`.
class TraceWriter {
 public:
  /// Creates the directory and subscribes to `aggregator`'s events (which must outlive the
  /// writer). Fails when the directory cannot be created.
  static expected<std::unique_ptr<TraceWriter>, Error> start(
      supervisor::ComponentAggregator& aggregator, TraceWriterOptions options);
  /// Unsubscribes (after the record being written).
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// Writes component `name`'s recorder now (on demand) as `<name>-demand-<n>.trace.json`.
  /// Returns the path, or an error (unknown component, I/O error). Any thread.
  expected<std::filesystem::path, Error> write_now(std::string_view name);
  /// Waits until the events published so far are handled. True when done in time.
  bool flush(Nanos timeout_ns = 2 * kNanosPerSecond);
  /// The files written so far, in order. Any thread.
  [[nodiscard]] std::vector<std::filesystem::path> written() const;
  /// The latest error (empty: none). Any thread.
  [[nodiscard]] std::string error() const;

 private:
  TraceWriter(supervisor::ComponentAggregator& aggregator, TraceWriterOptions options);
  void on_event(const Event& e);
  expected<std::filesystem::path, Error> write(const supervisor::FlightRecord& r,
                                               const std::string& stem);

  supervisor::ComponentAggregator& aggregator_;
  TraceWriterOptions options_;
  std::uint64_t subscription_ = 0;
  mutable std::mutex mutex_;
  std::vector<std::filesystem::path> written_;
  std::string error_;
  std::uint64_t demands_ = 0;
};

/// Writes `text` to `path` through a temporary file renamed into place. Not RT-safe.
expected<void, Error> write_file_atomically(const std::filesystem::path& path,
                                            const std::string& text);

/// Appends every event of a hub to a file, one JSON object per line (`event_json`), flushed
/// after each line.
class EventLogWriter {
 public:
  /// Opens (truncates) `path` and subscribes to `hub` (which must outlive the writer).
  static expected<std::unique_ptr<EventLogWriter>, Error> start(supervisor::EventHub& hub,
                                                                const std::filesystem::path& path);
  /// Unsubscribes and closes the file.
  ~EventLogWriter();
  EventLogWriter(const EventLogWriter&) = delete;
  EventLogWriter& operator=(const EventLogWriter&) = delete;
  /// Events written so far.
  [[nodiscard]] std::uint64_t written() const;
  /// Events the hub dropped for this writer (its queue was full).
  [[nodiscard]] std::uint64_t lost() const;
  /// The first write error (empty: none).
  [[nodiscard]] std::string error() const;

 private:
  EventLogWriter(supervisor::EventHub& hub, std::FILE* file, std::filesystem::path path);
  supervisor::EventHub& hub_;
  std::FILE* file_;
  std::filesystem::path path_;
  std::uint64_t subscription_ = 0;
  mutable std::mutex mutex_;
  std::uint64_t written_ = 0;
  std::string error_;
};

}  // namespace vigil::exporter
