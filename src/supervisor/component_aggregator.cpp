#include "vigil/supervisor/component_aggregator.hpp"

#include <cxxabi.h>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <fstream>
#include <string>

#include <unistd.h>

#if defined(__x86_64__)
#include <cpuid.h>
#endif

#include "vigil/assert.hpp"
#include "vigil/supervisor/health_supervision.hpp"
#include "vigil/task/shm_messages.hpp"

namespace vigil::supervisor {

namespace {
// Total time is user time plus the latest measured supervision overhead: its count, extremes,
// mean and EWMA are kept exactly here (ScalarStats), and its percentiles are user time's plus that
// overhead, so the aggregator keeps no fifth histogram per component (9 KiB and one more bucket
// update per message).
struct TotalStats {
  ScalarStats stats;  // count, last, min, max, mean, EWMA: the same code as RunningStats'

  void add(Nanos v) noexcept { stats.add(v); }
  [[nodiscard]] StatsSummary summary(const StatsSummary& user, Nanos overhead) const noexcept {
    StatsSummary s = stats.summary();
    if (s.count == 0) return s;
    auto shifted = [&](Nanos p) { return std::min(p + overhead, s.max); };
    s.p50 = shifted(user.p50);
    s.p90 = shifted(user.p90);
    s.p99 = shifted(user.p99);
    s.p999 = shifted(user.p999);
    return s;
  }
};
}  // namespace

// The catch-up (Slot::take_pending), chosen once for this CPU (defined after Slot).
void take_pending_into_stats(const ComponentAggregator::Slot& s) noexcept;

// A component's record, in three parts by how often they are touched. Per drain (take_sample,
// end): the mutex, counters, the fields it tests and the flight ring's header, ~5 cache lines,
// the only ones a drain loads besides the ring's next slots. Per catch-up, every few hundred
// cycles of the component: the five statistics (scalars and histogram headers, and the
// histograms' counters, a few hundred bytes on the heap). Cold: `data` (names, info, latest
// reports, latch), touched by the drain only when a message other than a sample arrives. Fields
// of ComponentSnapshot kept in the hot parts (counters, state, samples...) are stale in `data`:
// copy_of() fills them in.
struct ComponentAggregator::Slot {
  // --- per drain ---
  mutable std::mutex mutex;
  task::Counters counters;           // cumulative (ComponentSnapshot::counters)
  std::uint64_t samples = 0;         // ComponentSnapshot::samples
  std::uint64_t last_cycle = 0;      // cycle of the latest sample (when has_sample)
  Nanos last_sample_at = 0;          // ComponentSnapshot::last_sample_at
  Nanos warm_until = 0;              // component clock
  std::uint64_t drain_overruns = 0;  // overrun samples in this drain (one coalesced event)
  std::uint64_t overrun_cycle = 0;
  Nanos overrun_end = 0;
  TaskState state = TaskState::PreOperational;
  bool has_sample = false;
  bool warming_up = false;
  bool warm_armed = true;           // the next sample starts a warm-up
  bool silent = false;              // ComponentSnapshot::silent
  bool watched = false;             // a cycle arrived since the component entered Running
  std::size_t port_high_water = 0;  // ComponentSnapshot::port_high_water
  Nanos deadline_ns = 0;            // data.deadline_ns, for the watchdog's walk
  // The flight ring doubles as the queue of cycles not yet in the statistics: a drain only
  // packs each sample into it (pending); the statistics take the pending cycles in bulk,
  // `catch_up()`, when enough have gathered (`catch_up_at`), before the ring would overwrite
  // one, and before anyone reads them. Their lines are then loaded once per few hundred cycles
  // instead of once per drain. The ring, the statistics and their cursor are mutable: brought
  // up to date under the mutex by whoever reads (copy_of is const).
  mutable FlightRing ring;  // allocated at join
  std::size_t catch_up_at = 0;

  // An exception or loss report waiting for the sample of its cycle (which carries its time).
  struct Pending {
    EventKind kind = EventKind::Exception;
    EventSeverity severity = EventSeverity::Error;
    std::uint64_t cycle = 0;
    std::uint64_t count = 1;
    std::string detail;
    int drains = 0;  // drains it has waited through
  };
  std::vector<Pending> pending;

  // --- per catch-up ---
  mutable CompactRunningStats user, latency, period, overhead;
  mutable TotalStats total;
  mutable Nanos last_overhead = 0;     // latest measured supervision overhead (statistics' order)
  mutable Nanos stats_last_start = 0;  // start of the latest cycle in the statistics
  mutable bool stats_has_prev = false;
  // The worst cycle of each distribution (execution, total, latency, period) by window of
  // worst_window_ns (0: not kept), taken at each flush: note_worst().
  mutable std::array<WorstCycles, 4> worst{};
  mutable Nanos worst_window_end = 0;  // component clock; 0: before the first window
  Nanos worst_window_ns = 0;

