#pragma once
/// @file
/// `Source`: the producer end of one component's log, and the process-wide settings of all
/// sources (run-time levels, drop counts).
///
/// Design: every supervised component owns one Source (inside its CycleRecorder), bound to the
/// component's port. Around each cycle the recorder calls `enter()` (which makes the source the
/// calling thread's current one and records the cycle's number and start time) and `leave()`.
/// A VIGIL_LOG_* call finds the current source through one thread-local pointer, checks its
/// level (one relaxed atomic load), writes the record in place in the source's scratch
/// `Message` and pushes it: the push is the record's only copy. The source is used by one
/// thread at a time (the component's), like its port.
///
/// Levels and drop counts are reachable by component name from any thread through the free
/// functions below (a small directory of sources behind a mutex; joining it is the only
/// allocation, when the component is built). This header depends on nothing above the bus, so
/// the task module can include it.

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/log/level.hpp"
#include "vigil/log/record.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::log {

class Source;

namespace detail {

/// The source of the cycle running on this thread; null outside a supervised cycle.
inline constinit thread_local Source* t_current = nullptr;

/// Log calls made outside any supervised cycle (dropped: no component to attribute them to).
inline std::atomic<std::uint64_t> g_unattributed{0};

/// The directory of sources. Not RT-safe (mutex, allocation).
struct Directory {
  std::mutex mutex;
  std::vector<Source*> sources;
  std::vector<std::pair<std::string, Level>> overrides;  // set_level() by name
  Level default_level = Level::Info;

  [[nodiscard]] Level level_for(std::string_view name) const noexcept {
    for (const auto& [n, l] : overrides) {
      if (n == name) return l;
    }
    return default_level;
  }
};

/// The one directory of the process (created on first use).
inline Directory& directory() {
  static Directory d;
  return d;
}

}  // namespace detail

/// The producer end of one component's log. Construction and destruction are not RT-safe; the
/// members marked RT-safe are wait-free and allocation-free and are called by the component's
/// thread only, except where "any thread" is said.
class Source {
 public:
  /// Pushes one message (the scratch) into the bound port; false when the port was full.
  using PushFn = bool (*)(void* port, const void* message) noexcept;

  /// Joins the directory under `name`, at the level set for that name (or the default).
  /// Not RT-safe (allocates, locks).
  explicit Source(std::string name) : name_(std::move(name)) {
    auto& d = detail::directory();
    std::lock_guard lock(d.mutex);
    level_.store(static_cast<std::uint8_t>(d.level_for(name_)), std::memory_order_relaxed);
    d.sources.push_back(this);
  }
  /// Leaves the directory. Not RT-safe.
  ~Source() {
    auto& d = detail::directory();
    std::lock_guard lock(d.mutex);
    std::erase(d.sources, this);
  }
  Source(const Source&) = delete;
  Source& operator=(const Source&) = delete;

  [[nodiscard]] const std::string& name() const noexcept { return name_; }

  /// The run-time level: calls below it are filtered. Any thread (relaxed atomic).
  [[nodiscard]] Level level() const noexcept {
    return static_cast<Level>(level_.load(std::memory_order_relaxed));
  }
  /// Changes this source's level only (see log::set_level for by-name). Any thread.
  void set_level(Level l) noexcept {
    level_.store(static_cast<std::uint8_t>(l), std::memory_order_relaxed);
  }
  /// True when a call at `l` passes the run-time level. RT-safe, any thread.
  [[nodiscard]] bool enabled(Level l) const noexcept {
    return static_cast<std::uint8_t>(l) >= level_.load(std::memory_order_relaxed);
  }

  /// Records dropped because the port was full (cumulative). Any thread.
  [[nodiscard]] std::uint64_t dropped() const noexcept {
    return dropped_.load(std::memory_order_relaxed);
  }
  /// Records pushed (cumulative). Any thread.
  [[nodiscard]] std::uint64_t pushed() const noexcept {
    return pushed_.load(std::memory_order_relaxed);
  }

  /// Makes this source the thread's current one for cycle `cycle`, which began at `time_ns`.
  /// Nests: leave() restores the previous one. RT-safe.
  void enter(std::uint64_t cycle, Nanos time_ns) noexcept {
    previous_ = detail::t_current;
    detail::t_current = this;
    cycle_ = cycle;
    time_ns_ = time_ns;
  }
  /// Ends the cycle begun by enter(). RT-safe.
  void leave() noexcept { detail::t_current = previous_; }

  [[nodiscard]] std::uint64_t cycle() const noexcept { return cycle_; }
  [[nodiscard]] Nanos time_ns() const noexcept { return time_ns_; }

  /// The scratch record the next push sends; the logging macros write it in place, then call
  /// push(). Never null (an unbound source has a scratch of its own and drops every push).
  /// RT-safe.
  [[nodiscard]] LogRecord* scratch() noexcept { return scratch_; }

