// `vigil demo`: builds a System from the built-in deployment (or --config), registers the outputs
// its flags ask for on the system's pipeline (the live text view, the components' log, event
// lines, the event file, traces; HTTP, the textfile and the JSON file through the deployment's
// outputs), runs it until Ctrl-C or --duration, and stops it. The work is the library's: this
// file translates flags and says what was written.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

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
#include "vigil/service/component_log.hpp"
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

// The outputs the flags register on the system's pipeline.
struct DemoOutputs {
  exporter::EventLogOutput* event_file = nullptr;
  exporter::TraceOutput* traces = nullptr;
  exporter::TextOutput* text = nullptr;
};

// The deployment (built-in or --config) with the flags' overrides of its outputs; the exit code
// when it or a flag is wrong.
expected<deploy::DeploymentSpec, int> load_spec(const DemoOptions& o) {
  auto spec = o.config.empty()
                  ? deploy::load_deployment_string(demo::kDemoDeployment, "<built-in demo>")
                  : deploy::load_deployment_file(o.config);
  if (!spec) {
    std::fprintf(stderr, "vigil demo: invalid deployment:\n%s\n",
                 config::to_string(spec.error()).c_str());
    return unexpected(1);
  }
  const auto level = log::parse_level(o.log_level);
  if (!level) {
    std::fprintf(stderr, "vigil demo: --log-level %s: expected debug, info, warn, error or off\n",
                 o.log_level.c_str());
    return unexpected(1);
  }
  log::set_default_level(*level);
  if (!o.http.empty()) {
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil demo: --http %s\n", listen.error().c_str());
      return unexpected(2);
    }
    if (!spec->outputs.http) spec->outputs.http.emplace();
    spec->outputs.http->listen = *listen;
  }
  if (!o.textfile.empty()) spec->outputs.textfile = o.textfile;
  if (!o.json.empty()) spec->outputs.json = o.json;
  if (o.http_clear && spec->outputs.http) spec->outputs.http->clear = true;
  if (o.ros2 && !spec->outputs.ros2) spec->outputs.ros2.emplace();  // ROS_DOMAIN_ID, else 0
  if (o.dry_run_reactions) spec->reactions.dry_run = true;
  return std::move(*spec);
}

// Registers what the flags ask for: the components' log (under the live view, else on stderr;
// a rotating file), the event file and traces, event lines, the text view.
expected<DemoOutputs, int> add_outputs(deploy::System& system, const DemoOptions& o) {
  service::SupervisionService& pipeline = system.service();
  const bool live = platform::is_terminal(stdout) && !o.no_live;
  DemoOutputs out;
  auto& log = pipeline.add_output<service::ComponentLog>();
  if (live) {
    log.show_tail(kLogPanelLines);
  } else {
    log.logs().add_sink(std::make_shared<log::StreamSink>(stderr));
  }
  if (!o.log_file.empty()) {
    auto file =
        log::RotatingFileSink::open({.path = o.log_file, .max_bytes = 1U << 20U, .max_files = 3});
    if (!file) {
      std::fprintf(stderr, "vigil demo: %s\n", file.error().message.c_str());
      return unexpected(1);
    }
    log.logs().add_sink(std::shared_ptr<log::RotatingFileSink>(std::move(*file)));
  }
  if (!o.events.empty()) out.event_file = &pipeline.add_output<exporter::EventLogOutput>(o.events);
  if (!o.trace_dir.empty()) {
    out.traces = &pipeline.add_output<exporter::TraceOutput>(
        exporter::TraceWriterOptions{.directory = o.trace_dir, .log = [](const std::string& line) {
                                       std::fprintf(stderr, "vigil demo: %s\n", line.c_str());
                                     }});
  }
  auto& event_lines = pipeline.add_output<exporter::EventLineOutput>(
      exporter::EventLineOutput::Options{.file = live ? nullptr : stderr});
  std::vector<const exporter::TextPanel*> panels{&log};
  if (live) panels.push_back(&event_lines);
  out.text = &pipeline.add_output<exporter::TextOutput>(
      exporter::TextOutputOptions{.file = stdout,
                                  .every_cycle = !o.no_live,
                                  .details_at_stop = o.details,
                                  .color = color_mode(o.color),
                                  .title = fmt::format("vigil demo — {}", system.spec().name),
                                  .redraw = live,
                                  .panels = std::move(panels),
                                  .final_title = "Stopped"});
  return out;
}

