// `vigil demo`: builds a System from the built-in deployment (or --config), runs it with a live
// view refreshed every second, stops cleanly on Ctrl-C or after --duration, and writes the final
// reports.
#include <fmt/format.h>

#include <cstdio>
#include <fstream>
#include <thread>

#include "commands.hpp"
#include "demo_components.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/export/http_service.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/version.hpp"

namespace vigil::app {

namespace {

ColorMode color_mode(const std::string& s) {
  if (s == "always") return ColorMode::Always;
  if (s == "never") return ColorMode::Never;
  return ColorMode::Auto;
}

void print_view(const deploy::System& sys, const ReportSet& reports, double elapsed_s,
                bool live_tty, bool color) {
  std::string out;
  if (live_tty) out += "\x1b[H\x1b[2J";  // home + clear: redraw in place
  out += fmt::format("vigil demo — {} — {:.0f} s — worst: {}\n", sys.spec().name, elapsed_s,
                     to_string(reports.worst()));
  out += format_summary(reports, color);
  if (!live_tty) out += '\n';
  std::fwrite(out.data(), 1, out.size(), stdout);
  std::fflush(stdout);
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
  std::string json_path = o.json;
  if (json_path.empty() && spec->outputs.json) json_path = spec->outputs.json->string();

  auto sys = deploy::System::create(std::move(*spec));
  if (!sys) {
    std::fprintf(stderr, "vigil demo: cannot build the system:\n%s\n",
                 config::to_string(sys.error()).c_str());
    return 1;
  }
  deploy::System& system = **sys;

  // HTTP and the textfile: started before the components, so that a taken port stops the demo
  // before anything runs.
  exporter::ExportOptions exports;
  if (!o.http.empty()) {
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil demo: --http %s\n", listen.error().c_str());
      return 2;
    }
    exports.http.emplace();
    exports.http->listen = *listen;
  } else if (const auto& h = system.spec().outputs.http) {
    exports.http.emplace();
    exports.http->listen = h->listen;
    exports.http->threads = h->threads;
    exports.http->dashboard = h->dashboard;
  }
  if (exports.http)
    exports.http->log = [](const std::string& line) { std::printf("%s\n", line.c_str()); };
  exports.textfile = o.textfile;
  exports.augment = [&system](ReportSet& r) { r = system.reports(); };  // with CAN's reports
  std::unique_ptr<exporter::MonitorExporter> exporter;
  if (exports.http || !exports.textfile.empty()) {
    auto e = exporter::MonitorExporter::start(system.monitor(), &system.aggregator(),
                                              std::move(exports));
    if (!e) {
      std::fprintf(stderr, "vigil demo: %s\n", e.error().message.c_str());
      return 1;
    }
    exporter = std::move(*e);
    std::fflush(stdout);
  }

  platform::install_stop_signals();  // Ctrl-C and SIGTERM stop cleanly

  if (auto r = system.start(); !r) {
    std::fprintf(stderr, "vigil demo: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  const bool tty = platform::is_terminal(stdout);
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
      print_view(system, system.reports(), static_cast<double>(now - start) / 1e9, tty, color);
    }
  }
  const bool interrupted = platform::stop_requested();
  system.stop();
  const ReportSet final_reports = system.step_monitor();
  if (exporter) {
    exporter->publish(final_reports);  // served until the demo exits
    if (const std::string err = exporter->textfile_error(); !err.empty()) {
      std::fprintf(stderr, "vigil demo: %s\n", err.c_str());
    }
  }
  std::printf("\n%s after %.1f s. Final report:\n", interrupted ? "Interrupted" : "Stopped",
              static_cast<double>(platform::now_ns() - start) / 1e9);
  std::fputs(format_summary(final_reports, color).c_str(), stdout);
  if (o.details) std::fputs(("\n" + format_details(final_reports, color)).c_str(), stdout);
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    f << to_json(final_reports, {.indent = 2}) << '\n';
    if (!f) {
      std::fprintf(stderr, "vigil demo: cannot write %s\n", json_path.c_str());
      return 1;
    }
    std::printf("Final reports written to %s\n", json_path.c_str());
  }
  return 0;
}

}  // namespace vigil::app
