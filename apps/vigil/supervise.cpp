// `vigil supervise`: the daemon that supervises the components of other processes (those started
// with VIGIL_SUPERVISOR=<name>). Live view every monitor period, process events as they happen,
// final reports on Ctrl-C or after --duration. The work is deploy::ProcessSupervisor's; this file
// only presents it.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <thread>

#include "commands.hpp"
#include "vigil/deploy/process_supervisor.hpp"
#include "vigil/export/http_service.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/version.hpp"

namespace vigil::app {

namespace {

ColorMode mode_of(const std::string& s) {
  if (s == "always") return ColorMode::Always;
  if (s == "never") return ColorMode::Never;
  return ColorMode::Auto;
}

std::string format_processes(const std::vector<deploy::ProcessInfo>& procs) {
  std::string out = fmt::format("{:<16} {:>7} {:<19} {:>3} {:<40} {}\n", "PROCESS", "PID",
                                "STARTED", "RUN", "STATE", "COMMAND");
  for (const auto& p : procs) {
    std::string state = p.alive ? fmt::format("running, {} component{}", p.components.size(),
                                              p.components.size() == 1 ? "" : "s")
                                : p.exit + (p.exit_source.empty() || p.exit_source == "unknown"
                                                ? std::string()
                                                : " [" + p.exit_source + "]");
    out += fmt::format("{:<16} {:>7} {:<19} {:>3} {:<40} {}\n", p.name, p.pid,
                       platform::format_unix_time(p.started_unix_ns), p.incarnation, state,
                       p.command_line);
  }
  return out;
}

std::string event_line(const deploy::ProcessEvent& e, Nanos start) {
  return fmt::format("[{:8.3f} s] {}: {}", static_cast<double>(e.time_ns - start) / 1e9,
                     to_string(e.kind), e.message);
}

}  // namespace

int run_supervise(const SuperviseOptions& o) {
  deploy::ProcessSupervisorOptions opts;
  opts.name = o.name;
  opts.group = o.group;
  opts.period_ns = static_cast<Nanos>(o.period_ms * static_cast<double>(kNanosPerMilli));
  opts.reclaim = !o.keep_segments;
  opts.monitor.period_ns = kNanosPerSecond;
  auto created = deploy::ProcessSupervisor::create(opts);
  if (!created) {
    std::fprintf(stderr, "vigil supervise: %s\n", created.error().message.c_str());
    return 1;
  }
  deploy::ProcessSupervisor& daemon = **created;

  std::mutex events_mutex;
  std::deque<deploy::ProcessEvent> pending;
  daemon.subscribe([&](const deploy::ProcessEvent& e) {
    std::lock_guard lock(events_mutex);
    pending.push_back(e);
  });

  platform::install_stop_signals();
  if (auto r = daemon.start(); !r) {
    std::fprintf(stderr, "vigil supervise: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  // --http: the exporter serves every monitor cycle with the processes' reports added.
  std::unique_ptr<exporter::MonitorExporter> http;
  if (!o.http.empty()) {
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil supervise: --http %s\n", listen.error().c_str());
      daemon.stop();
      return 2;
    }
    exporter::ExportOptions e;
    e.http.emplace();
    e.http->listen = *listen;
    e.http->log = [](const std::string& line) { std::printf("%s\n", line.c_str()); };
    e.augment = [&daemon](ReportSet& r) { r = daemon.compose(r); };
    auto started =
        exporter::MonitorExporter::start(daemon.monitor(), &daemon.aggregator(), std::move(e));
    if (!started) {
      std::fprintf(stderr, "vigil supervise: %s\n", started.error().message.c_str());
      daemon.stop();
      return 1;
    }
    http = std::move(*started);
  }
  const bool tty = platform::is_terminal(stdout);
  const bool color = use_color(mode_of(o.color), stdout);
  const Nanos start = daemon.options().monitor.clock.now();
  std::printf("vigil %s: supervising '%s' (segments /dev/shm/vigil.%s.*), drained every %s%s\n",
              kVersion, o.name.c_str(), o.name.c_str(),
              format_nanos(static_cast<double>(opts.period_ns)).c_str(),
              o.duration_s > 0 ? fmt::format(" for {} s", o.duration_s).c_str() : "; Ctrl-C stops");
  std::printf("Start processes with VIGIL_SUPERVISOR=%s in their environment.\n", o.name.c_str());
  std::fflush(stdout);

  const Nanos end = o.duration_s > 0 ? start + static_cast<Nanos>(o.duration_s * 1e9) : INT64_MAX;
  Nanos next_view = start + kNanosPerSecond;
  std::deque<std::string> recent;  // the live view's last events (terminal redraw)
  while (!platform::stop_requested() && daemon.options().monitor.clock.now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::deque<deploy::ProcessEvent> evs;
    {
      std::lock_guard lock(events_mutex);
      evs.swap(pending);
    }
    bool redraw_now = false;
    for (const auto& e : evs) {
      const std::string line = event_line(e, start);
      if (tty && !o.no_live) {
        recent.push_back(line);
        if (recent.size() > 8) recent.pop_front();
        redraw_now = redraw_now || e.kind == deploy::ProcessEvent::Kind::Exited;
      } else {
        std::printf("%s\n", line.c_str());
      }
    }
    if (!evs.empty()) std::fflush(stdout);
    const Nanos now = daemon.options().monitor.clock.now();
    if (o.no_live || (now < next_view && !redraw_now)) continue;
    if (now >= next_view) next_view += kNanosPerSecond;
    const ReportSet reports = daemon.reports();
    std::string out;
    if (tty) out += "\x1b[H\x1b[2J";
    out += fmt::format("vigil supervise — {} — {:.0f} s — worst: {}\n", o.name,
                       static_cast<double>(now - start) / 1e9, to_string(reports.worst()));
    out += format_processes(daemon.processes());
    out += '\n';
    out += format_summary(reports, color);
    if (tty && !recent.empty()) {
      out += "\nRecent events:\n";
      for (const auto& l : recent) out += "  " + l + "\n";
    }
    if (!tty) out += '\n';
    std::fwrite(out.data(), 1, out.size(), stdout);
    std::fflush(stdout);
  }
  const bool interrupted = platform::stop_requested();
  http.reset();  // unsubscribes from the monitor, stops the server
  daemon.stop();
  daemon.step();
  const ReportSet final_reports = daemon.step_monitor();
  std::printf("\n%s after %.1f s. Final report:\n", interrupted ? "Interrupted" : "Stopped",
              static_cast<double>(daemon.options().monitor.clock.now() - start) / 1e9);
  std::fputs(format_processes(daemon.processes()).c_str(), stdout);
  std::fputs("\n", stdout);
  std::fputs(format_summary(final_reports, color).c_str(), stdout);
  if (o.details) std::fputs(("\n" + format_details(final_reports, color)).c_str(), stdout);
  if (!o.json.empty()) {
    std::ofstream f(o.json);
    f << to_json(final_reports, {.indent = 2}) << '\n';
    if (!f) {
      std::fprintf(stderr, "vigil supervise: cannot write %s\n", o.json.c_str());
      return 1;
    }
    std::printf("Final reports written to %s\n", o.json.c_str());
  }
  return 0;
}

}  // namespace vigil::app
