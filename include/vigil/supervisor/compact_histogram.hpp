#pragma once
/// @file
/// `CompactHistogram`: the buckets of `LogLinearHistogram`, allocated only for the range of values
/// actually seen. Same layout, same bucket bounds, same quantiles (so the same documented relative
/// error, < 2^-S), in a few hundred bytes instead of 9 KiB for a stream whose values stay within
/// an octave or two, which is what a component's cycle time, wake-up latency, period and
/// supervision overhead are.
///
/// Why: the supervisor keeps four such distributions per component and updates them for every
/// message; with 1,000 to 10,000 components, 9 KiB each (36 KiB a component, on nine pages) put
/// every record out of the caches and the TLB. This one keeps a 48-byte header in the record
/// and one contiguous block of counters on the heap.
///
/// Memory: the counters of the bucket range [first, last] seen so far, rounded out to whole
/// chunks of 2^S buckets (one chunk = one power of two of values = 2^S x 8 bytes, 256 bytes for
/// S = 5): a stream within one octave costs one chunk. The block grows, by reallocation, when a
/// value falls outside it: at most kChunks - 1 times over the histogram's life (every growth
/// adds at least one chunk), and never beyond the 9 KiB of the full layout. So it allocates
/// while it learns the range of its stream, then no more: allocation-free in the steady state.
///
/// Thread-safety: none (one writer, the supervisor thread). RT-safety: `add` allocates when a
/// value falls outside the range seen so far, so it is NOT RT-safe (use `LogLinearHistogram` on
/// a real-time thread); everything else is allocation-free but copying. Out of memory never
/// throws from `add`/`merge`: the sample is counted in `lost_count()` (and `count()`) but in no
/// bucket, and a quantile that falls among such samples reports `kOverflowValue`, as overflowed
/// ones do.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <utility>

#include "vigil/supervisor/histogram.hpp"

namespace vigil::supervisor {

/**
 * A `LogLinearHistogram<SubBucketBits, MaxExponent>` whose counters are allocated for the seen
 * range only (see the file comment). Every bucket, bound and quantile is the same as the fixed
 * histogram's: `value_at_quantile(q)` is an upper bound with relative error < 2^-S, exact below
 * `kExactLimit` (tested against the fixed layout and against exact nearest-rank quantiles).
 *
 * Not RT-safe (`add` may allocate, see above); not thread-safe. Copying allocates (a deep copy);
 * moving does not.
 *
 * @code
 * vigil::supervisor::CompactHistogram<> h;              // 48 bytes until the first sample
 * h.add(52'000);                            // allocates one chunk: [32768, 65535], 256 bytes
 * h.add(61'000);                            // same chunk: no allocation
 * const vigil::Nanos p99 = h.value_at_quantile(0.99);
 * @endcode
 */
template <unsigned SubBucketBits = 5, unsigned MaxExponent = 40>
class CompactHistogram {
  using Layout = LogLinearHistogram<SubBucketBits, MaxExponent>;

 public:
  static constexpr unsigned kSubBucketBits = SubBucketBits;
  static constexpr unsigned kMaxExponent = MaxExponent;
  /// Buckets of the full layout (indexes 0 .. kBucketCount - 1, as LogLinearHistogram's).
  static constexpr std::size_t kBucketCount = Layout::kBucketCount;
  static constexpr std::int64_t kExactLimit = Layout::kExactLimit;
  static constexpr std::int64_t kMaxTrackable = Layout::kMaxTrackable;
  static constexpr double kMaxRelativeError = Layout::kMaxRelativeError;
  static constexpr std::int64_t kOverflowValue = Layout::kOverflowValue;
  /// Buckets allocated at a time: one power of two of values.
  static constexpr std::size_t kChunkBuckets = std::size_t{1} << SubBucketBits;
  /// Chunks of the full layout: the most the block can grow to.
  static constexpr std::size_t kChunks = kBucketCount / kChunkBuckets;

