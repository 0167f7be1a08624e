#pragma once
/// @file
/// The flight recorder: the last N cycles of each component, kept on the supervisor side from
/// the samples it drains (the real-time side does nothing more than it already does). When an
/// event raises a component to ERROR, the ring is frozen into a `FlightRecord` (a copy taken at
/// that moment: the cycles up to and including the faulting one), which an exporter writes as a
/// Chrome/Perfetto trace (vigil/export/trace_event.hpp).
///
/// Memory: one ring of `capacity` slots (32 bytes each: 32 KiB for the default 1024) per
/// component, allocated when the component joins (on a large system from huge-page regions:
/// `RingPages`); recording a cycle writes one slot and never allocates. A slot keeps a cycle
/// packed (`PackedCycle`: times as offsets from the release, exact to the nanosecond up to
/// 2.1 s, in microseconds beyond); readers get it unpacked as a
/// `CycleRecord`. Not RT-safe; one writer (the supervisor thread), readers copy under the
/// aggregator's per-component lock.
///
/// The ring doubles as the aggregator's queue of cycles not yet in the statistics: the newest
/// `pending()` slots (`push_pending`, `take_pending`), which it takes in bulk.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__x86_64__)
#include <emmintrin.h>  // _mm_stream_si64, _mm_sfence
#endif

#include "vigil/assert.hpp"
#include "vigil/health/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/supervisor/events.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::supervisor {

/// One cycle as the flight recorder hands it out.
struct CycleRecord {
  std::uint64_t cycle = 0;  ///< the component's 1-based cycle number
  Nanos release_ns = 0;     ///< scheduled release
  Nanos start_ns = 0;       ///< on_update() began
  Nanos end_ns = 0;         ///< on_update() ended
  Nanos overhead_ns = 0;    ///< supervision's measured overhead carried by the sample (0: none)
  std::uint32_t missed_before = 0;  ///< releases skipped just before it
  std::uint8_t flags = 0;           ///< kOverrun, kGap, kWarmup, kCoarse, kClipped
  TaskState state = TaskState::Running;

  static constexpr std::uint8_t kOverrun = 1;  ///< ended after the next release
  static constexpr std::uint8_t kGap = 2;      ///< cycles before it are missing (port dropped)
  static constexpr std::uint8_t kWarmup = 4;   ///< inside the warm-up (kept out of statistics)
  /// The wake-up latency or on_update()'s time was beyond 2.1 s: kept in microseconds (start
  /// and end are exact to 1 us, not 1 ns).
  static constexpr std::uint8_t kCoarse = 8;
  /// A value beyond what a slot holds was saturated: latency or time beyond +-35 minutes,
  /// overhead beyond 4.29 s, or more than 65,535 missed releases (the statistics and counters
  /// have the exact values; only this record is clipped).
  static constexpr std::uint8_t kClipped = 16;

  /// on_update()'s own time.
  [[nodiscard]] Nanos execution_ns() const noexcept { return end_ns - start_ns; }
  /// Wake-up latency: start - release.
  [[nodiscard]] Nanos latency_ns() const noexcept { return start_ns - release_ns; }
};

/// A cycle as a ring slot keeps it: 32 bytes, two to a cache line (the supervisor writes one
/// per message drained, so a slot's size is most of what the recorder costs it). The release
/// and the cycle number are kept whole; the start as an offset from the release and the end as
/// an offset from the start, each exact in nanoseconds within +-2.1 s and in microseconds
/// beyond (`kCoarse`), saturated beyond +-35 minutes (`kClipped`); the overhead saturates at
/// 4.29 s, the missed releases at 65,535 (`kClipped`).
class PackedCycle {
 public:
  PackedCycle() noexcept = default;
  /// Packs `r` (its kCoarse and kClipped flags are recomputed).
  explicit PackedCycle(const CycleRecord& r) noexcept
      : cycle_(r.cycle),
        release_ns_(r.release_ns),
        tail_(tail(r.missed_before > 0xFFFFU ? 0xFFFFU : r.missed_before, 0, r.state)) {
    std::uint8_t flags = r.flags & ~(CycleRecord::kCoarse | CycleRecord::kClipped);
    if (r.missed_before > 0xFFFFU) flags |= CycleRecord::kClipped;
    const Nanos latency = r.start_ns - r.release_ns;
    const Nanos user = r.end_ns - r.start_ns;
    if (!fits_ns(latency) || !fits_ns(user)) {
      flags |= CycleRecord::kCoarse;
      flags |= to_us(latency, latency_) | to_us(user, user_);
    } else {
      latency_ = static_cast<std::int32_t>(latency);
      user_ = static_cast<std::int32_t>(user);
    }
    if (r.overhead_ns < 0 || r.overhead_ns > 0xFFFF'FFFFLL) {
      flags |= CycleRecord::kClipped;
      overhead_ = r.overhead_ns < 0 ? 0U : 0xFFFF'FFFFU;
    } else {
      overhead_ = static_cast<std::uint32_t>(r.overhead_ns);
    }
    tail_ |= std::uint32_t{flags} << 16;
  }

