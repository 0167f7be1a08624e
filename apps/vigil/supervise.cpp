// `vigil supervise`: the daemon that supervises the components of other processes (those started
// with VIGIL_SUPERVISOR=<name>). Live view every monitor period, process events as they happen,
// final reports on Ctrl-C or after --duration. The work is a SupervisionService draining the
// segments (service::SegmentSource); this file translates flags and presents it.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <thread>

#include "commands.hpp"
#include "vigil/config/load.hpp"
#include "vigil/deploy/diagnosis_section.hpp"
#include "vigil/deploy/health_section.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/export/ros2_diagnostics.hpp"
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

// The service's options from the flags; the exit code when a flag is wrong.
expected<service::SupervisionServiceOptions, int> options_of(const SuperviseOptions& o) {
  service::SupervisionServiceOptions opts;
  opts.segments =
      service::SegmentSourceOptions{.name = o.name, .group = o.group, .reclaim = !o.keep_segments};
  opts.supervisor_period_ns = static_cast<Nanos>(o.period_ms * static_cast<double>(kNanosPerMilli));
  opts.monitor_period_ns = kNanosPerSecond;
  opts.summary_file = nullptr;  // the text output below shows the processes too
  if (!o.http.empty()) {        // --http: the server publishes every cycle, processes included
    auto listen = exporter::parse_listen(o.http);
    if (!listen) {
      std::fprintf(stderr, "vigil supervise: --http %s\n", listen.error().c_str());
      return unexpected(2);
    }
    opts.http.emplace();
    opts.http->listen = *listen;
    opts.http->log = [](const std::string& line) { std::printf("%s\n", line.c_str()); };
  }
  if (auto ok = service::validate(*opts.segments); !ok) {
    std::fprintf(stderr, "vigil supervise: %s\n", ok.error().message.c_str());
    return unexpected(1);
  }
  return opts;
}

// `--health FILE`: its `health:` section (or the whole file as one). The components come from
// other processes, so any component name is accepted; the exit code on an error.
expected<health::HealthConfig, int> health_of(const std::string& file) {
  auto root = config::load_file(file);
  if (!root) {
    std::fprintf(stderr, "vigil supervise: --health %s\n", config::to_string(root.error()).c_str());
    return unexpected(1);
  }
  const config::Node section =
      root->is_mapping() && root->has("health") ? (*root)["health"] : *root;
  deploy::HealthSpec spec = deploy::parse_health(section, {});
  if (root->has_errors()) {
    std::fprintf(stderr, "vigil supervise: --health %s:\n%s\n", file.c_str(),
                 config::to_string(root->errors()).c_str());
    return unexpected(1);
  }
  if (spec.empty()) {
    std::fprintf(stderr, "vigil supervise: --health %s: no supervision in it\n", file.c_str());
    return unexpected(1);
  }
  return std::move(spec.config);
}

// `--diagnosis FILE`: its `diagnosis:` section (or the whole file as one). Unit names are not
// checked against a system (the components come and go with their processes).
expected<monitor::DiagnosisConfig, int> diagnosis_of(const std::string& file) {
  auto root = config::load_file(file);
  if (!root) {
    std::fprintf(stderr, "vigil supervise: --diagnosis %s\n",
                 config::to_string(root.error()).c_str());
    return unexpected(1);
  }
  const config::Node section =
      root->is_mapping() && root->has("diagnosis") ? (*root)["diagnosis"] : *root;
  deploy::DiagnosisSpec spec = deploy::parse_diagnosis(section);
  if (root->has_errors()) {
    std::fprintf(stderr, "vigil supervise: --diagnosis %s:\n%s\n", file.c_str(),
                 config::to_string(root->errors()).c_str());
    return unexpected(1);
  }
  return std::move(spec.config);
}

}  // namespace

