#include "vigil/service/supervision_service.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <exception>

#include "vigil/export/metrics_snapshot.hpp"
#include "vigil/service/health_units.hpp"
#include "vigil/service/thread_units.hpp"

namespace vigil::service {

namespace {

supervisor::AggregatorOptions aggregator_options(const SupervisionServiceOptions& o) {
  supervisor::AggregatorOptions a = o.aggregator;
  a.ewma_weight = o.ewma_weight;
  a.clock = o.clock;
  return a;
}

supervisor::DrainOptions supervisor_options(const SupervisionServiceOptions& o) {
  supervisor::DrainOptions s = o.supervisor;
  s.period_ns = o.supervisor_period_ns;
  return s;
}

MonitorOptions monitor_options(const SupervisionServiceOptions& o) {
  MonitorOptions m = o.monitor;
  m.period_ns = o.monitor_period_ns;
  m.clock = o.clock;
  return m;
}

std::unique_ptr<Source> make_source(const SupervisionServiceOptions& o, ComponentRegistry& registry,
                                    supervisor::ComponentAggregator& aggregator) {
  if (o.segments) {
    SegmentSourceOptions s = *o.segments;
    s.period_ns = o.supervisor_period_ns;
    return std::make_unique<SegmentSource>(std::move(s), aggregator);
  }
  return std::make_unique<RegistrySource>(registry, aggregator, supervisor_options(o));
}

// Runs `f`, saying on stderr what it threw: one part's failure must not stop the pipeline.
template <class F>
void guarded(const char* what, F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vigil: %s threw: %s\n", what, e.what());
  } catch (...) {
    std::fprintf(stderr, "vigil: %s threw\n", what);
  }
}

}  // namespace

SupervisionService::SupervisionService(SupervisionServiceOptions options)
    : options_(std::move(options)),
      registry_(options_.registry != nullptr ? *options_.registry : default_registry()),
      aggregator_(aggregator_options(options_)),
      source_(make_source(options_, registry_, aggregator_)),
      monitor_(aggregator_, monitor_options(options_)),
      latest_(std::make_shared<const exporter::Snapshot>()) {
  if (auto* s = supervisor(); s != nullptr) monitor_.set_supervisor(s);
  if (auto* s = segments(); s != nullptr) add_contributor(*s);
  // The supervisor's half of the threads' cross-check (on_cycle() has the monitor's).
  aggregator_.set_cycle_hook([this](Nanos now) { watch_monitor(now); });
  // Health supervisions as units (none until `aggregator().supervise_health()` is called).
  add_contributor(std::make_unique<HealthUnits>(aggregator_));
  // Threads shared by several components, as units their components depend on.
  add_contributor(std::make_unique<ThreadUnits>());
  if (options_.summary_file != nullptr) {
    add_output<exporter::TextOutput>(
        exporter::TextOutputOptions{.file = options_.summary_file,
                                    .every_cycle = options_.summary_every_cycle,
                                    .details_at_stop = options_.details_at_stop,
                                    .color = options_.color});
  }
  if (!options_.json_file.empty()) {
    add_output<exporter::JsonFileOutput>(options_.json_file, options_.json_indent);
  }
  if (options_.http.has_value()) http_ = &add_output<exporter::HttpOutput>(*options_.http);
  if (!options_.prom_textfile.empty()) {
    add_output<exporter::TextfileOutput>(options_.prom_textfile);
  }
  if (options_.systemd_notify) {
    exporter::SystemdEnvironment env =
        options_.systemd_environment.value_or(exporter::SystemdEnvironment::from_process());
    if (env.notify_socket) {
      systemd_ = &add_output<exporter::SystemdNotifyOutput>(exporter::SystemdNotifyOptions{
          .environment = std::move(env), .monitor_period_ns = options_.monitor_period_ns});
    }
  }
  // The buckets are read at the start of each monitor cycle, just before the monitor copies the
  // aggregator's snapshots: the outputs get the reports and the buckets of the same cycle.
  histogram_hook_ = monitor_.add_cycle_hook([this] {
    if (!outputs_.empty()) cycle_histograms_ = exporter::collect_histograms(aggregator_);
  });
  monitor_subscription_ = monitor_.subscribe([this](const ReportSet& r) { on_cycle(r); });
}

SupervisionService::~SupervisionService() {
  // stop() writes the final outputs (files, allocation): a failure there must not terminate
  // the process from a destructor; it was reported by the output itself.
  try {
    stop();
    monitor_.unsubscribe(monitor_subscription_);
    monitor_.remove_cycle_hook(histogram_hook_);
  } catch (...) {  // NOLINT(bugprone-empty-catch)
  }
}

supervisor::ComponentDrainLoop* SupervisionService::supervisor() noexcept {
  auto* r = dynamic_cast<RegistrySource*>(source_.get());
  return r != nullptr ? &r->supervisor() : nullptr;
}

