// `vigil demo`: builds a System from the built-in deployment (or --config), runs it with a live
// view refreshed every second, stops cleanly on Ctrl-C or after --duration, and writes the final
// reports. The components' log lines appear below the live view's table (or on stderr without a
// live view), and in the final reports.
#include <fmt/format.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "commands.hpp"
#include "demo_components.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/export/log_report.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/log/service.hpp"
#include "vigil/log/source.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/version.hpp"

namespace vigil::app {

namespace {

ColorMode color_mode(const std::string& s) {
  if (s == "always") return ColorMode::Always;
  if (s == "never") return ColorMode::Never;
  return ColorMode::Auto;
}

/// Lines of the components' log shown under the live view's table.
constexpr std::size_t kLogPanelLines = 8;

void print_log_panel(std::string& out, const log::TailSink& tail) {
  const auto lines = tail.lines();
  out += fmt::format("\nlog ({} line{} so far; the last {} here):\n", tail.total(),
                     tail.total() == 1 ? "" : "s", kLogPanelLines);
  for (const auto& l : lines) out += "  " + l + '\n';
}

/// The latest event lines (rate-limited: one per component per second), for the live view.
class EventPanel {
 public:
  static constexpr std::size_t kLines = 6;
  void add(std::string line) {
    std::lock_guard lock(mutex_);
    lines_.push_back(std::move(line));
    if (lines_.size() > kLines) lines_.pop_front();
    ++total_;
  }
  void print(std::string& out) const {
    std::lock_guard lock(mutex_);
    if (total_ == 0) return;
    out += fmt::format("\nevents ({} line{}; the last {} here):\n", total_, total_ == 1 ? "" : "s",
                       kLines);
    for (const auto& l : lines_) out += "  " + l + '\n';
  }

 private:
  mutable std::mutex mutex_;
  std::deque<std::string> lines_;
  std::uint64_t total_ = 0;
};

void print_view(const deploy::System& sys, const ReportSet& reports, double elapsed_s,
                bool live_tty, bool color, const log::TailSink* log_tail,
                const EventPanel* events) {
  std::string out;
  if (live_tty) out += "\x1b[H\x1b[2J";  // home + clear: redraw in place
  out += fmt::format("vigil demo — {} — {:.0f} s — worst: {}\n", sys.spec().name, elapsed_s,
                     to_string(reports.worst()));
  out += format_summary(reports, color);
  // The log stays below the table: a line written to the terminal between two redraws would
  // push the view down, so while the view is live the lines are shown here instead.
  if (log_tail != nullptr) print_log_panel(out, *log_tail);
  if (events != nullptr) events->print(out);
  if (!live_tty) out += '\n';
  std::fwrite(out.data(), 1, out.size(), stdout);
  std::fflush(stdout);
}

// Whether `path` can be opened for writing now (opened to append: an existing file is kept).
std::optional<std::string> probe_writable(const std::string& path) {
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (f == nullptr) return std::strerror(errno != 0 ? errno : EIO);
  std::fclose(f);
  return std::nullopt;
}

// Writes the final reports; on failure says so on stderr, naming the path and the reason.
bool write_json(const std::string& path, const ReportSet& reports) {
  if (auto ok = exporter::write_json_file(path, reports); !ok) {
    std::fprintf(stderr, "vigil demo: %s\n", ok.error().message.c_str());
    return false;
  }
  std::printf("Final reports written to %s\n", path.c_str());
  return true;
}

// Stops `system`, waiting at most `timeout`: a component stuck in on_update never returns, and
// its activity's thread cannot be joined. False when the deadline passed; the stopping thread is
// then left blocked and the caller must leave the process without destroying `system`.
bool stop_within(deploy::System& system, std::chrono::seconds timeout) {
  auto done = std::make_shared<std::promise<void>>();
  std::future<void> stopped = done->get_future();
  std::thread([&system, done] {
    system.stop();
    done->set_value();
  }).detach();
  return stopped.wait_for(timeout) == std::future_status::ready;
}

}  // namespace

int run_demo(const DemoOptions& o) {
  demo::register_components();
  if (o.print_config) {
    std::fputs(demo::kDemoDeployment, stdout);
    return 0;
  }
  auto spec = o.config.empty()
                  ? deploy::load_deployment_string(demo::kDemoDeployment, "<built-in demo>")
                  : deploy::load_deployment_file(o.config);
  if (!spec) {
    std::fprintf(stderr, "vigil demo: invalid deployment:\n%s\n",
                 config::to_string(spec.error()).c_str());
    return 1;
  }
  const auto level = log::parse_level(o.log_level);
  if (!level) {
    std::fprintf(stderr, "vigil demo: --log-level %s: expected debug, info, warn, error or off\n",
                 o.log_level.c_str());
    return 1;
  }
  log::set_default_level(*level);
  std::string json_path = o.json;
  if (json_path.empty() && spec->outputs.json) json_path = spec->outputs.json->string();

  // Command-line overrides of the deployment's outputs (the System starts them).
  if (!o.http.empty()) {
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil demo: --http %s\n", listen.error().c_str());
      return 2;
    }
    if (!spec->outputs.http) spec->outputs.http.emplace();
    spec->outputs.http->listen = *listen;
  }
  if (!o.textfile.empty()) spec->outputs.textfile = o.textfile;
  if (o.http_clear && spec->outputs.http) spec->outputs.http->clear = true;