int run_supervise(const SuperviseOptions& o) {
  auto opts = options_of(o);
  if (!opts) return opts.error();
  std::optional<health::HealthConfig> health;
  if (!o.health.empty()) {
    auto h = health_of(o.health);
    if (!h) return h.error();
    health = std::move(*h);
  }
  std::optional<monitor::DiagnosisConfig> diagnosis;
  if (!o.diagnosis.empty()) {
    auto d = diagnosis_of(o.diagnosis);
    if (!d) return d.error();
    diagnosis = std::move(*d);
  }
  service::SupervisionService daemon(std::move(*opts));
  if (diagnosis) {
    if (auto r = daemon.set_diagnosis(std::move(*diagnosis)); !r) {
      std::fprintf(stderr, "vigil supervise: --diagnosis %s: %s\n", o.diagnosis.c_str(),
                   r.error().message.c_str());
      return 1;
    }
  }
  if (health) {
    if (auto r = daemon.aggregator().supervise_health(std::move(*health)); !r) {
      std::fprintf(stderr, "vigil supervise: --health %s: %s\n", o.health.c_str(),
                   r.error().message.c_str());
      return 1;
    }
  }
  service::SegmentSource& segments = *daemon.segments();
  // What happens to processes (joined, left, exited, rejected) as lines, as it happens: under
  // the live view on a terminal, else on stdout. The live view: the summary and the process
  // table every second (redrawn in place on a terminal), and the final report.
  const bool live = platform::is_terminal(stdout) && !o.no_live;
  auto& events = daemon.add_output<exporter::EventLineOutput>(
      exporter::EventLineOutput::Options{.file = live ? nullptr : stdout, .lines = 8});
  std::vector<const exporter::TextPanel*> panels{&segments};
  if (live) panels.push_back(&events);
  auto& text = daemon.add_output<exporter::TextOutput>(
      exporter::TextOutputOptions{.file = stdout,
                                  .every_cycle = !o.no_live,
                                  .details_at_stop = o.details,
                                  .color = mode_of(o.color),
                                  .title = fmt::format("vigil supervise — {}", o.name),
                                  .redraw = live,
                                  .panels = std::move(panels),
                                  .final_title = "Stopped"});
  auto* json = o.json.empty() ? nullptr : &daemon.add_output<exporter::JsonFileOutput>(o.json, 2);
  // --ros2: the domain is ROS_DOMAIN_ID, else 0; a bad one is a warning (nothing published).
  exporter::Ros2DiagnosticsOutput* ros2 = nullptr;
  if (o.ros2) ros2 = &daemon.add_output<exporter::Ros2DiagnosticsOutput>();

  platform::install_stop_signals();
  if (auto r = daemon.start(); !r) {
    std::fprintf(stderr, "vigil supervise: cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  std::printf("vigil %s: supervising '%s' (segments /dev/shm/vigil.%s.*), drained every %s%s\n",
              kVersion, o.name.c_str(), o.name.c_str(),
              format_nanos(static_cast<double>(segments.options().period_ns)).c_str(),
              o.duration_s > 0 ? fmt::format(" for {} s", o.duration_s).c_str() : "; Ctrl-C stops");
  std::printf("Start processes with VIGIL_SUPERVISOR=%s in their environment.\n", o.name.c_str());
  if (ros2 != nullptr && ros2->active()) {
    const std::string node = ros2->node();
    std::printf("ROS 2: /diagnostics (DDS topic rt/diagnostics) in domain %d%s\n",
                ros2->domain_id(), node.empty() ? "" : (", node " + node).c_str());
  }
  std::fflush(stdout);

  const Clock clock = daemon.options().clock;
  const Nanos end =
      o.duration_s > 0 ? clock.now() + static_cast<Nanos>(o.duration_s * 1e9) : INT64_MAX;
  while (!platform::stop_requested() && clock.now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (platform::stop_requested()) text.set_final_title("Interrupted");
  (void)daemon.stop();  // last drain, last cycle: the final report, the JSON file
  if (json != nullptr) {
    if (!json->written()) return 1;  // said on stderr by the output
    std::printf("Final reports written to %s\n", o.json.c_str());
  }
  return 0;
}

}  // namespace vigil::app