SegmentSource* SupervisionService::segments() noexcept {
  return dynamic_cast<SegmentSource*>(source_.get());
}

exporter::HttpServer* SupervisionService::http() noexcept {
  return http_ != nullptr ? http_->server() : nullptr;
}

void SupervisionService::stop_outputs(const exporter::Snapshot& final_snapshot, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    guarded("an output's stop", [&] { outputs_[i]->stop(final_snapshot); });
  }
}

expected<void, Error> SupervisionService::start() {
  if (running_) return unexpected(Error{"the supervision service is already running"});
  if (options_.segments) {
    if (auto ok = validate(*options_.segments); !ok) return ok;
  }
  const exporter::Snapshot empty;
  exporter::OutputContext context{aggregator_};
  std::size_t started = 0;
  for (; started < outputs_.size(); ++started) {
    if (auto r = outputs_[started]->start(context); !r) {
      stop_outputs(empty, started);
      return r;
    }
  }
  last_event_seq_ = aggregator_.events().last_seq();
  if (auto r = reactions_.start(aggregator_.events(), systemd_); !r) {
    stop_outputs(empty, outputs_.size());
    return r;
  }
  monitor_heartbeat_.store(options_.clock.now(), std::memory_order_relaxed);
  monitor_stalled_.store(false, std::memory_order_relaxed);
  publishing_.store(true, std::memory_order_release);
  if (auto r = source_->start(); !r) {
    reactions_.stop();
    publishing_.store(false, std::memory_order_release);
    stop_outputs(empty, outputs_.size());
    return r;
  }
  if (options_.monitor_thread) {
    if (auto r = monitor_.start(); !r) {
      source_->stop();
      reactions_.stop();
      publishing_.store(false, std::memory_order_release);
      stop_outputs(empty, outputs_.size());
      return r;
    }
  }
  running_ = true;
  return {};
}

ReportSet SupervisionService::stop() {
  if (!running_) return final_;
  source_->stop();  // joins after a last full drain
  monitor_.stop();
  running_ = false;
  publishing_.store(false,
                    std::memory_order_release);  // the last cycle goes to the outputs' stop(), once
  if (options_.final_cycle) (void)monitor_.step();
  reactions_.stop();  // the handlers queued run first
  const std::shared_ptr<const exporter::Snapshot> last = snapshot();
  final_ = last->reports;
  stop_outputs(*last, outputs_.size());
  return final_;
}

ReportSet SupervisionService::step() {
  if (!source_->running()) source_->step();
  (void)monitor_.step();
  return reports();
}

ReportSet SupervisionService::reports() const { return snapshot()->reports; }

std::shared_ptr<const exporter::Snapshot> SupervisionService::snapshot() const {
  std::lock_guard lock(latest_mutex_);
  return latest_;
}

exporter::Output& SupervisionService::add_output(std::unique_ptr<exporter::Output> output) {
  // A part that is both (the components' log) is registered once, as both.
  if (auto* c = dynamic_cast<Contributor*>(output.get()); c != nullptr) contributors_.push_back(c);
  outputs_.push_back(std::move(output));
  return *outputs_.back();
}

Contributor& SupervisionService::add_contributor(std::unique_ptr<Contributor> contributor) {
  owned_contributors_.push_back(std::move(contributor));
  contributors_.push_back(owned_contributors_.back().get());
  return *owned_contributors_.back();
}

void SupervisionService::add_contributor(Contributor& contributor) {
  contributors_.push_back(&contributor);
}

expected<void, Error> SupervisionService::set_diagnosis(monitor::DiagnosisConfig config) {
  if (auto ok = monitor::validate(config); !ok) return ok;
  std::lock_guard lock(diagnosis_mutex_);
  diagnosis_ = monitor::DiagnosisGraph(std::move(config));
  return {};
}

std::size_t SupervisionService::clear_diagnosis(std::string_view name) {
  std::lock_guard lock(diagnosis_mutex_);
  return diagnosis_.clear(name);
}