  // Cycles on their way into the statistics: the values of a run of up to kRun cycles, staged,
  // then each statistic takes its run at once (its EWMA chain and histogram increments
  // interleaved with the others'): flush(). The one place the rule lives: what a cycle gives each
  // statistic. The arrays are memory; the run's cursor (`Run`) is a separate object, so that once
  // inlined it stays in registers (in one object with the arrays, each 64-bit store into them
  // could alias it). The staging loop has no flush in it: it stages a whole run, then flushes.
  struct Staging {
    static constexpr std::size_t kRun = 64;
    static_assert(kRun <= 256, "period_of holds indices as bytes");
    std::array<Nanos, kRun> user, total, latency, period, overhead;
    // Each staged cycle's number and start (by the index of user/total/latency), and which of
    // them each staged period ends: for the worst cycles (note_worst).
    std::array<std::uint64_t, kRun> cycle;
    std::array<Nanos, kRun> start;
    std::array<std::uint8_t, kRun> period_of;
  };
  struct Run {
    std::size_t n = 0, np = 0, no = 0;
    bool has_prev = false;
    Nanos prev_start = 0;
    Nanos last_overhead = 0;
  };
  // At most kRun cycles between two flushes (checked in debug builds).
  [[gnu::always_inline]] static void stage(Staging& st, Run& run, const CycleRecord& r) noexcept {
    VIGIL_ASSERT(run.n < Staging::kRun, "a run of cycles staged beyond Staging::kRun");
    const bool had_prev = run.has_prev;
    const Nanos before = run.prev_start;
    run.has_prev = true;
    run.prev_start = r.start_ns;
    if ((r.flags & CycleRecord::kWarmup) != 0) [[unlikely]]
      return;  // kept out of the statistics; still the start of the next period
    if (had_prev && (r.flags & CycleRecord::kGap) == 0) {
      st.period_of[run.np] = static_cast<std::uint8_t>(run.n);
      st.period[run.np++] = r.start_ns - before;
    }
    if (r.overhead_ns > 0) {
      run.last_overhead = r.overhead_ns;
      st.overhead[run.no++] = r.overhead_ns;
    }
    const Nanos execution_ns = r.end_ns - r.start_ns;
    st.user[run.n] = execution_ns;
    st.total[run.n] = execution_ns + run.last_overhead;
    st.latency[run.n] = r.start_ns - r.release_ns;
    st.cycle[run.n] = r.cycle;
    st.start[run.n] = r.start_ns;
    ++run.n;
  }
  [[gnu::always_inline]] void flush(const Staging& st, Run& run) const noexcept {
    CompactRunningStats::add_all<3, 1>(
        {&user, &latency, &period}, {&total.stats},
        {st.user.data(), st.latency.data(), st.period.data(), st.total.data()},
        {run.n, run.n, run.np, run.n});
    overhead.add_all(st.overhead.data(), run.no);
    if (worst_window_ns > 0 && run.n > 0) note_worst(st, run);
    run.n = run.np = run.no = 0;
  }
  // Keeps the worst cycle of each distribution in the current window: a run's cycles count in
  // the window its first cycle started in (a run is at most kRun cycles). A pass over each
  // staged array; the worst's number is looked up only when it beats the window's.
  [[gnu::always_inline]] void note_worst(const Staging& st, const Run& run) const noexcept {
    const Nanos first = st.start[0];
    if (worst_window_end == 0) {
      worst_window_end = first + worst_window_ns;
    } else if (first >= worst_window_end) {
      const Nanos behind = first - worst_window_end;  // a window without cycles: none previous
      for (WorstCycles& w : worst) {
        w.previous = behind < worst_window_ns ? w.current : WorstCycle{};
        w.current = WorstCycle{};
      }
      worst_window_end += (behind / worst_window_ns + 1) * worst_window_ns;
    }
    const auto keep = [&](WorstCycles& w, const std::array<Nanos, Staging::kRun>& v, std::size_t n,
                          bool of_periods) {
      if (n == 0) return;
      std::size_t best = 0;
      for (std::size_t i = 1; i < n; ++i) best = v[i] > v[best] ? i : best;
      if (w.current.cycle != 0 && v[best] <= w.current.value_ns) return;
      const std::size_t at = of_periods ? st.period_of[best] : best;
      w.current = WorstCycle{.cycle = st.cycle[at], .value_ns = v[best], .start_ns = st.start[at]};
    };
    keep(worst[0], st.user, run.n, false);
    keep(worst[1], st.total, run.n, false);
    keep(worst[2], st.latency, run.n, false);
    keep(worst[3], st.period, run.np, true);
  }
  // Takes cycles into the statistics, in order (the period is from the previous one): `feed`
  // stages them, flushing at least every kRun cycles. Under the mutex. Inlined into the
  // out-of-line catch-ups (take_pending_into_stats): a drain calls one once per few hundred
  // cycles, and inline its buffers would weigh on every call.
  template <class Feed>
  [[gnu::always_inline]] void take(Feed&& feed) const noexcept {
    Staging st;
    Run run;
    run.has_prev = stats_has_prev;
    run.prev_start = stats_last_start;
    run.last_overhead = last_overhead;
    feed(st, run);
    stats_has_prev = run.has_prev;
    stats_last_start = run.prev_start;
    last_overhead = run.last_overhead;
  }
  // Takes one cycle into the statistics at once (rare: no ring, or a cycle it keeps inexactly).
  [[gnu::noinline]] void aggregate(const CycleRecord& r) const noexcept {
    take([&](Staging& st, Run& run) {
      stage(st, run, r);
      flush(st, run);
    });
  }
  // Takes every pending cycle of the ring into the statistics.
  void catch_up() const noexcept {
    if (ring.pending() == 0) return;
    take_pending_into_stats(*this);
  }
  // What catch_up() does, compiled once for each instruction set (take_pending_into_stats): the
  // ring's pending cycles, a run of kRun at a time.
  [[gnu::always_inline]] void take_pending() const noexcept {
    const auto stage_run = [&](auto& st, auto& run) __attribute__((always_inline)) {
      const auto to = [&](const CycleRecord& r) __attribute__((always_inline)) {
        stage(st, run, r);
      };
      while (ring.pending() > 0) {
        ring.take_pending(Staging::kRun, to);
        flush(st, run);
      }
    };
    take(stage_run);
  }

  // What every sample taken does to the per-drain fields, whichever path took it (take_run()
  // or take_sample()): the gap rule, and the bookkeeping after it.
  [[nodiscard]] static bool gap_between(std::uint64_t last, std::uint64_t cycle) noexcept {
    return cycle != last + 1;
  }
  [[nodiscard]] bool gap_before(std::uint64_t cycle) const noexcept {
    return has_sample && gap_between(last_cycle, cycle);
  }
  // `count` samples taken, the latest of cycle `cycle`.
  void took(std::uint64_t cycle, Nanos at, std::uint64_t count = 1) noexcept {
    watched = true;
    has_sample = true;
    last_cycle = cycle;
    samples += count;
    last_sample_at = at;
  }

  // What the drains of this component sweep through: its flight ring and its port (RingStores).
  [[nodiscard]] std::size_t drained_bytes() const noexcept {
    return ring.capacity() * sizeof(PackedCycle) + data.port_capacity * sizeof(task::Message);
  }

  // --- cold ---
  ComponentSnapshot data;  // see above; summaries are filled only in copies handed to readers
  Nanos last_frozen = 0;

