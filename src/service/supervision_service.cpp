#include "vigil/service/supervision_service.hpp"

#include <cstdio>
#include <exception>

#include "vigil/export/json_report.hpp"

namespace vigil::service {

namespace {

// The text summary (and detail views) on a FILE*: at stop, and after every cycle if asked.
class TextOutput final : public ReportOutput {
 public:
  TextOutput(std::FILE* out, bool every_cycle, bool details, ColorMode color)
      : out_(out), every_cycle_(every_cycle), details_(details), color_(color) {}
  void on_reports(const ReportSet& reports) override {
    if (!every_cycle_) return;
    print_summary(out_, reports, color_);
    std::fflush(out_);
  }
  void stop(const ReportSet& final_reports) override {
    print_summary(out_, final_reports, color_);
    if (details_) {
      std::fputc('\n', out_);
      print_details(out_, final_reports, color_);
    }
    std::fflush(out_);
  }

 private:
  std::FILE* out_;
  bool every_cycle_;
  bool details_;
  ColorMode color_;
};

// The final reports as a JSON file.
class JsonFileOutput final : public ReportOutput {
 public:
  JsonFileOutput(std::string path, int indent) : path_(std::move(path)), indent_(indent) {}
  void stop(const ReportSet& final_reports) override {
    const std::string text = to_json(final_reports, {.indent = indent_});
    std::FILE* f = std::fopen(path_.c_str(), "w");
    if (f == nullptr) {
      std::fprintf(stderr, "vigil: cannot write the JSON report to '%s'\n", path_.c_str());
      return;
    }
    const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
    if (std::fclose(f) != 0 || !ok) {
      std::fprintf(stderr, "vigil: writing the JSON report to '%s' failed\n", path_.c_str());
    }
  }

 private:
  std::string path_;
  int indent_;
};

// The HTTP server and/or the node-exporter textfile (exporter::MonitorExporter), published
// after every monitor cycle by the exporter's own subscription, and once more at stop with the
// final reports.
class ExporterOutput final : public ReportOutput {
 public:
  ExporterOutput(Monitor& monitor, const supervisor::ComponentAggregator& aggregator,
                 exporter::ExportOptions options, exporter::MonitorExporter*& slot)
      : monitor_(monitor), aggregator_(aggregator), options_(std::move(options)), slot_(slot) {}
  expected<void, Error> start() override {
    auto e = exporter::MonitorExporter::start(monitor_, &aggregator_, options_);
    if (!e) return unexpected(e.error());
    exporter_ = std::move(*e);
    slot_ = exporter_.get();
    return {};
  }
  void stop(const ReportSet& final_reports) override {
    if (exporter_ == nullptr) return;
    exporter_->publish(final_reports);
    slot_ = nullptr;
    exporter_.reset();
  }

