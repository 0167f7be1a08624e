#pragma once
/// @file
/// `DrainLoop<Variant, Handler>`: drains every registered port each cycle and visits each
/// message into a handler. Generic: the component supervisor and the CAN supervisor are the same
/// class with different variants and handlers.
///
/// Design: one non-RT thread (or `step()` called from a loop you own). It polls at its period and
/// never notifies or wakes anything on the RT side; the RT side never waits for it. A cycle:
/// (1) if the registry's generation changed, pick up new entries (handler.on_join); (2) for each
/// entry, pop its messages in batches and visit them (handler.begin, handler.on, handler.end);
/// (3) forget entries that left once drained (handler.on_leave); (4) measure itself
/// (handler.on_cycle). A port is drained at most up to its capacity per cycle, so a producer that
/// pushes without pause cannot hold the supervisor in one port.

#include <algorithm>
#include <atomic>
#include <concepts>
#include <memory>
#include <mutex>
#include <string>
#include <variant>
#include <vector>

#include "vigil/bus/registry.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/supervisor/running_stats.hpp"

namespace vigil::supervisor {

/// What the supervisor learnt about one port in one cycle.
struct PortDrain {
  std::size_t messages = 0;   ///< messages popped this cycle
  std::size_t occupancy = 0;  ///< messages waiting when the drain began
  std::size_t capacity = 0;
  std::uint64_t dropped = 0;  ///< the port's drop counter (cumulative)
  /// When this cycle began (supervisor clock), before this port's drain began.
  Nanos cycle_ns = 0;
  /// The drain stopped on an empty port: every message pushed before `cycle_ns` was visited.
  /// False when it stopped at its budget (the port's capacity) with messages perhaps left.
  bool emptied = false;
};

/// The supervisor's measurement of itself, after each cycle.
struct DrainCycle {
  std::uint64_t cycle = 0;
  Nanos time_ns = 0;         ///< when the cycle began (supervisor clock)
  Nanos drain_ns = 0;        ///< time spent in this cycle
  std::size_t messages = 0;  ///< messages visited this cycle
  std::size_t ports = 0;     ///< ports drained
  std::size_t max_occupancy = 0;
};

namespace detail {
template <class H, class E, class M>
concept HandlesMessage = requires(H& h, const E& e, const M& m) {
  h.on(e, m);
};

template <class H, class E, class V>
struct handles_all : std::false_type {};
template <class H, class E, class... T>
struct handles_all<H, E, std::variant<T...>>
    : std::bool_constant<(HandlesMessage<H, E, T> && ...)> {};
}  // namespace detail

/// A handler: told about joins and leaves, visited with every message (one `on(entry, m)` per
/// alternative of the variant, or a template catch-all), told about cycles. A handler may also
/// have `on_batch(entry, const Variant* messages, std::size_t n)`: the supervisor then hands it
/// each popped batch instead of visiting message by message (it must do what `on` would). A
/// handler may also have `Nanos next_deadline() const`: the supervisor's thread then wakes at
/// the earlier of its next period and that time (monotonic clock) for one more cycle.
template <class H, class Variant>
concept SupervisorHandler = detail::handles_all<H, bus::RegistryEntry<Variant>, Variant>::value &&
    requires(H& h, const bus::RegistryEntry<Variant>& e, const PortDrain& d, const DrainCycle& c) {
  h.on_join(e);
  h.on_leave(e);
  h.begin(e);
  h.end(e, d);
  h.on_cycle(c);
};

/// The supervisor's own statistics, readable from any thread.
struct DrainStats {
  std::uint64_t cycles = 0;
  std::uint64_t messages = 0;
  std::size_t ports = 0;
  std::size_t max_occupancy = 0;  ///< highest port occupancy seen (high-water mark)
  StatsSummary drain_ns;          ///< time per cycle
  StatsSummary messages_per_cycle;
};

/// Options of a supervisor.
struct DrainOptions {
  /// Period of the supervisor's own thread. 10 ms: at 1 kHz a component queues 10 messages.
  Nanos period_ns = 10 * kNanosPerMilli;
  /// Messages popped from a port at a time.
  std::size_t batch = 64;
  std::string thread_name = "vigil-supervisor";
  /// Stack of the supervisor's thread, in bytes (0: the system default, usually 8 MiB).
  std::size_t stack_bytes = platform::kDefaultStackBytes;
  /// Clock used for the supervisor's own timing.
  Clock clock = Clock::system();
};

template <class Variant, class Handler>
requires SupervisorHandler<Handler, Variant>
class DrainLoop {
 public:
  using Entry = bus::RegistryEntry<Variant>;

