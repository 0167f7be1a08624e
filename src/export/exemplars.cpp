#include "vigil/export/exemplars.hpp"

#include <algorithm>
#include <chrono>

namespace vigil::exporter {

std::uint8_t bucket_of(Nanos value_ns) noexcept {
  const auto* it = std::lower_bound(kBucketBoundsNs.begin(), kBucketBoundsNs.end(), value_ns);
  return static_cast<std::uint8_t>(it - kBucketBoundsNs.begin());
}
static_assert(kBucketBounds < 255, "bucket indices (and +Inf) fit a byte");

ExemplarClock ExemplarClock::now() noexcept {
  ExemplarClock c;
  c.monotonic_ns = Clock::system().now();  // the clock the cycles are stamped with
  c.unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                  std::chrono::system_clock::now().time_since_epoch())
                  .count();
  return c;
}

namespace {

// The newest kept flight record of component `id` whose cycles include `cycle`: its event's
// sequence number, or 0.
std::uint64_t trace_of(std::span<const std::shared_ptr<const supervisor::FlightRecord>> frozen,
                       std::uint32_t id, std::uint64_t cycle) {
  for (auto it = frozen.rbegin(); it != frozen.rend(); ++it) {
    const supervisor::FlightRecord& r = **it;
    if (r.component_id != id || r.cycles.empty()) continue;
    if (r.cycles.front().cycle <= cycle && cycle <= r.cycles.back().cycle) return r.event.seq;
  }
  return 0;
}

}  // namespace

void ExemplarBook::update(std::vector<ComponentHistograms>& histograms,
                          std::span<const Event> events,
                          std::span<const std::shared_ptr<const supervisor::FlightRecord>> frozen,
                          const ExemplarClock& clock) {
  // Forget the components that are gone.
  std::vector<std::uint32_t> ids;
  ids.reserve(histograms.size());
  for (const ComponentHistograms& h : histograms) ids.push_back(h.id);
  std::sort(ids.begin(), ids.end());
  for (auto it = components_.begin(); it != components_.end();) {
    it = std::binary_search(ids.begin(), ids.end(), it->first) ? std::next(it)
                                                               : components_.erase(it);
  }
  for (ComponentHistograms& h : histograms) {
    Component& c = components_[h.id];
    // The worst cycles: the complete window first, then the one under way (later cycles).
    for (std::size_t k = 0; k < kTimingHistograms; ++k) {
      for (const supervisor::WorstCycle* w : {&h.worst[k].previous, &h.worst[k].current}) {
        if (w->cycle == 0) continue;
        BucketExemplar b;
        b.histogram = static_cast<TimingHistogram>(k);
        b.bucket = bucket_of(w->value_ns);
        b.exemplar.cycle = w->cycle;
        b.exemplar.value = static_cast<double>(w->value_ns) / 1e9;
        b.exemplar.unix_ns = clock.to_unix(w->start_ns);
        const auto at = std::lower_bound(
            c.buckets.begin(), c.buckets.end(), b,
            [](const BucketExemplar& x, const BucketExemplar& y) {
              return x.histogram != y.histogram ? x.histogram < y.histogram : x.bucket < y.bucket;
            });
        if (at != c.buckets.end() && at->histogram == b.histogram && at->bucket == b.bucket) {
          if (at->exemplar.cycle < b.exemplar.cycle) *at = b;
        } else {
          c.buckets.insert(at, b);
        }
      }
    }
    // Trace them: a flight record may have been frozen since the cycle became an exemplar.
    for (BucketExemplar& b : c.buckets) {
      if (b.exemplar.trace == 0) b.exemplar.trace = trace_of(frozen, h.id, b.exemplar.cycle);
    }
  }
  for (const Event& e : events) {
    if ((e.kind != EventKind::Overrun && e.kind != EventKind::OverrunLimit) || e.cycle == 0) {
      continue;
    }
    const auto it = components_.find(e.component_id);
    if (it == components_.end() || it->second.overrun.cycle >= e.cycle) continue;
    CycleExemplar& o = it->second.overrun;
    o.cycle = e.cycle;
    o.value = 1;
    o.unix_ns = e.fault_ns > 0 ? clock.to_unix(e.fault_ns) : 0;
    o.trace = e.traced ? e.seq : 0;
  }
  for (ComponentHistograms& h : histograms) {
    Component& c = components_[h.id];
    if (c.overrun.cycle != 0 && c.overrun.trace == 0) {
      c.overrun.trace = trace_of(frozen, h.id, c.overrun.cycle);
    }
    h.exemplars = c.buckets;
    h.overrun = c.overrun;
  }
}

}  // namespace vigil::exporter
