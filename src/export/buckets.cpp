#include "vigil/export/buckets.hpp"

#include <algorithm>

namespace vigil::exporter {

namespace {

using Histogram = supervisor::RunningStats::Histogram;

template <class H>
BucketCounts reduce(const H& h, std::size_t first, std::size_t last, Nanos shift,
                    double sum_ns) noexcept {
  BucketCounts out;
  out.count = h.count();
  out.sum_ns = sum_ns;
  if (out.count == 0) return out;
  std::array<std::uint64_t, kBucketBounds> own{};  // per boundary, not yet cumulative
  std::size_t j = 0;                               // boundaries only grow with the bucket
  for (std::size_t i = first; i <= last && i < Histogram::kBucketCount; ++i) {
    const std::uint64_t c = h.count_at(i);
    if (c == 0) continue;
    const Nanos edge = Histogram::bucket_highest(i) + shift;
    while (j < kBucketBounds && kBucketBoundsNs[j] < edge) ++j;
    if (j == kBucketBounds) break;  // this bucket and all above: only in +Inf
    own[j] += c;
  }
  std::uint64_t running = 0;
  for (std::size_t k = 0; k < kBucketBounds; ++k) {
    running += own[k];
    out.cumulative[k] = running;
  }
  return out;
}

template <class Stats>
BucketCounts reduce_stats(const Stats& stats, Nanos shift_ns, double sum_ns) noexcept {
  if (stats.count() == 0) return BucketCounts{};
  const Nanos lo = std::max<Nanos>(stats.min(), 0);
  const Nanos hi = std::max<Nanos>(stats.max(), 0);
  const std::size_t first = Histogram::bucket_index(std::min(lo, Histogram::kMaxTrackable));
  const std::size_t last =
      hi > Histogram::kMaxTrackable ? Histogram::kBucketCount - 1 : Histogram::bucket_index(hi);
  const double sum = sum_ns >= 0 ? sum_ns : stats.mean() * static_cast<double>(stats.count());
  return reduce(stats.histogram(), first, last, shift_ns, sum);
}

}  // namespace

BucketCounts reduce_to_buckets(const supervisor::RunningStats& stats, Nanos shift_ns,
                               double sum_ns) noexcept {
  return reduce_stats(stats, shift_ns, sum_ns);
}

BucketCounts reduce_to_buckets(const supervisor::CompactRunningStats& stats, Nanos shift_ns,
                               double sum_ns) noexcept {
  return reduce_stats(stats, shift_ns, sum_ns);
}

BucketCounts reduce_to_buckets(const Histogram& histogram, double sum_ns, Nanos shift_ns) noexcept {
  return reduce(histogram, 0, Histogram::kBucketCount - 1, shift_ns, sum_ns);
}

BucketCounts reduce_samples_to_buckets(std::span<const Nanos> samples) noexcept {
  BucketCounts out;
  std::array<std::uint64_t, kBucketBounds> own{};
  long double sum = 0;
  for (const Nanos v : samples) {
    sum += static_cast<long double>(v);
    const auto it = std::lower_bound(kBucketBoundsNs.begin(), kBucketBoundsNs.end(), v);
    if (it != kBucketBoundsNs.end()) ++own[static_cast<std::size_t>(it - kBucketBoundsNs.begin())];
  }
  out.count = samples.size();
  out.sum_ns = static_cast<double>(sum);
  std::uint64_t running = 0;
  for (std::size_t k = 0; k < kBucketBounds; ++k) {
    running += own[k];
    out.cumulative[k] = running;
  }
  return out;
}

}  // namespace vigil::exporter
