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

void TextOutput::publish(const Snapshot& snapshot) {
  if (!options_.every_cycle || options_.file == nullptr) return;
  print_summary(options_.file, snapshot.reports, options_.color);
  std::fflush(options_.file);
}

void TextOutput::stop(const Snapshot& final_snapshot) {
  if (options_.file == nullptr) return;
  print_summary(options_.file, final_snapshot.reports, options_.color);
  if (options_.details_at_stop) {
    std::fputc('\n', options_.file);
    print_details(options_.file, final_snapshot.reports, options_.color);
  }
  std::fflush(options_.file);
}

// --- JSON file ---------------------------------------------------------------------------------

void JsonFileOutput::stop(const Snapshot& final_snapshot) {
  auto ok = write_json_file(path_, final_snapshot.reports, indent_);
  std::lock_guard lock(mutex_);
  error_ = ok ? std::string() : ok.error().message;
  if (!ok) std::fprintf(stderr, "vigil: %s\n", error_.c_str());
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
  }
  auto server = std::make_unique<HttpServer>(std::move(o));
  if (auto ok = server->start(); !ok) return ok;
  server_ = std::move(server);
  return {};
}

void HttpOutput::publish(const Snapshot& snapshot) {
  if (!server_) return;
  server_->publish(snapshot.reports, snapshot.histograms, snapshot.can_histograms);
}

void HttpOutput::stop(const Snapshot& final_snapshot) {
  if (!server_) return;
  publish(final_snapshot);
  server_->stop();
  server_.reset();
}

// --- textfile ----------------------------------------------------------------------------------

void TextfileOutput::publish(const Snapshot& snapshot) {
  MetricsSnapshot m;
  m.reports = snapshot.reports;
  m.histograms = snapshot.histograms;
  m.can_histograms = snapshot.can_histograms;
  std::sort(m.can_histograms.begin(), m.can_histograms.end(),
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
