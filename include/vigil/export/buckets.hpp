#pragma once
/// @file
/// Prometheus histogram buckets from vigil's log-linear histograms.
///
/// A `LogLinearHistogram<>` has 1,152 buckets of at most 3.1 % relative width: far too many time
/// series for a fleet. The exporter reduces it to one fixed set of `le` boundaries, 1, 1.5, 2,
/// 3, 5, 7 per decade from 1 µs to 10 s (43 boundaries, then +Inf), the same for every component
/// and every timing family so that fleets can aggregate them (`sum by (le)`).
///
/// Rule: a sample is counted under the smallest boundary >= the upper edge of its log-linear
/// bucket. The edges do not fall on decimal boundaries, so a sample within 3.1 % below a
/// boundary may be counted under the next one: like vigil's percentiles, the buckets never
/// under-state a duration. Samples above 2^40 ns (18 min) count only in +Inf. Everything is
/// exact apart from that: counts are cumulative, `+Inf` equals `count`.
///
/// Allocation-free; any thread.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/running_stats.hpp"

namespace vigil::exporter {

/// Number of finite `le` boundaries.
inline constexpr std::size_t kBucketBounds = 43;

/// The finite `le` boundaries in nanoseconds: 1, 1.5, 2, 3, 5, 7 per decade from 1 µs to 10 s
/// (neighbours at most 1.5 apart, so `histogram_quantile`'s interpolation stays within that).
inline constexpr std::array<Nanos, kBucketBounds> kBucketBoundsNs = [] {
  std::array<Nanos, kBucketBounds> b{};
  constexpr std::array<Nanos, 6> kSteps = {10, 15, 20, 30, 50, 70};  // x 100 ns
  Nanos decade = 100;                                                // 1 us = 10 x 100 ns
  std::size_t i = 0;
  for (int d = 0; d < 7; ++d, decade *= 10) {
    for (Nanos s : kSteps) b[i++] = s * decade;
  }
  b[i] = 10 * decade;  // 10 s
  return b;
}();
static_assert(kBucketBoundsNs.front() == 1'000 && kBucketBoundsNs.back() == 10'000'000'000);

/// One distribution as Prometheus wants it: cumulative counts at each boundary, the count
/// (the +Inf bucket) and the sum. Plain value, trivially copyable.
struct BucketCounts {
  /// cumulative[i] = samples counted at or below kBucketBoundsNs[i] (see the file comment).
  std::array<std::uint64_t, kBucketBounds> cumulative{};
  std::uint64_t count = 0;  ///< every sample: the +Inf bucket
  double sum_ns = 0.0;      ///< sum of the samples in nanoseconds (count * mean)

  friend bool operator==(const BucketCounts&, const BucketCounts&) = default;
};

/// Reduces `stats`' histogram to the fixed boundaries. `shift_ns` is added to every bucket's
/// upper edge first (total time: user time plus the latest overhead); `sum_ns` overrides the
/// sum when >= 0 (else count * mean). O(buckets between the minimum's and the maximum's).
/// Allocation-free; not thread-safe against writers of `stats`.
[[nodiscard]] BucketCounts reduce_to_buckets(const supervisor::RunningStats& stats,
                                             Nanos shift_ns = 0, double sum_ns = -1.0) noexcept;

/// The same for the supervisor's per-component statistics (same buckets, allocated for the seen
/// range only): identical results for identical samples.
[[nodiscard]] BucketCounts reduce_to_buckets(const supervisor::CompactRunningStats& stats,
                                             Nanos shift_ns = 0, double sum_ns = -1.0) noexcept;

/// The same from a bare histogram with a known sum. O(histogram buckets).
[[nodiscard]] BucketCounts reduce_to_buckets(const supervisor::RunningStats::Histogram& histogram,
                                             double sum_ns, Nanos shift_ns = 0) noexcept;

/// The same from every sample of a distribution (e.g. the CAN aggregator's exact mode): each
/// sample counts under the smallest boundary >= it, exactly; the sum is exact up to the double
/// rounding. O(samples x log boundaries). Allocation-free; any thread.
[[nodiscard]] BucketCounts reduce_samples_to_buckets(std::span<const Nanos> samples) noexcept;

}  // namespace vigil::exporter