  auto sys = deploy::System::create(std::move(*spec));
  if (!sys) {
    std::fprintf(stderr, "vigil demo: cannot build the system:\n%s\n",
                 config::to_string(sys.error()).c_str());
    return 1;
  }
  deploy::System& system = **sys;

  // The components' log: formatted on the supervisor thread, never on theirs.
  const bool tty = platform::is_terminal(stdout);
  const bool live_tty = tty && !o.no_live;
  // Destroyed before the system (declared after it): `detach` unhooks it first.
  log::LogService logs;
  std::shared_ptr<log::TailSink> log_tail;
  if (live_tty) {
    log_tail = std::make_shared<log::TailSink>(kLogPanelLines);
    logs.add_sink(log_tail);
  } else {
    logs.add_sink(std::make_shared<log::StreamSink>(stderr));
  }
  if (!o.log_file.empty()) {
    auto file =
        log::RotatingFileSink::open({.path = o.log_file, .max_bytes = 1U << 20U, .max_files = 3});
    if (!file) {
      std::fprintf(stderr, "vigil demo: %s\n", file.error().message.c_str());
      return 1;
    }
    logs.add_sink(std::shared_ptr<log::RotatingFileSink>(std::move(*file)));
  }
  system.aggregator().set_log_consumer(&logs);
  struct Detach {
    deploy::System& s;
    ~Detach() { s.aggregator().set_log_consumer(nullptr); }
  } detach{system};

  // Events: the JSON-lines file and the traces are outputs of the system's pipeline (each
  // writes within milliseconds of an event, on a thread of its own: none can delay the
  // supervisor); the rate-limited lines for people subscribe to the event stream.
  exporter::EventLogOutput* event_file = nullptr;
  if (!o.events.empty()) {
    event_file = &system.service().add_output<exporter::EventLogOutput>(o.events);
  }
  exporter::TraceOutput* traces = nullptr;
  if (!o.trace_dir.empty()) {
    traces = &system.service().add_output<exporter::TraceOutput>(
        exporter::TraceWriterOptions{.directory = o.trace_dir, .log = [](const std::string& line) {
                                       std::fprintf(stderr, "vigil demo: %s\n", line.c_str());
                                     }});
  }
  const bool events_live = platform::is_terminal(stdout) && !o.no_live;
  auto event_panel = std::make_shared<EventPanel>();
  auto limiter = std::make_shared<supervisor::EventLineLimiter>(kNanosPerSecond);
  const std::uint64_t line_sub =
      system.aggregator().events().subscribe([event_panel, limiter, events_live](const Event& e) {
        if (e.kind == EventKind::StateChange) return;  // the lifecycle is in the table
        std::string line = limiter->line(e);
        if (line.empty()) return;
        if (events_live) {
          event_panel->add(std::move(line));
        } else {
          std::fprintf(stderr, "event: %s\n", line.c_str());
        }
      });
  struct Unsubscribe {
    deploy::System& s;
    std::uint64_t id;
    ~Unsubscribe() { s.aggregator().events().unsubscribe(id); }
  } unsubscribe{system, line_sub};

  platform::install_stop_signals();  // Ctrl-C and SIGTERM stop cleanly