  // Hints for the records of the ports to come, in two stages so that neither waits for memory:
  // two ports ahead, the lines a drain touches; one port ahead (they are in by then), what they
  // point to: the flight ring's next slots.
  void prefetch_hot() const noexcept;
  void prefetch_targets() const noexcept {  // not when the ring streams: no line to bring in
    if (const auto* r = static_cast<const char*>(ring.next_slot())) {
      for (std::size_t off = 0; off < 16 * sizeof(PackedCycle); off += 64) {
        __builtin_prefetch(r + off, 1);
      }
    }
  }
};

// The part a drain touches: everything before the statistics (offsetof on a non-standard-layout
// type is conditionally supported; GCC and Clang support it).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Winvalid-offsetof"
constexpr std::size_t kSlotHotBytes = offsetof(ComponentAggregator::Slot, user);
#pragma GCC diagnostic pop
static_assert(kSlotHotBytes <= std::size_t{6} * 64,
              "keep the part of a record a drain touches within 6 cache lines");

// The catch-up compiled twice on x86-64: for the base instruction set, and with LZCNT and
// BMI2 for the CPUs that have them. A histogram's bucket is a bit width and a shift: the base
// set's bit-width instruction (BSR) is slow on AMD cores (one per four cycles), and its shift by
// a register a further dependency; LZCNT and SHRX are one cycle. Both are the same source with
// every call inlined (flatten; the statistics' loops are always_inline for it), integer
// arithmetic, and the same floating point (no FMA in the set): the same results bit for bit
// (tested). Measured: 1.13x the messages per second at 1,000 components x 10 messages, 1.16x
// at 10,000 (docs/design/performance-history.md, "The statistics with LZCNT and BMI2"). Chosen
// once, from CPUID; set_instruction_set() changes it. A build that already targets LZCNT and
// BMI2 has one copy, which is then the LzcntBmi2 one.
namespace {
using InstructionSet = ComponentAggregator::InstructionSet;
using TakePending = void (*)(const ComponentAggregator::Slot&) noexcept;

[[gnu::flatten, gnu::noinline]] void take_pending_base(
    const ComponentAggregator::Slot& s) noexcept {
  s.take_pending();
}

#if defined(__x86_64__) && defined(__LZCNT__) && defined(__BMI__) && defined(__BMI2__)
// A build for CPUs that have them (-march=haswell or later): the one copy uses them.
constexpr bool kBaseCopyHasBits = true;
#else
constexpr bool kBaseCopyHasBits = false;
#if defined(__x86_64__)
#define VIGIL_CATCH_UP_BITS 1
[[gnu::target("lzcnt,bmi,bmi2"), gnu::flatten, gnu::noinline]] void take_pending_bits(
    const ComponentAggregator::Slot& s) noexcept {
  s.take_pending();
}
#endif
#endif

// Whether this build and this CPU can run the catch-up with `set`.
bool can_run(InstructionSet set) noexcept {
  if (set == InstructionSet::Base) return !kBaseCopyHasBits;
  if (kBaseCopyHasBits) return true;
#if defined(VIGIL_CATCH_UP_BITS)
  unsigned a = 0, b = 0, c = 0, d = 0;
  if (__get_cpuid(0x80000001U, &a, &b, &c, &d) == 0 || (c & bit_LZCNT) == 0) return false;
  if (__get_cpuid_count(7, 0, &a, &b, &c, &d) == 0) return false;
  return (b & bit_BMI) != 0 && (b & bit_BMI2) != 0;
#else
  return false;
#endif
}

TakePending take_pending_for(InstructionSet set) noexcept {
#if defined(VIGIL_CATCH_UP_BITS)
  if (set == InstructionSet::LzcntBmi2) return &take_pending_bits;
#endif
  (void)set;
  return &take_pending_base;
}

// The copy in use: the set alone (its function follows from it, take_pending_for).
std::atomic<InstructionSet>& current_set() noexcept {
  static std::atomic<InstructionSet> set{
      can_run(InstructionSet::LzcntBmi2) ? InstructionSet::LzcntBmi2 : InstructionSet::Base};
  return set;
}
}  // namespace

void take_pending_into_stats(const ComponentAggregator::Slot& s) noexcept {
  take_pending_for(current_set().load(std::memory_order_relaxed))(s);
}

ComponentAggregator::InstructionSet ComponentAggregator::instruction_set() noexcept {
  return current_set().load(std::memory_order_relaxed);
}

bool ComponentAggregator::set_instruction_set(InstructionSet set) noexcept {
  if (!can_run(set)) return false;
  // A catch-up that loaded the other one finishes with it: both give the same results.
  current_set().store(set, std::memory_order_relaxed);
  return true;
}

const char* ComponentAggregator::name(InstructionSet set) noexcept {
  return set == InstructionSet::LzcntBmi2 ? "lzcnt+bmi2" : "base";
}

void ComponentAggregator::Slot::prefetch_hot() const noexcept {
  const auto* p = reinterpret_cast<const char*>(this);
  for (std::size_t off = 0; off < kSlotHotBytes; off += 64) __builtin_prefetch(p + off, 1);
}

namespace {

// Frozen flight records kept for readers (the trace writer takes them as their events arrive).
constexpr std::size_t kKeptRecords = 64;

std::string demangle(const char* mangled) {
  int status = 0;
  char* s = abi::__cxa_demangle(mangled, nullptr, nullptr, &status);
  if (status != 0 || s == nullptr) return mangled;
  std::string out(s);
  std::free(s);
  return out;
}

// The last-level cache that CPU 0 shares, in bytes (0: unknown). From sysfs, which describes the
// cache a core can use (on AMD, its CCX's L3); glibc's sysconf() may count every L3 of the socket,
// so it is only the fallback.
std::size_t last_level_cache_bytes() {
  int best_level = 0;
  std::size_t best = 0;
  for (int i = 0; i < 8; ++i) {
    const std::string dir = fmt::format("/sys/devices/system/cpu/cpu0/cache/index{}/", i);
    std::ifstream level_file(dir + "level");
    std::ifstream size_file(dir + "size");
    int level = 0;
    std::string size;  // "32768K", "1M"
    if (!(level_file >> level) || !(size_file >> size) || size.empty()) continue;
    char* end = nullptr;
    const unsigned long long n = std::strtoull(size.c_str(), &end, 10);
    const std::size_t unit = *end == 'K' ? 1024 : *end == 'M' ? 1024 * 1024 : *end == 0 ? 1 : 0;
    if (unit != 0 && n > 0 && level > best_level) {
      best_level = level;
      best = static_cast<std::size_t>(n) * unit;
    }
  }
  if (best > 0) return best;
#if defined(_SC_LEVEL3_CACHE_SIZE) && defined(_SC_LEVEL2_CACHE_SIZE)
  for (const int name : {_SC_LEVEL3_CACHE_SIZE, _SC_LEVEL2_CACHE_SIZE}) {
    if (const long bytes = ::sysconf(name); bytes > 0) return static_cast<std::size_t>(bytes);
  }
#endif
  return 0;
}

// RingStores::Auto streams when the drains sweep more than this many times the last-level cache.
constexpr std::size_t kStreamBeyondCaches = 4;

}  // namespace

ComponentAggregator::ComponentAggregator(AggregatorOptions options)
    : options_(options),
      ewma_weight_(options.ewma_weight),
      cache_bytes_(last_level_cache_bytes()),
      events_(options.events) {
  if (options_.recorder.cycles > 0 && options_.recorder.pages != RingPages::Ordinary) {
    ring_blocks_ =
        std::make_unique<platform::HugePageBlocks>(options_.recorder.cycles * sizeof(PackedCycle));
  }
  choose_ring_stores();
}
ComponentAggregator::~ComponentAggregator() = default;

bool ComponentAggregator::streams_rings(RingStores mode, std::size_t drained_bytes,
                                        std::size_t cache_bytes) noexcept {
  switch (mode) {
    case RingStores::Cached:
      return false;
    case RingStores::Streaming:
      return true;
    case RingStores::Auto:
      break;
  }
  // Far beyond the cache, a slot written now is evicted before the statistics read it back (a
  // few hundred drains later): reading its line first, as an ordinary store does, is wasted.
  // Measured (docs/design/performance-history.md, "Streaming stores for large systems"): at twice
  // the cache (1,000 components, 65 MB, a 32 MB cache) streaming was 13 % slower, at twenty
  // times 13 % faster.
  return cache_bytes > 0 && drained_bytes / kStreamBeyondCaches > cache_bytes;
}

platform::HugePageBlocks* ComponentAggregator::ring_blocks_for_next() const noexcept {
  if (!ring_blocks_) return nullptr;
  // Auto: once the rings in use would fill a region (a smaller system keeps its few rings on
  // ordinary pages rather than lock a 2 MiB region for them).
  const bool huge = options_.recorder.pages == RingPages::Huge ||
                    slots_.size() >= ring_blocks_->blocks_per_region();
  return huge ? ring_blocks_.get() : nullptr;
}

std::size_t ComponentAggregator::rings_on_huge_pages() const noexcept {
  return ring_blocks_ ? ring_blocks_->in_use() : 0;
}

std::size_t ComponentAggregator::ring_region_bytes() const noexcept {
  return ring_blocks_ ? ring_blocks_->mapped_bytes() : 0;
}

void ComponentAggregator::choose_ring_stores() noexcept {
  stream_rings_ = streams_rings(options_.recorder.stores, footprint_bytes_, cache_bytes_);
}

ComponentAggregator::Slot* ComponentAggregator::slot_for(const Entry& e) {
  // Called by the supervisor thread, the only writer of slots_: no lock needed to read it.
  // The supervisor visits ports in id order, so the slot after the previous one is the usual
  // answer; otherwise a binary search over the contiguous ids (no pointer chasing: with
  // thousands of components every dereference would be a cache miss).
  if (hint_ < ids_.size() && ids_[hint_] == e.id) {
    if (hint_ + 2 < slots_.size()) slots_[hint_ + 2]->prefetch_hot();
    if (hint_ + 1 < slots_.size() && !stream_rings_) slots_[hint_ + 1]->prefetch_targets();
    return slots_[hint_++].get();
  }
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), e.id);
  if (it == ids_.end() || *it != e.id) return nullptr;
  const auto i = static_cast<std::size_t>(it - ids_.begin());
  hint_ = i + 1;
  return slots_[i].get();
}

