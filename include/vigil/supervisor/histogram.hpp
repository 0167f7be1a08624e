#pragma once
/// @file
/// `LogLinearHistogram`: a fixed-size, allocation-free histogram of non-negative 64-bit values
/// (nanoseconds) with a bounded relative error, for percentiles in the supervisor.
///
/// Layout (the HdrHistogram idea with one sub-bucket count for every power of two). With S
/// sub-bucket bits and maximum exponent E:
///
///   - values in [0, 2^(S+1)) each get their own bucket: they are counted exactly;
///   - every range [2^e, 2^(e+1)) with S+1 <= e < E is cut into 2^S buckets of equal width
///     2^(e-S), so a bucket's width is at most 2^-S times its lowest value;
///   - values >= 2^E go to an overflow counter, negative values are counted in bucket 0 (they
///     clamp to 0) and also in a counter of their own.
///
/// That makes (E - S + 1) * 2^S buckets: 1152 for the defaults S = 5, E = 40, i.e. values up to
/// 2^40 - 1 ns (18.3 minutes) with at most 1/32 = 3.1 % relative error, in 9240 bytes.
///
/// The bucket of a value is found with one bit-width (count-leading-zeros) instruction, a
/// shift and an add; the histogram never allocates, never throws and is trivially copyable.
/// It is not thread-safe: one thread writes it (the supervisor), others read copies.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

namespace vigil::supervisor {

/// An inclusive range of values, [lowest, highest]: where a quantile of a histogram lies.
struct HistogramRange {
  std::int64_t lowest = 0;   ///< smallest value the range holds
  std::int64_t highest = 0;  ///< largest value the range holds (inclusive)

  friend constexpr bool operator==(const HistogramRange&, const HistogramRange&) = default;
};

namespace detail {

/// Nearest-rank of quantile `q` among `n` samples (1-based): ceil(q * n), clamped to [1, n].
/// `q` is clamped to [0, 1] first; NaN counts as 0. Requires n > 0.
[[nodiscard]] inline std::uint64_t nearest_rank(double q, std::uint64_t n) noexcept {
  if (!(q > 0.0)) return 1;  // also NaN
  if (q >= 1.0) return n;
  const double r = std::ceil(q * static_cast<double>(n));
  if (!(r >= 1.0)) return 1;
  if (r >= static_cast<double>(n)) return n;
  return static_cast<std::uint64_t>(r);
}

}  // namespace detail

/**
 * A log-linear histogram of `std::int64_t` values (nanoseconds) in fixed memory.
 *
 * `SubBucketBits` (S) sets the precision, `MaxExponent` (E) the range: values in [0, 2^E) are
 * tracked, values in [0, 2^(S+1)) exactly. Quantiles use the nearest-rank definition (the
 * smallest sample x such that at least q * count samples are <= x) and report the highest value
 * of the bucket that holds that sample, so for a tracked value the report never under-estimates:
 *
 *     exact <= value_at_quantile(q) <= exact + (exact >> S),  i.e. relative error < 2^-S
 *
 * and it is exact when the sample is below 2^(S+1) (`kExactLimit`).
 *
 * RT-safety of every member: allocation-free, lock-free, no system call, noexcept. Not
 * thread-safe.
 *
 * @code
 * vigil::LogLinearHistogram<> h;               // S = 5, E = 40: 3.1 % error, up to 18 minutes
 * for (vigil::Nanos d : durations) h.add(d);
 * const vigil::Nanos p99 = h.value_at_quantile(0.99);
 * @endcode
 */
template <unsigned SubBucketBits = 5, unsigned MaxExponent = 40>
class LogLinearHistogram {
  static_assert(SubBucketBits >= 1 && SubBucketBits <= 16,
                "LogLinearHistogram: SubBucketBits must be in [1, 16]");
  static_assert(MaxExponent > SubBucketBits + 1 && MaxExponent <= 62,
                "LogLinearHistogram: MaxExponent must be in [SubBucketBits + 2, 62]");

 public:
  /// S: each power-of-two range is cut into 2^S buckets.
  static constexpr unsigned kSubBucketBits = SubBucketBits;
  /// E: values >= 2^E overflow.
  static constexpr unsigned kMaxExponent = MaxExponent;
  /// Number of buckets (counters): (E - S + 1) * 2^S.
  static constexpr std::size_t kBucketCount = std::size_t{MaxExponent - SubBucketBits + 1}
                                              << SubBucketBits;
  /// Values below this are counted exactly (one bucket per value): 2^(S+1).
  static constexpr std::int64_t kExactLimit = std::int64_t{1} << (SubBucketBits + 1);
  /// The largest value that does not overflow: 2^E - 1.
  static constexpr std::int64_t kMaxTrackable = (std::int64_t{1} << MaxExponent) - 1;
  /// Upper bound of the relative error of a reported quantile of tracked values: 2^-S.
  static constexpr double kMaxRelativeError = 1.0 / static_cast<double>(1U << SubBucketBits);
  /// What `value_at_quantile` reports when the quantile falls among overflowed samples (the
  /// only upper bound it knows); `quantile` reports [2^E, kOverflowValue] then.
  static constexpr std::int64_t kOverflowValue = std::numeric_limits<std::int64_t>::max();