// One monitor cycle, on the monitor's thread (or step()'s or stop()'s caller): the snapshot is
// made once (contributors run once), kept for readers, and handed to every output.
void SupervisionService::on_cycle(const ReportSet& monitor_reports) {
  auto s = std::make_shared<exporter::Snapshot>();
  s->cycle = monitor_reports.cycle;
  s->reports = monitor_reports;
  s->histograms = std::move(cycle_histograms_);
  cycle_histograms_.clear();
  for (auto& h : s->histograms) h.cycle = s->cycle;
  supervisor::EventHub& hub = aggregator_.events();
  s->events = hub.since(last_event_seq_);
  if (!s->events.empty()) {
    const std::uint64_t first = s->events.front().seq;
    s->events_missed = first > last_event_seq_ + 1 ? first - last_event_seq_ - 1 : 0;
    last_event_seq_ = s->events.back().seq;
  }
  for (Contributor* c : contributors_) guarded("a contributor", [&] { c->contribute(*s); });
  // The default graph: the components and the shared threads need the supervisor that drains
  // them (a supervisor that stops draining explains their silence).
  std::vector<std::string> supervisors;
  for (const monitor::Report& r : s->reports.components) {
    if (r.kind == monitor::ReportKind::Supervisor) supervisors.push_back(r.name);
  }
  for (monitor::Report& r : s->reports.components) {
    if (r.kind == monitor::ReportKind::Component || r.is_unit(kThreadUnit)) {
      r.depends_on.insert(r.depends_on.end(), supervisors.begin(), supervisors.end());
    }
  }
  if (!reactions_.reactions().empty()) {
    guarded("the reactions' unit",
            [&] { s->reports.components.push_back(reactions_.unit(options_.clock.now())); });
  }
  {
    std::lock_guard lock(diagnosis_mutex_);
    guarded("the diagnosis graph", [&] { diagnosis_.apply(s->reports, s->reports.time_ns); });
  }
  guarded("the threads' cross-check", [&] { watch_threads(s->reports); });
  if (publishing_.load(std::memory_order_acquire)) {
    guarded("the reactions", [&] { reactions_.on_reports(s->reports); });
  }
  monitor_heartbeat_.store(options_.clock.now(), std::memory_order_relaxed);
  std::shared_ptr<const exporter::Snapshot> done = std::move(s);
  {
    std::lock_guard lock(latest_mutex_);
    latest_ = done;
  }
  if (!publishing_.load(std::memory_order_acquire)) return;
  for (auto& o : outputs_) guarded("an output", [&] { o->publish(*done); });
}

// On the supervisor's thread, after each drain: the monitor must have ended a cycle within
// three of its periods (at least 2 s: a loaded host delays a SCHED_OTHER thread that long
// without anything being wrong).
void SupervisionService::watch_monitor(Nanos now) {
  if (!options_.monitor_thread || !publishing_.load(std::memory_order_acquire)) return;
  const Nanos last = monitor_heartbeat_.load(std::memory_order_relaxed);
  if (last == 0) return;
  const Nanos limit = std::max(3 * options_.monitor_period_ns, 2 * kNanosPerSecond);
  const bool stalled = now - last > limit;
  if (stalled == monitor_stalled_.load(std::memory_order_relaxed)) return;
  monitor_stalled_.store(stalled, std::memory_order_relaxed);
  supervisor::Event e;
  e.kind = stalled ? supervisor::EventKind::ThreadStalled : supervisor::EventKind::ThreadResumed;
  e.severity = stalled ? supervisor::EventSeverity::Error : supervisor::EventSeverity::Info;
  e.component = options_.monitor.monitor_name;
  e.fault_ns = stalled ? last + limit : 0;
  e.detected_ns = now;
  e.detail = stalled ? fmt::format(
                           "the monitor thread has ended no cycle for {} (limit {}): "
                           "reports, outputs and status reactions are stalled",
                           monitor::format_nanos(static_cast<double>(now - last)),
                           monitor::format_nanos(static_cast<double>(limit)))
                     : "the monitor thread cycles again";
  aggregator_.events().publish(std::move(e));
}

// On the monitor's thread: a supervisor that stopped draining (its report STALE) and a reaction
// handler stuck over its budget (the reactions' unit ERROR) are threads stalled.
void SupervisionService::watch_threads(const ReportSet& reports) {
  for (const monitor::Report& r : reports.components) {
    bool stalled = false;
    if (r.kind == monitor::ReportKind::Supervisor) {
      stalled = r.status.level() == monitor::StatusLevel::Stale;
    } else if (r.is_unit("reactions")) {
      stalled = r.status.level() == monitor::StatusLevel::Error;
    } else {
      continue;
    }
    const auto it = std::find(stalled_.begin(), stalled_.end(), r.name);
    if (stalled == (it != stalled_.end())) continue;
    supervisor::Event e;
    e.component = r.name;
    e.detected_ns = options_.clock.now();
    if (stalled) {
      stalled_.push_back(r.name);
      e.kind = supervisor::EventKind::ThreadStalled;
      e.severity = supervisor::EventSeverity::Error;
      e.fault_ns = r.silence_ns > 0 ? reports.time_ns - r.silence_ns : 0;
      e.detail =
          r.status.messages().empty() ? std::string("stalled") : r.status.messages().front().text;
    } else {
      stalled_.erase(it);
      e.kind = supervisor::EventKind::ThreadResumed;
      e.detail = r.kind == monitor::ReportKind::Supervisor ? "the supervisor drains again"
                                                           : "the reaction thread is free again";
    }
    aggregator_.events().publish(std::move(e));
  }
}

}  // namespace vigil::service