void ComponentAggregator::on_join(const Entry& e) {
  auto slot = std::make_unique<Slot>();
  slot->ring = FlightRing(options_.recorder.cycles, ring_blocks_for_next());
  // Catch up every half to three quarters of a ring (the longer the run, the fewer times the
  // statistics' lines are loaded; shorter runs measured slower), spread by id so that
  // components started together do not all catch up in the same drain.
  const std::size_t quarter = options_.recorder.cycles / 4;
  slot->catch_up_at = quarter == 0 ? options_.recorder.cycles
                                   : 2 * quarter + static_cast<std::size_t>(e.id) % quarter;
  slot->worst_window_ns = options_.worst_window_ns > 0 ? options_.worst_window_ns : 0;
  slot->data.id = e.id;
  slot->data.name = e.name;
  slot->data.joined_at = options_.clock.now();
  slot->data.port_capacity = e.port->capacity();
  for (CompactRunningStats* s : {&slot->user, &slot->latency, &slot->period, &slot->overhead}) {
    (void)s->set_ewma_weight(ewma_weight_.load(std::memory_order_relaxed));
  }
  (void)slot->total.stats.set_ewma_weight(ewma_weight_.load(std::memory_order_relaxed));
  std::unique_lock lock(list_mutex_);
  const auto at = std::lower_bound(ids_.begin(), ids_.end(), e.id) - ids_.begin();
  ids_.insert(ids_.begin() + at, e.id);
  footprint_bytes_ += slot->drained_bytes();
  slots_.insert(slots_.begin() + at, std::move(slot));
  hint_ = 0;
  choose_ring_stores();
  lock.unlock();
  if (health_) health_->join(e.id, e.name);
}

void ComponentAggregator::on_leave(const Entry& e) {
  if (health_) health_->leave(e.id);
  if (Slot* s = slot_for(e)) {
    std::lock_guard lock(s->mutex);
    s->data.alive = false;
    s->data.left_at = options_.clock.now();
    ++departed_;
  }
}

namespace {
// A drain of at least this many messages from one port is taken into the statistics at once.
constexpr std::size_t kCatchUpDrain = 64;
}  // namespace

void ComponentAggregator::begin(const Entry& e) {
  current_ = slot_for(e);
  drained_ = 0;
  if (current_ != nullptr) current_->mutex.lock();
  // One clock read per 16 port drains, not per message or per port (a read costs ~20 ns, as
  // much as a message): samples are stamped with their arrival within the time of 16 drains
  // (microseconds; the watchdog's limits are milliseconds).
  if (clock_reads_++ % 16 == 0) drain_time_ = options_.clock.now();
}

void ComponentAggregator::end(const Entry& /*e*/, const PortDrain& d) {
  if (current_ == nullptr) return;
  Slot& s = *current_;
  if (s.drain_overruns > 0) {
    Event ev;
    ev.kind = EventKind::Overrun;
    ev.severity = EventSeverity::Warn;
    ev.cycle = s.overrun_cycle;
    ev.fault_ns = s.overrun_end;
    ev.count = s.drain_overruns;
    ev.detail = s.drain_overruns == 1
                    ? std::string("a cycle ended after its next release")
                    : fmt::format("{} cycles ended after their next release", s.drain_overruns);
    s.drain_overruns = 0;
    raise(s, std::move(ev));
  }
  if (!s.pending.empty()) resolve_pending(s, nullptr);
  s.port_high_water = std::max(s.port_high_water, d.occupancy);
  s.counters.dropped = std::max(s.counters.dropped, d.dropped);
  // At the threshold; or now when this drain brought many cycles (a port that was full, a
  // fast component): they are still in the caches, and the statistics' lines are paid for once
  // per drain either way.
  if (s.ring.pending() >= s.catch_up_at || d.messages >= kCatchUpDrain) s.catch_up();
  if (stream_rings_) PackedCycle::fence_streams();  // before a reader may take the lock
  current_->mutex.unlock();
  current_ = nullptr;
}

