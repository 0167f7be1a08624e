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
///    counts the frame EXACTLY in two fixed tables owned by `detail::SnifferState`: one per
///    (bus, id, direction) and one per (bus, node, direction), with first and last time seen.
///    The tables are open-addressing arrays sized at construction; a lookup examines at most
///    `kMaxProbe` slots, so every call is O(1). A frame whose key finds no room (the table holds
///    `max_ids` / `max_nodes` keys, or its probe run is full) is counted in `untracked_ids` /
///    `untracked_nodes`, exactly, and never blocks.
///  - The accepted frame's timing (`FrameRecord`: begin/end of the call, the exact gap since the
///    previous frame of the same id and of the same node, the first 8 data bytes) is pushed to
///    the sniffer's `Port`. When the port is full the record is dropped and counted: timing
///    distributions are sampled under load, but counts and liveness come from the tables and
///    stay exact, so no node can starve (the original's weakness).
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
/// clock at run time, the log's timestamps in replay). A frame's time is `end`: when the read
/// returned it or the write handed it over. Error frames are counted (`error_frames`) and not
/// otherwise supervised.

#include <array>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/can/filter.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can {

/// The timing of one accepted frame, as the sniffer pushes it to its port. Trivially copyable,
/// 64 bytes.
struct FrameRecord {
  Nanos begin_ns = 0;           ///< when the read/write call began
  Nanos end_ns = 0;             ///< when it returned: the frame's time
  Nanos id_gap_ns = -1;         ///< since the previous frame of (bus, id, direction); -1 if none
  Nanos node_gap_ns = -1;       ///< since the previous frame of (bus, node, direction); -1 if none
  std::uint64_t id_frames = 0;  ///< frames of (bus, id, direction) so far, this one included;
                                ///< 0 when the id is untracked
  std::uint32_t id = 0;         ///< identifier
  std::uint32_t node = 0;       ///< mapped node
  std::uint32_t function = 0;   ///< mapped function
  std::uint8_t bus = 0;         ///< bus index
  Direction direction = Direction::Rx;
  std::uint8_t length = 0;             ///< DLC or CAN FD length, as in `Frame`
  bool extended : 1 = false;           ///< 29-bit identifier
  bool rtr : 1 = false;                ///< remote frame
  bool fd : 1 = false;                 ///< CAN FD frame
  std::array<std::uint8_t, 8> data{};  ///< the first min(8, data_size) data bytes, zero-padded

  /// Time spent in the read/write call. RT-safe.
  [[nodiscard]] constexpr Nanos io_ns() const noexcept { return end_ns - begin_ns; }
};
static_assert(std::is_trivially_copyable_v<FrameRecord> && sizeof(FrameRecord) == 64);

/// What a sniffer's port carries. A variant so that messages can be added without changing
/// the supervisor; today it has one alternative.
using CanMessage = std::variant<FrameRecord>;

/// Options of a sniffer (fixed at construction).
struct SnifferOptions {
  /// (bus, id, direction) keys counted exactly; more are counted in `untracked_ids`.
  std::size_t max_ids = 1024;
  /// (bus, node, direction) keys counted exactly; more are counted in `untracked_nodes`.
  std::size_t max_nodes = 256;
  /// How identifiers map to nodes (for the node table, node filters and the statistics).
  NodeMap node_map = NodeMap::identity();
};

/// A sniffer's cumulative counters (exact). `frames` = `error_frames` + `rejected` + accepted,
/// and accepted = `records` + ... every accepted frame gives one record: pushed or `dropped`.
struct SnifferTotals {
  std::uint64_t frames = 0;           ///< on_read/on_write calls
  std::uint64_t rx = 0;               ///< of which reads
  std::uint64_t tx = 0;               ///< of which writes
  std::uint64_t error_frames = 0;     ///< error frames (not filtered, tracked or pushed)
  std::uint64_t rejected = 0;         ///< refused by the filter
  std::uint64_t accepted = 0;         ///< passed the filter (each gives one record)
  std::uint64_t untracked_ids = 0;    ///< accepted, but no room in the id table
  std::uint64_t untracked_nodes = 0;  ///< accepted, but no room in the node table
  std::uint64_t dropped = 0;          ///< records the port dropped (full)
  std::uint64_t filter_changes = 0;   ///< set_filter/clear_filter calls
};

