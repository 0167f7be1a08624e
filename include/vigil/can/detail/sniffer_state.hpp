#pragma once
/// @file
/// Internals of the CAN sniffer, in a header only because `Sniffer<N>::on_frame` inlines
/// `SnifferState::process` on the I/O thread: the fixed O(1) count tables (`TrackTable`), their
/// slots and keys, and the state a sniffer shares with the CAN supervisor. Not part of the API:
/// use `Sniffer` and `CanAggregator`. The protocols are described in sniffer.hpp.

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "vigil/can/filter.hpp"
#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/can/sniffer_types.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::can::detail {

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

/// Table key of (bus, id, format, direction, remote, error); never 0.
[[nodiscard]] constexpr std::uint64_t id_key(std::uint8_t bus, std::uint32_t id, bool extended,
                                             bool tx, bool rtr = false,
                                             bool error = false) noexcept {
  return kUsedBit | (std::uint64_t{bus} << 40) | (std::uint64_t{error} << 35) |
         (std::uint64_t{rtr} << 34) | (std::uint64_t{tx} << 33) | (std::uint64_t{extended} << 32) |
         id;
}
/// Table key of (bus, node, direction); never 0.
[[nodiscard]] constexpr std::uint64_t node_key(std::uint8_t bus, std::uint32_t node,
                                               bool tx) noexcept {
  return kUsedBit | (std::uint64_t{bus} << 40) | (std::uint64_t{tx} << 32) | node;
}

/// A slot of the id table. `key` is published last (release) so that a reader that sees it
/// (acquire) sees the slot's constant fields.
struct IdCounter {
  std::atomic<std::uint64_t> key{0};  ///< 0: empty
  std::uint32_t node = 0;             ///< constant once published
  std::uint32_t function = 0;         ///< constant once published
  std::uint32_t peer = kNoNode;       ///< constant once published
  std::uint8_t flags = 0;             ///< constant once published
  std::atomic<std::uint64_t> frames{0};
  std::atomic<Nanos> first{0};
  std::atomic<Nanos> last{0};
};