  /// Index of the bucket that counts `value`, for 0 <= value <= kMaxTrackable.
  /// O(1): one bit-width instruction, a shift and an add.
  [[nodiscard]] static constexpr std::size_t bucket_index(std::int64_t value) noexcept {
    const auto v = static_cast<std::uint64_t>(value);
    // OR-ing in the exact range's mask makes the shift 0 below kExactLimit without a branch.
    constexpr std::uint64_t kExactMask = (std::uint64_t{1} << (SubBucketBits + 1)) - 1;
    const auto shift = static_cast<unsigned>(std::bit_width(v | kExactMask)) - (SubBucketBits + 1);
    return (std::size_t{shift} << SubBucketBits) + static_cast<std::size_t>(v >> shift);
  }

  /// Smallest value counted by bucket `index` (< kBucketCount). O(1).
  [[nodiscard]] static constexpr std::int64_t bucket_lowest(std::size_t index) noexcept {
    const std::size_t shift = std::max<std::size_t>(index >> SubBucketBits, 1) - 1;
    return static_cast<std::int64_t>(index - (shift << SubBucketBits)) << shift;
  }

  /// Largest value counted by bucket `index` (< kBucketCount), inclusive. O(1).
  [[nodiscard]] static constexpr std::int64_t bucket_highest(std::size_t index) noexcept {
    const std::size_t shift = std::max<std::size_t>(index >> SubBucketBits, 1) - 1;
    return bucket_lowest(index) + (std::int64_t{1} << shift) - 1;
  }

  /// Counts one sample. Negative values count as 0 (and in `negative_count`); values above
  /// kMaxTrackable count only in `overflow_count`. O(1), RT-safe, a few ns.
  constexpr void add(std::int64_t value) noexcept {
    if (admit(value, count_, negative_, overflow_)) ++counts_[bucket_index(value)];
  }