/// One (bus, id, direction) of a sniffer's id table: exact counts.
struct IdEntry {
  std::uint8_t bus = 0;
  std::uint32_t id = 0;
  bool extended = false;
  Direction direction = Direction::Rx;
  std::uint32_t node = 0;      ///< mapped node
  std::uint32_t function = 0;  ///< mapped function
  std::uint64_t frames = 0;    ///< exact
  Nanos first_ns = 0;          ///< time of the first frame
  Nanos last_ns = 0;           ///< time of the latest frame
};

/// One (bus, node, direction) of a sniffer's node table: exact counts and liveness.
struct NodeEntry {
  std::uint8_t bus = 0;
  std::uint32_t node = 0;
  Direction direction = Direction::Rx;
  std::uint64_t frames = 0;  ///< exact
  Nanos first_ns = 0;
  Nanos last_ns = 0;
};

namespace detail {

static_assert(std::atomic<std::uint64_t>::is_always_lock_free &&
                  std::atomic<std::int64_t>::is_always_lock_free,
              "the sniffer's counters need lock-free 64-bit atomics");

/// +n on a counter that only the calling thread writes: a relaxed load and store, no locked
/// read-modify-write (readers see the old or the new value, never a torn one).
inline void bump(std::atomic<std::uint64_t>& c, std::uint64_t n = 1) noexcept {
  c.store(c.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
}

/// MurmurHash3's 64-bit finaliser: every key bit affects every slot bit.
[[nodiscard]] constexpr std::uint64_t mix64(std::uint64_t x) noexcept {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

inline constexpr std::uint64_t kUsedBit = std::uint64_t{1} << 63;

/// Table key of (bus, id, format, direction); never 0.
[[nodiscard]] constexpr std::uint64_t id_key(std::uint8_t bus, std::uint32_t id, bool extended,
                                             bool tx) noexcept {
  return kUsedBit | (std::uint64_t{bus} << 40) | (std::uint64_t{tx} << 33) |
         (std::uint64_t{extended} << 32) | id;
}
/// Table key of (bus, node, direction); never 0.
[[nodiscard]] constexpr std::uint64_t node_key(std::uint8_t bus, std::uint32_t node,
                                               bool tx) noexcept {
  return kUsedBit | (std::uint64_t{bus} << 40) | (std::uint64_t{tx} << 32) | node;
}

/// A slot of the id table. `key` is published last (release) so that a reader that sees it
/// (acquire) sees the slot's constant fields.
struct IdSlot {
  std::atomic<std::uint64_t> key{0};  ///< 0: empty
  std::uint32_t node = 0;             ///< constant once published
  std::uint32_t function = 0;         ///< constant once published
  std::atomic<std::uint64_t> frames{0};
  std::atomic<Nanos> first{0};
  std::atomic<Nanos> last{0};
};

/// A slot of the node table.
struct NodeSlot {
  std::atomic<std::uint64_t> key{0};  ///< 0: empty
  std::atomic<std::uint64_t> frames{0};
  std::atomic<Nanos> first{0};
  std::atomic<Nanos> last{0};
};

/**
 * A fixed, insert-only open-addressing table with linear probing: one writer (the I/O thread),
 * any number of readers. `slot_count()` is the smallest power of two >= 4 * max_entries (load
 * factor <= 1/4), so runs are short; a lookup examines at most kMaxProbe slots: O(1).
 */
template <class Slot>
class TrackTable {
 public:
  /// Most slots a lookup examines.
  static constexpr std::size_t kMaxProbe = 32;

  /// Allocates the slots. `max_entries` = 0 makes a table that tracks nothing. Not RT-safe.
  explicit TrackTable(std::size_t max_entries)
      : slot_count_(max_entries == 0 ? 0
                                     : std::bit_ceil(std::max<std::size_t>(max_entries * 4, 16))),
        mask_(slot_count_ == 0 ? 0 : slot_count_ - 1),
        max_(max_entries),
        probe_limit_(std::min(kMaxProbe, slot_count_)),
        slots_(slot_count_ == 0 ? nullptr : std::make_unique<Slot[]>(slot_count_)) {}

  /// The slot of `key`; a new slot is set up by `init(slot)` and published when there is room.
  /// Returns {slot, inserted}, or {nullptr, false} when the key finds no room. Writer only.
  /// RT-safe: at most kMaxProbe slots examined, no allocation.
  template <class Init>
  std::pair<Slot*, bool> find_or_insert(std::uint64_t key, Init&& init) noexcept {
    std::size_t i = static_cast<std::size_t>(mix64(key)) & mask_;
    for (std::size_t p = 0; p < probe_limit_; ++p, i = (i + 1) & mask_) {
      Slot& s = slots_[i];
      // Relaxed: only this thread stores keys.
      const std::uint64_t k = s.key.load(std::memory_order_relaxed);
      if (k == key) return {&s, false};
      if (k == 0) {  // insert-only: the first empty slot ends the run, the key is absent
        if (used_ >= max_) return {nullptr, false};
        init(s);
        s.key.store(key, std::memory_order_release);  // publishes init's stores to readers
        ++used_;
        size_.store(used_, std::memory_order_relaxed);
        return {&s, true};
      }
    }
    return {nullptr, false};
  }

  /// Calls `f(key, slot)` for every published slot. Any thread; O(slot_count()).
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t i = 0; i < slot_count_; ++i) {
      const std::uint64_t k = slots_[i].key.load(std::memory_order_acquire);  // see IdSlot
      if (k != 0) f(k, slots_[i]);
    }
  }

  /// Keys held. Any thread.
  [[nodiscard]] std::size_t size() const noexcept { return size_.load(std::memory_order_relaxed); }
  /// Most keys it will hold.
  [[nodiscard]] std::size_t max_entries() const noexcept { return max_; }
  /// Slots allocated (a power of two, or 0).
  [[nodiscard]] std::size_t slot_count() const noexcept { return slot_count_; }

 private:
  std::size_t slot_count_;
  std::size_t mask_;
  std::size_t max_;
  std::size_t probe_limit_;
  std::unique_ptr<Slot[]> slots_;
  std::size_t used_ = 0;  // writer's own count
  std::atomic<std::size_t> size_{0};
};

/**
 * What a sniffer shares with the CAN supervisor: the tables, the counters and the current
 * filter (see the file comment for the protocols). Created by `Sniffer`; kept alive by the
 * `CanRegistry` and the aggregator after the sniffer is gone. `process` is for the I/O thread;
 * every other member is for non-RT threads and is thread-safe.
 */
class SnifferState {
 public:
  SnifferState(std::string name, const SnifferOptions& options);
  ~SnifferState();
  SnifferState(const SnifferState&) = delete;
  SnifferState& operator=(const SnifferState&) = delete;

