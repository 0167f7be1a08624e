#pragma once
/// @file
/// `RunningStats`: the statistics the supervisor keeps for one measured quantity of one
/// component (cycle time, user time, period...), and `StatsSummary`, its plain-value snapshot.
///
/// Design: everything lives inline (a `LogLinearHistogram<>` plus a few scalars: 9312 bytes), so
/// `add()` is a handful of instructions on memory the supervisor thread owns: no allocation,
/// no lock, no virtual call. `CompactRunningStats` is the same with a `CompactHistogram` (the
/// buckets of the seen range only, on the heap: 120 bytes inline), for the supervisor's
/// per-component records, where thousands of 9 KiB histograms would not stay in the caches. Readers
/// in other threads get copies (`summary()` or the whole object, which is trivially copyable)
/// through whatever hand-over the Registry uses.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/compact_histogram.hpp"
#include "vigil/supervisor/histogram.hpp"

namespace vigil::supervisor {

/**
 * A snapshot of `RunningStats`, trivially copyable and 80 bytes, for reports and exporters.
 *
 * With no samples every field is 0. Percentiles are nearest-rank upper bounds with relative
 * error < 1/32 (see `RunningStats`).
 */
struct StatsSummary {
  std::uint64_t count = 0;  ///< samples seen
  Nanos last = 0;           ///< most recent sample
  Nanos min = 0;            ///< smallest sample (exact)
  Nanos max = 0;            ///< largest sample (exact)
  double mean = 0.0;        ///< arithmetic mean (exact sum / count, rounded to double)
  double ewma = 0.0;        ///< exponentially weighted moving average
  Nanos p50 = 0;            ///< median
  Nanos p90 = 0;            ///< 90th percentile
  Nanos p99 = 0;            ///< 99th percentile
  Nanos p999 = 0;           ///< 99.9th percentile

  friend constexpr bool operator==(const StatsSummary&, const StatsSummary&) = default;
};
static_assert(std::is_trivially_copyable_v<StatsSummary> && sizeof(StatsSummary) == 80);

namespace detail {

/// An exact signed 128-bit sum of int64 values, in two words (portable: no `__int128`, which
/// 32-bit ARM lacks and -Wpedantic rejects). Two's complement: value = hi * 2^64 + lo.
struct WideSum {
  std::uint64_t lo = 0;
  std::uint64_t hi = 0;  // the signed high word, kept unsigned so that wrap-around is defined

  constexpr void add(std::int64_t v) noexcept {
    const auto u = static_cast<std::uint64_t>(v);
    lo += u;
    hi += (lo < u ? 1U : 0U) + (v < 0 ? ~std::uint64_t{0} : 0U);  // carry + sign extension
  }

  constexpr void add(const WideSum& other) noexcept {
    lo += other.lo;
    hi += other.hi + (lo < other.lo ? 1U : 0U);
  }

  /// The sum rounded to double: one rounding while it fits in int64, at most three beyond.
  [[nodiscard]] constexpr double to_double() const noexcept {
    const bool fits = (hi == 0 && lo >> 63 == 0) || (hi == ~std::uint64_t{0} && lo >> 63 == 1);
    // Converting the two words separately would cancel catastrophically for small negative
    // sums (hi = -1, lo ~ 2^64), hence the exact path.
    if (fits) return static_cast<double>(static_cast<std::int64_t>(lo));
    return static_cast<double>(static_cast<std::int64_t>(hi)) * 0x1p64 + static_cast<double>(lo);
  }
};

}  // namespace detail

/// Default weight of the newest sample in every EWMA vigil keeps (`RunningStats`,
/// `AggregatorOptions::ewma_weight`, a deployment's `supervision.ewma_weight`, CAN statistics):
/// 0.05, so a change of level is followed within about 1 / 0.05 = 20 samples. The one place this
/// default is stated.
inline constexpr double kDefaultEwmaWeight = 0.05;

/**
 * The histogram-free part of `RunningStats`: count, last, min, max, an exact mean and an EWMA of
 * a stream of nanosecond values, in 72 bytes. `RunningStats` is this plus a histogram; use this
 * alone where percentiles come from elsewhere (the aggregator's total time).
 *
 * Precision, thread-safety and RT-safety: as `RunningStats` (every member is allocation-free,
 * lock-free, noexcept and O(1)).
 */
class ScalarStats {
 public:
  /// Counts sample `value` (a duration in ns). O(1), allocation-free, RT-safe.
  constexpr void add(Nanos value) noexcept {
    if (count_ == 0) [[unlikely]] {
      first_ = value;
      ewma_ = static_cast<double>(value);
    } else {
      ewma_ += ewma_weight_ * (static_cast<double>(value) - ewma_);
    }
    ++count_;
    last_ = value;
    min_ = value < min_ ? value : min_;
    max_ = value > max_ ? value : max_;
    sum_.add(value);
  }