  /// True when a slot keeps `r` exactly (unpack() gives it back: nothing coarse or clipped).
  [[nodiscard]] static bool packs_exactly(const CycleRecord& r) noexcept {
    return fits_exactly(r.start_ns - r.release_ns, r.end_ns - r.start_ns, r.overhead_ns,
                        r.missed_before);
  }
  /// The same from a cycle's parts: its wake-up latency (start - release), on_update()'s time
  /// (end - start), the overhead it carries and its missed releases. Branch-free.
  [[nodiscard]] static bool fits_exactly(Nanos latency, Nanos user, Nanos overhead,
                                         std::uint32_t missed) noexcept {
    return (static_cast<int>(fits_ns(latency)) & static_cast<int>(fits_ns(user)) &
            static_cast<int>(static_cast<std::uint64_t>(overhead) <= 0xFFFF'FFFFULL) &
            static_cast<int>(missed <= 0xFFFFU)) != 0;
  }
  /// Tag of the constructor below.
  struct Exact {};
  /// A slot from parts that fit (`fits_exactly`): no check, no kCoarse or kClipped. `flags` are
  /// the record's kOverrun, kGap and kWarmup. For the supervisor's common case, which has
  /// checked already.
  PackedCycle(Exact /*tag*/, std::uint64_t cycle, Nanos release_ns, Nanos latency, Nanos user,
              Nanos overhead, std::uint32_t missed, std::uint8_t flags, TaskState state) noexcept
      : cycle_(cycle),
        release_ns_(release_ns),
        latency_(static_cast<std::int32_t>(latency)),
        user_(static_cast<std::int32_t>(user)),
        overhead_(static_cast<std::uint32_t>(overhead)),
        tail_(tail(missed, flags, state)) {}

  /// The same slot as the constructor above, written at `slot` with streaming stores where the
  /// CPU has them (x86-64: four non-temporal stores, which do not read the slot's cache line
  /// first and do not keep it in the caches); placement new elsewhere. For rings too large to
  /// stay in the caches (`RingStores`). The writer calls `fence_streams()` before any other
  /// thread may read the slot (the same thread reads it back without one).
  static void stream(void* slot, std::uint64_t cycle, Nanos release_ns, Nanos latency, Nanos user,
                     Nanos overhead, std::uint32_t missed, std::uint8_t flags,
                     TaskState state) noexcept {
#if defined(__x86_64__)
    auto* w = static_cast<long long*>(slot);
    const auto lo32 = [](auto v) { return std::uint64_t{static_cast<std::uint32_t>(v)}; };
    _mm_stream_si64(w, static_cast<long long>(cycle));
    _mm_stream_si64(w + 1, static_cast<long long>(release_ns));
    _mm_stream_si64(w + 2, static_cast<long long>(lo32(latency) | lo32(user) << 32));
    _mm_stream_si64(w + 3, static_cast<long long>(lo32(overhead) |
                                                  std::uint64_t{tail(missed, flags, state)} << 32));
#else
    ::new (slot)
        PackedCycle(Exact{}, cycle, release_ns, latency, user, overhead, missed, flags, state);
#endif
  }
  /// Makes the slots written by `stream()` visible to other threads (before the lock that hands
  /// them over is released). A no-op where `stream()` stores as usual.
  static void fence_streams() noexcept {
#if defined(__x86_64__)
    _mm_sfence();
#endif
  }

  /// unpack() of a slot that holds its cycle exactly (written from a record for which
  /// packs_exactly() held, as every pending slot is: no kCoarse), without the unit's select and
  /// multiplies. The same record as unpack() for such a slot.
  [[nodiscard]] CycleRecord unpack_exact() const noexcept {
    CycleRecord r;
    r.cycle = cycle_;
    r.release_ns = release_ns_;
    r.start_ns = release_ns_ + latency_;
    r.end_ns = r.start_ns + user_;
    r.overhead_ns = overhead_;
    r.missed_before = tail_ & 0xFFFFU;
    r.flags = static_cast<std::uint8_t>(tail_ >> 16);
    r.state = static_cast<TaskState>(tail_ >> 24);
    return r;
  }

  [[nodiscard]] CycleRecord unpack() const noexcept {
    CycleRecord r;
    r.cycle = cycle_;
    r.release_ns = release_ns_;
    const auto flags = static_cast<std::uint8_t>(tail_ >> 16);
    const Nanos unit = (flags & CycleRecord::kCoarse) != 0 ? 1000 : 1;
    r.start_ns = release_ns_ + latency_ * unit;
    r.end_ns = r.start_ns + user_ * unit;
    r.overhead_ns = overhead_;
    r.missed_before = tail_ & 0xFFFFU;
    r.flags = flags;
    r.state = static_cast<TaskState>(tail_ >> 24);
    return r;
  }

 private:
  static constexpr Nanos kMax32 = 0x7FFF'FFFF;
  static constexpr bool fits_ns(Nanos v) noexcept {
    // Unsigned: -kMax32 .. kMax32 maps to 0 .. 2 kMax32, everything else above (no overflow).
    return static_cast<std::uint64_t>(v) + std::uint64_t{kMax32} <= std::uint64_t{2 * kMax32};
  }
  // v in microseconds (rounded toward zero), saturated: kClipped when it did not fit.
  static std::uint8_t to_us(Nanos v, std::int32_t& out) noexcept {
    const Nanos us = v / 1000;
    out = static_cast<std::int32_t>(us < -kMax32 ? -kMax32 : us > kMax32 ? kMax32 : us);
    return fits_ns(us) ? 0 : CycleRecord::kClipped;
  }

  std::uint64_t cycle_ = 0;
  Nanos release_ns_ = 0;
  std::int32_t latency_ = 0;  // start - release (ns, or us with kCoarse)
  std::int32_t user_ = 0;     // end - start (ns, or us with kCoarse)
  std::uint32_t overhead_ = 0;
  // Missed releases (bits 0-15), flags (16-23) and state (24-31), one word: composed in a
  // register and stored at once. (Three fields stored apart were merged by the compiler through
  // the stack, and the wider load of the merge waited for the narrower stores: ~15 cycles.)
  std::uint32_t tail_ = tail(0, 0, TaskState::Running);

  static constexpr std::uint32_t tail(std::uint32_t missed, std::uint8_t flags,
                                      TaskState state) noexcept {
    return missed | std::uint32_t{flags} << 16 |
           std::uint32_t{static_cast<std::uint8_t>(state)} << 24;
  }

 public:
  /// stream() writes a slot as four little-endian words: cycle, release, latency | user << 32,
  /// overhead | tail << 32. True when that is the members' layout (checked below).
  static constexpr bool layout_is_four_words() noexcept {
    return offsetof(PackedCycle, cycle_) == 0 && offsetof(PackedCycle, release_ns_) == 8 &&
           offsetof(PackedCycle, latency_) == 16 && offsetof(PackedCycle, user_) == 20 &&
           offsetof(PackedCycle, overhead_) == 24 && offsetof(PackedCycle, tail_) == 28;
  }
};
static_assert(sizeof(PackedCycle) == 32, "keep the flight recorder's slot at 32 bytes");
static_assert(PackedCycle::layout_is_four_words(), "PackedCycle::stream() writes this layout");
static_assert(std::is_trivially_destructible_v<PackedCycle>,
              "FlightRing frees its slots without destroying them");

/// A fixed-capacity ring of cycles. Not thread-safe (the owner locks).
class FlightRing {
 public:
  /// Allocates `capacity` slots (0: records nothing): from `blocks` when given and a block holds
  /// them (and one can be had), else from the heap. Not RT-safe.
  explicit FlightRing(std::size_t capacity = 0, platform::HugePageBlocks* blocks = nullptr)
      : capacity_(capacity) {
    if (capacity == 0) return;
    if (blocks != nullptr && blocks->block_bytes() >= capacity * sizeof(PackedCycle)) {
      if (void* b = blocks->allocate()) {
        slots_ = static_cast<PackedCycle*>(b);
        blocks_ = blocks;
      }
    }
    if (slots_ == nullptr) slots_ = static_cast<PackedCycle*>(::operator new(bytes()));
    std::uninitialized_value_construct_n(slots_, capacity);
  }
  ~FlightRing() { free(); }
  FlightRing(FlightRing&& o) noexcept { take(o); }
  FlightRing& operator=(FlightRing&& o) noexcept {
    if (this != &o) {
      free();
      take(o);
    }
    return *this;
  }
  FlightRing(const FlightRing&) = delete;
  FlightRing& operator=(const FlightRing&) = delete;
  /// The slots' bytes.
  [[nodiscard]] std::size_t bytes() const noexcept { return capacity_ * sizeof(PackedCycle); }
  /// Records one cycle, overwriting the oldest when full. Never allocates. Only when nothing is
  /// pending (see push_pending).
  void push(const CycleRecord& r) noexcept {
    if (capacity_ == 0) return;
    // Packed in place: a slot built elsewhere and copied would be read back with wider loads
    // than it was written with, which stalls (no store forwarding).
    ::new (static_cast<void*>(&slots_[next_])) PackedCycle(r);
    next_ = next_ + 1 == capacity_ ? 0 : next_ + 1;
    size_ += size_ < capacity_ ? 1 : 0;
  }
  /// Records one cycle as pending: the newest `pending()` records are cycles their owner has not
  /// yet taken into its statistics (`take_pending`). Only when pending() < capacity() (a pending
  /// record is never overwritten) and PackedCycle::packs_exactly(r). Never allocates.
  void push_pending(const CycleRecord& r) noexcept {
    push(r);
    ++pending_;
  }
  /// True when push_pending() may be called (there are slots, and a free one).
  [[nodiscard]] bool has_room_pending() const noexcept { return pending_ < capacity_; }
  /// push_pending() of a run of cycles: while there is room, calls `pack(void* slot)`, which
  /// either constructs a PackedCycle at `slot` (placement new) and returns true, or returns false
  /// having written nothing, which ends the run. Returns the cycles pushed. The cursor stays in
  /// registers over the run (one store of it at the end, not one per cycle). Never allocates.
  template <class Pack>
  std::size_t push_pending_while(Pack&& pack) noexcept {
    PackedCycle* const slots = slots_;
    const std::size_t cap = capacity_;
    std::size_t next = next_;
    std::size_t pending = pending_;
    const std::size_t before = pending;
    while (pending < cap && pack(static_cast<void*>(slots + next))) {
      next = next + 1 == cap ? 0 : next + 1;
      ++pending;
    }
    const std::size_t n = pending - before;
    next_ = next;
    pending_ = pending;
    size_ = size_ + n < cap ? size_ + n : cap;
    return n;
  }
  /// Records pushed by push_pending() and not yet taken.
  [[nodiscard]] std::size_t pending() const noexcept { return pending_; }
  /// Hands every pending record to `f(const CycleRecord&)`, oldest first; none is pending after.
  /// Always inlined, so that a caller compiled for another instruction set runs it with that set.
  template <class F>
  [[gnu::always_inline]] void take_pending(F&& f) noexcept {
    take_pending(pending_, f);
  }
  /// As take_pending(f), for the oldest `max` pending records only (all of them when fewer are
  /// pending); returns how many were handed. The loop's state is in locals, not in the ring's
  /// members: `f` may store 64-bit values, which could alias those and force a reload per record.
  template <class F>
  [[gnu::always_inline]] std::size_t take_pending(std::size_t max, F&& f) noexcept {
    const std::size_t n = pending_ < max ? pending_ : max;
    const std::size_t capacity = capacity_;
    const PackedCycle* const slots = slots_;
    std::size_t i = next_ >= pending_ ? next_ - pending_ : next_ + capacity - pending_;
    pending_ -= n;
    for (std::size_t left = n; left > 0; --left) {
      // Pending slots are exact (push_pending's contract).
      VIGIL_ASSERT((slots[i].unpack().flags & CycleRecord::kCoarse) == 0,
                   "a pending flight-ring slot that is not exact");
      f(slots[i].unpack_exact());
      i = i + 1 == capacity ? 0 : i + 1;
    }
    return n;
  }
  /// The records, oldest first (a copy, unpacked).
  [[nodiscard]] std::vector<CycleRecord> ordered() const {
    std::vector<CycleRecord> out;
    out.reserve(size_);
    const std::size_t first = size_ < capacity_ ? 0 : next_;
    for (std::size_t i = 0; i < size_; ++i) out.push_back(slots_[(first + i) % capacity_].unpack());
    return out;
  }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] bool empty() const noexcept { return size_ == 0; }
  /// The slot the next push writes (null when the ring has no slots): for prefetching.
  [[nodiscard]] const void* next_slot() const noexcept {
    return capacity_ == 0 ? nullptr : &slots_[next_];
  }
  /// The newest record; only when !empty().
  [[nodiscard]] CycleRecord back() const noexcept {
    return slots_[next_ == 0 ? capacity_ - 1 : next_ - 1].unpack();
  }