  /// Counts frame `f` and fills `out` when it passes the filter; returns whether it did.
  /// I/O thread only (one at a time). RT-safe: wait-free, no allocation, no lock, noexcept.
  [[nodiscard]] bool process(const Frame& f, Direction d, Nanos begin, Nanos end,
                             FrameRecord& out) noexcept;

  /// Publishes `filter` (null or accept-all: accept every frame) and retires the previous one.
  /// Never waits for the I/O thread. Not RT-safe.
  void set_filter(std::unique_ptr<const Filter> filter);
  /// Frees retired filters that the I/O thread can no longer use; returns how many. Not RT-safe.
  std::size_t reclaim();
  /// Retired filters not freed yet.
  [[nodiscard]] std::size_t retired() const;
  /// The current filter's text ("true" for accept-all).
  [[nodiscard]] std::string filter_text() const;

  /// The counters (without `dropped`, which the port counts). Any thread; relaxed loads.
  [[nodiscard]] SnifferTotals totals() const noexcept;
  /// Appends every id table entry to `out` (unordered). Any thread; O(slots).
  void read_ids(std::vector<IdEntry>& out) const;
  /// Appends every node table entry to `out` (unordered). Any thread; O(slots).
  void read_nodes(std::vector<NodeEntry>& out) const;

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] const NodeMap& node_map() const noexcept { return node_map_; }
  [[nodiscard]] std::size_t max_ids() const noexcept { return ids_.max_entries(); }
  [[nodiscard]] std::size_t max_nodes() const noexcept { return nodes_.max_entries(); }
  [[nodiscard]] std::size_t id_count() const noexcept { return ids_.size(); }
  [[nodiscard]] std::size_t node_count() const noexcept { return nodes_.size(); }