void ComponentAggregator::on(const Entry& /*e*/, const task::TaskInfo& m) {
  if (current_ == nullptr) return;
  current_->data.has_info = true;
  current_->data.info = m;
  current_->data.deadline_ns = options_.watchdog.limit(m.period_ns);
  current_->deadline_ns = current_->data.deadline_ns;
}

void ComponentAggregator::on(const Entry& e, const task::CycleSample& m) {
  if (current_ == nullptr) return;
  if (health_ && health_->watches_cycles(e.id)) health_->cycle(e.id, m);
  // Counters only grow: merging keeps the larger of each, so a late totals-only sample or an
  // exception report counted before its sample never moves one back.
  current_->counters.merge(m.counters);
  take_sample(*current_, m);
  if (!m.totals_only) current_->data.last = m;
}

namespace {
// take_sample() of a run of common samples, from the first of `ms`: a component past its
// warm-up, with a sample before, no event to raise or report waiting; samples that are not
// overruns, that a ring slot keeps exactly, while the ring has room. Each is packed straight into
// the ring; the record's fields change once, after the run. The same effect as take_sample() on
// each (tested by running every stream both ways). Returns the samples taken (0: none, nothing
// changed). `Stream`: the slots are written with streaming stores (RingStores).
template <bool Stream>
[[gnu::always_inline]] inline std::size_t take_run(ComponentAggregator::Slot& s,
                                                   const task::Message* ms, std::size_t n,
                                                   Nanos drain_time) noexcept {
  const bool steady = (static_cast<int>(s.warm_armed) | static_cast<int>(s.warming_up) |
                       static_cast<int>(s.silent) | static_cast<int>(!s.has_sample) |
                       static_cast<int>(!s.pending.empty())) == 0;
  if (!steady) [[unlikely]]
    return 0;
  using Slot = ComponentAggregator::Slot;
  std::uint64_t last = s.last_cycle;
  std::size_t i = 0;
  const std::size_t taken = s.ring.push_pending_while([&](void* slot) {
    if (i == n) return false;
    const auto* m = std::get_if<task::CycleSample>(&ms[i]);
    if (m == nullptr || (static_cast<int>(m->totals_only) | static_cast<int>(m->overrun)) != 0)
      return false;
    const Nanos latency = m->start_ns - m->release_ns;
    const Nanos user = m->end_ns - m->start_ns;
    if (!PackedCycle::fits_exactly(latency, user, m->overhead_ns, m->missed_before)) [[unlikely]]
      return false;
    const std::uint64_t cycle = m->cycle();
    const auto flags =
        static_cast<std::uint8_t>(Slot::gap_between(last, cycle) ? CycleRecord::kGap : 0);
    if constexpr (Stream) {
      PackedCycle::stream(slot, cycle, m->release_ns, latency, user, m->overhead_ns,
                          m->missed_before, flags, m->state);
    } else {
      ::new (slot) PackedCycle(PackedCycle::Exact{}, cycle, m->release_ns, latency, user,
                               m->overhead_ns, m->missed_before, flags, m->state);
    }
    last = cycle;
    ++i;
    return true;
  });
  if (taken > 0) {
    s.state = std::get_if<task::CycleSample>(&ms[taken - 1])->state;
    s.took(last, drain_time, taken);
  }
  return taken;
}
}  // namespace

void ComponentAggregator::on_batch(const Entry& e, const task::Message* messages, std::size_t n) {
  if (current_ == nullptr) return;
  Slot& s = *current_;
  // Samples, the common case, are handled without a variant dispatch; the full copy of the
  // latest one into the record is made once per batch (or before another message needs it).
  // Likewise the counters: a component's samples carry cumulative counters that only grow, so
  // merging those of the batch's latest sample equals merging each (as on() does); the merge is
  // also made before another message and whenever the warm-up needs the counters of a sample.
  const task::CycleSample* latest = nullptr;   // not yet copied into data.last
  const task::CycleSample* counted = nullptr;  // not yet merged into the counters
  const auto settle = [&] {
    if (counted != nullptr) s.counters.merge(counted->counters);
    if (latest != nullptr) s.data.last = *latest;
    latest = counted = nullptr;
  };
  // Streaming stores only for a drain the statistics will not take at once (kCatchUpDrain): the
  // catch-up would read the slots straight back, from memory instead of the cache.
  const bool stream = stream_rings_ && drained_ + n < kCatchUpDrain;
  drained_ += n;
  // Alive supervision of this component's cycles: each sample is an indication.
  if (health_ && health_->watches_cycles(e.id)) {
    for (std::size_t i = 0; i < n; ++i) {
      if (const auto* m = std::get_if<task::CycleSample>(&messages[i])) health_->cycle(e.id, *m);
    }
  }
  for (std::size_t i = 0; i < n;) {
    const std::size_t k = stream ? take_run<true>(s, messages + i, n - i, drain_time_)
                                 : take_run<false>(s, messages + i, n - i, drain_time_);
    if (k > 0) [[likely]] {
      // Past the warm-up, not totals-only: their counters are merged as the latest's.
      latest = counted = std::get_if<task::CycleSample>(&messages[i + k - 1]);
      i += k;
      continue;
    }
    if (const auto* m = std::get_if<task::CycleSample>(&messages[i])) {
      if (s.warming_up || s.warm_armed || m->totals_only) [[unlikely]] {
        s.counters.merge(m->counters);  // the warm-up copies the counters as of this sample
      } else {
        counted = m;
      }
      take_sample(s, *m);
      if (!m->totals_only) latest = m;
    } else {
      settle();
      std::visit([&](const auto& other) { on(e, other); }, messages[i]);
    }
    ++i;
  }
  settle();
}