  /// Counts `n` samples, oldest first: the same result as add() on each, bit for bit (the same
  /// operations in the same order), with the state in registers across the run. O(n),
  /// allocation-free, RT-safe.
  [[gnu::always_inline]] constexpr void add_all(const Nanos* values, std::size_t n) noexcept {
    if (n == 0) return;
    std::size_t i = 0;
    if (count_ == 0) {
      add(values[0]);
      i = 1;
    }
    const std::size_t rest = n - i;  // add() counted the first one
    double e = ewma_;
    const double w = ewma_weight_;
    Nanos lo = min_;
    Nanos hi = max_;
    detail::WideSum sum = sum_;
    for (; i < n; ++i) {
      const Nanos v = values[i];
      e += w * (static_cast<double>(v) - e);
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
      sum.add(v);
    }
    count_ += rest;
    ewma_ = e;
    min_ = lo;
    max_ = hi;
    sum_ = sum;
    last_ = values[n - 1];
  }

  /// The smallest and largest of a run of values (lo > hi: an empty run).
  struct RunRange {
    Nanos lo = std::numeric_limits<Nanos>::max();
    Nanos hi = std::numeric_limits<Nanos>::min();
  };
  static constexpr void widen(RunRange& r, Nanos v) noexcept {
    r.lo = v < r.lo ? v : r.lo;
    r.hi = v > r.hi ? v : r.hi;
  }

