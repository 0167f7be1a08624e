#pragma once
/// @file
/// The CAN sniffer: the hook a CAN I/O component calls on every frame it reads or writes, and
/// what it hands to the CAN supervisor.
///
/// Design (who owns what):
///  - `Sniffer<N>` belongs to the CAN I/O component. Its `on_read` / `on_write` run on the I/O
///    thread (one thread at a time: the sniffer is the single producer of its port) and are
///    RT-safe: wait-free, allocation-free, lock-free, noexcept, no system call.
///  - Each call maps the identifier to a node (`NodeMap`), applies the current filter, then
///    counts the frame EXACTLY in two fixed tables owned by `detail::SnifferState`
///    (vigil/can/detail/sniffer_state.hpp, internals): one per
///    (bus, id, direction) and one per (bus, node, direction), with first and last time seen.
///    The tables are open-addressing arrays sized at construction; a lookup examines at most
///    `kMaxProbe` slots, so every call is O(1). A frame whose key finds no room (the table holds
///    `max_ids` / `max_nodes` keys, or its probe run is full) is counted in `untracked_ids` /
///    `untracked_nodes`, exactly, and never blocks.
///  - The accepted frame's timing (`FrameRecord`: its time and the call's duration, the exact
///    gap since the previous frame of the same id and of the same node, the first 8 data bytes)
///    is pushed to the sniffer's `Port`. When the port is full the record is dropped and
///    counted: timing distributions are sampled under load, but counts and liveness come from
///    the tables and stay exact, so no node can starve (the original's weakness).
///  - The table counters are written by the I/O thread only and read by the supervisor side
///    with relaxed atomics (single writer: no read-modify-write, no tearing; 64-bit atomics are
///    lock-free on the supported targets, which a static_assert checks).
///  - Filter replacement is RCU-style. The I/O thread reads the current `Filter` through an
///    atomic pointer inside a guard: it bumps an epoch counter to odd before the load (seq_cst)
///    and to even after its last use (release). `set_filter` (any non-RT thread) exchanges the
///    pointer (seq_cst) and reads the epoch (seq_cst); the old filter is retired with that epoch
///    and freed by the non-RT side (the next `set_filter`/`reclaim`, or the CAN supervisor's next
///    cycle) once the epoch was even or has moved: the I/O thread was not inside a call, or has
///    left the call that could hold the old pointer. The I/O thread never waits, allocates or
///    frees. A null filter means "accept all" and costs one relaxed load.
///  - The shared state lives in a `shared_ptr` that the `CanRegistry` hands to the CAN
///    aggregator, so a sniffer's counts survive the sniffer until the supervisor has read them.
///
/// Times: `begin`/`end` are on the clock of the CAN supervisor and monitor (vigil's monotonic
/// clock at run time, the log's timestamps in replay). A frame's time is its receive timestamp
/// when the I/O gives one (`on_read(f, begin, end, at)`: SocketCAN's kernel or hardware
/// timestamp, mapped onto that clock), else `end`: when the read returned it or the write handed
/// it over. The CAN monitor judges a node's silence from these times against the time up to
/// which the sniffer's tables were read, never against the wall clock (can_monitor.hpp). Error
/// frames are counted (`error_frames`, and per bus and error class in the id table, with no
/// node) and not otherwise supervised; remote frames have id keys of their own and are counted
/// per node (`remote`).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/can/detail/sniffer_state.hpp"
#include "vigil/can/filter.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/can/sniffer_types.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/**
 * Where sniffers meet the CAN supervisor: the registry of their ports (`ports()`, drained by
 * `DrainLoop<CanMessage, CanAggregator>`) and, beside it, each sniffer's shared state (tables,
 * counters) by port id. A sniffer's state stays here after the sniffer is destroyed, until the
 * CAN aggregator has read it one last time and calls `release`. Thread-safe; not RT-safe.
 */
class CanRegistry {
 public:
  CanRegistry() = default;
  CanRegistry(const CanRegistry&) = delete;
  CanRegistry& operator=(const CanRegistry&) = delete;

  /// The ports, for `DrainLoop<CanMessage, CanAggregator>`.
  [[nodiscard]] Registry<CanMessage>& ports() noexcept { return ports_; }

  /// Records the state of the sniffer whose port has registry id `port_id` (called by Sniffer).
  void attach(std::uint32_t port_id, std::shared_ptr<detail::SnifferState> state);
  /// The state of port `port_id`, or null (not attached yet, or released).
  [[nodiscard]] std::shared_ptr<detail::SnifferState> find(std::uint32_t port_id) const;
  /// Forgets the state of port `port_id` (called by the aggregator once the sniffer left).
  void release(std::uint32_t port_id);
  /// Number of states held.
  [[nodiscard]] std::size_t size() const;

 private:
  Registry<CanMessage> ports_;
  mutable std::mutex mutex_;
  std::vector<std::pair<std::uint32_t, std::shared_ptr<detail::SnifferState>>> states_;
};