  /// Counts the samples `values[k][0 .. n[k])` in `*hs[k]`, for each k: the same counts as
  /// add() of each in turn (tested). The histograms' runs are interleaved, so that their
  /// increments overlap, and each one's totals are kept in registers over its run (add()'s count
  /// is a store per sample that the next sample's load waits for). `in_range`: the caller knows
  /// every value is within 0 .. kMaxTrackable, so the common part of the runs skips the
  /// per-sample checks. RT-safe, O(sum of n).
  template <std::size_t K>
  static void add_all(const std::array<LogLinearHistogram*, K>& hs,
                      const std::array<const std::int64_t*, K>& values,
                      const std::array<std::size_t, K>& n, bool in_range = false) noexcept {
    std::array<std::uint64_t, K> negative{};
    std::array<std::uint64_t, K> overflow{};
    std::size_t common = std::numeric_limits<std::size_t>::max();
    for (std::size_t k = 0; k < K; ++k) common = std::min(common, n[k]);
    const auto checked = [&](std::size_t k, std::int64_t v) {
      if (admit_counted(v, negative[k], overflow[k])) ++hs[k]->counts_[bucket_index(v)];
    };
    if (in_range) {
      for (std::size_t j = 0; j < common; ++j) {
#pragma GCC unroll 8
        for (std::size_t k = 0; k < K; ++k) ++hs[k]->counts_[bucket_index(values[k][j])];
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

  /// The rule `add` applies before a bucket, shared with CompactHistogram: counts the sample in
  /// `count`; a negative one also in `negative`, and `value` becomes 0; one above kMaxTrackable
  /// only in `overflow` (returns false: it goes in no bucket). O(1), RT-safe.
  static constexpr bool admit(std::int64_t& value, std::uint64_t& count, std::uint64_t& negative,
                              std::uint64_t& overflow) noexcept {
    ++count;
    return admit_counted(value, negative, overflow);
  }
  /// `admit` for a sample already counted (add_all counts a run at once). O(1), RT-safe.
  static constexpr bool admit_counted(std::int64_t& value, std::uint64_t& negative,
                                      std::uint64_t& overflow) noexcept {
    if (value < 0) [[unlikely]] {
      ++negative;
      value = 0;
    }
    if (value > kMaxTrackable) [[unlikely]] {
      ++overflow;
      return false;
    }
    return true;
  }

  /// Adds every count of `other` to this one: the result equals a histogram that was given
  /// the samples of both. O(kBucketCount), RT-safe.
  constexpr void merge(const LogLinearHistogram& other) noexcept {
    for (std::size_t i = 0; i < kBucketCount; ++i) counts_[i] += other.counts_[i];
    count_ += other.count_;
    negative_ += other.negative_;
    overflow_ += other.overflow_;
  }

  /// Forgets every sample. O(kBucketCount), RT-safe.
  constexpr void reset() noexcept { *this = LogLinearHistogram{}; }

  /// Number of samples added, including negative and overflowed ones. O(1).
  [[nodiscard]] constexpr std::uint64_t count() const noexcept { return count_; }
  /// Number of negative samples (counted as 0). O(1).
  [[nodiscard]] constexpr std::uint64_t negative_count() const noexcept { return negative_; }
  /// Number of samples above kMaxTrackable (in no bucket). O(1).
  [[nodiscard]] constexpr std::uint64_t overflow_count() const noexcept { return overflow_; }
  /// Samples counted by bucket `index` (< kBucketCount), e.g. for exporters. O(1).
  [[nodiscard]] constexpr std::uint64_t count_at(std::size_t index) const noexcept {
    return counts_[index];
  }

  /**
   * The range that holds the q-quantile (nearest rank) of the samples: the bounds of its
   * bucket, [2^E, kOverflowValue] if it is an overflowed sample, {0, 0} when empty.
   *
   * `q` is clamped to [0, 1] (NaN counts as 0); q = 0 gives the minimum's bucket, q = 1 the
   * maximum's; with one sample every q gives that sample's bucket. O(kBucketCount) at worst:
   * it scans from the nearer end, so high quantiles of a low-latency stream are quick. RT-safe.
   */
  [[nodiscard]] HistogramRange quantile(double q) const noexcept {
    if (count_ == 0) return {};
    constexpr HistogramRange kOverflowRange{kMaxTrackable + 1, kOverflowValue};
    const std::uint64_t rank = detail::nearest_rank(q, count_);
    if (rank <= count_ / 2) {
      std::uint64_t seen = 0;
      for (std::size_t i = 0; i < kBucketCount; ++i) {
        seen += counts_[i];
        if (seen >= rank) return {bucket_lowest(i), bucket_highest(i)};
      }
      return kOverflowRange;
    }
    // From the top: the bucket holding rank r is the first whose count, added to the samples
    // above it, exceeds count - r.
    const std::uint64_t above_rank = count_ - rank;
    std::uint64_t seen = overflow_;
    if (seen > above_rank) return kOverflowRange;
    for (std::size_t i = kBucketCount; i-- > 0;) {
      seen += counts_[i];
      if (seen > above_rank) return {bucket_lowest(i), bucket_highest(i)};
    }
    return {0, 0};  // not reached: the buckets and overflow hold count_ samples
  }

  /**
   * Several quantiles in one pass: `out[k]` = value_at_quantile(qs[k]) for ascending `qs`.
   * Scans only buckets `first`..`last`, which must hold every tracked sample (a caller that
   * knows its minimum and maximum passes their bucket indexes: a few buckets instead of all).
   * RT-safe; O(last - first + K).
   */
  template <std::size_t K>
  void values_at_quantiles(const std::array<double, K>& qs, std::array<std::int64_t, K>& out,
                           std::size_t first = 0,
                           std::size_t last = kBucketCount - 1) const noexcept {
    out.fill(0);
    if (count_ == 0) return;
    std::array<std::uint64_t, K> ranks{};
    for (std::size_t k = 0; k < K; ++k) ranks[k] = detail::nearest_rank(qs[k], count_);
    std::size_t k = 0;
    std::uint64_t seen = 0;
    for (std::size_t i = first; i <= last && i < kBucketCount && k < K; ++i) {
      seen += counts_[i];
      while (k < K && seen >= ranks[k]) out[k++] = bucket_highest(i);
    }
    for (; k < K; ++k) out[k] = kOverflowValue;  // among the overflowed samples
  }

  /// The q-quantile (nearest rank) as one value: `quantile(q).highest`, an upper bound with
  /// relative error < 2^-S for tracked values, exact below kExactLimit; kOverflowValue when it
  /// falls among overflowed samples; 0 when empty. Same q rules and cost as `quantile`.
  [[nodiscard]] std::int64_t value_at_quantile(double q) const noexcept {
    return quantile(q).highest;
  }

 private:
  std::array<std::uint64_t, kBucketCount> counts_{};
  std::uint64_t count_ = 0;
  std::uint64_t negative_ = 0;
  std::uint64_t overflow_ = 0;
};

// The supervisor keeps several of these per component: its size is part of the design.
static_assert(sizeof(LogLinearHistogram<>) == 1152 * 8 + 3 * 8,
              "LogLinearHistogram<> should be 9240 bytes (1152 uint64 counters + 3 counters)");
static_assert(std::is_trivially_copyable_v<LogLinearHistogram<>>);

}  // namespace vigil::supervisor
