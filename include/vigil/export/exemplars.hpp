#pragma once
/// @file
/// `ExemplarBook`: the exemplars of the OpenMetrics exposition (docs/reference/metrics.md,
/// "Exemplars"). Each bucket of a component's timing histograms that one of its worst cycles
/// fell into names that cycle, and the overrun counter names the latest overrun; each names the
/// flight-recorder trace that holds the cycle when one was frozen. A spike in a dashboard leads
/// to the Perfetto trace of those cycles.
///
/// Where the cycles come from: the aggregator keeps the worst cycle of each distribution per
/// window (`supervisor::WorstCycles`, taken with the statistics on the supervisor side), the
/// events carry the overrun cycles, and the kept flight records (`FlightRecord`) their cycles.
/// The book remembers, from one monitor cycle to the next, the latest exemplar of every bucket
/// (as a client library's histogram does): a bucket's exemplar is replaced only by a later
/// cycle (a higher cycle number), so each series' exemplars arrive in time order (Prometheus
/// drops older ones), and an exemplar kept is written the same way at every scrape.
///
/// Not RT-safe (allocates); one thread at a time (the publisher's).

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <vector>

#include "vigil/export/metrics_snapshot.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/events.hpp"
#include "vigil/supervisor/flight_recorder.hpp"

namespace vigil::exporter {

/// The bucket of `value_ns` among the fixed boundaries: the first i with value_ns <=
/// kBucketBoundsNs[i], or kBucketBounds (`+Inf`).
[[nodiscard]] std::uint8_t bucket_of(Nanos value_ns) noexcept;

/// The clocks an exemplar's time is converted with: a component's cycle times are on the
/// supervision clock (`Clock::system()`: monotonic, or the TSC calibrated to it), exemplars
/// carry Unix time.
struct ExemplarClock {
  Nanos monotonic_ns = 0;    ///< now, on the supervision clock
  std::int64_t unix_ns = 0;  ///< the same instant, Unix time
  /// Both read now.
  [[nodiscard]] static ExemplarClock now() noexcept;
  /// `t_ns` (monotonic) in Unix time.
  [[nodiscard]] std::int64_t to_unix(Nanos t_ns) const noexcept {
    return unix_ns - (monotonic_ns - t_ns);
  }
};

/// Keeps the exemplars of every component's buckets and overrun counter between monitor cycles.
class ExemplarBook {
 public:
  /// Takes one monitor cycle: the worst cycles in `histograms` (by component id) go into their
  /// buckets, the latest overrun (or overrun-limit) event of `events` into each component's
  /// overrun counter; exemplars without a trace get the newest of `frozen` that holds their
  /// cycle. Then writes every component's exemplars into `histograms` (`exemplars`, `overrun`).
  /// Components absent from `histograms` are forgotten.
  void update(std::vector<ComponentHistograms>& histograms, std::span<const Event> events,
              std::span<const std::shared_ptr<const supervisor::FlightRecord>> frozen,
              const ExemplarClock& clock);

  /// Components remembered.
  [[nodiscard]] std::size_t size() const noexcept { return components_.size(); }

 private:
  struct Component {
    std::vector<BucketExemplar> buckets;  // sorted by histogram, bucket
    CycleExemplar overrun;
  };
  std::map<std::uint32_t, Component> components_;
};

}  // namespace vigil::exporter