 private:
  struct Retired {
    const Filter* filter;
    std::uint64_t epoch;  // the I/O thread's epoch right after the filter was unpublished
  };
  std::size_t reclaim_locked();

  const std::string name_;
  const NodeMap node_map_;
  TrackTable<IdSlot> ids_;
  TrackTable<NodeSlot> nodes_;

  // Written by the I/O thread only (relaxed single-writer stores; see bump()).
  alignas(64) std::atomic<std::uint64_t> frames_{0};
  std::atomic<std::uint64_t> tx_{0};
  std::atomic<std::uint64_t> error_frames_{0};
  std::atomic<std::uint64_t> rejected_{0};
  std::atomic<std::uint64_t> accepted_{0};
  std::atomic<std::uint64_t> untracked_ids_{0};
  std::atomic<std::uint64_t> untracked_nodes_{0};
  std::atomic<std::uint64_t> epoch_{0};  // odd while the I/O thread may hold a filter pointer
  std::uint64_t epoch_local_ = 0;        // the I/O thread's copy of epoch_

  // Written by set_filter (non-RT), read by the I/O thread.
  alignas(64) std::atomic<const Filter*> filter_{nullptr};
  std::atomic<std::uint64_t> filter_changes_{0};
  mutable std::mutex writer_mutex_;  // serialises set_filter/reclaim; never taken by process()
  std::vector<Retired> retired_;
  std::string filter_text_ = "true";
};

