#pragma once
// `vigil can-stats`: what the command does, callable from tests (tests/can/replay_test.cpp).
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/can/replay.hpp"

namespace vigil::app {

/// Options of `vigil can-stats` (one field per command-line option).
struct CanStatsOptions {
  std::vector<std::filesystem::path> files{};     ///< FILE...: candump logs or PEAK traces
  std::optional<std::filesystem::path> config{};  ///< --config FILE: a CAN configuration
  bool json = false;                              ///< --json: one JSON object instead of text
  std::optional<can::NodeMapKind> node_map{};     ///< --node-map: overrides the configuration's
  can::LogFormat format = can::LogFormat::Auto;   ///< the log format (auto: by extension)
  can::Direction default_direction = can::Direction::Rx;  ///< for lines without a direction
  bool ids = true;                                        ///< per-id table in the text output
};

/// Replays the logs (vigil::can::LogReplay), judges them with the CAN monitor at the last
/// timestamp and prints the result to `out` as text or JSON (vigil/export/can_report.hpp);
/// warnings (malformed lines, the first 10 of each file) and errors go to `err`.
/// Returns 0 when every file was read, 1 when a file or the configuration could not be read (or
/// a malformed line with OnMalformed::Stop), 2 when no file was given. The monitor's verdict
/// does not change the exit code: it is in the output.
int run_can_stats(const CanStatsOptions& options, std::ostream& out, std::ostream& err);

}  // namespace vigil::app
