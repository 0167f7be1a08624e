// `vigil can-stats FILE...`: replays CAN logs through the CAN supervision pipeline.
#include "can_stats.hpp"

#include <iostream>

#include "commands.hpp"
#include "vigil/can/can_config.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/config/error.hpp"
#include "vigil/export/can_report.hpp"

namespace vigil::app {

int run_can_stats(const CanStatsOptions& options, std::ostream& out, std::ostream& err) {
  if (options.files.empty()) {
    err << "vigil can-stats: no log file given\n"
           "usage: vigil can-stats FILE... [--config FILE] [--json] "
           "[--node-map identity|canopen|j1939|dronecan]\n";
    return 2;
  }
  can::CanConfig config;
  if (options.config) {
    auto loaded = can::load_can_config_file(*options.config);
    if (!loaded) {
      err << config::to_string(loaded.error()) << '\n';
      return 1;
    }
    config = std::move(*loaded);
  }
  if (options.node_map) config.node_map = *options.node_map;

  can::LogReplay replay({.node_map = can::NodeMap::of(config.node_map),
                         .filter = config.filter,
                         .default_direction = options.default_direction,
                         .exact_percentiles = true,
                         .protocol = [&] {
                           can::ProtocolOptions p = config.protocol_options();
                           p.max_events = 65536;
                           return p;
                         }()});
  const auto fed = replay.feed_files(options.files, options.format);
  err << exporter::format_replay_warnings(replay, "vigil can-stats: ");
  if (!fed) {
    err << "vigil can-stats: " << fed.error().message << '\n';
    return 1;
  }
  const can::CanMonitor monitor(config);
  const can::CanReport report = replay.report(monitor);
  if (options.json) {
    out << exporter::can_replay_json(replay, report) << '\n';
  } else {
    out << exporter::format_can_replay(
        replay, report,
        {.ids = options.ids, .config = options.config ? options.config->string() : ""});
  }
  return 0;
}

int run_can_stats_command(const CanStatsArgs& args) {
  CanStatsOptions o;
  for (const auto& f : args.files) o.files.emplace_back(f);
  if (!args.config.empty()) o.config = args.config;
  o.json = args.json;
  if (!args.node_map.empty()) o.node_map = can::parse_node_map_kind(args.node_map);
  return run_can_stats(o, std::cout, std::cerr);
}

}  // namespace vigil::app