 private:
  void free() noexcept {
    if (slots_ == nullptr) return;
    if (blocks_ != nullptr) {
      blocks_->release(slots_);
    } else {
      ::operator delete(slots_);
    }
    slots_ = nullptr;
  }
  void take(FlightRing& o) noexcept {
    slots_ = std::exchange(o.slots_, nullptr);
    blocks_ = std::exchange(o.blocks_, nullptr);
    capacity_ = std::exchange(o.capacity_, 0);
    next_ = std::exchange(o.next_, 0);
    size_ = std::exchange(o.size_, 0);
    pending_ = std::exchange(o.pending_, 0);
  }

  PackedCycle* slots_ = nullptr;  // capacity_ of them (PackedCycle is trivially destructible)
  platform::HugePageBlocks* blocks_ = nullptr;  // where slots_ came from (null: the heap)
  std::size_t capacity_ = 0;
  std::size_t next_ = 0;
  std::size_t size_ = 0;
  std::size_t pending_ = 0;
};

/// A frozen ring and what it is about: the input of the trace writer.
struct FlightRecord {
  std::string component;
  std::uint32_t component_id = 0;
  bool has_info = false;
  task::TaskInfo info;              ///< activity, period, thread id, policy (when has_info)
  std::vector<CycleRecord> cycles;  ///< oldest first
  /// The component's checkpoints over the recorded cycles (health supervision; empty when none
  /// is supervised), oldest first.
  std::vector<health::CheckpointMark> checkpoints;
  /// The latest start/end pairs of the deadline supervisions that start or end on it.
  std::vector<health::DeadlineSpan> deadlines;
  /// Why it was frozen: the event (kind, cycle, fault time, detail); for a record taken on
  /// demand, kind is StateChange with detail "on demand" and no fault time.
  Event event;
  bool on_demand = false;
  Nanos frozen_ns = 0;  ///< supervisor clock
};

