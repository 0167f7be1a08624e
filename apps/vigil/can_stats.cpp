// `vigil can-stats FILE...`: replays CAN logs through the CAN supervision pipeline.
#include <cstdio>

#include "commands.hpp"

namespace vigil::app {

int run_can_stats_command(const CanStatsArgs& /*args*/) {
  std::fprintf(stderr, "vigil can-stats: CAN supervision is not built into this vigil yet\n");
  return 2;
}

}  // namespace vigil::app
