#include "vigil/export/http_service.hpp"

#include <algorithm>
#include <chrono>

#include "vigil/export/textfile.hpp"
#include "vigil/export/trace_event.hpp"

namespace vigil::exporter {

MonitorExporter::MonitorExporter(Monitor& monitor,
                                 const supervisor::ComponentAggregator* aggregator,
                                 ExportOptions options)
    : monitor_(monitor), aggregator_(aggregator), options_(std::move(options)) {}

expected<std::unique_ptr<MonitorExporter>, Error> MonitorExporter::start(
    Monitor& monitor, const supervisor::ComponentAggregator* aggregator, ExportOptions options) {
  std::unique_ptr<MonitorExporter> e(new MonitorExporter(monitor, aggregator, std::move(options)));
  if (e->options_.http) {
    if (aggregator != nullptr && e->options_.events) {
      HttpOptions& h = *e->options_.http;
      if (h.events == nullptr) h.events = &aggregator->events();
      if (!h.trace) {
        h.trace = [aggregator](const std::string& name) -> std::optional<std::string> {
          auto r = aggregator->flight_record(name);
          if (!r) return std::nullopt;
          return trace_event_json(*r);
        };
      }
    }
    e->http_ = std::make_unique<HttpServer>(*e->options_.http);
    if (auto ok = e->http_->start(); !ok) return vigil::unexpected(ok.error());
  }
  // The callback may still run on the monitor's thread while the exporter is destroyed: it
  // reaches the exporter through `link_`, which the destructor clears under its mutex.
  e->link_ = std::make_shared<Link>();
  e->link_->self = e.get();
  e->subscription_ = monitor.subscribe([link = e->link_](const ReportSet& r) {
    std::lock_guard lock(link->mutex);
    if (link->self != nullptr) link->self->on_cycle(r);
  });
  // Serve something at once: the latest cycle (empty before the monitor's first).
  if (const ReportSet latest = monitor.latest(); latest.cycle > 0) e->on_cycle(latest);
  return e;
}

MonitorExporter::~MonitorExporter() {
  monitor_.unsubscribe(subscription_);
  if (link_) {
    std::lock_guard lock(link_->mutex);  // waits for a callback in progress
    link_->self = nullptr;
  }
  if (http_) http_->stop();
}

void MonitorExporter::on_cycle(const ReportSet& reports) {
  if (!options_.augment && !options_.augment_metrics) {
    publish(reports);
    return;
  }
  ReportSet copy = reports;
  std::vector<CanHistograms> can;
  if (options_.augment) options_.augment(copy);
  if (options_.augment_metrics) options_.augment_metrics(copy, can);
  publish(copy, std::move(can));
}

void MonitorExporter::publish(const ReportSet& reports, std::vector<CanHistograms> can_histograms) {
  std::lock_guard lock(mutex_);
  std::vector<ComponentHistograms> histograms;
  if (aggregator_ != nullptr) histograms = collect_histograms(*aggregator_);
  std::shared_ptr<const MetricsSnapshot> snap;
  if (http_) {
    http_->publish(reports, std::move(histograms), std::move(can_histograms));
    snap = http_->snapshot();
  } else if (!options_.textfile.empty()) {
    auto s = std::make_shared<MetricsSnapshot>();
    s->reports = reports;
    s->histograms = std::move(histograms);
    s->can_histograms = std::move(can_histograms);
    std::sort(s->can_histograms.begin(), s->can_histograms.end(),
              [](const auto& a, const auto& b) { return a.name < b.name; });
    s->wall_time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
    snap = std::move(s);
  }
  if (!options_.textfile.empty() && snap) {
    auto ok = write_textfile(options_.textfile, *snap);
    textfile_error_ = ok ? std::string() : ok.error().message;
  }
}

std::string MonitorExporter::textfile_error() const {
  std::lock_guard lock(mutex_);
  return textfile_error_;
}

}  // namespace vigil::exporter