// A component never returned from on_update: says what the monitor (still running, it stops
// after the activities) last saw, writes it, and leaves without joining the blocked thread.
[[noreturn]] void leave_stuck(deploy::System& system, const DemoOptions& o, Nanos start) {
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
              platform::stop_requested() ? "Interrupted" : "Ended",
              static_cast<double>(platform::now_ns() - start) / 1e9);
  std::fputs(format_summary(last, use_color(color_mode(o.color), stdout)).c_str(), stdout);
  if (system.json_output() != nullptr) {
    const std::string path = system.spec().outputs.json->string();
    if (auto ok = exporter::write_json_file(path, last); ok) {
      std::printf("Final reports written to %s\n", path.c_str());
    } else {
      std::fprintf(stderr, "vigil demo: %s\n", ok.error().message.c_str());
    }
  }
  std::fflush(stdout);
  std::fflush(stderr);
  std::_Exit(kDemoExitStuck);
}

// Says what the outputs wrote; the exit code (kDemoExitOutput when the JSON file failed).
int say_written(const deploy::System& system, const DemoOutputs& out, const DemoOptions& o) {
  if (out.event_file != nullptr) {  // written up to the stop (the output waited for its writer)
    if (const std::string err = out.event_file->error(); !err.empty()) {
      std::fprintf(stderr, "vigil demo: %s\n", err.c_str());
    }
    const std::uint64_t lost = out.event_file->lost();
    std::printf("%llu events written to %s%s\n",
                static_cast<unsigned long long>(out.event_file->written()), o.events.c_str(),
                lost > 0 ? fmt::format(" ({} lost: the writer fell behind)", lost).c_str() : "");
  }
  if (out.traces != nullptr) {
    const std::size_t n = out.traces->written().size();
    std::printf("%zu trace%s written to %s (open them in https://ui.perfetto.dev)\n", n,
                n == 1 ? "" : "s", o.trace_dir.c_str());
  }
  if (const std::string err = system.output_error(); !err.empty()) {
    std::fprintf(stderr, "vigil demo: %s\n", err.c_str());
  }
  int rc = 0;
  if (const auto* json = system.json_output(); json != nullptr) {
    if (json->written()) {
      std::printf("Final reports written to %s\n", system.spec().outputs.json->c_str());
    } else {
      rc = kDemoExitOutput;  // said on stderr by the output
    }
  }
  std::fflush(stdout);
  return rc;
}

}  // namespace

int run_demo(const DemoOptions& o) {
  demo::register_components();
  if (o.print_config) {
    std::fputs(demo::kDemoDeployment, stdout);
    return 0;
  }
  auto spec = load_spec(o);
  if (!spec) return spec.error();
  auto sys = deploy::System::create(std::move(*spec));
  if (!sys) {
    std::fprintf(stderr, "vigil demo: cannot build the system:\n%s\n",
                 config::to_string(sys.error()).c_str());
    return 1;
  }
  deploy::System& system = **sys;
  const auto outputs = add_outputs(system, o);
  if (!outputs) return outputs.error();

  platform::install_stop_signals();  // Ctrl-C and SIGTERM stop cleanly
  if (auto r = system.start(); !r) {
    std::fprintf(stderr, "vigil demo: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  std::printf("vigil %s: running '%s' with %zu components%s\n", kVersion,
              system.spec().name.c_str(), system.spec().components.size(),
              o.duration_s > 0 ? fmt::format(" for {} s (Ctrl-C stops)", o.duration_s).c_str()
                               : " until Ctrl-C");
  for (const auto& line : system.log()) std::printf("  %s\n", line.c_str());
  std::fflush(stdout);

  const Nanos start = platform::now_ns();
  const Nanos end =
      o.duration_s > 0
          ? start + static_cast<Nanos>(o.duration_s * static_cast<double>(kNanosPerSecond))
          : INT64_MAX;
  while (!platform::stop_requested() && platform::now_ns() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (platform::stop_requested()) outputs->text->set_final_title("Interrupted");
  const Nanos timeout_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(kDemoStopTimeout).count();
  if (!system.stop_within(timeout_ns)) leave_stuck(system, o, start);
  return say_written(system, *outputs, o);
}

}  // namespace vigil::app