inline bool SnifferState::process(const Frame& f, Direction d, Nanos begin, Nanos end,
                                  FrameRecord& out) noexcept {
  bump(frames_);
  const bool tx = d == Direction::Tx;
  if (tx) bump(tx_);
  if (f.error) [[unlikely]] {
    bump(error_frames_);
    return false;
  }
  const NodeAddress a = node_map_.map(f.id, f.extended);

  // Relaxed: only a hint. Null means accept-all and nothing to protect; a non-null hint is
  // reloaded inside the epoch guard below, and only that load is dereferenced.
  if (filter_.load(std::memory_order_relaxed) != nullptr) {
    ++epoch_local_;
    // seq_cst store then seq_cst load: with set_filter's seq_cst exchange then load (Dekker),
    // either this load sees the new pointer or set_filter sees the odd epoch and keeps the old
    // filter alive.
    epoch_.store(epoch_local_, std::memory_order_seq_cst);
    const Filter* filter = filter_.load(std::memory_order_seq_cst);
    const bool pass = filter == nullptr || filter->matches(f, d, a);
    ++epoch_local_;
    // Release: our last use of `filter` happens before reclaim() sees the epoch move.
    epoch_.store(epoch_local_, std::memory_order_release);
    if (!pass) {
      bump(rejected_);
      return false;
    }
  }
  bump(accepted_);

  out.begin_ns = begin;
  out.end_ns = end;
  out.id_gap_ns = -1;
  out.node_gap_ns = -1;
  out.id_frames = 0;
  out.id = f.id;
  out.node = a.node;
  out.function = a.function;
  out.bus = f.bus;
  out.direction = d;
  out.length = f.length;
  out.extended = f.extended;
  out.rtr = f.rtr;
  out.fd = f.fd;
  const std::size_t n = std::min<std::size_t>(f.data_size(), out.data.size());
  if constexpr (std::endian::native == std::endian::little) {
    // One 8-byte load and a mask instead of a branch per byte; the bytes past the data are
    // zeroed (little-endian: the first n bytes are the low ones).
    std::uint64_t bytes = 0;
    std::memcpy(&bytes, f.data.data(), sizeof bytes);
    bytes &= n >= 8 ? ~std::uint64_t{0} : (std::uint64_t{1} << (8 * n)) - 1;
    std::memcpy(out.data.data(), &bytes, sizeof bytes);
  } else {
    for (std::size_t i = 0; i < out.data.size(); ++i) out.data[i] = i < n ? f.data[i] : 0;
  }

  const auto [is, id_new] =
      ids_.find_or_insert(id_key(f.bus, f.id, f.extended, tx), [&](IdSlot& s) noexcept {
        s.node = a.node;
        s.function = a.function;
        s.frames.store(1, std::memory_order_relaxed);
        s.first.store(end, std::memory_order_relaxed);
        s.last.store(end, std::memory_order_relaxed);
      });
  if (is == nullptr) {
    bump(untracked_ids_);
  } else if (id_new) {
    out.id_frames = 1;
  } else {
    out.id_gap_ns = end - is->last.load(std::memory_order_relaxed);
    out.id_frames = is->frames.load(std::memory_order_relaxed) + 1;
    is->last.store(end, std::memory_order_relaxed);
    is->frames.store(out.id_frames, std::memory_order_relaxed);
  }

  const auto [ns, node_new] =
      nodes_.find_or_insert(node_key(f.bus, a.node, tx), [&](NodeSlot& s) noexcept {
        s.frames.store(1, std::memory_order_relaxed);
        s.first.store(end, std::memory_order_relaxed);
        s.last.store(end, std::memory_order_relaxed);
      });
  if (ns == nullptr) {
    bump(untracked_nodes_);
  } else if (!node_new) {
    out.node_gap_ns = end - ns->last.load(std::memory_order_relaxed);
    ns->last.store(end, std::memory_order_relaxed);
    bump(ns->frames);
  }
  return true;
}

}  // namespace detail

/**
 * Where sniffers meet the CAN supervisor: the registry of their ports (`ports()`, drained by
 * `Supervisor<CanMessage, CanAggregator>`) and, beside it, each sniffer's shared state (tables,
 * counters) by port id. A sniffer's state stays here after the sniffer is destroyed, until the
 * CAN aggregator has read it one last time and calls `release`. Thread-safe; not RT-safe.
 */
class CanRegistry {
 public:
  CanRegistry() = default;
  CanRegistry(const CanRegistry&) = delete;
  CanRegistry& operator=(const CanRegistry&) = delete;

  /// The ports, for `Supervisor<CanMessage, CanAggregator>`.
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

  /// A frame was read in [begin, end]. RT-safe: wait-free, allocation-free, noexcept.
  void on_read(const Frame& f, Nanos begin, Nanos end) noexcept {
    on_frame(f, Direction::Rx, begin, end);
  }
  /// A frame was written in [begin, end]. RT-safe.
  void on_write(const Frame& f, Nanos begin, Nanos end) noexcept {
    on_frame(f, Direction::Tx, begin, end);
  }
  /// A frame went in direction `d` in [begin, end]. RT-safe.
  void on_frame(const Frame& f, Direction d, Nanos begin, Nanos end) noexcept {
    FrameRecord r;
    if (raw_->process(f, d, begin, end, r)) {
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
  Membership<CanMessage, PortCapacity> membership_;
  Port<CanMessage, PortCapacity>* port_;
};

}  // namespace vigil::can
