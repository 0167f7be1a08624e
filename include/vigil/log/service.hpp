#pragma once
/// @file
/// `LogService`: the supervisor side of logging. It receives the records the supervisor drains
/// from components' ports (it is a RecordConsumer: `aggregator.set_log_consumer(&service)`),
/// formats them with fmt, applies the rate limit per call site, writes the lines to its sinks,
/// and keeps the recent lines of every component for reports and the HTTP API.
///
/// ```cpp
/// vigil::log::LogService logs;                               // before the system: outlives it
/// logs.add_sink(std::make_shared<vigil::log::StreamSink>());  // stderr
/// system.aggregator().set_log_consumer(&logs);
/// ```
///
/// Rate limit: at most `rate_limit` lines per second per call site and component (windows of
/// one second of the component's clock, from the first line of a window). The lines over the
/// limit are counted, and one line "... N lines suppressed" is written when the window closes
/// (at the site's next line, at the end of a supervisor cycle one second after the window began,
/// or at flush()).
///
/// Dropped records (port full): each record carries its component's count of drops; when it
/// grows, the service writes "... N log records dropped (port full)" before the record.
///
/// Threads: on_record/on_supervisor_cycle run on the supervisor thread; every other member is
/// thread-safe (one mutex, held while one record is formatted and written). Nothing is RT-safe.

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "vigil/log/consumer.hpp"
#include "vigil/log/sinks.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::log {

/// Options of a LogService.
struct LogServiceOptions {
  /// Lines per second per call site and component; 0 = no limit.
  std::uint32_t rate_limit = 20;
  /// Lines kept per component for recent() and reports.
  std::size_t recent = 64;
  /// The supervisor side's clock: closes the rate windows of call sites that went quiet.
  Clock clock = Clock::system();
};

/// What the service counted for one component.
struct ComponentLogStats {
  std::uint64_t lines = 0;       ///< lines written (records formatted and not suppressed)
  std::uint64_t suppressed = 0;  ///< lines suppressed by the rate limit
  std::uint64_t dropped = 0;     ///< records dropped on the RT side (port full)
};

class LogService final : public RecordConsumer {
 public:
  explicit LogService(LogServiceOptions options = {});
  ~LogService() override;
  LogService(const LogService&) = delete;
  LogService& operator=(const LogService&) = delete;

  /// Adds a sink; lines from then on go to it too. Thread-safe.
  void add_sink(std::shared_ptr<Sink> sink);

  // --- RecordConsumer (supervisor thread) ---
  void on_record(std::uint32_t id, std::string_view component, const LogRecord& record) override;
  void on_supervisor_cycle(Nanos now) override;

  /// Writes the suppressed counts still pending and flushes every sink. Thread-safe; call it
  /// after the last supervisor drain (e.g. after System::stop()).
  void flush();

  /// The last `n` lines of component `component`, oldest first (at most `recent` are kept).
  /// Thread-safe.
  [[nodiscard]] std::vector<Line> recent(std::string_view component, std::size_t n) const;
  /// The counts of component `component` (zeros for a component that never logged). Drops
  /// include those not yet reported by a later record (read from the live component).
  /// Thread-safe.
  [[nodiscard]] ComponentLogStats stats(std::string_view component) const;
  /// The components that logged (or dropped), by name. Thread-safe.
  [[nodiscard]] std::vector<std::string> components() const;
  /// Records whose formatting failed (shown as "<format error: ...>"). Thread-safe.
  [[nodiscard]] std::uint64_t format_errors() const;

  [[nodiscard]] const LogServiceOptions& options() const noexcept { return options_; }

 private:
  struct Component;
  /// The rate window of one call site of one component.
  struct Rate {
    bool open = false;
    Nanos window_ns = 0;  // when the window began (record time)
    std::uint32_t count = 0;
    std::uint64_t suppressed = 0;
    std::uint64_t last_cycle = 0;  // of the last suppressed record
    Nanos last_time_ns = 0;
    Component* component = nullptr;
  };
  struct RateKey {
    std::uint32_t id;
    const CallSite* site;
    friend bool operator<(const RateKey& a, const RateKey& b) noexcept {
      return a.id != b.id ? a.id < b.id : std::less<const CallSite*>()(a.site, b.site);
    }
  };

  Component& component(std::string_view name);
  void write(Component& c, Line line);
  void close_window(const RateKey& key, Rate& r);

  LogServiceOptions options_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Sink>> sinks_;
  std::map<std::string, std::unique_ptr<Component>, std::less<>> components_;
  std::map<RateKey, Rate> rates_;
  std::map<std::uint32_t, std::uint32_t> seen_dropped_;  // by component id: drops reported
  std::size_t pending_ = 0;                              // rate windows holding suppressed lines
  bool wrote_ = false;                                   // since the last flush of the sinks
  std::uint64_t format_errors_ = 0;
};

}  // namespace vigil::log