 private:
  Monitor& monitor_;
  const supervisor::ComponentAggregator& aggregator_;
  exporter::ExportOptions options_;
  exporter::MonitorExporter*& slot_;
  std::unique_ptr<exporter::MonitorExporter> exporter_;
};

MonitorOptions monitor_options(const SupervisionServiceOptions& o) {
  MonitorOptions m = o.monitor;
  m.period_ns = o.monitor_period_ns;
  m.clock = o.clock;
  return m;
}

}  // namespace

SupervisionService::SupervisionService(SupervisionServiceOptions options)
    : options_(std::move(options)),
      registry_(options_.registry != nullptr ? *options_.registry : default_registry()),
      aggregator_(supervisor::AggregatorOptions{.ewma_weight = options_.ewma_weight,
                                                .clock = options_.clock}),
      supervisor_(registry_, aggregator_,
                  supervisor::SupervisorOptions{.period_ns = options_.supervisor_period_ns}),
      monitor_(aggregator_, monitor_options(options_)) {
  monitor_.set_supervisor(&supervisor_);
  if (options_.summary_file != nullptr) {
    outputs_.push_back(std::make_unique<TextOutput>(options_.summary_file,
                                                    options_.summary_every_cycle,
                                                    options_.details_at_stop, options_.color));
  }
  if (!options_.json_file.empty()) {
    outputs_.push_back(std::make_unique<JsonFileOutput>(options_.json_file, options_.json_indent));
  }
  if (options_.http.has_value() || !options_.prom_textfile.empty()) {
    outputs_.push_back(std::make_unique<ExporterOutput>(
        monitor_, aggregator_,
        exporter::ExportOptions{.http = options_.http,
                                .textfile = options_.prom_textfile,
                                .augment = [this](ReportSet& r) { r = contribute(r); },
                                .augment_metrics = {},
                                .events = true},
        exporter_));
  }
  monitor_subscription_ = monitor_.subscribe([this](const ReportSet& r) { publish(r); });
}

SupervisionService::~SupervisionService() {
  // stop() writes the final outputs (files, allocation): a failure there must not terminate
  // the process from a destructor; it was reported by the output itself.
  try {
    stop();
    monitor_.unsubscribe(monitor_subscription_);
  } catch (...) {  // NOLINT(bugprone-empty-catch)
  }
}

expected<void, Error> SupervisionService::start() {
  if (running_) return unexpected(Error{"the supervision service is already running"});
  std::size_t started = 0;
  for (; started < outputs_.size(); ++started) {
    if (auto r = outputs_[started]->start(); !r) {
      for (std::size_t i = 0; i < started; ++i) outputs_[i]->stop(ReportSet{});
      return r;
    }
  }
  if (auto r = supervisor_.start(); !r) {
    for (auto& o : outputs_) o->stop(ReportSet{});
    return r;
  }
  if (options_.monitor_thread) {
    if (auto r = monitor_.start(); !r) {
      supervisor_.stop();
      for (auto& o : outputs_) o->stop(ReportSet{});
      return r;
    }
  }
  running_ = true;
  stopped_ = false;
  return {};
}

ReportSet SupervisionService::stop() {
  if (!running_) return final_;
  supervisor_.stop();  // joins after a last full drain
  monitor_.stop();
  running_ = false;
  if (options_.final_cycle) {
    // The last cycle is published here, once, rather than through the monitor's subscription.
    monitor_.unsubscribe(monitor_subscription_);
    final_ = contribute(monitor_.step());
    monitor_subscription_ = monitor_.subscribe([this](const ReportSet& r) { publish(r); });
  } else {
    final_ = contribute(monitor_.latest());
  }
  std::vector<std::pair<std::uint64_t, Subscriber>> subscribers;
  {
    std::lock_guard lock(subscribers_mutex_);
    subscribers = subscribers_;
  }
  if (options_.final_cycle) {
    for (auto& [id, s] : subscribers) s(final_);
  }
  for (auto& o : outputs_) o->stop(final_);
  stopped_ = true;
  return final_;
}

ReportSet SupervisionService::step() {
  if (!supervisor_.running()) supervisor_.step();
  return contribute(monitor_.step());
}

ReportSet SupervisionService::reports() const { return contribute(monitor_.latest()); }

std::uint64_t SupervisionService::subscribe(Subscriber subscriber) {
  std::lock_guard lock(subscribers_mutex_);
  const std::uint64_t id = next_subscriber_++;
  subscribers_.emplace_back(id, std::move(subscriber));
  return id;
}

void SupervisionService::unsubscribe(std::uint64_t id) {
  std::lock_guard lock(subscribers_mutex_);
  std::erase_if(subscribers_, [id](const auto& s) { return s.first == id; });
}

ReportOutput& SupervisionService::add_output(std::unique_ptr<ReportOutput> output) {
  outputs_.push_back(std::move(output));
  return *outputs_.back();
}

void SupervisionService::add_contributor(Contributor contributor) {
  contributors_.push_back(std::move(contributor));
}

ReportSet SupervisionService::contribute(const ReportSet& monitor_reports) const {
  ReportSet r = monitor_reports;
  for (const auto& c : contributors_) c(r);
  return r;
}

void SupervisionService::publish(const ReportSet& monitor_reports) {
  std::vector<std::pair<std::uint64_t, Subscriber>> subscribers;
  {
    std::lock_guard lock(subscribers_mutex_);
    subscribers = subscribers_;
  }
  // Nobody listens: no copy, and contributors run only when someone asks (reports(), step()).
  if (subscribers.empty() && outputs_.empty()) return;
  const ReportSet r = contribute(monitor_reports);
  for (auto& [id, s] : subscribers) {
    try {
      s(r);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "vigil: a report subscriber threw: %s\n", e.what());
    } catch (...) {
      std::fprintf(stderr, "vigil: a report subscriber threw\n");
    }
  }
  for (auto& o : outputs_) o->on_reports(r);
}

}  // namespace vigil::service
