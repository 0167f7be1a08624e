#pragma once
// The subcommands of the vigil tool.
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
};
int run_demo(const DemoOptions& options);

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
  double duration_s = 0;  ///< 0: until Ctrl-C
  double period_ms = 10;
  std::string group;
  std::string color = "auto";
  bool no_live = false;
  bool details = false;
  bool keep_segments = false;
};
int run_supervise(const SuperviseOptions& options);

}  // namespace vigil::app