  /// Counts runs of samples into K statistics at once: stats[k] gets values[k][0 .. n[k]), as
  /// add_all() on each would (bit for bit), with their EWMA chains interleaved, so that each
  /// addition waits only for the previous one of its own statistic. Returns each run's range
  /// (what a histogram needs to know to skip its per-sample range checks). O(sum of n), RT-safe.
  template <std::size_t K>
  [[gnu::always_inline]] static std::array<RunRange, K> add_all(
      const std::array<ScalarStats*, K>& stats, const std::array<const Nanos*, K>& values,
      const std::array<std::size_t, K>& n) noexcept {
    std::array<RunRange, K> range{};
    std::array<std::size_t, K> at{};
    std::size_t common = std::numeric_limits<std::size_t>::max();
    for (std::size_t k = 0; k < K; ++k) {
      if (n[k] > 0 && stats[k]->count_ == 0) {
        stats[k]->add(values[k][0]);
        at[k] = 1;
      }
      common = std::min(common, n[k] - at[k]);
    }
    if (common > 0) {
      std::array<double, K> e;
      std::array<double, K> w;
      std::array<detail::WideSum, K> sum;
      for (std::size_t k = 0; k < K; ++k) {
        e[k] = stats[k]->ewma_;
        w[k] = stats[k]->ewma_weight_;
        sum[k] = stats[k]->sum_;
      }
      // In blocks of kBlock: each block's sum in one 64-bit word (no carry to propagate per
      // sample), exact when the block's values are within +-2^56 (kBlock of them cannot reach
      // 2^62); otherwise that block is summed again into the wide sum, value by value.
      constexpr std::size_t kBlock = 64;
      constexpr Nanos kSafe = Nanos{1} << 56;
      for (std::size_t j0 = 0; j0 < common; j0 += kBlock) {
        const std::size_t j1 = std::min(common, j0 + kBlock);
        std::array<std::uint64_t, K> block_sum{};
        std::array<RunRange, K> block{};
        for (std::size_t j = j0; j < j1; ++j) {
#pragma GCC unroll 8
          for (std::size_t k = 0; k < K; ++k) {
            const Nanos v = values[k][at[k] + j];
            e[k] += w[k] * (static_cast<double>(v) - e[k]);
            widen(block[k], v);
            block_sum[k] += static_cast<std::uint64_t>(v);  // wraps harmlessly if unsafe
          }
        }
        for (std::size_t k = 0; k < K; ++k) {
          if (block[k].lo >= -kSafe && block[k].hi <= kSafe) [[likely]] {
            sum[k].add(static_cast<std::int64_t>(block_sum[k]));
          } else {
            for (std::size_t j = j0; j < j1; ++j) sum[k].add(values[k][at[k] + j]);
          }
          range[k].lo = std::min(range[k].lo, block[k].lo);
          range[k].hi = std::max(range[k].hi, block[k].hi);
        }
      }
      for (std::size_t k = 0; k < K; ++k) {
        ScalarStats& t = *stats[k];
        t.count_ += common;
        t.ewma_ = e[k];
        t.min_ = std::min(t.min_, range[k].lo);
        t.max_ = std::max(t.max_, range[k].hi);
        t.sum_ = sum[k];
        t.last_ = values[k][at[k] + common - 1];
      }
    }
    for (std::size_t k = 0; k < K; ++k) {
      const std::size_t done = at[k] + common;
      stats[k]->add_all(values[k] + done, n[k] - done);
      // The values outside the common part (a first one, a longer run's tail) in the range too.
      for (std::size_t j = 0; j < at[k]; ++j) widen(range[k], values[k][j]);
      for (std::size_t j = done; j < n[k]; ++j) widen(range[k], values[k][j]);
    }
    return range;
  }

  /// Merges `other` as if its samples had been added after this one's (see RunningStats::merge).
  void merge(const ScalarStats& other) noexcept {
    if (other.count_ == 0) return;
    if (count_ == 0) {
      const double weight = ewma_weight_;
      *this = other;
      ewma_weight_ = weight;
      return;
    }
    // The EWMA recursion is linear in its start value: other's stream began at first_other
    // instead of at our EWMA, and that difference decays by (1 - alpha) per sample.
    const double decay = std::pow(1.0 - ewma_weight_, static_cast<double>(other.count_));
    ewma_ = other.ewma_ + decay * (ewma_ - static_cast<double>(other.first_));
    count_ += other.count_;
    last_ = other.last_;
    min_ = other.min_ < min_ ? other.min_ : min_;
    max_ = other.max_ > max_ ? other.max_ : max_;
    sum_.add(other.sum_);
  }

  /// Forgets every sample; keeps the EWMA weight.
  constexpr void reset() noexcept {
    const double weight = ewma_weight_;
    *this = ScalarStats{};
    ewma_weight_ = weight;
  }

  /// Sets the EWMA weight alpha of the samples to come (the current EWMA is kept). Returns false
  /// and changes nothing unless 0 < alpha <= 1.
  [[nodiscard]] constexpr bool set_ewma_weight(double alpha) noexcept {
    if (!(alpha > 0.0 && alpha <= 1.0)) return false;  // also rejects NaN
    ewma_weight_ = alpha;
    return true;
  }