  if (auto r = system.start(); !r) {
    std::fprintf(stderr, "vigil demo: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  if (!json_path.empty()) {
    if (auto err = probe_writable(json_path)) {
      std::fprintf(stderr,
                   "vigil demo: cannot write %s: %s; supervision goes on, the final reports "
                   "will be printed and written there again at the end\n",
                   json_path.c_str(), err->c_str());
    }
  }
  const ColorMode mode = color_mode(o.color);
  const bool color = use_color(mode, stdout);
  std::printf("vigil %s: running '%s' with %zu components%s\n", kVersion,
              system.spec().name.c_str(), system.spec().components.size(),
              o.duration_s > 0 ? fmt::format(" for {} s (Ctrl-C stops)", o.duration_s).c_str()
                               : " until Ctrl-C");
  for (const auto& line : system.log()) std::printf("  %s\n", line.c_str());
  std::fflush(stdout);
  const Nanos start = platform::now_ns();  // the system runs from here
  if (tty && !o.no_live) std::this_thread::sleep_for(std::chrono::milliseconds(1500));

  const Nanos end =
      o.duration_s > 0
          ? start + static_cast<Nanos>(o.duration_s * static_cast<double>(kNanosPerSecond))
          : INT64_MAX;
  Nanos next_view = start + kNanosPerSecond;
  while (!platform::stop_requested() && platform::now_ns() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const Nanos now = platform::now_ns();
    if (!o.no_live && now >= next_view) {
      next_view += kNanosPerSecond;
      print_view(system, system.reports(), static_cast<double>(now - start) / 1e9, tty, color,
                 log_tail.get(), events_live ? event_panel.get() : nullptr);
    }
  }
  const bool interrupted = platform::stop_requested();
  if (!stop_within(system, kDemoStopTimeout)) {
    // A component never returned from on_update: report what the monitor (still running, it
    // stops after the activities) last saw, and leave without joining the blocked thread.
    const ReportSet last = system.reports();
    std::string stuck;
    for (const Report& r : last.components) {
      if (r.kind == ReportKind::Component && r.status.level() == StatusLevel::Stale) {
        stuck += stuck.empty() ? r.name : ", " + r.name;
      }
    }
    std::fprintf(stderr,
                 "vigil demo: the system did not stop within %lld s: a component is stuck in "
                 "on_update (STALE: %s); its thread cannot be joined. Final reports: the "
                 "monitor's latest.\n",
                 static_cast<long long>(kDemoStopTimeout.count()),
                 stuck.empty() ? "none reported yet" : stuck.c_str());
    std::printf("\n%s after %.1f s, not stopped. Latest report:\n",
                interrupted ? "Interrupted" : "Ended",
                static_cast<double>(platform::now_ns() - start) / 1e9);
    std::fputs(format_summary(last, color).c_str(), stdout);
    if (!json_path.empty()) (void)write_json(json_path, last);
    std::fflush(stdout);
    std::fflush(stderr);
    std::_Exit(kDemoExitStuck);
  }
  logs.flush();                 // after the last drain: the suppressed counts still pending
  if (event_file != nullptr) {  // written up to the stop (the output waited for its writer)
    if (const std::string err = event_file->error(); !err.empty()) {
      std::fprintf(stderr, "vigil demo: %s\n", err.c_str());
    }
    std::printf("%llu events written to %s%s\n",
                static_cast<unsigned long long>(event_file->written()), o.events.c_str(),
                event_file->lost() > 0
                    ? fmt::format(" ({} lost: the writer fell behind)", event_file->lost()).c_str()
                    : "");
  }
  if (traces != nullptr) {
    std::printf("%zu trace%s written to %s (open them in https://ui.perfetto.dev)\n",
                traces->written().size(), traces->written().size() == 1 ? "" : "s",
                o.trace_dir.c_str());
  }
  ReportSet final_reports = system.step_monitor();
  exporter::add_log_lines(logs,
                          final_reports);  // log counts and recent lines, in --details and the JSON
  if (const std::string& err = system.output_error(); !err.empty()) {
    std::fprintf(stderr, "vigil demo: %s\n", err.c_str());
  }
  std::printf("\n%s after %.1f s. Final report:\n", interrupted ? "Interrupted" : "Stopped",
              static_cast<double>(platform::now_ns() - start) / 1e9);
  std::fputs(format_summary(final_reports, color).c_str(), stdout);
  if (log_tail != nullptr && log_tail->total() > 0) {
    std::string panel;
    print_log_panel(panel, *log_tail);
    std::fputs(panel.c_str(), stdout);
  }
  if (o.details) std::fputs(("\n" + format_details(final_reports, color)).c_str(), stdout);
  std::fflush(stdout);
  if (!json_path.empty() && !write_json(json_path, final_reports)) return kDemoExitOutput;
  return 0;
}

}  // namespace vigil::app
