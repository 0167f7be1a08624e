#pragma once
/// @file
/// The flight recorder: the last N cycles of each component, kept on the supervisor side from
/// the samples it drains (the real-time side does nothing more than it already does). When an
/// event raises a component to ERROR, the ring is frozen into a `FlightRecord` (a copy taken at
/// that moment: the cycles up to and including the faulting one), which an exporter writes as a
/// Chrome/Perfetto trace (vigil/export/trace_event.hpp).
///
/// Memory: one ring of `capacity` records (48 bytes each: 48 KiB for the default 1024) per
/// component, allocated when the component joins; recording a cycle writes one slot and never
/// allocates. Not RT-safe; one writer (the supervisor thread), readers copy under the
/// aggregator's per-component lock.

#include <cstdint>
#include <string>
#include <vector>

#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/events.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::supervisor {

/// One cycle as the flight recorder keeps it.
struct CycleRecord {
  std::uint64_t cycle = 0;  ///< the component's 1-based cycle number
  Nanos release_ns = 0;     ///< scheduled release
  Nanos start_ns = 0;       ///< on_update() began
  Nanos end_ns = 0;         ///< on_update() ended
  Nanos overhead_ns = 0;    ///< supervision's measured overhead carried by the sample (0: none)
  std::uint32_t missed_before = 0;  ///< releases skipped just before it
  std::uint8_t flags = 0;           ///< kOverrun, kGap, kWarmup
  TaskState state = TaskState::Running;

  static constexpr std::uint8_t kOverrun = 1;  ///< ended after the next release
  static constexpr std::uint8_t kGap = 2;      ///< cycles before it are missing (port dropped)
  static constexpr std::uint8_t kWarmup = 4;   ///< inside the warm-up (kept out of statistics)

  /// on_update()'s own time.
  [[nodiscard]] Nanos user_ns() const noexcept { return end_ns - start_ns; }
  /// Wake-up latency: start - release.
  [[nodiscard]] Nanos latency_ns() const noexcept { return start_ns - release_ns; }
};
static_assert(sizeof(CycleRecord) <= 48, "keep the flight recorder's slot at 48 bytes");

/// A fixed-capacity ring of cycle records. Not thread-safe (the owner locks).
class FlightRing {
 public:
  /// Allocates `capacity` slots (0: records nothing). Not RT-safe.
  explicit FlightRing(std::size_t capacity = 0) : slots_(capacity), capacity_(capacity) {}
  /// Records one cycle, overwriting the oldest when full. Never allocates.
  void push(const CycleRecord& r) noexcept {
    if (slots_.empty()) return;
    slots_[next_] = r;
    next_ = next_ + 1 == slots_.size() ? 0 : next_ + 1;
    if (size_ < slots_.size()) ++size_;
  }
  /// The records, oldest first (a copy).
  [[nodiscard]] std::vector<CycleRecord> ordered() const {
    std::vector<CycleRecord> out;
    out.reserve(size_);
    const std::size_t first = size_ < slots_.size() ? 0 : next_;
    for (std::size_t i = 0; i < size_; ++i) out.push_back(slots_[(first + i) % slots_.size()]);
    return out;
  }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] std::size_t capacity() const noexcept { return slots_.size(); }
  [[nodiscard]] bool empty() const noexcept { return size_ == 0; }
  /// The slot for one more cycle, to be filled in place by the caller (every field: it holds an
  /// old record), overwriting the oldest when full; null when the ring has no slots. Never
  /// allocates.
  [[nodiscard]] CycleRecord* emplace() noexcept {
    if (capacity_ == 0) return nullptr;
    CycleRecord* r = slots_.data() + next_;
    next_ = next_ + 1 == capacity_ ? 0 : next_ + 1;
    size_ += size_ < capacity_ ? 1 : 0;
    return r;
  }
  /// The slot the next push writes (null when the ring has no slots): for prefetching.
  [[nodiscard]] const CycleRecord* next_slot() const noexcept {
    return slots_.empty() ? nullptr : &slots_[next_];
  }
  /// The newest record; only when !empty().
  [[nodiscard]] const CycleRecord& back() const noexcept {
    return slots_[next_ == 0 ? slots_.size() - 1 : next_ - 1];
  }

 private:
  std::vector<CycleRecord> slots_;
  std::size_t capacity_ = 0;  // slots_.size(), kept: no division by 48 per record
  std::size_t next_ = 0;
  std::size_t size_ = 0;
};

/// A frozen ring and what it is about: the input of the trace writer.
struct FlightRecord {
  std::string component;
  std::uint32_t component_id = 0;
  bool has_info = false;
  task::TaskInfo info;              ///< activity, period, thread id, policy (when has_info)
  std::vector<CycleRecord> cycles;  ///< oldest first
  /// Why it was frozen: the event (kind, cycle, fault time, detail); for a record taken on
  /// demand, kind is StateChange with detail "on demand" and no fault time.
  Event event;
  bool on_demand = false;
  Nanos frozen_ns = 0;  ///< supervisor clock
};

/// Options of the flight recorder (part of `AggregatorOptions`).
struct FlightRecorderOptions {
  /// Cycles kept per component (0: no recorder, no memory).
  std::size_t cycles = 1024;
  /// At most one frozen record per component per this interval (the events keep counting).
  Nanos min_interval_ns = 10 * kNanosPerSecond;
  /// At most this many frozen records over the aggregator's life (0: no limit).
  std::size_t max_records = 64;
};

}  // namespace vigil::supervisor