  [[nodiscard]] static constexpr std::size_t bucket_index(std::int64_t value) noexcept {
    return Layout::bucket_index(value);
  }
  [[nodiscard]] static constexpr std::int64_t bucket_lowest(std::size_t index) noexcept {
    return Layout::bucket_lowest(index);
  }
  [[nodiscard]] static constexpr std::int64_t bucket_highest(std::size_t index) noexcept {
    return Layout::bucket_highest(index);
  }

  CompactHistogram() noexcept = default;
  ~CompactHistogram() { delete[] counts_; }
  /// Deep copy: allocates the other's block (throws std::bad_alloc when out of memory).
  CompactHistogram(const CompactHistogram& o)
      : counts_(o.size_ > 0 ? new std::uint64_t[o.size_] : nullptr),
        first_(o.first_),
        size_(o.size_),
        count_(o.count_),
        negative_(o.negative_),
        overflow_(o.overflow_),
        lost_(o.lost_) {
    if (size_ > 0) std::memcpy(counts_, o.counts_, size_ * sizeof(std::uint64_t));
  }
  CompactHistogram(CompactHistogram&& o) noexcept
      : counts_(std::exchange(o.counts_, nullptr)),
        first_(std::exchange(o.first_, 0)),
        size_(std::exchange(o.size_, 0)),
        count_(std::exchange(o.count_, 0)),
        negative_(std::exchange(o.negative_, 0)),
        overflow_(std::exchange(o.overflow_, 0)),
        lost_(std::exchange(o.lost_, 0)) {}
  CompactHistogram& operator=(CompactHistogram o) noexcept {
    swap(o);
    return *this;
  }
  void swap(CompactHistogram& o) noexcept {
    std::swap(counts_, o.counts_);
    std::swap(first_, o.first_);
    std::swap(size_, o.size_);
    std::swap(count_, o.count_);
    std::swap(negative_, o.negative_);
    std::swap(overflow_, o.overflow_);
    std::swap(lost_, o.lost_);
  }

  /// Counts one sample (negative values as 0 and in `negative_count`, values above
  /// kMaxTrackable only in `overflow_count`). O(1) and allocation-free when the value's chunk is
  /// within the block; else grows the block first (one allocation and copy, O(kBucketCount)).
  void add(std::int64_t value) noexcept {
    if (!Layout::admit(value, count_, negative_, overflow_)) return;
    const auto i = static_cast<std::uint32_t>(Layout::bucket_index(value));
    const std::uint32_t off = i - first_;  // wraps for i < first_: one compare covers both ends
    if (off < size_) [[likely]] {
      ++counts_[off];
      return;
    }
    add_outside(i);
  }

  /// Counts the samples `values[k][0 .. n[k])` in `*hs[k]`, for each k: the same counts, and the
  /// same growth, as add() of each in turn (tested). As LogLinearHistogram::add_all: the runs
  /// interleaved, each histogram's header kept in registers over its run; `in_range`: the caller
  /// knows every value is within 0 .. kMaxTrackable (ScalarStats::add_all's ranges), so the
  /// common part of the runs skips the per-sample checks. Not RT-safe (a sample outside the
  /// allocated range allocates, as add()).
  template <std::size_t K>
  [[gnu::always_inline]] static void add_all(const std::array<CompactHistogram*, K>& hs,
                                             const std::array<const std::int64_t*, K>& values,
                                             const std::array<std::size_t, K>& n,
                                             bool in_range = false) noexcept {
    std::array<std::uint64_t*, K> counts;
    std::array<std::uint32_t, K> first;
    std::array<std::uint32_t, K> size;
    std::array<std::uint64_t, K> negative{};
    std::array<std::uint64_t, K> overflow{};
    std::size_t common = std::numeric_limits<std::size_t>::max();
    for (std::size_t k = 0; k < K; ++k) {
      counts[k] = hs[k]->counts_;
      first[k] = hs[k]->first_;
      size[k] = hs[k]->size_;
      common = std::min(common, n[k]);
    }
    const auto count = [&](std::size_t k, std::int64_t v) {
      const auto i = static_cast<std::uint32_t>(Layout::bucket_index(v));
      const std::uint32_t off = i - first[k];  // wraps below first: one compare, as add()
      if (off < size[k]) [[likely]] {
        ++counts[k][off];
        return;
      }
      hs[k]->add_outside(i);  // grows the block: its header changes
      counts[k] = hs[k]->counts_;
      first[k] = hs[k]->first_;
      size[k] = hs[k]->size_;
    };
    const auto checked = [&](std::size_t k, std::int64_t v) {
      if (Layout::admit_counted(v, negative[k], overflow[k])) count(k, v);
    };
    if (in_range) {
      for (std::size_t j = 0; j < common; ++j) {
#pragma GCC unroll 8
        for (std::size_t k = 0; k < K; ++k) count(k, values[k][j]);
      }
    } else {
      for (std::size_t j = 0; j < common; ++j) {
#pragma GCC unroll 8
        for (std::size_t k = 0; k < K; ++k) checked(k, values[k][j]);
      }
    }
    for (std::size_t k = 0; k < K; ++k) {
      for (std::size_t j = common; j < n[k]; ++j) checked(k, values[k][j]);
      hs[k]->count_ += n[k];
      hs[k]->negative_ += negative[k];
      hs[k]->overflow_ += overflow[k];
    }
  }

