#pragma once
/// @file
/// The supervisor side of logging: `Line` (one formatted log line), `Sink` (where lines go) and
/// the sinks vigil ships: a stream (stderr), a size-rotated file, and a tail kept in memory (for
/// a live view). Nothing here is RT-safe: sinks run on the supervisor thread (or on the thread
/// that calls LogService::flush), one at a time, serialized by the LogService.

#include <cstdint>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/log/level.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::log {

/// One log line, formatted from a record (or written by the service: suppressed and dropped
/// counts). Plain data.
struct Line {
  std::string component;
  Level level = Level::Info;
  std::uint64_t cycle = 0;  ///< the component's cycle that logged it
  Nanos time_ns = 0;        ///< when that cycle began (the component's clock, monotonic)
  std::string text;
  std::string_view file;  ///< the call site's file (static storage); empty for service lines
  std::uint32_t line = 0;
  /// > 0: this line says that this many lines of its call site were suppressed by the rate
  /// limit (text "... N lines suppressed").
  std::uint64_t suppressed = 0;
  /// > 0: this line says that this many records of the component were dropped (port full)
  /// before the next one arrived (text "... N log records dropped (port full)").
  std::uint64_t dropped = 0;

  friend bool operator==(const Line&, const Line&) = default;
};

/// How a line is written.
struct LineFormat {
  bool component = true;  ///< the component's name
  bool source = false;    ///< "(file.cpp:42)" at the end
  bool color = false;     ///< the level in color (ANSI), for terminals
};

/// `[    12.345678] WARN  load_ramp #1234: text (demo_components.cpp:120)`: the time is the
/// cycle's start in seconds of the monotonic clock, then level, component, cycle number, text.
[[nodiscard]] std::string format_line(const Line& line, const LineFormat& format = {});

/// Where log lines go. Implementations need not be thread-safe for write/flush (the service
/// serializes them); readers they add (TailSink::lines) must be.
class Sink {
 public:
  virtual ~Sink() = default;
  /// Writes one line. Must not throw (report failures through the sink's own counters).
  virtual void write(const Line& line) noexcept = 0;
  /// Makes what was written durable/visible (called after each supervisor cycle that wrote).
  virtual void flush() noexcept {}
};

/// Writes each line to a stdio stream (stderr by default), one fwrite per line.
class StreamSink final : public Sink {
 public:
  explicit StreamSink(std::FILE* stream = stderr, LineFormat format = {})
      : stream_(stream), format_(format) {}
  void write(const Line& line) noexcept override;
  void flush() noexcept override;

 private:
  std::FILE* stream_;
  LineFormat format_;
};

/// Options of a rotating file.
struct RotatingFileOptions {
  std::string path;                      ///< the current file; older ones are path.1, path.2...
  std::uint64_t max_bytes = 10U << 20U;  ///< a file is rotated before it would exceed this
  unsigned max_files = 5;                ///< files kept, the current one included (>= 1)
  LineFormat format{.component = true, .source = true, .color = false};
};

/// A log file rotated by size: when the next line would make `path` larger than `max_bytes`,
/// path.(N-2) becomes path.(N-1) (the oldest is removed), ..., path becomes path.1, and a new
/// `path` is started (N = max_files; with N = 1 the file is simply started again). Appends to an
/// existing file at open. Write and rotation failures never throw: they are counted (errors())
/// and the latest is kept (last_error()).
class RotatingFileSink final : public Sink {
 public:
  /// Opens (creates or appends to) `options.path`. Errors: a path that cannot be opened (the
  /// message names it and says why), max_bytes == 0 or max_files == 0.
  static expected<std::unique_ptr<RotatingFileSink>, Error> open(RotatingFileOptions options);
  ~RotatingFileSink() override;
  RotatingFileSink(const RotatingFileSink&) = delete;
  RotatingFileSink& operator=(const RotatingFileSink&) = delete;

  void write(const Line& line) noexcept override;
  void flush() noexcept override;

  [[nodiscard]] std::uint64_t rotations() const noexcept { return rotations_; }
  [[nodiscard]] std::uint64_t errors() const noexcept { return errors_; }
  [[nodiscard]] const std::string& last_error() const noexcept { return last_error_; }
  /// Bytes in the current file.
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  [[nodiscard]] const RotatingFileOptions& options() const noexcept { return options_; }

 private:
  explicit RotatingFileSink(RotatingFileOptions options) : options_(std::move(options)) {}
  void rotate() noexcept;
  void fail(std::string message) noexcept;

  RotatingFileOptions options_;
  std::FILE* file_ = nullptr;
  std::uint64_t size_ = 0;
  std::uint64_t rotations_ = 0;
  std::uint64_t errors_ = 0;
  std::string last_error_;
};

/// Keeps the last `capacity` lines, formatted, for a live view to show. lines() and total() are
/// thread-safe.
class TailSink final : public Sink {
 public:
  explicit TailSink(std::size_t capacity = 10, LineFormat format = {})
      : capacity_(capacity), format_(format) {}
  void write(const Line& line) noexcept override;

  /// The kept lines, oldest first.
  [[nodiscard]] std::vector<std::string> lines() const;
  /// Lines written so far.
  [[nodiscard]] std::uint64_t total() const;

 private:
  mutable std::mutex mutex_;
  std::size_t capacity_;
  LineFormat format_;
  std::deque<std::string> lines_;
  std::uint64_t total_ = 0;
};

}  // namespace vigil::log
