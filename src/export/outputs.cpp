#include "vigil/export/outputs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "vigil/export/json_report.hpp"
#include "vigil/export/textfile.hpp"

namespace vigil::exporter {

namespace {

std::string reason(int err) { return std::strerror(err != 0 ? err : EIO); }

}  // namespace

expected<void, Error> write_json_file(const std::filesystem::path& path, const ReportSet& reports,
                                      int indent) {
  const std::string text = to_json(reports, {.indent = indent}) + "\n";
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    const int err = errno;
    return unexpected(Error{
        err, fmt::format("cannot write the final reports to {}: {}", path.string(), reason(err))});
  }
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0;
  int err = ok ? 0 : errno;
  if (std::fclose(f) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (!ok) {
    return unexpected(Error{
        err, fmt::format("cannot write the final reports to {}: {}", path.string(), reason(err))});
  }
  return {};
}

// --- text --------------------------------------------------------------------------------------

expected<void, Error> TextOutput::start(OutputContext& context) {
  started_ns_ = context.aggregator.options().clock.now();
  return {};
}

void TextOutput::publish(const Snapshot& snapshot) {
  if (!options_.every_cycle || options_.file == nullptr) return;
  const bool color = use_color(options_.color, options_.file);
  std::string out;
  if (options_.redraw) out += "\x1b[H\x1b[2J";  // home + clear: redraw in place
  if (!options_.title.empty()) {
    out += fmt::format("{} — {:.0f} s — worst: {}\n", options_.title,
                       static_cast<double>(snapshot.reports.time_ns - started_ns_) / 1e9,
                       to_string(snapshot.reports.worst()));
  }
  out += format_summary(snapshot.reports, color);
  // The panels stay below the table: a line written to a terminal between two redraws would
  // push the view down.
  for (const TextPanel* p : options_.panels) p->append(out);
  if (!options_.redraw) out += '\n';
  std::fwrite(out.data(), 1, out.size(), options_.file);
  std::fflush(options_.file);
}

void TextOutput::stop(const Snapshot& final_snapshot) {
  if (options_.file == nullptr) return;
  const bool color = use_color(options_.color, options_.file);
  std::string out;
  if (!options_.final_title.empty()) {
    out += fmt::format("\n{} after {:.1f} s. Final report:\n", options_.final_title,
                       static_cast<double>(final_snapshot.reports.time_ns - started_ns_) / 1e9);
  }
  out += format_summary(final_snapshot.reports, color);
  for (const TextPanel* p : options_.panels) p->append(out);
  if (options_.details_at_stop) out += "\n" + format_details(final_snapshot.reports, color);
  std::fwrite(out.data(), 1, out.size(), options_.file);
  std::fflush(options_.file);
}

// --- event lines -------------------------------------------------------------------------------

expected<void, Error> EventLineOutput::start(OutputContext& context) {
  hub_ = &context.aggregator.events();
  subscription_ = hub_->subscribe([this](const Event& e) { on_event(e); });
  return {};
}

void EventLineOutput::stop(const Snapshot& /*final_snapshot*/) {
  if (hub_ == nullptr) return;
  (void)hub_->flush(kNanosPerSecond);
  hub_->unsubscribe(subscription_);
  hub_ = nullptr;
}

void EventLineOutput::on_event(const Event& e) {
  if (e.kind == EventKind::StateChange) return;  // the lifecycle is in the table
  std::string line = limiter_.line(e);
  if (line.empty()) return;
  if (options_.file != nullptr) {
    std::fprintf(options_.file, "event: %s\n", line.c_str());
    return;
  }
  std::lock_guard lock(mutex_);
  lines_.push_back(std::move(line));
  if (lines_.size() > options_.lines) lines_.erase(lines_.begin());
  ++total_;
}

void EventLineOutput::append(std::string& out) const {
  std::lock_guard lock(mutex_);
  if (total_ == 0) return;
  out += fmt::format("\nevents ({} line{}; the last {} here):\n", total_, total_ == 1 ? "" : "s",
                     options_.lines);
  for (const auto& l : lines_) out += "  " + l + '\n';
}

// --- JSON file ---------------------------------------------------------------------------------

expected<void, Error> JsonFileOutput::start(OutputContext& /*context*/) {
  // Say at once when the path cannot be written (opened to append: an existing file is kept);
  // supervision goes on, and the write is tried again at stop.
  errno = 0;
  std::FILE* f = std::fopen(path_.c_str(), "ab");
  if (f == nullptr) {
    const int err = errno;
    std::fprintf(stderr,
                 "vigil: cannot write %s: %s; supervision goes on, the final reports will be "
                 "printed and written there again at the end\n",
                 path_.c_str(), reason(err).c_str());
  } else {
    std::fclose(f);
  }
  return {};
}

void JsonFileOutput::stop(const Snapshot& final_snapshot) {
  auto ok = write_json_file(path_, final_snapshot.reports, indent_);
  std::lock_guard lock(mutex_);
  error_ = ok ? std::string() : ok.error().message;
  written_ = ok.has_value();
  if (!ok) std::fprintf(stderr, "vigil: %s\n", error_.c_str());
}

bool JsonFileOutput::written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

std::string JsonFileOutput::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

// --- HTTP --------------------------------------------------------------------------------------

expected<void, Error> HttpOutput::start(OutputContext& context) {
  HttpOptions o = options_;
  if (serve_events_) {
    supervisor::ComponentAggregator* aggregator = &context.aggregator;
    if (o.events == nullptr) o.events = &aggregator->events();
    if (!o.trace) {
      o.trace = [aggregator](const std::string& name) -> std::optional<std::string> {
        auto r = aggregator->flight_record(name);
        if (!r) return std::nullopt;
        return trace_event_json(*r);
      };
    }
    if (!o.event_trace) {
      o.event_trace = [aggregator](std::uint64_t seq) -> std::optional<std::string> {
        auto r = aggregator->frozen_record(seq);
        if (!r) return std::nullopt;
        return trace_event_json(*r);
      };
    }
  }
  auto server = std::make_unique<HttpServer>(std::move(o));
  if (auto ok = server->start(); !ok) return ok;
  server_ = std::move(server);
  aggregator_ = &context.aggregator;
  return {};
}

void HttpOutput::publish(const Snapshot& snapshot) {
  if (!server_) return;
  std::vector<ComponentHistograms> histograms = snapshot.histograms;
  std::vector<std::shared_ptr<const supervisor::FlightRecord>> frozen;
  if (aggregator_ != nullptr) frozen = aggregator_->frozen_records();
  exemplars_.update(histograms, snapshot.events, frozen, ExemplarClock::now());
  server_->publish(snapshot.reports, std::move(histograms), snapshot.can_histograms,
                   snapshot.can_buses);
}

void HttpOutput::stop(const Snapshot& final_snapshot) {
  if (!server_) return;
  publish(final_snapshot);
  server_->stop();
  server_.reset();
  aggregator_ = nullptr;
}

// --- textfile ----------------------------------------------------------------------------------

void TextfileOutput::publish(const Snapshot& snapshot) {
  MetricsSnapshot m;
  m.reports = snapshot.reports;
  m.histograms = snapshot.histograms;
  m.can_histograms = snapshot.can_histograms;
  std::sort(m.can_histograms.begin(), m.can_histograms.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  m.can_buses = snapshot.can_buses;
  std::sort(m.can_buses.begin(), m.can_buses.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  m.wall_time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count();
  auto ok = write_textfile(path_, m);
  std::lock_guard lock(mutex_);
  error_ = ok ? std::string() : ok.error().message;
}

std::string TextfileOutput::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

// --- event log ---------------------------------------------------------------------------------

expected<void, Error> EventLogOutput::start(OutputContext& context) {
  auto w = EventLogWriter::start(context.aggregator.events(), path_);
  if (!w) return unexpected(w.error());
  hub_ = &context.aggregator.events();
  writer_ = std::move(*w);
  return {};
}

void EventLogOutput::stop(const Snapshot& /*final_snapshot*/) {
  if (!writer_) return;
  (void)hub_->flush(2 * kNanosPerSecond);  // the events published so far are written
  std::lock_guard lock(mutex_);
  written_ = writer_->written();
  lost_ = writer_->lost();
  error_ = writer_->error();
  writer_.reset();  // unsubscribes, closes the file
  hub_ = nullptr;
}

std::uint64_t EventLogOutput::written() const {
  std::lock_guard lock(mutex_);
  return writer_ ? writer_->written() : written_;
}

std::uint64_t EventLogOutput::lost() const {
  std::lock_guard lock(mutex_);
  return writer_ ? writer_->lost() : lost_;
}

std::string EventLogOutput::error() const {
  std::lock_guard lock(mutex_);
  return writer_ ? writer_->error() : error_;
}

// --- traces ------------------------------------------------------------------------------------

expected<void, Error> TraceOutput::start(OutputContext& context) {
  auto w = TraceWriter::start(context.aggregator, options_);
  if (!w) return unexpected(w.error());
  hub_ = &context.aggregator.events();
  writer_ = std::move(*w);
  return {};
}

void TraceOutput::stop(const Snapshot& /*final_snapshot*/) {
  if (!writer_) return;
  (void)writer_->flush(2 * kNanosPerSecond);
  std::lock_guard lock(mutex_);
  written_ = writer_->written();
  writer_.reset();
  hub_ = nullptr;
}

std::vector<std::filesystem::path> TraceOutput::written() const {
  std::lock_guard lock(mutex_);
  return writer_ ? writer_->written() : written_;
}

}  // namespace vigil::exporter
