// vigil: the command-line tool. `vigil demo` runs a supervised system (the built-in simulated
// robot, or a deployment file); `vigil check-config` validates configuration files;
// `vigil can-stats` replays CAN logs through the CAN supervision pipeline; `vigil supervise`
// supervises the components of other processes through shared memory.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

#include "commands.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/version.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "vigil supervises real-time components: timing, overruns, real-time losses, exceptions,\n"
      "and an OK / WARN / ERROR status for each component, as text and JSON.",
      "vigil"};
  app.set_version_flag("-V,--version", std::string("vigil ") + vigil::kVersion);
  app.require_subcommand(1);
  app.footer(
      "Run `vigil COMMAND --help` for a command's options. Documentation: docs/ in the "
      "source tree.");

  vigil::app::DemoOptions demo;
  auto* demo_cmd = app.add_subcommand(
      "demo",
      "Run a supervised system with a live view: the built-in simulated robot, or "
      "--config FILE");
  demo_cmd->add_option("-c,--config", demo.config, "Deployment file (YAML) to run instead")
      ->check(CLI::ExistingFile);
  demo_cmd
      ->add_option("-d,--duration", demo.duration_s,
                   "Seconds to run; 0 runs until Ctrl-C (default: 20)")
      ->check(CLI::NonNegativeNumber);
  demo_cmd->add_option("-j,--json", demo.json, "Write the final reports to FILE (JSON schema 1)");
  demo_cmd->add_option("--color", demo.color, "Colour: auto, always or never")
      ->check(CLI::IsMember({"auto", "always", "never"}));
  demo_cmd->add_flag("--no-live", demo.no_live, "Print only the final report, no live view");
  demo_cmd->add_flag("--details", demo.details, "End with the detail view of every component");
  demo_cmd->add_flag("--print-config", demo.print_config, "Print the built-in deployment and exit");
  demo_cmd->add_option("--http", demo.http,
                       "Serve /metrics, the JSON APIs and the dashboard on [ADDR:]PORT "
                       "(127.0.0.1 unless ADDR is given; PORT 0 picks a free one)");
  demo_cmd->add_option("--prom-file", demo.textfile,
                       "Rewrite FILE.prom (node-exporter textfile) after every monitor cycle");
  demo_cmd->add_option("--log-file", demo.log_file,
                       "Also write the components' log lines to FILE (rotated at 1 MiB, 3 files)");
  demo_cmd
      ->add_option("--log-level", demo.log_level,
                   "The components' log level: debug, info (default), warn, error or off")
      ->check(CLI::IsMember({"debug", "info", "warn", "error", "off"}));

  demo_cmd->add_option("--events", demo.events,
                       "Write every event (exceptions, deadlines, overruns, ...) to FILE as JSON "
                       "lines");
  demo_cmd->add_option("--trace-dir", demo.trace_dir,
                       "Write a component's last cycles as a Perfetto/Chrome trace into DIR when "
                       "it goes to ERROR (open them in ui.perfetto.dev)");
  demo_cmd->add_flag("--http-clear", demo.http_clear,
                     "Enable POST /api/v1/clear (clears latched faults) on the HTTP endpoint");
  demo_cmd->add_flag("--ros2", demo.ros2,
                     "Publish ROS 2 /diagnostics over DDS (domain: ROS_DOMAIN_ID, else 0)");
  demo_cmd->add_flag(
      "--dry-run-reactions", demo.dry_run_reactions,
      "The reactions log what they would do (safe state, CAN frames) and do nothing");

  vigil::app::CheckConfigOptions check;
  auto* check_cmd = app.add_subcommand(
      "check-config", "Validate a deployment or thresholds file; errors name file:line:col");
  check_cmd->add_option("FILE", check.files, "Files to check")->required();
  check_cmd->add_option("--kind", check.kind, "deployment, thresholds or auto (default)")
      ->check(CLI::IsMember({"auto", "deployment", "thresholds"}));

  vigil::app::CanStatsArgs can;
  auto* can_cmd = app.add_subcommand(
      "can-stats", "Replay CAN logs (candump -l, PCAN .trc) and report per-node statistics");
  can_cmd->add_option("FILE", can.files, "Log files")->required()->check(CLI::ExistingFile);
  can_cmd->add_option("-c,--config", can.config, "CAN configuration (filters, groups, thresholds)")
      ->check(CLI::ExistingFile);
  can_cmd->add_flag("--json", can.json, "Print JSON instead of text");
  can_cmd->add_option("--node-map", can.node_map, "identity, canopen, j1939 or dronecan")
      ->check(CLI::IsMember({"identity", "canopen", "j1939", "dronecan"}));

  vigil::app::SuperviseOptions sup;
  auto* sup_cmd = app.add_subcommand(
      "supervise",
      "Supervise the components of other processes (started with VIGIL_SUPERVISOR=NAME): live "
      "view, processes that die, final reports");
  sup_cmd->add_option("-n,--name", sup.name, "Supervisor name the processes use (default: vigil)");
  sup_cmd->add_option("-j,--json", sup.json, "Write the final reports to FILE (JSON schema 1)");
  sup_cmd->add_option("--http", sup.http,
                      "Serve the reports, /metrics and the dashboard on [ADDR:]PORT (default "
                      "address 127.0.0.1)");
  sup_cmd->add_option("--health", sup.health,
                      "Supervise the alive, deadline and logical supervisions of FILE's `health:` "
                      "section (a deployment file, or one with the section's keys)");
  sup_cmd->add_option("--diagnosis", sup.diagnosis,
                      "Apply FILE's `diagnosis:` section (dependencies, aggregates, hysteresis, "
                      "start-up suppression, latches) to the processes' components");
  sup_cmd
      ->add_option("-d,--duration", sup.duration_s,
                   "Seconds to run; 0 runs until Ctrl-C (default: 0)")
      ->check(CLI::NonNegativeNumber);
  sup_cmd->add_option("--period-ms", sup.period_ms, "Drain period in ms (default: 10)")
      ->check(CLI::Range(0.1, 10000.0));
  sup_cmd->add_option("--group", sup.group,
                      "Also accept segments shared with this group (mode 0660)");
  sup_cmd->add_option("--color", sup.color, "Colour: auto, always or never")
      ->check(CLI::IsMember({"auto", "always", "never"}));
  sup_cmd->add_flag("--no-live", sup.no_live, "Print events and the final report, no live view");
  sup_cmd->add_flag("--details", sup.details, "End with the detail view of every component");
  sup_cmd->add_flag("--keep-segments", sup.keep_segments,
                    "Do not remove the segments of dead processes and departed components");
  sup_cmd->add_flag("--ros2", sup.ros2,
                    "Publish ROS 2 /diagnostics over DDS (domain: ROS_DOMAIN_ID, else 0)");

  CLI11_PARSE(app, argc, argv);

  // Xenomai Cobalt: libcobalt starts here, after vigil has read its own command line (the build
  // links no automatic start-up, which would act on --help, --version, --verbose, ... before
  // main(); docs/guide/xenomai-cobalt.md). Only the commands that supervise need it: check-config,
  // can-stats and `demo --print-config` read and print files. Linux: nothing to start.
  if ((demo_cmd->parsed() && !demo.print_config) || sup_cmd->parsed()) {
    if (auto core = vigil::platform::initialize(); !core) {
      fmt::print(stderr, "vigil: {}\n", core.error().message);
      return 1;
    }
  }

  if (demo_cmd->parsed()) return vigil::app::run_demo(demo);
  if (check_cmd->parsed()) return vigil::app::run_check_config(check);
  if (can_cmd->parsed()) return vigil::app::run_can_stats_command(can);
  if (sup_cmd->parsed()) return vigil::app::run_supervise(sup);
  return 2;
}