/// A slot of the node table.
struct NodeCounter {
  std::atomic<std::uint64_t> key{0};  ///< 0: empty
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> remote{0};  ///< remote frames (RTR)
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
        slots_(slot_count_ == 0 ? nullptr : std::make_unique<Slot[]>(slot_count_)),
        order_(max_ == 0 || slot_count_ == 0 ? nullptr : std::make_unique<std::uint32_t[]>(max_)) {}

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
        order_[used_] = static_cast<std::uint32_t>(i);
        ++used_;
        size_.store(used_, std::memory_order_release);  // publishes order_[used_ - 1]
        return {&s, true};
      }
    }
    return {nullptr, false};
  }

  /// Calls `f(key, slot)` for every published slot, in the order they were inserted. Any
  /// thread; O(size()): the writer lists the slots it fills, so a reader never scans the empty
  /// ones (a replay's table has 32768 slots for a few dozen keys, read every 4096 frames).
  template <class F>
  void for_each(F&& f) const {
    const std::size_t n = size_.load(std::memory_order_acquire);  // pairs with the insert's
    for (std::size_t j = 0; j < n; ++j) {
      const Slot& slot = slots_[order_[j]];
      const std::uint64_t k = slot.key.load(std::memory_order_acquire);  // see IdCounter
      if (k != 0) f(k, slot);
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
  std::unique_ptr<std::uint32_t[]> order_;  // the filled slots' indices, in insertion order
  std::size_t used_ = 0;                    // writer's own count
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

  /// Counts frame `f`, whose time is `at`, and fills `out` when it passes the filter; returns
  /// whether it did. `io` is the time spent in the read/write call. I/O thread only (one at a
  /// time). RT-safe: wait-free, no allocation, no lock, noexcept.
  [[nodiscard]] bool process(const Frame& f, Direction d, Nanos io, Nanos at,
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
  void count_error(const Frame& f, bool tx, Nanos at) noexcept;  // I/O thread

  const std::string name_;
  const NodeMap node_map_;
  TrackTable<IdCounter> ids_;
  TrackTable<NodeCounter> nodes_;

  // Written by the I/O thread only (relaxed single-writer stores; see bump()).
  alignas(64) std::atomic<std::uint64_t> frames_{0};
  std::atomic<std::uint64_t> tx_{0};
  std::atomic<std::uint64_t> error_frames_{0};
  std::atomic<std::uint64_t> remote_frames_{0};
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

inline bool SnifferState::process(const Frame& f, Direction d, Nanos io, Nanos at,
                                  FrameRecord& out) noexcept {
  bump(frames_);
  const bool tx = d == Direction::Tx;
  if (tx) bump(tx_);
  if (f.error) [[unlikely]] {
    bump(error_frames_);
    count_error(f, tx, at);
    // Pushed (unfiltered) for the CAN supervisor's controller-state decoding; no node, no gap.
    out = FrameRecord{};
    out.time_ns = at;
    out.io_ns = io;
    out.id = f.id;
    out.node = kNoNode;
    out.bus = f.bus;
    out.direction = d;
    out.length = f.length;
    out.error = true;
    out.id_untracked = true;
    out.node_untracked = true;
    std::memcpy(out.data.data(), f.data.data(), out.data.size());
    return true;
  }
  const NodeAddress a = node_map_.map(f.id, f.extended, f.rtr);

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
  if (f.rtr) bump(remote_frames_);

  out.time_ns = at;
  out.io_ns = io;
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
  out.id_untracked = false;
  out.node_untracked = false;
  out.brs = f.brs;
  out.error = false;
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
      ids_.find_or_insert(id_key(f.bus, f.id, f.extended, tx, f.rtr), [&](IdCounter& s) noexcept {
        s.node = a.node;
        s.function = a.function;
        s.peer = a.peer;
        s.flags = a.flags;
        s.frames.store(1, std::memory_order_relaxed);
        s.first.store(at, std::memory_order_relaxed);
        s.last.store(at, std::memory_order_relaxed);
      });
  if (is == nullptr) {
    bump(untracked_ids_);
    out.id_untracked = true;
  } else if (id_new) {
    out.id_frames = 1;
  } else {
    out.id_gap_ns = at - is->last.load(std::memory_order_relaxed);
    out.id_frames = is->frames.load(std::memory_order_relaxed) + 1;
    is->last.store(at, std::memory_order_relaxed);
    is->frames.store(out.id_frames, std::memory_order_relaxed);
  }

  const auto [ns, node_new] =
      nodes_.find_or_insert(node_key(f.bus, a.node, tx), [&](NodeCounter& s) noexcept {
        s.frames.store(1, std::memory_order_relaxed);
        s.remote.store(f.rtr ? 1 : 0, std::memory_order_relaxed);
        s.first.store(at, std::memory_order_relaxed);
        s.last.store(at, std::memory_order_relaxed);
      });
  if (ns == nullptr) {
    bump(untracked_nodes_);
    out.node_untracked = true;
  } else if (!node_new) {
    out.node_gap_ns = at - ns->last.load(std::memory_order_relaxed);
    ns->last.store(at, std::memory_order_relaxed);
    bump(ns->frames);
    if (f.rtr) bump(ns->remote);
  }
  return true;
}

inline void SnifferState::count_error(const Frame& f, bool tx, Nanos at) noexcept {
  // Error frames have no node: one id key per (bus, error class, direction). A full table only
  // loses this detail; `error_frames` stays exact.
  const auto [es, inserted] =
      ids_.find_or_insert(id_key(f.bus, f.id, true, tx, false, true), [&](IdCounter& s) noexcept {
        s.node = kNoNode;
        s.function = 0;
        s.frames.store(1, std::memory_order_relaxed);
        s.first.store(at, std::memory_order_relaxed);
        s.last.store(at, std::memory_order_relaxed);
      });
  if (es != nullptr && !inserted) {
    bump(es->frames);
    es->last.store(at, std::memory_order_relaxed);
  }
}

}  // namespace vigil::can::detail