  /// Pushes the scratch record (stamping the drop count), or drops and counts it when the port
  /// is full (the port counts it too, as every dropped message). RT-safe: wait-free, one
  /// indirect call.
  bool push() noexcept {
    const std::uint64_t d = dropped_.load(std::memory_order_relaxed);
    scratch_->dropped = static_cast<std::uint32_t>(d);
    if (push_(port_, message_)) {
      pushed_.store(pushed_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      return true;
    }
    // Single writer: a relaxed load + store, no locked read-modify-write on the RT path.
    dropped_.store(d + 1, std::memory_order_relaxed);
    return false;
  }

 protected:
  /// Binds the port: `message` is a Message holding a LogRecord at `record`; `push` pushes it.
  void bind(void* port, PushFn push_fn, const void* message, LogRecord* record) noexcept {
    port_ = port;
    push_ = push_fn;
    message_ = message;
    scratch_ = record;
  }

 private:
  std::string name_;
  std::atomic<std::uint8_t> level_{static_cast<std::uint8_t>(Level::Info)};
  Source* previous_ = nullptr;
  std::uint64_t cycle_ = 0;
  Nanos time_ns_ = 0;
  static bool drop(void* /*port*/, const void* /*message*/) noexcept { return false; }

  LogRecord unbound_;  // the scratch of a source without a port
  void* port_ = nullptr;
  PushFn push_ = &drop;
  const void* message_ = nullptr;
  LogRecord* scratch_ = &unbound_;
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> pushed_{0};
};

/// A Source bound to a `Port<Variant, N>` whose variant has a LogRecord alternative: what a
/// component's CycleRecorder owns. Not movable (the thread-local pointer refers to it).
template <class Variant, std::size_t N>
class PortSource final : public Source {
 public:
  /// Joins the directory and binds `port` (which may be null: every push then drops).
  /// Not RT-safe.
  PortSource(std::string name, Port<Variant, N>* port) : Source(std::move(name)) {
    if (port != nullptr) bind(port, &push_message, &message_, std::get_if<LogRecord>(&message_));
  }

 private:
  static bool push_message(void* port, const void* message) noexcept {
    return static_cast<Port<Variant, N>*>(port)->try_push(*static_cast<const Variant*>(message));
  }
  Variant message_{std::in_place_type<LogRecord>};
};

// --- settings by component name (any thread, not RT-safe) -------------------------------------

/// Sets the run-time level of every component named `component`, now and for components of that
/// name created later. Not RT-safe (locks); the components see it at their next log call.
inline void set_level(std::string_view component, Level level) {
  auto& d = detail::directory();
  std::lock_guard lock(d.mutex);
  bool found = false;
  for (auto& [n, l] : d.overrides) {
    if (n == component) {
      l = level;
      found = true;
    }
  }
  if (!found) d.overrides.emplace_back(std::string(component), level);
  for (Source* s : d.sources) {
    if (s->name() == component) s->set_level(level);
  }
}

/// Forgets the level set for `component` (it follows the default again). Not RT-safe.
inline void reset_level(std::string_view component) {
  auto& d = detail::directory();
  std::lock_guard lock(d.mutex);
  std::erase_if(d.overrides, [&](const auto& o) { return o.first == component; });
  for (Source* s : d.sources) {
    if (s->name() == component) s->set_level(d.default_level);
  }
}

/// Sets the level of every component without its own level (Info until changed). Not RT-safe.
inline void set_default_level(Level level) {
  auto& d = detail::directory();
  std::lock_guard lock(d.mutex);
  d.default_level = level;
  for (Source* s : d.sources) s->set_level(d.level_for(s->name()));
}

/// The level a component named `component` gets (its own, or the default). Not RT-safe.
[[nodiscard]] inline Level level_of(std::string_view component) {
  auto& d = detail::directory();
  std::lock_guard lock(d.mutex);
  return d.level_for(component);
}

/// Log records dropped (port full) by the live components named `component`. Not RT-safe.
[[nodiscard]] inline std::uint64_t dropped(std::string_view component) {
  auto& d = detail::directory();
  std::lock_guard lock(d.mutex);
  std::uint64_t n = 0;
  for (const Source* s : d.sources) {
    if (s->name() == component) n += s->dropped();
  }
  return n;
}

/// Log calls made outside any supervised cycle, process-wide (they are dropped: there is no
/// component to attribute them to). Any thread.
[[nodiscard]] inline std::uint64_t unattributed() noexcept {
  return detail::g_unattributed.load(std::memory_order_relaxed);
}

/// The source of the cycle running on the calling thread, or null. RT-safe.
[[nodiscard]] inline Source* current() noexcept { return detail::t_current; }

}  // namespace vigil::log