  [[nodiscard]] constexpr double ewma_weight() const noexcept { return ewma_weight_; }
  [[nodiscard]] constexpr std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] constexpr Nanos last() const noexcept { return last_; }
  [[nodiscard]] constexpr Nanos min() const noexcept { return count_ == 0 ? 0 : min_; }
  [[nodiscard]] constexpr Nanos max() const noexcept { return count_ == 0 ? 0 : max_; }
  [[nodiscard]] constexpr double mean() const noexcept {
    return count_ == 0 ? 0.0 : sum_.to_double() / static_cast<double>(count_);
  }
  [[nodiscard]] constexpr double ewma() const noexcept { return ewma_; }

  /// count, last, min, max, mean and ewma; the percentiles are 0 (this keeps no histogram).
  [[nodiscard]] constexpr StatsSummary summary() const noexcept {
    if (count_ == 0) return {};
    return StatsSummary{.count = count_,
                        .last = last_,
                        .min = min_,
                        .max = max_,
                        .mean = mean(),
                        .ewma = ewma_,
                        .p50 = 0,
                        .p90 = 0,
                        .p99 = 0,
                        .p999 = 0};
  }

 private:
  std::uint64_t count_ = 0;
  Nanos last_ = 0;
  Nanos min_ = std::numeric_limits<Nanos>::max();  // sentinels make add() branch-free
  Nanos max_ = std::numeric_limits<Nanos>::min();
  Nanos first_ = 0;  // for merge(): where the EWMA of this stream started
  double ewma_ = 0.0;
  double ewma_weight_ = kDefaultEwmaWeight;
  detail::WideSum sum_;
};

static_assert(std::is_trivially_copyable_v<ScalarStats> && sizeof(ScalarStats) == 72);

/**
 * Running statistics of a stream of nanosecond values: count, last, min, max, mean, an EWMA
 * (`ScalarStats`) and a `LogLinearHistogram<>` for percentiles.
 *
 * Precision:
 *  - count, last, min, max are exact; the sum behind `mean()` is exact (128 bits), so the mean
 *    is the exact mean rounded to double within a few ulp (relative error < 1e-15);
 *  - `ewma()`: e = x1 for the first sample, then e += alpha * (x - e) in double;
 *  - percentiles: the nearest-rank q-quantile x (smallest sample with at least q * count
 *    samples <= x), reported as an upper bound: x <= reported <= x + (x >> 5), i.e. relative
 *    error < 2^-5 = 3.125 %, exact for x < 64 ns; never above `max()`, so q = 1 gives the exact
 *    maximum. Valid for samples in [0, 2^40) ns (18.3 min). Negative samples count as 0 in the
 *    histogram (min/max/mean/last/EWMA use them as they are); a quantile that falls among
 *    samples >= 2^40 reports `max()`.
 *
 * With no samples, every accessor returns 0. With one sample s, every statistic and every
 * percentile is exactly s (the bucket's upper bound is clamped to max = s).
 *
 * Thread-safety: none; one writer (the supervisor thread). RT-safety: every member is
 * allocation-free, lock-free and noexcept; `add()` is O(1) (a few ns), `merge`, `reset` and
 * the percentile accessors are O(buckets) (~1k steps at worst).
 *
 * `BasicRunningStats<H>` is this for any histogram type with LogLinearHistogram's interface:
 * `RunningStats` (a fixed `LogLinearHistogram<5, 40>`, 9,312 bytes, trivially copyable, every
 * member RT-safe) and `CompactRunningStats` (a `CompactHistogram<5, 40>`: the same buckets
 * allocated for the seen range only, 120 bytes plus a few hundred on the heap; `add` allocates
 * while the range grows, so not RT-safe: the supervisor's per-component statistics). Both give
 * exactly the same values for the same samples.
 *
 * @code
 * vigil::RunningStats cycle;
 * cycle.add(sample.end_ns - sample.start_ns);         // per message, in the supervisor
 * const vigil::StatsSummary s = cycle.summary();      // per report
 * @endcode
 */