void ComponentAggregator::take_sample(Slot& s, const task::CycleSample& m) {
  // The caller merged m's counters, or will before anything reads them.
  s.state = m.state;
  if (m.totals_only) return;
  // Warm-up: from the first cycle after the component entered Running, on its own clock.
  if (s.warm_armed) [[unlikely]] {
    s.warm_armed = false;
    s.warm_until = m.start_ns + options_.warmup_ns;
    s.warming_up = options_.warmup_ns > 0;
  }
  const bool warm = s.warming_up && m.start_ns < s.warm_until;
  if (s.warming_up && !warm) s.warming_up = false;
  if (warm) [[unlikely]] {
    s.data.warmup_counters = s.counters;
    ++s.data.warmup_cycles;
  }
  const bool gap = s.gap_before(m.cycle());
  const CycleRecord r{.cycle = m.cycle(),
                      .release_ns = m.release_ns,
                      .start_ns = m.start_ns,
                      .end_ns = m.end_ns,
                      .overhead_ns = m.overhead_ns,
                      .missed_before = m.missed_before,
                      .flags = static_cast<std::uint8_t>((m.overrun ? CycleRecord::kOverrun : 0) |
                                                         (gap ? CycleRecord::kGap : 0) |
                                                         (warm ? CycleRecord::kWarmup : 0)),
                      .state = m.state};
  if (s.ring.capacity() > 0 && PackedCycle::packs_exactly(r)) [[likely]] {
    // Into the statistics later, from the ring (Slot::catch_up), in the same order.
    if (s.ring.pending() == s.ring.capacity()) [[unlikely]]
      s.catch_up();
    s.ring.push_pending(r);
  } else {
    // No ring, or a cycle the ring keeps inexactly (beyond 2.1 s): now, after the pending ones.
    s.catch_up();
    s.ring.push(r);
    s.aggregate(r);
  }
  if (m.overrun && !warm) [[unlikely]] {
    if (s.drain_overruns++ == 0) {
      s.overrun_cycle = m.cycle();
      s.overrun_end = m.end_ns;
    }
  }
  if (s.silent) [[unlikely]] {
    s.silent = false;
    Event ev;
    ev.kind = EventKind::Recovered;
    ev.severity = EventSeverity::Info;
    ev.cycle = m.cycle();
    ev.fault_ns = m.end_ns;
    ev.detail = fmt::format("cycling again after {:.1f} ms without a cycle",
                            static_cast<double>(drain_time_ - s.last_sample_at) / 1e6);
    raise(s, std::move(ev));
  }
  s.took(m.cycle(), drain_time_);
  if (!s.pending.empty()) [[unlikely]]
    resolve_pending(s, &m);
}

void ComponentAggregator::resolve_pending(Slot& s, const task::CycleSample* sample) {
  // With a sample: the reports of its cycle get its end as their fault time; reports of older
  // cycles (whose sample was dropped) are raised without one. Without (end of a drain): reports
  // that waited one drain already are raised without a fault time.
  std::erase_if(s.pending, [&](Slot::Pending& p) {
    const bool mine = sample != nullptr && sample->cycle() == p.cycle;
    const bool older = sample != nullptr && sample->cycle() > p.cycle;
    const bool expired = sample == nullptr && ++p.drains > 1;
    if (!mine && !older && !expired) return false;
    Event ev;
    ev.kind = p.kind;
    ev.severity = p.severity;
    ev.cycle = p.cycle;
    ev.count = p.count;
    ev.fault_ns = mine ? sample->end_ns : 0;
    ev.detail = std::move(p.detail);
    raise(s, std::move(ev));
    return true;
  });
}

void ComponentAggregator::on(const Entry& /*e*/, const task::RealTimeLoss& m) {
  // The cumulative counters of the samples are authoritative for counts (a loss report can be
  // dropped by a full port); the report tells which cycle lost, and when it arrived, and makes
  // an event: it waits for the sample of its cycle, which carries the cycle's end.
  if (current_ == nullptr) return;
  Slot& s = *current_;
  s.data.has_loss = true;
  s.data.last_loss = m;
  s.data.last_loss_at = drain_time_;
  const bool rt = s.data.has_info && s.data.info.policy != SchedPolicy::Other;
  Slot::Pending p;
  p.kind = EventKind::RealTimeLoss;
  p.severity = rt ? EventSeverity::Error : EventSeverity::Warn;
  p.cycle = m.cycle;
  p.count = m.count;
  p.detail = fmt::format("{} in one cycle{}", platform::to_string(m.cause),
                         rt ? "" : " (not a real-time thread)");
  s.pending.push_back(std::move(p));
  // Its sample came first (it was kept and pushed again later): resolve it now.
  if (s.has_sample && s.data.last.cycle() >= m.cycle) resolve_pending(s, &s.data.last);
}

void ComponentAggregator::on(const Entry& /*e*/, const task::ExceptionReport& m) {
  if (current_ == nullptr) return;
  Slot& s = *current_;
  s.data.has_exception = true;
  s.data.last_exception = m;
  s.data.last_exception_type = demangle(m.type.c_str());
  s.counters.exceptions = std::max(s.counters.exceptions, std::uint64_t{m.count});
  const bool limit = std::string_view(m.type.c_str()) == "vigil::OverrunLimit";
  Slot::Pending p;
  p.kind = limit ? EventKind::OverrunLimit : EventKind::Exception;
  p.severity = EventSeverity::Error;
  // An exception thrown by on_update() is reported before its cycle's sample (m.cycle counts the
  // cycles completed before it); the overrun limit after the sample of the cycle that reached it.
  p.cycle = m.hook == Hook::Update && !limit ? m.cycle + 1 : m.cycle;
  p.detail = limit ? std::string(m.message.c_str())
                   : fmt::format("{} in {}: {}", s.data.last_exception_type, to_string(m.hook),
                                 m.message.c_str());
  if (m.hook != Hook::Update) {  // not a cycle's fault: no cycle time to wait for
    Event ev;
    ev.kind = p.kind;
    ev.severity = p.severity;
    ev.detail = std::move(p.detail);
    raise(s, std::move(ev));
    return;
  }
  s.pending.push_back(std::move(p));
  if (s.has_sample && s.data.last.cycle() >= s.pending.back().cycle) {
    resolve_pending(s, &s.data.last);
  }
}