  /// Adds every count of `other`: the result equals a histogram given the samples of both.
  /// Grows this block to cover other's (other's counts go to `lost_count` if that fails).
  void merge(const CompactHistogram& other) noexcept {
    count_ += other.count_;
    negative_ += other.negative_;
    overflow_ += other.overflow_;
    lost_ += other.lost_;
    if (other.size_ == 0) return;
    if (!cover(other.first_, other.first_ + other.size_ - 1)) {
      for (std::uint32_t k = 0; k < other.size_; ++k) lost_ += other.counts_[k];
      return;
    }
    const std::uint32_t at = other.first_ - first_;
    for (std::uint32_t k = 0; k < other.size_; ++k) counts_[at + k] += other.counts_[k];
  }

  /// Forgets every sample; keeps the block (so a reset histogram does not allocate again for
  /// the same range). O(allocated buckets).
  void reset() noexcept {
    if (size_ > 0) std::memset(counts_, 0, size_ * sizeof(std::uint64_t));
    count_ = negative_ = overflow_ = lost_ = 0;
  }

  [[nodiscard]] std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] std::uint64_t negative_count() const noexcept { return negative_; }
  [[nodiscard]] std::uint64_t overflow_count() const noexcept { return overflow_; }
  /// Samples that found no memory for their bucket (out of memory while growing). O(1).
  [[nodiscard]] std::uint64_t lost_count() const noexcept { return lost_; }
  /// Samples counted by bucket `index` (< kBucketCount; 0 outside the block). O(1).
  [[nodiscard]] std::uint64_t count_at(std::size_t index) const noexcept {
    const std::size_t off = index - first_;
    return off < size_ ? counts_[off] : 0;
  }
  /// The counter of `value`'s bucket, or null when it is not allocated; for prefetching.
  [[nodiscard]] const std::uint64_t* counter_of(std::int64_t value) const noexcept {
    if (value < 0 || value > kMaxTrackable) return nullptr;
    const std::size_t off = Layout::bucket_index(value) - first_;
    return off < size_ ? counts_ + off : nullptr;
  }
  /// First bucket index of the block (0 when none is allocated).
  [[nodiscard]] std::size_t first_allocated() const noexcept { return first_; }
  /// Buckets allocated (a multiple of kChunkBuckets, at most kBucketCount).
  [[nodiscard]] std::size_t allocated_buckets() const noexcept { return size_; }
  /// Heap bytes held (the block of counters).
  [[nodiscard]] std::size_t heap_bytes() const noexcept { return size_ * sizeof(std::uint64_t); }

