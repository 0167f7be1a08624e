#include "vigil/export/metrics_snapshot.hpp"

#include <algorithm>

#include "vigil/assert.hpp"
#include "vigil/can/can_monitor.hpp"

namespace vigil::exporter {

std::vector<ComponentHistograms> collect_histograms(
    const supervisor::ComponentAggregator& aggregator) {
  std::vector<ComponentHistograms> out;
  out.reserve(aggregator.size());
  aggregator.visit_distributions([&](const supervisor::ComponentDistributions& d) {
    ComponentHistograms h;
    h.id = d.id;
    h.name = std::string(d.name);
    h.execution = reduce_to_buckets(*d.execution);
    h.total = reduce_to_buckets(*d.execution, d.total_shift_ns,
                                d.total.mean * static_cast<double>(d.total.count));
    h.latency = reduce_to_buckets(*d.latency);
    h.measured_period = reduce_to_buckets(*d.measured_period);
    h.worst = {d.execution_worst, d.total_worst, d.latency_worst, d.measured_period_worst};
    out.push_back(std::move(h));
  });
  // visit_distributions() visits in id order: nothing to sort.
  VIGIL_ASSERT(std::is_sorted(out.begin(), out.end(),
                              [](const auto& a, const auto& b) { return a.id < b.id; }),
               "visit_distributions() visited out of id order");
  return out;
}

HistoryFrame make_history_frame(const ReportSet& reports) {
  HistoryFrame f;
  f.cycle = reports.cycle;
  f.time_ns = reports.time_ns;
  for (const Report& r : reports.components) {
    if (r.kind != ReportKind::Component) continue;
    f.points.push_back(HistoryPoint{.name = r.name,
                                    .execution_p99_ns = r.execution_ns.p99,
                                    .latency_p99_ns = r.latency_ns.p99,
                                    .overruns = r.counters.overruns,
                                    .window_overruns = r.window.overruns,
                                    .status = r.status.level()});
  }
  return f;
}

const ComponentHistograms* MetricsSnapshot::histograms_of(const Report& report) const noexcept {
  if (report.kind != ReportKind::Component) return nullptr;
  const auto it =
      std::lower_bound(histograms.begin(), histograms.end(), report.id,
                       [](const ComponentHistograms& h, std::uint32_t id) { return h.id < id; });
  if (it == histograms.end() || it->id != report.id || it->name != report.name) return nullptr;
  return &*it;
}

const CanHistograms* MetricsSnapshot::can_histograms_of(const Report& report) const noexcept {
  const bool group = report.is_unit(can::kGroupUnit);
  if (!group && !report.is_unit(can::kNodeUnit)) return nullptr;
  const auto it = std::lower_bound(
      can_histograms.begin(), can_histograms.end(), report.name,
      [](const CanHistograms& h, const std::string& name) { return h.name < name; });
  if (it == can_histograms.end() || it->name != report.name || it->group != group) {
    return nullptr;
  }
  return &*it;
}

const CanBusLoads* MetricsSnapshot::can_bus_of(const Report& report) const noexcept {
  if (!report.is_unit(can::kBusUnit)) return nullptr;
  const auto it =
      std::lower_bound(can_buses.begin(), can_buses.end(), report.name,
                       [](const CanBusLoads& b, const std::string& name) { return b.name < name; });
  if (it == can_buses.end() || it->name != report.name) return nullptr;
  return &*it;
}

BucketCounts reduce_to_buckets(const can::GapDistribution& distribution) noexcept {
  if (distribution.stats != nullptr) return reduce_to_buckets(*distribution.stats);
  return reduce_samples_to_buckets(distribution.samples);
}

}  // namespace vigil::exporter