void ComponentAggregator::on(const Entry& e, const task::StateChange& m) {
  if (health_) health_->state(e.id, m);
  if (current_ == nullptr) return;
  Slot& s = *current_;
  auto& d = s.data;
  d.has_state_change = true;
  d.last_change = m;
  s.state = m.to;
  if (!m.refused && m.to == TaskState::Running) {
    s.warm_armed = true;  // a (re)start warms up again
    s.watched = false;    // watched from its first cycle
    s.silent = false;
  } else if (!m.refused && m.from == TaskState::Running) {
    s.watched = false;
    s.silent = false;
  }
  const bool fault = !m.refused && (m.to == TaskState::Exception || m.to == TaskState::FatalError);
  if (!fault && !options_.state_events) return;
  Event ev;
  ev.kind = fault ? EventKind::FaultState : EventKind::StateChange;
  ev.severity = fault       ? EventSeverity::Error
                : m.refused ? EventSeverity::Warn
                            : EventSeverity::Info;
  ev.cycle = s.has_sample ? s.last_cycle : 0;
  ev.fault_ns = m.time_ns;
  ev.detail = m.refused ? fmt::format("{} refused in {}", to_string(m.from), to_string(m.hook))
                        : fmt::format("{} -> {}", to_string(m.from), to_string(m.to));
  if (!m.reason.empty()) ev.detail += fmt::format(" ({})", m.reason.c_str());
  raise(s, std::move(ev));
}

void ComponentAggregator::on(const Entry& e, const log::LogRecord& m) {
  if (auto* c = log_consumer_.load()) c->on_record(e.id, e.name, m);
}

void ComponentAggregator::on(const Entry& e, const health::CheckpointReport& m) {
  if (health_) health_->checkpoint(e.id, m);
}

std::size_t ComponentAggregator::raise_health(Nanos now, Nanos drained_to) {
  health_events_.clear();
  health_->advance(now, drained_to, health_events_);
  for (Event& ev : health_events_) {
    // On the component's record (latched when Error, a flight record frozen); an entity that
    // never joined has none: straight to the hub.
    const auto it = std::lower_bound(ids_.begin(), ids_.end(), ev.component_id);
    if (ev.component_id != 0 && it != ids_.end() && *it == ev.component_id) {
      Slot& s = *slots_[static_cast<std::size_t>(it - ids_.begin())];
      std::lock_guard lock(s.mutex);
      raise(s, std::move(ev));
    } else {
      events_.publish(std::move(ev));
    }
  }
  return health_events_.size();
}

Nanos ComponentAggregator::next_deadline() const {
  if (!health_ || options_.clock.fn != &Clock::system_now) return INT64_MAX;
  return health_->next_deadline();
}

expected<void, Error> ComponentAggregator::supervise_health(health::HealthConfig config) {
  if (auto ok = health::validate(config); !ok) return unexpected<Error>(ok.error());
  auto h = std::make_unique<HealthSupervision>(std::move(config), options_.clock);
  // Components already known: bound now, as if they joined (their state arrives again only
  // when it changes: one in Running is activated by its first report).
  {
    std::shared_lock lock(list_mutex_);
    for (const auto& slot : slots_) {
      if (slot->data.alive) h->join(slot->data.id, slot->data.name);
    }
  }
  health_ = std::move(h);
  return {};
}

std::vector<health::SupervisionReport> ComponentAggregator::health_reports() const {
  if (!health_) return {};
  return health_->reports();
}

void ComponentAggregator::on_cycle(const DrainCycle& c) {
  if (auto* lc = log_consumer_.load()) lc->on_supervisor_cycle(c.time_ns + c.drain_ns);
  hint_ = 0;
  clock_reads_ = 0;  // the first port of the next cycle reads the clock
  // The reports are complete up to when this drain began (ports are drained one after another).
  if (health_) (void)raise_health(options_.clock.now(), c.time_ns);
  if (options_.watchdog.enabled || options_.auto_clear_ns > 0) {
    const Nanos now = options_.clock.now();
    for (const auto& slot : slots_) watch(*slot, now);
  }
  if (cycle_hook_) cycle_hook_(options_.clock.now());
  if (departed_ == 0) return;  // nothing to forget: no walk over thousands of records
  const Nanos now = options_.clock.now();
  const auto expired = [&](const auto& s) {
    return !s->data.alive && now - s->data.left_at > options_.retain_left_ns;
  };
  if (std::none_of(slots_.begin(), slots_.end(), expired)) return;
  std::unique_lock lock(list_mutex_);
  std::size_t out = 0;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (expired(slots_[i])) {
      --departed_;
      footprint_bytes_ -= slots_[i]->drained_bytes();
      continue;
    }
    slots_[out] = std::move(slots_[i]);
    ids_[out] = ids_[i];
    ++out;
  }
  slots_.resize(out);
  ids_.resize(out);
  choose_ring_stores();
}

void ComponentAggregator::watch(Slot& s, Nanos now) {
  // Supervisor thread: the only writer of everything read here but the latch.
  auto& d = s.data;
  // Hot fields first: a record that is not late costs one cache line per cycle.
  if (s.watched && !s.silent && s.state == TaskState::Running && s.deadline_ns > 0 &&
      now - s.last_sample_at > s.deadline_ns && d.alive) {
    std::lock_guard lock(s.mutex);
    s.silent = true;
    ++d.deadline_misses;
    Event ev;
    ev.kind = EventKind::Deadline;
    ev.severity = EventSeverity::Error;
    ev.cycle = s.last_cycle;
    ev.fault_ns = s.last_sample_at + d.deadline_ns;
    ev.detected_ns = now;
    ev.detail = fmt::format("no cycle for {:.1f} ms (deadline {:.1f} ms; last cycle {})",
                            static_cast<double>(now - s.last_sample_at) / 1e6,
                            static_cast<double>(d.deadline_ns) / 1e6, s.last_cycle);
    raise(s, std::move(ev));
  }
  if (options_.auto_clear_ns > 0) {
    std::lock_guard lock(s.mutex);
    if (d.latch.active && now - d.latch.last_ns >= options_.auto_clear_ns) {
      (void)clear_slot(s, "auto-clear");
    }
  }
}

void ComponentAggregator::raise(Slot& s, Event e) {
  auto& d = s.data;
  e.component = d.name;
  e.component_id = d.id;
  if (e.detected_ns == 0) e.detected_ns = options_.clock.now();
  ++d.events;
  std::shared_ptr<FlightRecord> record;
  if (e.severity == EventSeverity::Error) {
    LatchedFault& l = d.latch;
    if (!l.active) {
      l.active = true;
      l.first_kind = e.kind;
      l.first_ns = e.detected_ns;
      l.first_detail = e.detail;
      l.count = 0;
      ++l.raised;
      e.latched = true;
      const auto& r = options_.recorder;
      if (!s.ring.empty() &&
          (s.last_frozen == 0 || e.detected_ns - s.last_frozen >= r.min_interval_ns)) {
        std::lock_guard lock(frozen_mutex_);
        if (r.max_records == 0 || frozen_total_ < r.max_records) {
          record = std::make_shared<FlightRecord>();
          record->component = d.name;
          record->component_id = d.id;
          record->has_info = d.has_info;
          record->info = d.info;
          record->cycles = s.ring.ordered();
          record->frozen_ns = e.detected_ns;
          e.traced = true;
          s.last_frozen = e.detected_ns;
          ++frozen_total_;
        }
      }
    }
    ++l.count;
    l.last_kind = e.kind;
    l.last_ns = e.detected_ns;
    l.last_detail = e.detail;
  }
  if (!record) {
    events_.publish(std::move(e));
    return;
  }
  add_health_trace(*record);
  // Stored under frozen_mutex_ with its sequence number before any subscriber can ask for it.
  std::lock_guard lock(frozen_mutex_);
  record->event = e;
  record->event.seq = events_.publish(std::move(e));
  frozen_.push_back(std::move(record));
  while (frozen_.size() > kKeptRecords) frozen_.pop_front();
}

