#pragma once
// The subcommands of the vigil tool.
#include <chrono>
#include <string>
#include <vector>

namespace vigil::app {

struct DemoOptions {
  std::string config;
  double duration_s = 20;
  std::string json;
  std::string color = "auto";
  bool no_live = false;
  bool details = false;
  bool print_config = false;
  std::string http;      ///< "[ADDR:]PORT": serve HTTP (overrides the deployment's outputs.http)
  std::string textfile;  ///< node-exporter textfile (.prom) rewritten every monitor cycle
  std::string log_file;  ///< rotating log file (empty: none)
  std::string log_level = "info";  ///< the components' run-time log level
  std::string events;              ///< write every event to FILE as JSON lines (empty: none)
  std::string trace_dir;           ///< write flight-recorder traces to DIR (empty: none)
  bool http_clear = false;         ///< enable POST /api/v1/clear on the HTTP endpoint
  bool ros2 = false;  ///< publish ROS 2 /diagnostics over DDS (adds the deployment's outputs.ros2)
  bool dry_run_reactions = false;  ///< the reactions log what they would do (reactions.dry_run)
};
/// Runs `vigil demo`. Exit codes (docs/guide/faults.md):
///  0 ran for --duration or was stopped by SIGINT/SIGTERM; final report printed, JSON written;
///  1 could not run: invalid deployment, the system could not be built or started;
///  3 ran, but the final reports could not be written to the JSON file (path and reason on
///    stderr; the report was printed);
///  4 did not stop within kDemoStopTimeout: a component stuck in on_update; the monitor's latest
///    reports were printed and written, and the process left without joining that thread.
/// (2 is a command-line error, from main.)
int run_demo(const DemoOptions& options);
inline constexpr int kDemoExitOutput = 3;
inline constexpr int kDemoExitStuck = 4;
inline constexpr std::chrono::seconds kDemoStopTimeout{5};

struct CheckConfigOptions {
  std::vector<std::string> files;
  std::string kind = "auto";
};
int run_check_config(const CheckConfigOptions& options);

struct CanStatsArgs {
  std::vector<std::string> files;
  std::string config;
  bool json = false;
  std::string node_map;  ///< empty: the configuration's (identity without one)
};
int run_can_stats_command(const CanStatsArgs& args);

struct SuperviseOptions {
  std::string name = "vigil";
  std::string json;
  std::string http;       ///< [ADDR:]PORT: serve the reports over HTTP (docs/reference/http.md)
  std::string health;     ///< a YAML file with a `health:` section (or the section's keys)
  std::string diagnosis;  ///< a YAML file with a `diagnosis:` section (or the section's keys)
  double duration_s = 0;  ///< 0: until Ctrl-C
  double period_ms = 10;
  std::string group;
  std::string color = "auto";
  bool no_live = false;
  bool details = false;
  bool keep_segments = false;
  bool ros2 = false;  ///< publish ROS 2 /diagnostics over DDS (domain: ROS_DOMAIN_ID)
};
int run_supervise(const SuperviseOptions& options);

}  // namespace vigil::app