  /// As `LogLinearHistogram::quantile`: the bucket range holding the q-quantile (nearest rank),
  /// [2^E, kOverflowValue] among overflowed or lost samples, {0, 0} when empty.
  /// O(allocated buckets), allocation-free.
  [[nodiscard]] HistogramRange quantile(double q) const noexcept {
    if (count_ == 0) return {};
    constexpr HistogramRange kOverflowRange{kMaxTrackable + 1, kOverflowValue};
    const std::uint64_t rank = detail::nearest_rank(q, count_);
    if (rank <= count_ / 2) {
      std::uint64_t seen = 0;
      for (std::uint32_t k = 0; k < size_; ++k) {
        seen += counts_[k];
        if (seen >= rank) return {bucket_lowest(first_ + k), bucket_highest(first_ + k)};
      }
      return kOverflowRange;
    }
    const std::uint64_t above_rank = count_ - rank;
    std::uint64_t seen = overflow_ + lost_;
    if (seen > above_rank) return kOverflowRange;
    for (std::uint32_t k = size_; k-- > 0;) {
      seen += counts_[k];
      if (seen > above_rank) return {bucket_lowest(first_ + k), bucket_highest(first_ + k)};
    }
    return {0, 0};  // not reached: the buckets, overflow and lost hold count_ samples
  }

  /// As `LogLinearHistogram::values_at_quantiles`: several quantiles in one pass over buckets
  /// `first`..`last` (clipped to the block), which must hold every tracked sample.
  /// Allocation-free; O(last - first + K).
  template <std::size_t K>
  void values_at_quantiles(const std::array<double, K>& qs, std::array<std::int64_t, K>& out,
                           std::size_t first = 0,
                           std::size_t last = kBucketCount - 1) const noexcept {
    out.fill(0);
    if (count_ == 0) return;
    std::array<std::uint64_t, K> ranks{};
    for (std::size_t k = 0; k < K; ++k) ranks[k] = detail::nearest_rank(qs[k], count_);
    const std::size_t lo = std::max<std::size_t>(first, first_);
    const std::size_t hi = std::min<std::size_t>(last, std::size_t{first_} + size_ - 1);
    std::size_t k = 0;
    std::uint64_t seen = 0;
    for (std::size_t i = lo; size_ > 0 && i <= hi && k < K; ++i) {
      seen += counts_[i - first_];
      while (k < K && seen >= ranks[k]) out[k++] = bucket_highest(i);
    }
    for (; k < K; ++k) out[k] = kOverflowValue;  // among the overflowed or lost samples
  }

  /// `quantile(q).highest`: an upper bound with relative error < 2^-S (see LogLinearHistogram).
  [[nodiscard]] std::int64_t value_at_quantile(double q) const noexcept {
    return quantile(q).highest;
  }

 private:
  // Grows the block to cover bucket `i`, then counts it there (or in lost_).
  [[gnu::noinline]] void add_outside(std::uint32_t i) noexcept {
    if (cover(i, i)) {
      ++counts_[i - first_];
    } else {
      ++lost_;
    }
  }

  // Makes the block cover buckets [lo, hi], rounded out to whole chunks. False when out of
  // memory (the block is unchanged then).
  bool cover(std::uint32_t lo, std::uint32_t hi) noexcept {
    constexpr auto kMask = static_cast<std::uint32_t>(kChunkBuckets - 1);
    std::uint32_t first = lo & ~kMask;
    std::uint32_t end = (hi | kMask) + 1;
    if (size_ > 0) {
      if (first >= first_ && end <= first_ + size_) return true;
      first = std::min(first, first_);
      end = std::max(end, first_ + size_);
    }
    const std::uint32_t size = end - first;
    auto* counts = new (std::nothrow) std::uint64_t[size]();
    if (counts == nullptr) return false;
    if (size_ > 0) {
      std::memcpy(counts + (first_ - first), counts_, size_ * sizeof(std::uint64_t));
    }
    delete[] counts_;
    counts_ = counts;
    first_ = first;
    size_ = size;
    return true;
  }

  std::uint64_t* counts_ = nullptr;  // size_ counters for buckets first_ .. first_ + size_ - 1
  std::uint32_t first_ = 0;
  std::uint32_t size_ = 0;
  std::uint64_t count_ = 0;
  std::uint64_t negative_ = 0;
  std::uint64_t overflow_ = 0;
  std::uint64_t lost_ = 0;
};

static_assert(sizeof(CompactHistogram<>) == 48, "CompactHistogram<>: a 48-byte header");

}  // namespace vigil::supervisor