  DrainLoop(Registry<Variant>& registry, Handler& handler, DrainOptions options = {})
      : registry_(registry), handler_(handler), options_(std::move(options)) {
    buffer_.resize(std::max<std::size_t>(options_.batch, 1));
  }
  DrainLoop(const DrainLoop&) = delete;
  DrainLoop& operator=(const DrainLoop&) = delete;
  ~DrainLoop() {
    // The final drain may allocate (a component that joined at the last moment); out of
    // memory there loses that drain's messages rather than terminating the process.
    try {
      stop();
    } catch (...) {  // NOLINT(bugprone-empty-catch): nothing left to report them to
    }
  }

  /// Runs one cycle in the calling thread; returns the number of messages visited.
  /// Not RT-safe (may allocate when components join). Not thread-safe against itself: call it
  /// from one thread, and not while the supervisor's own thread runs.
  std::size_t step() {
    const Nanos t0 = options_.clock.now();
    refresh();
    std::size_t total = 0;
    std::size_t max_occ = 0;
    for (std::size_t k = 0; k < tracked_.size(); ++k) {
      auto& tracked = tracked_[k];
      Entry& e = *tracked.entry;
      prefetch_ahead(k);
      // Read `closed` before draining: a member that left pushed nothing after this load, so an
      // empty port after the drain means it is finished.
      const bool closed = e.closed.load(std::memory_order_acquire);
      PortDrain d;
      d.cycle_ns = t0;
      d.capacity = e.port->capacity();
      d.occupancy = e.port->read_available();
      max_occ = std::max(max_occ, d.occupancy);
      handler_.begin(e);
      std::size_t budget = std::max(d.capacity, d.occupancy);
      while (budget > 0) {
        const std::size_t want = std::min(budget, buffer_.size());
        const std::size_t n = e.port->pop(buffer_.data(), want);
        if (n == 0) {
          d.emptied = true;
          break;
        }
        if constexpr (requires { handler_.on_batch(e, buffer_.data(), n); }) {
          handler_.on_batch(e, buffer_.data(), n);
        } else {
          for (std::size_t i = 0; i < n; ++i) {
            std::visit([&](const auto& m) { handler_.on(e, m); }, buffer_[i]);
          }
        }
        d.messages += n;
        budget -= n;
        // Fewer than asked: the port was empty. What arrived since waits for the next cycle
        // (no second pop, a virtual call and two atomic loads, per port and cycle).
        if (n < want) {
          d.emptied = true;
          break;
        }
      }
      // At its budget: empty only if nothing is left (one load, on this rare path only).
      if (!d.emptied) d.emptied = e.port->read_available() == 0;
      tracked.finished = closed && e.port->read_available() == 0;
      if (tracked.finished) {
        for (const Variant& m : e.last_words) {
          std::visit([&](const auto& x) { handler_.on(e, x); }, m);
        }
        d.messages += e.last_words.size();
      }
      d.dropped = e.port->dropped();
      handler_.end(e, d);
      total += d.messages;
    }
    std::erase_if(tracked_, [&](const Tracked& t) {
      if (t.finished) {
        handler_.on_leave(*t.entry);
        t.entry->finished.store(true, std::memory_order_relaxed);
      }
      return t.finished;
    });
    const Nanos t1 = options_.clock.now();
    DrainCycle c{cycle_ + 1, t0, t1 - t0, total, tracked_.size(), max_occ};
    ++cycle_;
    {
      std::lock_guard lock(stats_mutex_);
      stats_.cycles = cycle_;
      stats_.messages += total;
      stats_.ports = tracked_.size();
      stats_.max_occupancy = std::max(stats_.max_occupancy, max_occ);
      drain_.add(c.drain_ns);
      per_cycle_.add(static_cast<Nanos>(total));
    }
    handler_.on_cycle(c);
    return total;
  }