/// How the supervisor writes the flight rings' slots.
enum class RingStores : std::uint8_t {
  /// Streaming when every component's flight ring and port together exceed four times the
  /// last-level cache (a drain sweeps through them: a slot written now is evicted before the
  /// statistics read it back, and reading its line first only costs memory traffic); cached
  /// otherwise. About 2,000 components with the defaults and a 32 MiB cache.
  Auto,
  Cached,     ///< ordinary stores, through the caches
  Streaming,  ///< non-temporal stores on x86-64 (`PackedCycle::stream`); ordinary elsewhere
};

/// Whether the flight rings' memory comes from huge pages (`platform::HugePageBlocks`).
enum class RingPages : std::uint8_t {
  /// Huge pages for the rings that join once the rings in use fill a 2 MiB region (64 rings of
  /// the default 1,024 cycles); the first ones, and every ring of a smaller system, on ordinary
  /// pages (no 2 MiB region locked for a few rings).
  Auto,
  Huge,      ///< every ring from huge-page regions
  Ordinary,  ///< every ring from the heap
};

/// Options of the flight recorder (part of `AggregatorOptions`).
struct FlightRecorderOptions {
  /// Cycles kept per component (0: no recorder, no memory). The ring also holds the cycles the
  /// statistics take in bulk; with 0, each cycle is taken at once (more supervisor CPU).
  std::size_t cycles = 1024;
  /// At most one frozen record per component per this interval (the events keep counting).
  Nanos min_interval_ns = 10 * kNanosPerSecond;
  /// At most this many frozen records over the aggregator's life (0: no limit).
  std::size_t max_records = 64;
  /// How a drain writes the slots (docs/design/supervision.md, "Streaming stores").
  RingStores stores = RingStores::Auto;
  /// Where the rings' memory comes from (docs/design/supervision.md, "Huge pages").
  RingPages pages = RingPages::Auto;
};

}  // namespace vigil::supervisor