void ComponentAggregator::add_health_trace(FlightRecord& r) const {
  if (!health_) return;
  // The checkpoints from the first recorded cycle's release on (all kept when none is).
  const Nanos from = r.cycles.empty() ? 0 : r.cycles.front().release_ns;
  health_->trace(r.component_id, from, r.checkpoints, r.deadlines);
}

std::size_t ComponentAggregator::clear_slot(Slot& s, const char* why) {
  LatchedFault& l = s.data.latch;
  if (!l.active) return 0;
  l.active = false;
  ++l.cleared;
  Event ev;
  ev.kind = EventKind::Cleared;
  ev.severity = EventSeverity::Info;
  ev.detail = fmt::format("{}: {} error event{} since {} ({})", why, l.count,
                          l.count == 1 ? "" : "s", to_string(l.first_kind), l.first_detail);
  raise(s, std::move(ev));
  return 1;
}

std::size_t ComponentAggregator::clear(std::string_view name) {
  std::shared_lock lock(list_mutex_);
  std::size_t n = 0;
  for (const auto& s : slots_) {
    if (s->data.name != name) continue;
    std::lock_guard slot_lock(s->mutex);
    n += clear_slot(*s, "cleared");
  }
  return n;
}

std::size_t ComponentAggregator::clear_all() {
  std::shared_lock lock(list_mutex_);
  std::size_t n = 0;
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    n += clear_slot(*s, "cleared");
  }
  return n;
}

std::shared_ptr<const FlightRecord> ComponentAggregator::frozen_record(std::uint64_t seq) const {
  std::lock_guard lock(frozen_mutex_);
  for (const auto& r : frozen_) {
    if (r->event.seq == seq) return r;
  }
  return nullptr;
}

std::vector<std::shared_ptr<const FlightRecord>> ComponentAggregator::frozen_records() const {
  std::lock_guard lock(frozen_mutex_);
  return {frozen_.begin(), frozen_.end()};
}

std::optional<FlightRecord> ComponentAggregator::flight_record(std::string_view name) const {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    if (s->data.name != name) continue;
    std::lock_guard slot_lock(s->mutex);
    FlightRecord r;
    r.component = s->data.name;
    r.component_id = s->data.id;
    r.has_info = s->data.has_info;
    r.info = s->data.info;
    r.cycles = s->ring.ordered();
    r.on_demand = true;
    add_health_trace(r);
    r.frozen_ns = options_.clock.now();
    r.event.kind = EventKind::StateChange;
    r.event.component = r.component;
    r.event.component_id = r.component_id;
    r.event.detail = "on demand";
    r.event.detected_ns = r.frozen_ns;
    return r;
  }
  return std::nullopt;
}

namespace {
ComponentSnapshot copy_of(const ComponentAggregator::Slot& s) {
  std::lock_guard lock(s.mutex);
  s.catch_up();
  ComponentSnapshot out = s.data;
  out.counters = s.counters;
  out.samples = s.samples;
  out.last_sample_at = s.last_sample_at;
  out.state = s.state;
  out.has_sample = s.has_sample;
  out.warming_up = s.warming_up;
  out.silent = s.silent;
  out.port_high_water = s.port_high_water;
  out.execution_ns = s.user.summary();
  out.total_ns = s.total.summary(out.execution_ns, s.last_overhead);
  out.latency_ns = s.latency.summary();
  out.measured_period_ns = s.period.summary();
  out.overhead_ns = s.overhead.summary();
  return out;
}
}  // namespace

std::vector<ComponentSnapshot> ComponentAggregator::snapshot() const {
  std::shared_lock lock(list_mutex_);
  std::vector<ComponentSnapshot> out;
  out.reserve(slots_.size());
  for (const auto& s : slots_) out.push_back(copy_of(*s));
  return out;
}

std::optional<ComponentSnapshot> ComponentAggregator::find(std::string_view name) const {
  std::shared_lock lock(list_mutex_);
  const Slot* dead = nullptr;
  for (const auto& s : slots_) {
    if (s->data.name != name) continue;
    if (s->data.alive) return copy_of(*s);
    dead = s.get();
  }
  if (dead != nullptr) return copy_of(*dead);
  return std::nullopt;
}

std::optional<ComponentSnapshot> ComponentAggregator::find_id(std::uint32_t id) const {
  std::shared_lock lock(list_mutex_);
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), id);
  if (it == ids_.end() || *it != id) return std::nullopt;
  return copy_of(*slots_[static_cast<std::size_t>(it - ids_.begin())]);
}

void ComponentAggregator::visit_distributions(
    const std::function<void(const ComponentDistributions&)>& visit) const {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    s->catch_up();
    ComponentDistributions d;
    d.id = s->data.id;
    d.name = s->data.name;
    d.execution = &s->user;
    d.latency = &s->latency;
    d.measured_period = &s->period;
    d.overhead = &s->overhead;
    d.total_shift_ns = s->last_overhead;
    d.total = s->total.summary(StatsSummary{}, 0);
    d.execution_worst = s->worst[0];
    d.total_worst = s->worst[1];
    d.latency_worst = s->worst[2];
    d.measured_period_worst = s->worst[3];
    visit(d);
  }
}

void ComponentAggregator::catch_up() {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    s->catch_up();
  }
}

std::size_t ComponentAggregator::size() const {
  std::shared_lock lock(list_mutex_);
  return slots_.size();
}

void ComponentAggregator::set_ewma_weight(double w) {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    s->catch_up();  // the cycles before the change keep the weight they came under
    for (CompactRunningStats* r : {&s->user, &s->latency, &s->period, &s->overhead}) {
      (void)r->set_ewma_weight(w);
    }
    (void)s->total.stats.set_ewma_weight(w);
  }
  ewma_weight_.store(w, std::memory_order_relaxed);
}

}  // namespace vigil::supervisor
