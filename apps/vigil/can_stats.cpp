// `vigil can-stats FILE...`: replays CAN logs through the CAN supervision pipeline.
#include <iostream>

#include "commands.hpp"
#include "vigil/can/replay.hpp"

namespace vigil::app {

int run_can_stats_command(const CanStatsArgs& args) {
  can::CanStatsOptions o;
  for (const auto& f : args.files) o.files.emplace_back(f);
  if (!args.config.empty()) o.config = args.config;
  o.json = args.json;
  if (!args.node_map.empty()) o.node_map = can::parse_node_map_kind(args.node_map);
  return can::run_can_stats(o, std::cout, std::cerr);
}

}  // namespace vigil::app
