// `vigil supervise`: the daemon that supervises the components of other processes (those started
// with VIGIL_SUPERVISOR=<name>). Live view every monitor period, process events as they happen,
// final reports on Ctrl-C or after --duration. The work is a SupervisionService draining the
// segments (service::SegmentSource); this file translates flags and presents it.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <thread>

#include "commands.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/version.hpp"

namespace vigil::app {

namespace {

ColorMode mode_of(const std::string& s) {
  if (s == "always") return ColorMode::Always;
  if (s == "never") return ColorMode::Never;
  return ColorMode::Auto;
}

std::string format_processes(const std::vector<service::ProcessInfo>& procs) {
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

std::string event_line(const Event& e, Nanos start) {
  return fmt::format("[{:8.3f} s] {}: {}", static_cast<double>(e.detected_ns - start) / 1e9,
                     to_string(e.kind), e.detail.empty() ? format_event(e) : e.detail);
}

}  // namespace

int run_supervise(const SuperviseOptions& o) {
  service::SupervisionServiceOptions opts;
  opts.segments =
      service::SegmentSourceOptions{.name = o.name, .group = o.group, .reclaim = !o.keep_segments};
  opts.supervisor_period_ns = static_cast<Nanos>(o.period_ms * static_cast<double>(kNanosPerMilli));
  opts.monitor_period_ns = kNanosPerSecond;
  opts.summary_file = nullptr;  // the final summary is printed below, with the processes
  opts.final_cycle = true;
  if (!o.http.empty()) {  // --http: the server publishes every cycle, processes included
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil supervise: --http %s\n", listen.error().c_str());
      return 2;
    }
    opts.http.emplace();
    opts.http->listen = *listen;
    opts.http->log = [](const std::string& line) { std::printf("%s\n", line.c_str()); };
  }
  if (auto ok = service::validate(*opts.segments); !ok) {
    std::fprintf(stderr, "vigil supervise: %s\n", ok.error().message.c_str());
    return 1;
  }
  service::SupervisionService daemon(std::move(opts));
  service::SegmentSource& segments = *daemon.segments();

  // Process events (joined, left, exited, rejected) are events of the one stream.
  std::mutex events_mutex;
  std::deque<Event> pending;
  const std::uint64_t events_sub = daemon.events().subscribe([&](const Event& e) {
    std::lock_guard lock(events_mutex);
    pending.push_back(e);
  });
  struct Unsubscribe {
    service::SupervisionService& s;
    std::uint64_t id;
    ~Unsubscribe() { s.events().unsubscribe(id); }
  } unsubscribe{daemon, events_sub};

  platform::install_stop_signals();
  if (auto r = daemon.start(); !r) {
    std::fprintf(stderr, "vigil supervise: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  const Clock clock = daemon.options().clock;
  const bool tty = platform::is_terminal(stdout);
  const bool color = use_color(mode_of(o.color), stdout);
  const Nanos start = clock.now();
  std::printf("vigil %s: supervising '%s' (segments /dev/shm/vigil.%s.*), drained every %s%s\n",
              kVersion, o.name.c_str(), o.name.c_str(),
              format_nanos(static_cast<double>(segments.options().period_ns)).c_str(),
              o.duration_s > 0 ? fmt::format(" for {} s", o.duration_s).c_str() : "; Ctrl-C stops");
  std::printf("Start processes with VIGIL_SUPERVISOR=%s in their environment.\n", o.name.c_str());
  std::fflush(stdout);

  const Nanos end = o.duration_s > 0 ? start + static_cast<Nanos>(o.duration_s * 1e9) : INT64_MAX;
  Nanos next_view = start + kNanosPerSecond;
  std::deque<std::string> recent;  // the live view's last events (terminal redraw)
  while (!platform::stop_requested() && clock.now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::deque<Event> evs;
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
        redraw_now = redraw_now || e.kind == EventKind::ProcessExited;
      } else {
        std::printf("%s\n", line.c_str());
      }
    }
    if (!evs.empty()) std::fflush(stdout);
    const Nanos now = clock.now();
    if (o.no_live || (now < next_view && !redraw_now)) continue;
    if (now >= next_view) next_view += kNanosPerSecond;
    const ReportSet reports = daemon.reports();
    std::string out;
    if (tty) out += "\x1b[H\x1b[2J";
    out += fmt::format("vigil supervise — {} — {:.0f} s — worst: {}\n", o.name,
                       static_cast<double>(now - start) / 1e9, to_string(reports.worst()));
    out += format_processes(segments.processes());
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
  (void)daemon.events().flush(kNanosPerSecond);   // the last process events
  const ReportSet final_reports = daemon.stop();  // last drain, last cycle, outputs stopped
  {
    std::lock_guard lock(events_mutex);
    for (const auto& e : pending) std::printf("%s\n", event_line(e, start).c_str());
  }
  std::printf("\n%s after %.1f s. Final report:\n", interrupted ? "Interrupted" : "Stopped",
              static_cast<double>(clock.now() - start) / 1e9);
  std::fputs(format_processes(segments.processes()).c_str(), stdout);
  std::fputs("\n", stdout);
  std::fputs(format_summary(final_reports, color).c_str(), stdout);
  if (o.details) std::fputs(("\n" + format_details(final_reports, color)).c_str(), stdout);
  if (!o.json.empty()) {
    if (auto ok = exporter::write_json_file(o.json, final_reports); !ok) {
      std::fprintf(stderr, "vigil supervise: %s\n", ok.error().message.c_str());
      return 1;
    }
    std::printf("Final reports written to %s\n", o.json.c_str());
  }
  return 0;
}

}  // namespace vigil::app