/**
 * The hook a CAN I/O component calls on every frame: `on_read(frame, begin, end)` after a read
 * returned a frame, `on_write(frame, begin, end)` after a write, with the times around the call.
 * See the file comment for what happens to the frame.
 *
 * `PortCapacity` is the capacity of its port (records waiting for the supervisor); counts stay
 * exact whatever it is, only timing detail is sampled when it overflows.
 *
 * @code
 * vigil::can::CanRegistry can;
 * vigil::can::Sniffer<> sniffer(can, "motor-bus", {.node_map = vigil::can::NodeMap::canopen()});
 * // in the CAN I/O component's update (RT thread):
 * const vigil::Nanos t0 = vigil::platform::now_ns();
 * bool got = driver.read(frame);
 * const vigil::Nanos t1 = vigil::platform::now_ns();
 * if (got) sniffer.on_read(frame, t0, t1);
 * @endcode
 *
 * Threads: `on_read`, `on_write`, `on_frame` on the I/O thread (one at a time); everything else
 * on non-RT threads (thread-safe). Construction allocates (tables, port). Not movable.
 */
template <std::size_t PortCapacity = 1024>
class Sniffer {
 public:
  /// Joins `registry` with a port named `name`. Not RT-safe.
  Sniffer(CanRegistry& registry, std::string name, SnifferOptions options = {})
      : state_(std::make_shared<detail::SnifferState>(name, options)),
        raw_(state_.get()),
        membership_(registry.ports().template join<PortCapacity>(std::move(name))),
        port_(membership_.port()) {
    registry.attach(membership_.id(), state_);
  }
  Sniffer(const Sniffer&) = delete;
  Sniffer& operator=(const Sniffer&) = delete;
  /// Leaves the registry; the supervisor still drains what was pushed and reads the tables once
  /// more. No on_* call may run concurrently.
  ~Sniffer() = default;

  /// A frame was read in [begin, end]; its time is `end`. RT-safe: wait-free,
  /// allocation-free, noexcept.
  void on_read(const Frame& f, Nanos begin, Nanos end) noexcept {
    on_frame(f, Direction::Rx, begin, end, end);
  }
  /// A frame that arrived at `at` (its receive timestamp on the supervisor's clock, `at <= end`)
  /// was read in [begin, end]: its time is `at`, so a read that got to it late neither delays
  /// it nor shortens the gap before it. RT-safe.
  void on_read(const Frame& f, Nanos begin, Nanos end, Nanos at) noexcept {
    on_frame(f, Direction::Rx, begin, end, at);
  }
  /// A frame was written in [begin, end]; its time is `end`. RT-safe.
  void on_write(const Frame& f, Nanos begin, Nanos end) noexcept {
    on_frame(f, Direction::Tx, begin, end, end);
  }
  /// A frame went in direction `d` in [begin, end]; its time is `end`. RT-safe.
  void on_frame(const Frame& f, Direction d, Nanos begin, Nanos end) noexcept {
    on_frame(f, d, begin, end, end);
  }
  /// A frame went in direction `d` in [begin, end]; its time is `at`. RT-safe.
  void on_frame(const Frame& f, Direction d, Nanos begin, Nanos end, Nanos at) noexcept {
    FrameRecord r;
    if (raw_->process(f, d, end - begin, at, r)) {
      static_cast<void>(port_->try_push(CanMessage{r}));  // a full port counts the drop
    }
  }

  /// Compiles `expr` and makes it the filter; fails (EINVAL) as `Filter::compile`, leaving the
  /// current filter in place. Never blocks the I/O thread. Not RT-safe.
  expected<void, Error> set_filter(const FilterExpr& expr) {
    expected<Filter, Error> f = Filter::compile(expr);
    if (!f) return unexpected(f.error());
    set_filter(std::move(*f));
    return {};
  }
  /// Makes `filter` the filter. Never blocks the I/O thread. Not RT-safe.
  void set_filter(Filter filter) {
    raw_->set_filter(std::make_unique<const Filter>(std::move(filter)));
  }
  /// Back to accepting every frame. Not RT-safe.
  void clear_filter() { raw_->set_filter(nullptr); }
  /// Frees replaced filters the I/O thread has left; returns how many. Not RT-safe.
  std::size_t reclaim() { return raw_->reclaim(); }
  /// The current filter as text. Not RT-safe.
  [[nodiscard]] std::string filter_text() const { return raw_->filter_text(); }

  /// Exact counters, including the port's drops. Any thread; relaxed loads.
  [[nodiscard]] SnifferTotals totals() const noexcept {
    SnifferTotals t = raw_->totals();
    t.dropped = port_->dropped();
    return t;
  }
  /// The id table (exact counts per (bus, id, direction)). Not RT-safe (allocates).
  [[nodiscard]] std::vector<IdEntry> ids() const {
    std::vector<IdEntry> v;
    raw_->read_ids(v);
    return v;
  }
  /// The node table (exact counts and liveness per (bus, node, direction)). Not RT-safe.
  [[nodiscard]] std::vector<NodeEntry> nodes() const {
    std::vector<NodeEntry> v;
    raw_->read_nodes(v);
    return v;
  }

  /// The port's registry id.
  [[nodiscard]] std::uint32_t port_id() const noexcept { return membership_.id(); }
  /// The name given at construction.
  [[nodiscard]] const std::string& name() const noexcept { return raw_->name(); }
  /// The port's capacity.
  [[nodiscard]] static constexpr std::size_t port_capacity() noexcept { return PortCapacity; }
  /// The shared state (for tools and tests).
  [[nodiscard]] const std::shared_ptr<detail::SnifferState>& state() const noexcept {
    return state_;
  }

 private:
  std::shared_ptr<detail::SnifferState> state_;
  detail::SnifferState* raw_;
  bus::Membership<CanMessage, PortCapacity> membership_;
  Port<CanMessage, PortCapacity>* port_;
};

}  // namespace vigil::can