template <class H>
class BasicRunningStats {
 public:
  /// The histogram type: 5 sub-bucket bits, values up to 2^40 - 1 ns.
  using Histogram = H;
  /// Default EWMA weight (vigil::kDefaultEwmaWeight).
  static constexpr double kDefaultEwmaWeight = vigil::supervisor::kDefaultEwmaWeight;

  /// Counts sample `value` (a duration in ns). O(1), allocation-free, RT-safe.
  constexpr void add(Nanos value) noexcept {
    scalars_.add(value);
    histogram_.add(value);
  }
  /// Counts `n` samples, oldest first: the same result as add() on each. O(n); may allocate
  /// as add() may (CompactHistogram).
  [[gnu::always_inline]] constexpr void add_all(const Nanos* values, std::size_t n) noexcept {
    scalars_.add_all(values, n);
    Histogram::template add_all<1>({&histogram_}, {values}, {n});
  }
  /// Counts runs of samples into K statistics and L histogram-free ones at once: as add_all()
  /// on each, the K + L EWMA chains interleaved (ScalarStats::add_all). values and n: the K
  /// statistics' runs, then the L others'.
  template <std::size_t K, std::size_t L>
  [[gnu::always_inline]] static void add_all(const std::array<BasicRunningStats*, K>& stats,
                                             const std::array<ScalarStats*, L>& scalars,
                                             const std::array<const Nanos*, K + L>& values,
                                             const std::array<std::size_t, K + L>& n) noexcept {
    std::array<ScalarStats*, K + L> all;
    for (std::size_t k = 0; k < K; ++k) all[k] = &stats[k]->scalars_;
    for (std::size_t l = 0; l < L; ++l) all[K + l] = scalars[l];
    const auto range = ScalarStats::add_all<K + L>(all, values, n);
    // The histograms interleaved too: a run of samples in one bucket is a chain of increments
    // of one counter, which overlaps with the other histograms' chains. Runs known to be within
    // the histograms' range (the usual case) skip the per-sample checks.
    std::array<Histogram*, K> hs;
    std::array<const Nanos*, K> hv;
    std::array<std::size_t, K> hn;
    bool in_range = true;
    for (std::size_t k = 0; k < K; ++k) {
      hs[k] = &stats[k]->histogram_;
      hv[k] = values[k];
      hn[k] = n[k];
      in_range =
          in_range && (n[k] == 0 || (range[k].lo >= 0 && range[k].hi <= Histogram::kMaxTrackable));
    }
    Histogram::template add_all<K>(hs, hv, hn, in_range);
  }

  /**
   * Merges `other` into this object as if other's samples had been added after this one's:
   * count, min, max, mean and the histogram become exactly those of the combined stream,
   * `last` becomes other's last, and the EWMA is continued through other's samples:
   * e = e_other + (1 - alpha)^n_other * (e_this - first_other). The EWMA result is that of the
   * combined stream (up to rounding) when both use the same weight; this object's weight is
   * kept and used. O(buckets), allocation-free.
   */
  void merge(const BasicRunningStats& other) noexcept {
    if (other.count() == 0) return;
    scalars_.merge(other.scalars_);
    histogram_.merge(other.histogram_);
  }

  /// Forgets every sample; keeps the EWMA weight. O(buckets), allocation-free.
  constexpr void reset() noexcept {
    scalars_.reset();
    histogram_.reset();
  }

  /// Sets the EWMA weight alpha of the samples to come (the current EWMA is kept): a larger
  /// alpha follows changes faster. Returns false and changes nothing unless 0 < alpha <= 1.
  [[nodiscard]] constexpr bool set_ewma_weight(double alpha) noexcept {
    return scalars_.set_ewma_weight(alpha);
  }