  /// Starts the supervisor's own thread (SCHED_OTHER). Not RT-safe.
  expected<void, Error> start() {
    if (thread_.joinable()) return {};
    quit_.store(false, std::memory_order_relaxed);
    auto t = platform::Thread::spawn(
        {.name = options_.thread_name, .stack_bytes = options_.stack_bytes}, [this] { run(); });
    if (!t) return unexpected<Error>(t.error());
    thread_ = std::move(*t);
    return {};
  }

  /// Stops and joins the thread after one last full drain. Idempotent.
  void stop() {
    if (!thread_.joinable()) return;
    quit_.store(true, std::memory_order_release);
    thread_.join();
    step();
  }

  [[nodiscard]] bool running() const noexcept { return thread_.joinable(); }

  /// A copy of the supervisor's statistics. Any thread; takes a short lock.
  [[nodiscard]] DrainStats stats() const {
    std::lock_guard lock(stats_mutex_);
    DrainStats s = stats_;
    s.drain_ns = drain_.summary();
    s.messages_per_cycle = per_cycle_.summary();
    return s;
  }

  [[nodiscard]] const DrainOptions& options() const noexcept { return options_; }

 private:
  struct Tracked {
    std::shared_ptr<Entry> entry;
    bool finished = false;
  };

  // With thousands of ports nothing of the next ones is in the caches: a pipeline of hints, each
  // stage reading only what the previous one brought in: the entry four ports ahead, the port
  // object (vtable, indexes) three ahead, the oldest messages two ahead (PortReader::prefetch).
  void prefetch_ahead(std::size_t k) const noexcept {
    const std::size_t n = tracked_.size();
    if (k + 4 < n) __builtin_prefetch(tracked_[k + 4].entry.get());
    if (k + 3 < n) {
      const auto* p = reinterpret_cast<const char*>(tracked_[k + 3].entry->port.get());
      __builtin_prefetch(p);
      __builtin_prefetch(p + 64);
      __builtin_prefetch(p + 128);
    }
    if (k + 2 < n) tracked_[k + 2].entry->port->prefetch();
  }

  void refresh() {
    const std::uint64_t gen = registry_.generation();
    if (gen == generation_) return;
    generation_ = gen;
    registry_.collect(scratch_);
    // Both lists are ordered by id: merge, keeping entries that left but are not drained yet.
    for (auto& e : scratch_) {
      if (e->finished.load(std::memory_order_relaxed)) continue;  // drained and forgotten
      const auto it =
          std::lower_bound(tracked_.begin(), tracked_.end(), e->id,
                           [](const Tracked& t, std::uint32_t id) { return t.entry->id < id; });
      if (it == tracked_.end() || it->entry->id != e->id) {
        handler_.on_join(*e);
        tracked_.insert(it, Tracked{e, false});
      }
    }
    scratch_.clear();
  }

  void run() {
    Nanos next = platform::now_ns();
    while (!quit_.load(std::memory_order_acquire)) {
      step();
      const Nanos now = platform::now_ns();
      // A regular cycle schedules the next one; an early one (a handler's deadline) leaves the
      // regular schedule where it was.
      if (now >= next) {
        next += options_.period_ns;
        if (next < now) next = now;  // never try to catch up: polling later is enough
      }
      Nanos wake = next;
      // A handler with deadlines of its own (health supervision) is drained and judged when
      // the earliest one passes, not at the next period.
      if constexpr (requires(const Handler& h) {
                      { h.next_deadline() } -> std::convertible_to<Nanos>;
                    }) {
        wake = std::min(wake, static_cast<Nanos>(handler_.next_deadline()));
      }
      platform::sleep_until(wake);
    }
  }

  Registry<Variant>& registry_;
  Handler& handler_;
  DrainOptions options_;
  std::vector<Tracked> tracked_;
  std::vector<std::shared_ptr<Entry>> scratch_;
  std::vector<Variant> buffer_;
  std::uint64_t generation_ = ~std::uint64_t{0};
  std::uint64_t cycle_ = 0;
  std::atomic<bool> quit_{false};
  platform::Thread thread_;
  mutable std::mutex stats_mutex_;
  DrainStats stats_;
  RunningStats drain_;
  RunningStats per_cycle_;
};

}  // namespace vigil::supervisor