  /// The EWMA weight alpha, in (0, 1].
  [[nodiscard]] constexpr double ewma_weight() const noexcept { return scalars_.ewma_weight(); }
  /// Number of samples. O(1).
  [[nodiscard]] constexpr std::uint64_t count() const noexcept { return scalars_.count(); }
  /// Most recent sample, 0 when empty. O(1).
  [[nodiscard]] constexpr Nanos last() const noexcept { return scalars_.last(); }
  /// Smallest sample, 0 when empty. O(1).
  [[nodiscard]] constexpr Nanos min() const noexcept { return scalars_.min(); }
  /// Largest sample, 0 when empty. O(1).
  [[nodiscard]] constexpr Nanos max() const noexcept { return scalars_.max(); }
  /// Arithmetic mean (relative error < 1e-15), 0 when empty. O(1).
  [[nodiscard]] constexpr double mean() const noexcept { return scalars_.mean(); }
  /// Exponentially weighted moving average, 0 when empty. O(1).
  [[nodiscard]] constexpr double ewma() const noexcept { return scalars_.ewma(); }
  /// The scalar statistics alone.
  [[nodiscard]] constexpr const ScalarStats& scalars() const noexcept { return scalars_; }

  /// The q-quantile (nearest rank) as an upper bound with relative error < 1/32, never above
  /// `max()`; 0 when empty. q is clamped to [0, 1]: q = 0 is the minimum's bucket, q = 1 the
  /// exact maximum. O(buckets).
  [[nodiscard]] Nanos value_at_quantile(double q) const noexcept {
    if (count() == 0) return 0;
    const Nanos v = histogram_.value_at_quantile(q);
    const Nanos max = scalars_.max();
    return v < max ? v : max;  // the true quantile is <= max: clamping only removes error
  }

  /// The histogram behind the percentiles, e.g. for exporters. O(1).
  [[nodiscard]] constexpr const Histogram& histogram() const noexcept { return histogram_; }

  /// Everything above as one value; all zeros when empty. Allocation-free; the four
  /// percentiles come from one pass over the buckets between the minimum's and the maximum's
  /// (typically a few dozen of the 1,152).
  [[nodiscard]] StatsSummary summary() const noexcept {
    StatsSummary s = scalars_.summary();
    if (s.count == 0) return s;
    static constexpr std::array<double, 4> kQs{0.5, 0.9, 0.99, 0.999};
    std::array<std::int64_t, 4> q{};
    const std::size_t first = Histogram::bucket_index(s.min > 0 ? s.min : 0);
    const std::size_t last = s.max > Histogram::kMaxTrackable
                                 ? Histogram::kBucketCount - 1
                                 : Histogram::bucket_index(s.max > 0 ? s.max : 0);
    histogram_.values_at_quantiles(kQs, q, first, last);
    for (auto& v : q) v = v < s.max ? v : s.max;  // the true quantile is <= max
    s.p50 = q[0];
    s.p90 = q[1];
    s.p99 = q[2];
    s.p999 = q[3];
    return s;
  }

 private:
  // Scalars first: add() touches them and one histogram counter, nothing else.
  ScalarStats scalars_;
  Histogram histogram_;
};

/// Running statistics with a fixed 1,152-bucket histogram: trivially copyable, RT-safe.
using RunningStats = BasicRunningStats<LogLinearHistogram<5, 40>>;
/// The same statistics with the buckets allocated for the seen range only (CompactHistogram):
/// what the supervisor keeps per component. `add` may allocate while the range grows.
using CompactRunningStats = BasicRunningStats<CompactHistogram<5, 40>>;

static_assert(std::is_trivially_copyable_v<RunningStats>);
static_assert(sizeof(RunningStats) == 72 + sizeof(RunningStats::Histogram),
              "RunningStats should be 9312 bytes: 72 bytes of scalars and the histogram");
static_assert(sizeof(CompactRunningStats) == 72 + 48,
              "CompactRunningStats should be 120 bytes: 72 bytes of scalars and the header");

}  // namespace vigil::supervisor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using supervisor::StatsSummary;
}  // namespace vigil
